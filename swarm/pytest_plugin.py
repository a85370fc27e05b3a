"""pytest plugin (registered through the ``pytest11`` entry point).

Fixtures:

``swarm_run``
    ``swarm_run(scenario, mode="lockstep", seed=None, overrides=None,
    logger=True, faults=(), kills=(), timeout_s=300) -> RunResult``: runs a scenario (a
    shipped scenario's name, e.g. ``"fig11_obstacles"``, or a TOML file) as
    real processes (world, logger, one agent per robot) with a unique run id
    and its own loopback port, in the test's tmp_path; returns the summary and
    the run folder. ``faults`` takes strings such as ``"kill agent-3@20s"`` or
    ``"drop obs:2@10s for=5s p=0.3"``, ``Fault`` objects or tables (the
    grammar of ``[[faults]]``, docs/faults.md); ``kills`` takes ``"agent-3@20"``.
    Both are checked before any process starts. Every process is reaped when the test ends, pass or fail.
    A failed test's report lists the folders of the runs it started. A run
    that does not end within ``timeout_s`` fails the test (its processes
    stopped, the message naming its folder); Ctrl-C during a run stops it and
    then stops the test session, as Ctrl-C does in pytest. A run that ends
    badly (exit code 1: a robot lost, a process that never started) is
    returned for the test to check.

    ``external=[3]`` leaves robot 3 to an agent the test starts: give
    ``join``, called with the started ``Launch`` before the wait, to start it
    (``launch.external[3].flags()``: ``--id --scenario --run --connect
    --auth``); a ``subprocess.Popen`` (or a list of them) it returns is
    stopped and reaped after the run.

``swarm_launch``
    ``swarm_launch(scenario, **kwargs) -> Launch``: the same, started but not
    waited for, for tests that act on a run while it runs (``launch.endpoint``,
    ``launch.run_id``, ``launch.wait_until(...)``, ``launch.wait()``; with
    ``external=[3]``, ``launch.external[3]`` says what robot 3's agent needs).
"""

from __future__ import annotations

import math
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:  # imported by the fixtures when used: the launcher brings Zenoh, numpy and scipy
    from formation_swarm.launch.launcher import Launch, RunResult

INTERRUPTED = 130  # Launch.wait's exit codes
TIMED_OUT = 124


# The runs a test started, kept on its item: a failed test's report names their folders.
LAUNCHES = pytest.StashKey[list["Launch"]]()


@pytest.hookimpl(hookwrapper=True)  # the old-style wrapper: pytest 7 too
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()  # type: ignore[attr-defined]
    launches = item.stash.get(LAUNCHES, [])
    if report.failed and call.when == "call" and launches:
        report.sections.append(("swarm runs", "\n".join(_run_line(launch) for launch in launches)))


def _run_line(launch: Launch) -> str:
    """A run's folder and what it holds now: a run the test left while it went
    on has no summary.json (the fixture then stops it)."""
    held = [name for name in ("summary.json", "recording.rrd", "logs/") if (launch.run_dir / name.rstrip("/")).exists()]
    note = "" if "summary.json" in held else "; no summary.json: the test ended while the run went on"
    return f"{launch.run_dir} (run {launch.run_id}; {', '.join(held) or 'nothing yet'}{note})"


@pytest.fixture
def swarm_launch(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Callable[..., Launch]]:
    """Start runs (``Launch`` objects) that are stopped and reaped at teardown."""
    from formation_swarm.launch.launcher import Launch

    launches: list[Launch] = []
    request.node.stash[LAUNCHES] = launches

    def start(scenario: str | Path, **kwargs: Any) -> Launch:
        kwargs.setdefault("out", tmp_path / f"run-{len(launches)}")
        kwargs.setdefault("progress", lambda _line: None)
        launch = Launch(scenario, **kwargs)
        launches.append(launch)
        launch.start()
        return launch

    try:
        yield start
    finally:
        for launch in launches:
            launch.stop(graceful_first=False)


@pytest.fixture
def swarm_run(swarm_launch: Callable[..., Launch]) -> Callable[..., RunResult]:
    """Run a scenario to its end as real processes; returns a ``RunResult``."""

    def run(
        scenario: str | Path, *, timeout_s: float = 300.0, join: Callable[[Launch], Any] | None = None, **kwargs: Any
    ) -> RunResult:
        if isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) or not 0 < timeout_s < math.inf:
            raise ValueError(f"swarm_run: timeout_s must be a number of seconds > 0, got {timeout_s!r}")
        if kwargs.get("external") and join is None:
            raise ValueError("swarm_run: external robots need join=, which starts their agents (else the run waits)")
        launch = swarm_launch(scenario, **kwargs)
        joined = _as_processes(join(launch)) if join is not None else []
        try:
            res = launch.wait(timeout_s=timeout_s)
        finally:
            _reap(joined)
        if res.exit_code == INTERRUPTED:
            raise KeyboardInterrupt  # every process is stopped by now
        if res.exit_code == TIMED_OUT:
            reached = res.summary.get("ended_at_s")
            where = f" (it had reached t={reached:.2f} s)" if isinstance(reached, (int, float)) else ""
            pytest.fail(
                f"swarm_run: {scenario} did not end within timeout_s={timeout_s:g} s{where}; every process is "
                f"stopped; its folder: {res.run_dir}",
                pytrace=False,
            )
        return res

    return run


def _as_processes(value: Any) -> list[subprocess.Popen[Any]]:
    """What ``join`` returned that the fixture reaps: a Popen, or a list of them."""
    items = value if isinstance(value, (list, tuple)) else [value]
    return [p for p in items if isinstance(p, subprocess.Popen)]


def _reap(procs: list[subprocess.Popen[Any]], grace_s: float = 15.0) -> None:
    """Each outside agent leaves on the world's "done"; one still there after
    ``grace_s`` is terminated, then killed; all are reaped."""
    for p in procs:
        try:
            p.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            p.terminate()
            try:
                p.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
