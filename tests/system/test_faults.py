"""Every fault kind end to end, as a user's own test suite would write it.

Two schedules, each run twice in lockstep as real processes (world, logger,
one agent per robot) with the package's pytest fixtures:

- the link, partition, sensor and actuator kinds, one after another on
  robots 2 and 3 of fig11_obstacles, so each one's effect is counted apart;
- the process kinds: a restart, a freeze, a kill of the logger and a kill.

Each kind gets a test that asserts its numbers in summary.json; both
schedules repeat to the bit. More on each kind: tests/system/test_link_faults.py,
tests/unit/world/test_sensor_actuator_faults.py, tests/system/test_process_faults.py.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from formation_swarm.common.faults import KINDS
from formation_swarm.launch.launcher import Launch
from tests.helpers.links import assert_same_links

FIG11 = "fig11_obstacles"
SECONDS = 20.0
DT = 0.05
TICKS_PER_S = 20

# One kind at a time, each on its own robot and window (seconds of the run).
SCHEDULE = [
    "delay formation:2@0s ticks=3",
    "drop obs:2@2s for=2s p=0.5",
    "burst cmd:3@2s for=4s p_bad=0.2 p_good=0.5",
    "duplicate cmd:2@6s for=2s p=0.3",
    "reorder obs:3@6s for=2s p=0.3",
    "partition 3@9s for=1s from=world",
    "blackout 2@11s for=1s",
    "bias 3@11s for=1s rho_m=0.2",
    "outliers 2@13s for=1s p=0.5",
    "range 3@13s for=1s m=2",
    "wheel_noise 2@15s for=1s sigma_mps=0.05",
    "wheel_bias 3@15s for=1s left=0.05",
    "slip 2@17s for=1s fraction=0.3",
    "stuck 3@17s for=0.5s wheel=left",
]
PROCESS_SCHEDULE = [
    "restart agent-3@3s after=1",
    "freeze agent-2@6s for=1s",
    "kill logger@9s",
    "kill agent-3@12s",
]


def _run_twice(
    tmp_path_factory: pytest.TempPathFactory, faults: list[str], logger: bool, together: bool = False
) -> list[dict[str, Any]]:
    """The schedule, run twice (what the swarm_run fixture does, shared by the module's tests);
    ``together``: both runs at once, for a schedule without process faults (which the
    launcher executes while it waits for its run)."""
    out = []
    kwargs = {"mode": "lockstep", "logger": logger, "faults": faults, "overrides": {"run.duration_s": SECONDS}}
    for ks in ([0, 1],) if together else ([0], [1]):
        with contextlib.ExitStack() as stack:
            folders = [tmp_path_factory.mktemp("faults") / f"run-{k}" for k in ks]
            launches = [stack.enter_context(Launch(FIG11, out=f, progress=lambda _l: None, **kwargs)) for f in folders]
            results = [launch.wait(timeout_s=240) for launch in launches]
        for res in results:
            assert res.exit_code == 0, (res.summary.get("events"), res.summary.get("failure"))
            assert res.summary["lockstep_misses"] == 0
            out.append(res.summary)
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, Any]]:
    return _run_twice(tmp_path_factory, SCHEDULE, logger=False, together=True)


@pytest.fixture(scope="module")
def process_runs(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, Any]]:
    return _run_twice(tmp_path_factory, PROCESS_SCHEDULE, logger=True)


def fault(summary: dict[str, Any], text: str) -> dict[str, Any]:
    return next(f for f in summary["faults"] if f["fault"] == text)


def test_every_kind_is_in_a_schedule() -> None:
    assert {t.split()[0] for t in SCHEDULE + PROCESS_SCHEDULE} == set(KINDS)


def test_the_schedules_repeat_to_the_bit(runs: list[dict[str, Any]], process_runs: list[dict[str, Any]]) -> None:
    for a, b in (runs, process_runs):
        assert a["trajectory_digest"] == b["trajectory_digest"]
        assert a["faults"] == b["faults"] or _without_wall_times(a) == _without_wall_times(b)
        assert a["partial_links"] == b["partial_links"]
        assert_same_links(a["links"], b["links"], a["partial_links"])
        assert a["rejected"] == b["rejected"]
    # The process schedule kills agent-3 (its restart, agent-3.2, at 12 s): its inbound links only.
    assert process_runs[0]["partial_links"] == ["formation:1>3", "obs:0>3"]
    assert runs[0]["partial_links"] == []


def _without_wall_times(s: dict[str, Any]) -> list[dict[str, Any]]:
    """The faults of a summary without what the wall clock measured (process start-up) and pids."""
    out = []
    for f in s["faults"]:
        f = dict(f)
        for key in ("events", "executed", "rejoins"):
            if key in f:
                f[key] = [{k: v for k, v in e.items() if "wall" not in k and k != "pid"} for e in f[key]]
        out.append(f)
    return out


def _binomial_ok(k: int, n: int, p: float) -> bool:
    """k within 4 standard deviations of n p."""
    return abs(k - n * p) <= 4.0 * math.sqrt(n * p * (1 - p)) + 1


# -- links --------------------------------------------------------------------------


def test_drop(runs: list[dict[str, Any]]) -> None:
    f = fault(runs[0], "drop obs:2@2s for=2s p=0.5")
    assert (f["start_tick"], f["end_tick"]) == (40, 80)
    assert _binomial_ok(f["counts"]["dropped"], 2 * TICKS_PER_S, 0.5)
    assert runs[0]["links"]["obs:0>2"]["dropped"] == f["counts"]["dropped"]  # none outside its window


def test_burst(runs: list[dict[str, Any]]) -> None:
    f = fault(runs[0], "burst cmd:3@2s for=4s p_bad=0.2 p_good=0.5")
    # Gilbert-Elliott: bad a fraction p_bad / (p_bad + p_good) = 0.29 of the time, losing all in it.
    lost = f["counts"]["dropped"]
    assert 5 <= lost <= 50, lost  # of 80 commands, expected 23
    assert runs[0]["links"]["cmd:3>0"]["dropped"] == lost


def test_delay(runs: list[dict[str, Any]]) -> None:
    f = fault(runs[0], "delay formation:2@0s ticks=3")
    link = runs[0]["links"]["formation:1>2"]
    assert f["counts"]["delayed"] == link["received"]  # every code (the last 3 ticks' still held at the end)
    assert link["held"] == 3
    switch = {e["robot"]: e["tick"] for e in runs[0]["formation_events"] if e["formation"] == "line"}
    assert switch[2] - switch[3] == 3  # robot 2 hears the switch to line 3 ticks after robot 3


def test_duplicate(runs: list[dict[str, Any]]) -> None:
    f = fault(runs[0], "duplicate cmd:2@6s for=2s p=0.3")
    assert _binomial_ok(f["counts"]["duplicated"], 2 * TICKS_PER_S, 0.3)
    # Every copy meets the world's order check and ends there.
    assert runs[0]["rejected"]["world"]["replayed or reordered"] == f["counts"]["duplicated"]


def test_reorder(runs: list[dict[str, Any]]) -> None:
    f = fault(runs[0], "reorder obs:3@6s for=2s p=0.3")
    held = f["counts"]["reordered"]
    assert _binomial_ok(held, 2 * TICKS_PER_S, 0.3)
    # A held observation comes after a newer one and is refused, unless the next one was held too.
    assert 0 < runs[0]["rejected"]["agent-3"]["replayed or reordered"] <= held


def test_partition(runs: list[dict[str, Any]]) -> None:
    f = fault(runs[0], "partition 3@9s for=1s from=world")
    assert f["counts"] == {"partitioned": 2 * TICKS_PER_S}  # 20 observations and 20 commands, both ways
    assert runs[0]["links"]["obs:0>3"]["partitioned"] == runs[0]["links"]["cmd:3>0"]["partitioned"] == 20
    assert runs[0]["stale_stops"] == 1  # robot 3's body stopped once its last command was stale


# -- sensors (followers' cameras) ---------------------------------------------------------


def test_blackout(runs: list[dict[str, Any]]) -> None:
    c = fault(runs[0], "blackout 2@11s for=1s")["counts"]
    assert c["R2 ticks"] == TICKS_PER_S
    assert c["R2 blacked_out"] == 2 * TICKS_PER_S  # it sees the two others on every tick


def test_bias(runs: list[dict[str, Any]]) -> None:
    c = fault(runs[0], "bias 3@11s for=1s rho_m=0.2")["counts"]
    assert (c["R3 ticks"], c["R3 biased"]) == (TICKS_PER_S, 2 * TICKS_PER_S)


def test_outliers(runs: list[dict[str, Any]]) -> None:
    c = fault(runs[0], "outliers 2@13s for=1s p=0.5")["counts"]
    assert c["R2 ticks"] == TICKS_PER_S
    assert _binomial_ok(c["R2 replaced"], 2 * TICKS_PER_S, 0.5)


def test_range(runs: list[dict[str, Any]]) -> None:
    c = fault(runs[0], "range 3@13s for=1s m=2")["counts"]
    assert (c["R3 ticks"], c["R3 cut"]) == (TICKS_PER_S, 2 * TICKS_PER_S)  # both others are beyond 2 m


# -- actuators --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "robot", "ticks"),
    [
        ("wheel_noise 2@15s for=1s sigma_mps=0.05", 2, 20),
        ("wheel_bias 3@15s for=1s left=0.05", 3, 20),
        ("slip 2@17s for=1s fraction=0.3", 2, 20),
        ("stuck 3@17s for=0.5s wheel=left", 3, 10),
    ],
)
def test_actuators(runs: list[dict[str, Any]], text: str, robot: int, ticks: int) -> None:
    c = fault(runs[0], text)["counts"]
    assert (c[f"R{robot} ticks"], c[f"R{robot} moving_ticks"]) == (ticks, ticks)


def test_actuator_faults_change_the_trajectories(runs: list[dict[str, Any]], swarm_run: Callable[..., Any]) -> None:
    """The same schedule without its four actuator faults flies differently from 15 s on."""
    plain = swarm_run(
        FIG11, mode="lockstep", logger=False, faults=SCHEDULE[:-4], overrides={"run.duration_s": SECONDS}
    ).summary
    assert plain["trajectory_digest"] != runs[0]["trajectory_digest"]
    for key in ("mean_m", "max_m"):  # per follower, per second of the run
        for rid in ("2", "3"):
            before, after = plain["error_windows"][key][rid], runs[0]["error_windows"][key][rid]
            assert before[:15] == after[:15]  # identical up to 15 s: nothing changed before they began
            assert before[15:] != after[15:]


# -- processes ------------------------------------------------------------------------------------


def test_restart(process_runs: list[dict[str, Any]]) -> None:
    f = fault(process_runs[0], "restart agent-3@3s after=1")
    assert [(e["event"], e["tick"]) for e in f["events"]] == [
        ("killed", 60),
        ("started", 80),
        ("readmitted", 80),
        ("rejoined", 80),
    ]
    assert process_runs[0]["processes"]["agent-3.2"]["exit_code"] == -9  # killed again at 12 s


def test_freeze(process_runs: list[dict[str, Any]]) -> None:
    f = fault(process_runs[0], "freeze agent-2@6s for=1s")
    assert [(e["event"], e["tick"]) for e in f["events"]] == [("frozen", 120), ("thawed", 140)]
    parts = process_runs[0]["parts"]
    assert parts["agent-2"]["answered"] == SECONDS * TICKS_PER_S - TICKS_PER_S  # 20 ticks frozen


def test_kill_logger(process_runs: list[dict[str, Any]]) -> None:
    f = fault(process_runs[0], "kill logger@9s")
    assert [(e["event"], e["process"], e["tick"]) for e in f["executed"]] == [("killed", "logger", 180)]
    assert process_runs[0]["processes"]["logger"]["exit_code"] == -9
    assert process_runs[0]["deaths"][-1]["robot"] == 3  # robots are not the logger's business


def test_kill(process_runs: list[dict[str, Any]]) -> None:
    f = fault(process_runs[0], "kill agent-3@12s")
    assert [(e["event"], e["tick"], e["robot"]) for e in f["events"]] == [("killed", 240, 3)]
    assert process_runs[0]["parts"]["world"]["dead_robots"] == [3]


def test_the_report_marks_every_fault(process_runs: list[dict[str, Any]], tmp_path: Path) -> None:
    from formation_swarm.report.faults import fault_marks, faults_markdown

    marks = fault_marks(process_runs[0])
    assert [label for _, _, label in marks] == ["restart agent-3", "freeze agent-2", "kill logger", "kill agent-3"]
    assert marks[1][:2] == (6.0, 7.0)
    text = "\n".join(faults_markdown(process_runs[0]))
    assert "| `kill agent-3@12s` | from 240 | killed R3 at tick 240 (12.00 s) | - |" in text


# -- real time ------------------------------------------------------------------------------------


def test_the_same_faults_in_real_time(swarm_run: Callable[..., Any]) -> None:
    """In real time the schedule is placed on the world's wall-clock ticks: a
    partition still cuts exactly its ticks' observations, and the camera and
    wheel faults act on exactly their ticks."""
    faults = [
        "partition 3@2s for=1s from=world",
        "blackout 2@3s for=1s",
        "stuck 3@4s for=0.5s wheel=right",
        "delay cmd:2@1s for=2s ms=120",
    ]
    res = swarm_run(
        FIG11, mode="realtime", logger=False, faults=faults, overrides={"run.duration_s": 6.0}, timeout_s=60
    )
    s = res.summary
    assert res.exit_code == 0
    assert s["links"]["obs:0>3"]["partitioned"] == TICKS_PER_S  # the world publishes every tick
    # Commands are answers: at most one per observation, fewer if the agent skipped a stale one.
    assert 0.75 * TICKS_PER_S <= s["links"]["cmd:3>0"]["partitioned"] <= TICKS_PER_S
    assert fault(s, "blackout 2@3s for=1s")["counts"] == {"R2 ticks": 20, "R2 blacked_out": 40}
    assert fault(s, "stuck 3@4s for=0.5s wheel=right")["counts"]["R3 ticks"] == 10
    delayed = fault(s, "delay cmd:2@1s for=2s ms=120")["counts"]["delayed"]
    assert 0.75 * 2 * TICKS_PER_S <= delayed <= 2 * TICKS_PER_S  # 120 ms: held 3 ticks each
