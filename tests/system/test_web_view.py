"""The web viewer, seen in a headless Chromium: every panel of the layout
draws the run's data, live (``swarm run --serve-web``, at the address it
prints) and from the finished recording (served by ``rerun --serve-web``).

Needs a Chromium (``apt-get install -y chromium``); skipped without one.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from formation_swarm.launch.launcher import free_port
from formation_swarm.nodes.logger import viewer
from tests.helpers import RERUN, SCENARIOS, wait_listening
from tests.helpers.browser import Page, chromium, find_chromium

WIDTH, HEIGHT = 1600, 1000
TOP_BAR, TIME_BAR = 36, 28  # px: Rerun's top bar, the collapsed time panel
COLUMNS = (1.5, 1.75, 1.75)  # the blueprint's column shares: map | 3 series | 2 series and the events
SERIES = {
    (1, 0): "formation error",
    (1, 1): "V_N",
    (1, 2): "target error",
    (2, 0): "wheel speeds",
    (2, 1): "link drops",
}
ADDRESS = re.compile(r"http://127\.0\.0\.1:\d+/\?url=\S+")


def _panels(png: Path) -> dict[str, int]:
    """How much each panel of the screenshot draws: coloured pixels on the
    map and in each time series' plot (its right part: the legend is at the
    left), red ones for the obstacles, and text pixels in the event log's rows."""
    from PIL import Image

    im = np.asarray(Image.open(png).convert("RGB")).astype(int)
    xs = np.concatenate([[0], np.cumsum(COLUMNS) / sum(COLUMNS) * WIDTH]).astype(int)
    ys = np.linspace(TOP_BAR, HEIGHT - TIME_BAR, 4).astype(int)
    coloured = (im.max(-1) - im.min(-1)) > 50
    red = (im[..., 0] > 150) & (im[..., 1] < 100) & (im[..., 2] < 100)
    body = slice(ys[0] + 30, ys[3] - 5), slice(5, xs[1] - 5)
    seen = {"map": int(coloured[body].sum()), "obstacles": int(red[body].sum())}
    for (col, row), name in SERIES.items():
        x0, x1, y0, y1 = xs[col], xs[col + 1], ys[row], ys[row + 1]
        seen[name] = int(coloured[y0 + 27 : y1 - 25, x0 + (x1 - x0) // 2 : x1 - 10].sum())  # below the title
    rows = im[ys[2] + 60 : ys[3] - 5, xs[2] + 5 : xs[3] - 5]
    background = np.median(rows.reshape(-1, 3), axis=0)
    seen["events"] = int((np.abs(rows - background).max(-1) > 60).sum())
    return seen


DRAWN = {"map": 200, "obstacles": 30, "events": 500} | dict.fromkeys(SERIES.values(), 100)


def _drawn(seen: dict[str, int]) -> bool:
    return all(seen[name] >= least for name, least in DRAWN.items())


def _watch(
    page: Page, url: str, png: Path, timeout_s: float, drawn: Callable[[dict[str, int]], bool] | None = None
) -> dict[str, int]:
    """Open ``url`` and take screenshots until every panel has drawn (``drawn``
    says so; default ``_drawn``) or the timeout; the last count."""
    drawn = drawn or _drawn
    page.open(url, WIDTH, HEIGHT)
    deadline = time.monotonic() + timeout_s
    while True:
        time.sleep(1.0)  # a screenshot takes the software renderer about as long
        try:
            seen = _panels(page.screenshot(png))
        except RuntimeError as exc:
            # Once in a full suite (a loaded machine), the tab was between two
            # documents, the navigation still under way: the next second's, until the deadline.
            if "Not attached to an active page" not in str(exc) or time.monotonic() > deadline:
                raise
            continue
        if drawn(seen) or time.monotonic() > deadline:
            return seen


@contextlib.contextmanager
def _group(argv: list[str], **kwargs: object) -> Iterator[subprocess.Popen[str]]:
    """A process in its own group, stopped with its children at the end."""
    proc = subprocess.Popen(argv, start_new_session=True, text=True, **kwargs)  # type: ignore[call-overload]
    try:
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def _lines(proc: subprocess.Popen[str]) -> list[str]:
    """The process's output lines, read as they come by a thread."""
    lines: list[str] = []
    assert proc.stdout is not None
    threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True).start()
    return lines


def _stop_after_a_second_more(run: subprocess.Popen[str], lines: list[str]) -> None:
    """Once the live view has drawn, the rest of the run adds nothing to see: Ctrl-C
    it (its recording is kept whole up to the stop) and wait for its exit, 130."""
    time.sleep(1.0)  # a second more of rows for the file, whatever the render took
    with contextlib.suppress(ProcessLookupError):
        os.killpg(run.pid, signal.SIGINT)
    assert run.wait(timeout=120) in (0, 130), "".join(lines[-20:])  # 0: it had ended


def _first(lines: list[str], pattern: re.Pattern[str], timeout_s: float) -> str:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for line in list(lines):
            if m := pattern.search(line):
                return m.group(0)
        time.sleep(0.1)
    raise AssertionError(f"no line matching {pattern.pattern} in {timeout_s:g} s: {lines}")


@pytest.mark.slow
def test_every_panel_draws_live_and_from_the_recording(tmp_path: Path) -> None:
    exe = find_chromium()
    if exe is None:
        pytest.skip("no Chromium to load the web viewer in: apt-get install -y chromium")
    swarm = str(Path(sys.executable).parent / "swarm")
    # 40 s in real time: the viewer's page (tens of MB of WebAssembly) loads on a
    # busy machine before the run, and with it the served data, is over.
    grpc_port, web_port = free_port(), free_port()
    run_dir = tmp_path / "run"
    argv = [
        swarm,
        "run",
        str(SCENARIOS / "fig11_obstacles.toml"),
        "--mode",
        "realtime",
        "--out",
        str(run_dir),
        "--set",
        "run.duration_s=40",
        "--fault",
        "drop obs:2@2s for=5s p=0.3",
        "--serve-web",
        "--grpc-port",
        str(grpc_port),
        "--web-port",
        str(web_port),
    ]
    with chromium(exe, tmp_path / "profile") as page:
        with _group(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT) as run:
            lines = _lines(run)
            address = _first(lines, ADDRESS, timeout_s=60)
            assert address == viewer.web_address(grpc_port, web_port)
            live = _watch(page, address, tmp_path / "live.png", timeout_s=120)  # 45 s did not do at load 17
            assert _drawn(live), (live, DRAWN, tmp_path / "live.png")
            _stop_after_a_second_more(run, lines)
        rrd = run_dir / "recording.rrd"
        file_grpc, file_web = free_port(), free_port()
        serve = [RERUN, "--serve-web", str(rrd), "--port", str(file_grpc), "--web-viewer-port", str(file_web)]
        with _group(serve, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL):
            wait_listening(file_web, timeout_s=30)
            # A busy machine's software renderer takes its time over the file's first seconds.
            finished = _watch(page, viewer.web_address(file_grpc, file_web), tmp_path / "file.png", timeout_s=180)
        assert _drawn(finished), (finished, DRAWN, tmp_path / "file.png")


CROWD_DRAWN = {"map": 200, "formation error": 100, "V_N": 100, "target error": 100}


def _crowd_drawn(seen: dict[str, int]) -> bool:
    return all(seen[name] >= least for name, least in CROWD_DRAWN.items())


@pytest.mark.slow
def test_a_hundred_robots_draw_live_and_from_the_recording(tmp_path: Path) -> None:
    """100 robots in a line: the map and the aggregate plots draw, live and
    from the file. With SWARM_FIGURES=DIR the screenshots are kept there
    (docs/figures/viewer-100-live.png, viewer-100-file.png)."""
    exe = find_chromium()
    if exe is None:
        pytest.skip("no Chromium to load the web viewer in: apt-get install -y chromium")
    swarm = str(Path(sys.executable).parent / "swarm")
    grpc_port, web_port = free_port(), free_port()
    run_dir = tmp_path / "run"
    # Ten robots a process: the run leaves the software renderer more of the two cores.
    sets = ["run.robots=100", "leader.formation=line", "run.duration_s=60", "controller.lookahead_m=1"]
    sets += ["run.agents_per_process=10"]
    argv = [swarm, "run", str(SCENARIOS / "fig11_obstacles.toml"), "--mode", "realtime", "--out", str(run_dir)]
    argv += [a for kv in sets for a in ("--set", kv)]
    argv += ["--serve-web", "--grpc-port", str(grpc_port), "--web-port", str(web_port)]
    keep = os.environ.get("SWARM_FIGURES")
    with chromium(exe, tmp_path / "profile") as page:
        with _group(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT) as run:
            lines = _lines(run)
            address = _first(lines, ADDRESS, timeout_s=180)
            live = _watch(page, address, tmp_path / "live.png", timeout_s=240, drawn=_crowd_drawn)
            if keep:  # a few seconds more of the run
                time.sleep(10.0)
                page.screenshot(Path(keep) / "viewer-100-live.png")
            assert _crowd_drawn(live), (live, CROWD_DRAWN, tmp_path / "live.png")
            if keep:
                assert run.wait(timeout=240) == 0, "".join(lines[-20:])
            else:
                _stop_after_a_second_more(run, lines)
        rrd = run_dir / "recording.rrd"
        file_grpc, file_web = free_port(), free_port()
        serve = [RERUN, "--serve-web", str(rrd), "--port", str(file_grpc), "--web-viewer-port", str(file_web)]
        with _group(serve, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL):
            wait_listening(file_web, timeout_s=30)
            url = viewer.web_address(file_grpc, file_web)
            finished = _watch(page, url, tmp_path / "file.png", timeout_s=180, drawn=_crowd_drawn)
            if keep:
                time.sleep(5.0)
                page.screenshot(Path(keep) / "viewer-100-file.png")
        assert _crowd_drawn(finished), (finished, CROWD_DRAWN, tmp_path / "file.png")
