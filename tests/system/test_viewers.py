"""The logger's live outputs: a stream to a viewer (--live) and a served web viewer (--serve-web).

A headless ``rerun --save`` stands in for the viewer: it writes what it
receives to a file, which is then read back like the run's own recording.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import rerun.blueprint as rrb

from formation_swarm.common.faults import Fault
from formation_swarm.common.palette import robot_colour
from formation_swarm.launch.launcher import Launch, RunResult, free_port
from formation_swarm.nodes.logger import viewer
from formation_swarm.nodes.logger.recording import blueprint, open_recording
from formation_swarm.report.build import make_report
from formation_swarm.report.data import read_recording
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import RERUN, SCENARIOS, rrd_rows, wait_listening

FIG11 = SCENARIOS / "fig11_obstacles.toml"


@contextlib.contextmanager
def _saving_viewer(args: list[str], out: Path) -> Iterator[subprocess.Popen[bytes]]:
    """``rerun ARGS --save OUT``, stopped and reaped at the end. ``rerun`` is a
    Python launcher that starts the real binary as its child: the whole
    process group is stopped, or the binary would outlive the test."""
    proc = subprocess.Popen(
        [RERUN, *args, "--save", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    try:
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        deadline = time.monotonic() + 10
        while _group_alive(proc.pid):
            if time.monotonic() > deadline:
                os.killpg(proc.pid, signal.SIGKILL)
                break
            time.sleep(0.05)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _wait_rows(path: Path, entity: str, n: int, timeout_s: float) -> dict[str, int]:
    """The file's rows once ``entity`` has ``n`` (the viewer writes as it receives)."""
    deadline = time.monotonic() + timeout_s
    while (rows := rrd_rows(path)).get(entity, 0) < n and time.monotonic() < deadline:
        time.sleep(0.2)
    return rows


def test_live_stream_carries_what_the_recording_has(tmp_path: Path, swarm_run: Callable[..., RunResult]) -> None:
    port = free_port()
    live = tmp_path / "live.rrd"
    with _saving_viewer(["--port", str(port)], live):
        wait_listening(port, timeout_s=30)
        res = swarm_run(FIG11, live=f"rerun+http://127.0.0.1:{port}/proxy", overrides={"run.duration_s": 6.0})
        assert res.exit_code == 0
        ticks = res.summary["ticks"]
        got = _wait_rows(live, "/robots/r3/ekf/target", ticks, timeout_s=20)
    recorded = rrd_rows(res.recording)
    for entity in (
        "/robots/r1/trajectory",
        "/robots/r2/trajectory",
        "/robots/r3/trajectory",
        "/robots/r2/ekf/target",
        "/robots/r3/ekf/target",
        "/robots/r2/fis/v_n",
    ):
        assert recorded[entity] == ticks, entity
        assert got.get(entity, 0) == ticks, (entity, got.get(entity, 0), ticks)


@pytest.mark.slow
def test_served_web_viewer_answers_and_streams(tmp_path: Path, swarm_launch: Callable[..., Launch]) -> None:
    grpc_port, web_port, viewer_port = free_port(), free_port(), free_port()
    said: list[str] = []
    launch = swarm_launch(
        FIG11,
        mode="realtime",
        serve_web=True,
        web_ports=(grpc_port, web_port),
        overrides={"run.duration_s": 4.0},
        progress=said.append,
    )
    address = f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc_port}%2Fproxy"
    assert launch.wait_until(lambda: any(address in line for line in said), timeout_s=60), said
    with urllib.request.urlopen(address, timeout=10) as page:
        assert page.status == 200
        assert b"<html" in page.read(4096).lower()
    web = tmp_path / "web.rrd"
    with _saving_viewer([viewer.grpc_address(grpc_port), "--port", str(viewer_port)], web):
        res = launch.wait(timeout_s=120)
        assert res.exit_code == 0
        ticks = res.summary["ticks"]
        # In real time a follower answers only the newest observation it has: a
        # loaded machine leaves a tick or two without its telemetry, in the file too.
        recorded = rrd_rows(res.recording)
        last = "/robots/r3/ekf/target"
        # The saving viewer writes what it takes as it comes: wait for the last rows (seconds, loaded).
        got = _wait_rows(web, last, recorded[last], timeout_s=60)
    # The server keeps what was logged before the viewer connected, and the
    # logger flushes its sinks before it exits.
    assert got.get("/robots/r1/trajectory", 0) == ticks
    for entity in ("/robots/r1/trajectory", "/robots/r2/fis/v_n", "/robots/r3/ekf/target", "/robots/r3/fis/v_n_1s"):
        assert got.get(entity, 0) == recorded[entity], (entity, got.get(entity, 0), recorded[entity])
    assert sum(address in line for line in said) == 1
    # Serving the web viewer takes nothing from the file: every tick of every follower that answered it.
    _assert_complete(res)


def _assert_complete(res: RunResult) -> None:
    """Every follower's every tick in the run's recording, and a report drawn from it."""
    ticks = res.summary["ticks"]
    assert ticks > 0
    data = read_recording(res.recording)
    for rid in (2, 3):
        answered = res.summary["parts"][f"agent-{rid}"]["answered"]  # real time: not every tick (superseded)
        for leaf in ("error/formation", "trajectory"):  # the world's, every tick
            assert len(data[f"/robots/r{rid}/{leaf}"]) == ticks, (rid, leaf)
        for leaf in ("fis/v_n", "wheels/left"):  # the follower's telemetry, one per tick it answered
            assert len(data[f"/robots/r{rid}/{leaf}"]) == answered, (rid, leaf, answered)
    assert (make_report(res.run_dir) / "report.md").is_file()


@pytest.mark.slow
def test_an_absent_live_viewer_is_said_once_and_costs_nothing(swarm_run: Callable[..., RunResult]) -> None:
    said: list[str] = []
    short = {"run.duration_s": 4.0}
    start = time.monotonic()
    swarm_run(FIG11, overrides=short)
    alone_s = time.monotonic() - start
    nobody = f"rerun+http://127.0.0.1:{free_port()}/proxy"
    start = time.monotonic()
    res = swarm_run(FIG11, overrides=short, live=nobody, progress=said.append)
    with_absent_s = time.monotonic() - start
    assert res.exit_code == 0
    assert [line for line in said if nobody in line] == [
        f"[swarm] --live {nobody}: no Rerun viewer answers there (Connection refused); not streaming there, "
        "the run is recorded to recording.rrd only"
    ]
    # Rerun's own sink would hold the logger 5 s at its start and 5 s at its end.
    assert with_absent_s < alone_s + 7.0, (with_absent_s, alone_s)  # 10 s with the hold; two runs' load varies
    assert not [e for e in res.summary["events"] if e.get("event") == "killed after stop timeout"]
    _assert_complete(res)


def test_the_logger_alone_leaves_an_absent_viewer_out_at_once(tmp_path: Path) -> None:
    sc = scenario_mod.load(FIG11)
    nobody = f"rerun+http://127.0.0.1:{free_port()}/proxy"
    start = time.monotonic()
    rec = open_recording("r", tmp_path / "r.rrd", sc, live=nobody)
    assert time.monotonic() - start < 3.0  # under 0.5 s quiet; Rerun's own sink would hold it 5 s
    assert rec.live is None
    assert rec.dropped == f"no Rerun viewer answers at {nobody} (Connection refused)"
    assert rec.close() is True
    assert (tmp_path / "r.rrd").stat().st_size > 0


def _named_paths(part: Any) -> set[str]:
    """Every entity path a blueprint's views name (contents and overrides)."""
    if isinstance(part, rrb.Blueprint):
        return _named_paths(part.root_container)
    if isinstance(part, rrb.Container):
        return set().union(*(_named_paths(p) for p in part.contents))
    contents = [part.contents] if isinstance(part.contents, str) else list(part.contents)
    return {c.removeprefix("+ ") for c in contents} | {str(k) for k in part.visualizer_overrides}


def test_every_path_the_viewer_shows_is_in_the_recording(swarm_run: Callable[..., RunResult]) -> None:
    res = swarm_run(FIG11, overrides={"run.duration_s": 3.0}, faults=["drop obs:2@1s for=1s p=0.3"])
    assert res.exit_code == 0
    sc = scenario_mod.load(res.run_dir / "scenario.toml")
    named = _named_paths(blueprint(sc))
    timed, static = rrd_rows(res.recording), rrd_rows(res.recording, static=True)
    ticks = res.summary["ticks"]
    assert "/robots/r3/error/formation" in named
    assert "/events/faults" in named
    assert all("*" not in path for path in named), named  # the viewer matches no wildcard mid-path
    missing = sorted(path for path in named if path not in timed and path not in static)
    assert not missing, missing
    # The fault's start and end, each at its own sim time (2 rows), logged once the run got there.
    assert _times(res.recording, "/events/faults") == [1.0, 2.0]
    for path in named:
        if path.startswith("/robots/"):  # on the timeline; from the ground truth: every tick
            every_tick = path.endswith(("/pose", "/heading", "/trajectory", "/target/true", "/error/formation"))
            assert timed[path] == ticks if every_tick else timed[path] > 0, (path, timed[path], ticks)


def _texts(rrd: Path, entity: str) -> list[tuple[float, str]]:
    from rerun.chunk import RrdReader

    out = []
    for chunk in RrdReader(str(rrd)).stream():
        batch = chunk.to_record_batch()
        if str(chunk.entity_path) != entity or chunk.is_static:
            continue
        text = next(n for n in batch.schema.names if n.endswith(":text"))
        times = batch.column("sim_time").cast("int64").to_pylist()
        rows = zip(times, batch.column(text).to_pylist(), strict=True)
        out += [(round(t / 1e9, 2), row[0]) for t, row in rows if row]
    return sorted(out)


def test_the_event_log_has_every_robots_formation_switch_the_leaders_too(swarm_run: Callable[..., RunResult]) -> None:
    """The followers' switches come from their telemetry; the leader sends none,
    and its switch (the world's formation events list it) was missing."""
    res = swarm_run(FIG11)
    logged = [e for e in _texts(res.recording, "/events") if " flies " in e[1]]
    # Each robot's first formation, at its first tick; then its switches, as the world saw them.
    assert [text for t, text in logged if t == 0.0] == [
        "R1 (leader) flies triangle",
        "R2 flies triangle",
        "R3 flies triangle",
    ]
    expected = [(round(e["time_s"], 2), e["robot"], e["formation"]) for e in res.summary["formation_events"]]
    assert [(t, text.split()[0], text.split()[-1]) for t, text in logged if t > 0] == sorted(
        (t, f"R{r}", f) for t, r, f in expected
    )
    assert (19.6, "R1 (leader) flies line") in logged


def _times(rrd: Path, entity: str) -> list[float]:
    from rerun.chunk import RrdReader

    times = []
    for chunk in RrdReader(str(rrd)).stream():
        if str(chunk.entity_path) == entity and not chunk.is_static:
            times += [t / 1e9 for t in chunk.to_record_batch().column("sim_time").cast("int64").to_pylist()]
    return sorted(times)


def test_the_layout_follows_the_scenario() -> None:
    sc = scenario_mod.load(FIG11, {}, [Fault.coerce("kill agent-3@2s")])
    named = _named_paths(blueprint(sc))
    assert {"/events", "/events/faults", "/events/fault_calls", "/world/obstacles"} <= named
    assert {p.split("/")[2] for p in named if p.startswith("/robots/")} == {"r1", "r2", "r3"}
    assert "/robots/r1/error/formation" not in named  # the leader has no formation error
    quiet = _named_paths(blueprint(scenario_mod.load(SCENARIOS / "fig7_turn_vn_dynamic.toml")))
    assert "/events/faults" not in quiet
    assert "/world/obstacles" not in quiet
    assert robot_colour(2) != robot_colour(3)
    assert robot_colour(1) == robot_colour(9)


def test_serve_web_on_a_taken_port_is_refused_before_anything_starts(tmp_path: Path) -> None:
    import socket
    import sys

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        taken, free = busy.getsockname()[1], free_port()
        with pytest.raises(ValueError, match=f"^--web-port {taken}: cannot serve the web viewer there \\("):
            Launch(FIG11, serve_web=True, web_ports=(free, taken), out=tmp_path / "a")
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "formation_swarm.cli",
                "run",
                str(FIG11),
                "--serve-web",
                "--grpc-port",
                str(taken),
                "--web-port",
                str(free),
                "--out",
                str(tmp_path / "b"),
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    assert proc.stderr.startswith(f"swarm run: --grpc-port {taken}: cannot serve the web viewer there (")
    assert len(proc.stderr.splitlines()) == 1
    assert not (tmp_path / "a").exists()  # nothing started, nothing made
    assert not (tmp_path / "b").exists()


def test_the_layout_follows_the_leader_and_draws_many_followers_means_alone() -> None:
    from formation_swarm.nodes.logger.blueprint import LEADER_FRAME, formation_reach_m

    sc = scenario_mod.load(FIG11)
    bp = blueprint(sc)
    follow = bp.root_container.contents[0].contents[0]  # the first column's first view
    assert follow.origin == f"/{LEADER_FRAME}"
    assert 2.0 < formation_reach_m(sc) < 8.0  # a few metres (the line: R3 behind R2), not the 80 m path
    named = _named_paths(bp)
    assert {"/robots/r2/fis/v_n", "/robots/r2/fis/v_n_1s", "/robots/r3/wheels/right_1s"} <= named
    twelve = _named_paths(blueprint(scenario_mod.load(FIG11, {"run.robots": 12, "leader.formation": "line"})))
    assert "/robots/r12/fis/v_n_1s" in twelve
    assert "/robots/r12/fis/v_n" not in twelve  # 11 followers' per-tick values: a blur
    # Beyond a dozen: the swarm as a whole, each robot's series there but hidden (tests/unit/nodes/logger).
    many = _named_paths(blueprint(scenario_mod.load(FIG11, {"run.robots": 30, "leader.formation": "line"})))
    assert {"/swarm/fis/v_n/median", "/swarm/fis/v_n/worst", "/world/swarm/**", "/robots/r30/fis/v_n"} <= many
    assert "/robots/r30/fis/v_n_1s" not in many
