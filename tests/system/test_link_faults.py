"""Link faults end to end: real processes in lockstep, the faults of the
schedule applied by the receivers' link layer (protocol/links.py).

Every count here is exact: lockstep makes a run's messages a function of the
scenario and the seed, the link layer's decisions a function of (seed, link,
seq, fault index), so the same Link fed the same sequence numbers offline
must count what the processes counted.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from formation_swarm.common.faults import Fault
from formation_swarm.launch.launcher import Launch, RunResult
from formation_swarm.protocol.links import Link, faults_on
from tests.helpers import run_together
from tests.helpers.links import assert_same_links

pytestmark = pytest.mark.slow

FIG11 = "fig11_obstacles"
DT = 0.05
BURST, DELAY, DUPLICATE, REORDER, PARTITION = (
    "burst cmd:2@3s for=5s p_bad=0.05 p_good=0.3",
    "delay obs:3@2s for=4s ticks=2 jitter_ticks=2",
    "duplicate obs:2@1s for=5s p=0.2",
    "reorder cmd:3@1s for=5s p=0.1",
    "partition 3@10s for=2s from=world",
)
CODE_DELAY = "delay formation:2@0s for=20s ticks=3"
MIX = (BURST, DELAY, CODE_DELAY, DUPLICATE, REORDER, PARTITION)


def offline(link_class: str, robot: int, ticks: int, seq_of: Callable[[int], int]) -> tuple[dict, int]:
    """The counts a link of the run gets when message ``seq_of(t)`` of each tick
    t arrives (and ``due(t)`` is called), and how many of its outputs the
    receiver's order check refuses."""
    schedule = tuple(sorted((Fault.parse(f) for f in MIX), key=lambda f: f.at_s))  # as the scenario holds them
    name = f"obs:0>{robot}" if link_class == "obs" else f"cmd:{robot}>0"
    link: Link[int] = Link(name, 0.0, 1, faults_on(schedule, link_class, robot), DT)
    last, refused = -1, 0
    for t in range(ticks):
        for seq in link.deliver(seq_of(t), t, seq_of(t)) + link.due(t):
            refused += seq <= last
            last = max(last, seq)
    return link.stats(), refused


def test_every_link_fault_at_once_is_reproducible_and_counted_exactly(swarm_launch: Callable[..., Launch]) -> None:
    kwargs = {"mode": "lockstep", "logger": False, "faults": list(MIX), "overrides": {"run.duration_s": 20}}
    clean_kwargs = {"mode": "lockstep", "logger": False, "overrides": {"run.duration_s": 20}}
    a, b, clean = (
        r.summary for r in run_together(swarm_launch, (FIG11, kwargs), (FIG11, kwargs), (FIG11, clean_kwargs))
    )
    assert a["trajectory_digest"] == b["trajectory_digest"] != clean["trajectory_digest"]
    assert (a["ticks"], a["lockstep_misses"], b["lockstep_misses"]) == (400, 0, 0)
    assert_same_links(a["links"], b["links"])
    assert a["rejected"] == b["rejected"]

    links = a["links"]
    # Robot 3 cut off from the world for 2 s at 20 Hz: 40 observations and 40 commands lost.
    assert links["obs:0>3"]["partitioned"] == links["cmd:3>0"]["partitioned"] == 40
    # The world numbers each robot's observations from 1; a follower sends a command
    # then its telemetry each tick, so its command of tick t has seq 2t + 1.
    obs2, refused2 = offline("obs", 2, 400, lambda t: t + 1)
    obs3, refused3 = offline("obs", 3, 400, lambda t: t + 1)
    cmd2, _ = offline("cmd", 2, 400, lambda t: 2 * t + 1)
    cmd3, refused_cmd3 = offline("cmd", 3, 400, lambda t: 2 * t + 1)
    assert (links["obs:0>2"], links["obs:0>3"], links["cmd:2>0"], links["cmd:3>0"]) == (obs2, obs3, cmd2, cmd3)
    assert (obs2["duplicated"], obs3["delayed"], cmd2["dropped"], cmd3["reordered"]) == (24, 80, 6, 11)
    # Duplicates and messages held behind newer ones meet the receivers' order checks.
    assert a["rejected"] == {
        "agent-2": {"replayed or reordered": refused2},
        "agent-3": {"replayed or reordered": refused3},
        "world": {"replayed or reordered": refused_cmd3},
    }
    assert (refused2, refused3, refused_cmd3) == (24, 14, 10)
    # Every formation code to robot 2 is 3 ticks late: it takes the line 3 ticks after robot 3.
    assert links["formation:1>2"]["delayed"] == links["formation:1>2"]["received"] > 0
    line = {e["robot"]: e["tick"] for e in a["formation_events"] if e["formation"] == "line"}
    assert line[2] - line[3] == 3
    # Per fault (by its index in the schedule, which is sorted by start), on all its links.
    assert a["link_faults"] == {
        "0": {"fault": str(Fault.parse(CODE_DELAY)), "delayed": links["formation:1>2"]["delayed"]},
        "1": {"fault": str(Fault.parse(DUPLICATE)), "duplicated": 24},
        "2": {"fault": str(Fault.parse(REORDER)), "reordered": 11},
        "3": {"fault": str(Fault.parse(DELAY)), "delayed": 80},
        "4": {"fault": str(Fault.parse(BURST)), "dropped": 6},
        "5": {"fault": str(Fault.parse(PARTITION)), "partitioned": 80},
    }
    assert a["link_totals"]["obs"]["partitioned"] == a["link_totals"]["cmd"]["partitioned"] == 40


def recovery_s(summary: dict, robot: int, end_s: float, below_m: float = 0.5) -> float:
    """Seconds after ``end_s`` from which the follower's mean formation error,
    window by window (1 s), stays below ``below_m`` to the end of the run."""
    w = summary["error_windows"]
    width, means = w["window_s"], w["mean_m"][str(robot)]
    first = round(end_s / width)
    over = [i for i in range(first, len(means)) if means[i] >= below_m]
    return 0.0 if not over else (max(over) + 1) * width - end_s


def test_a_formation_cut_off_from_the_world_stops_then_flies_on(swarm_run: Callable[..., RunResult]) -> None:
    """15 s without observations or commands: every robot is stopped by its
    commands' staleness, every follower's EKF only predicts. Then the readings
    come back, the robots fly on and the formation closes again."""
    s = swarm_run(
        FIG11,
        mode="lockstep",
        logger=False,
        faults=["partition 1,2,3@5s for=15s from=world"],
        overrides={"run.duration_s": 30},
    ).summary
    assert (s["ticks"], s["lockstep_misses"]) == (600, 0)
    assert s["link_faults"]["0"]["partitioned"] == 300 * 3 * 2  # 3 robots, both ways, ticks 100..399
    assert s["stale_stops"] == 3  # each robot stopped once, 0.5 s into the partition
    final = s["parts"]["world"]["final_poses"]
    # The leader flew 5 s, 0.5 s on its last command, then the last 10 s: 15.5 s at 1.5 m/s.
    assert final["1"][1] == pytest.approx(15.5 * 1.5, abs=1e-6)
    assert min(final["2"][1], final["3"][1]) > 20.0  # the followers flew on too (stopped near 6 m)
    assert s["collisions"] == 0
    # Measured (seed 1): robot 2's mean error never leaves 0.5 m; robot 3's is back
    # below it 2 s after the partition's end, and stays there.
    recovered = {r: recovery_s(s, r, 20.0) for r in (2, 3)}
    assert recovered == {2: 0.0, 3: 2.0}, recovered
    assert max(recovered.values()) <= 5.0


def test_a_partitions_count_outlives_a_later_restart_and_a_kill_inside_it_is_marked(
    swarm_run: Callable[..., RunResult],
) -> None:
    """The receiving agent keeps a link's counts. It writes them two ticks after
    a fault's window ends, so restarting it later loses none of them (before,
    its last periodic write came before the partition and the line said
    nothing); an agent killed inside the window leaves counts that are marked
    as a lower bound, on the console line too."""
    from formation_swarm.launch.console import describe_fault

    alone = swarm_run(FIG11, mode="lockstep", logger=False, faults=["partition 2@30s for=5s from=leader"]).summary
    later = swarm_run(
        FIG11, mode="lockstep", logger=False, faults=["partition 2@30s for=5s from=leader", "restart agent-2@45s"]
    ).summary
    # Codes the leader sent in ticks 600..699: every 10 ticks, and every tick for
    # 1 s after its change to triangle at tick 608.
    assert alone["faults"][0]["counts"] == {"partitioned": 29}
    assert later["faults"][0]["counts"] == {"partitioned": 29}
    assert "counts_partial_for" not in later["faults"][0]
    line = describe_fault(later["faults"][0])  # with how R2's formation came back after it (1 s windows)
    assert line.startswith("partition 2@30s for=5s from=leader: R2 "), line
    assert " after the fault's end at t=35.00 s" in line, line
    assert line.endswith("; 29 messages lost to the partition"), line
    inside = swarm_run(
        FIG11, mode="lockstep", logger=False, faults=["partition 2@30s for=5s from=leader", "restart agent-2@32s"]
    ).summary
    cut = inside["faults"][0]
    assert cut["counts_partial_for"] == [2]
    # The restarted agent (from tick 660) counts the rest; the killed one's last write is wall-timed.
    assert cut["counts"].get("partitioned", 0) < 29
    line = describe_fault(cut)
    assert line.endswith("R2's agent was killed, and its counts end at its last stats write)") or line.endswith(
        "not counted: R2's agent was killed before it wrote its counts of this fault"
    ), line


def test_a_follower_cut_off_from_its_leader_misses_the_switch_and_catches_up(
    swarm_run: Callable[..., RunResult],
) -> None:
    """Robot 3 hears no formation code from 10 s to 25 s: it keeps flying on its
    camera, in its triangle slot beside robot 2, while the others go to line at
    19.6 s for the gap between the obstacles; the leader's next repeated code
    after the partition puts it in line, and it returns to triangle with the others."""
    s = swarm_run(FIG11, mode="lockstep", logger=False, faults=["partition 3@10s for=15s from=leader"]).summary
    assert s["end_reason"] == "leader_finished"
    assert s["lockstep_misses"] == 0
    # Codes the leader sent in ticks 200..499: every 10 ticks, every tick for 1 s after the change.
    assert s["links"]["formation:1>3"]["partitioned"] == 20 + 21 + 8
    assert s["links"]["formation:1>2"]["partitioned"] == 0
    events = sorted((e["tick"], e["robot"], e["formation"]) for e in s["formation_events"])
    assert events == [
        (392, 1, "line"),
        (393, 2, "line"),
        (503, 3, "line"),  # the code of tick 502, the first after the partition, from the tick after
        (608, 1, "triangle"),
        (609, 2, "triangle"),
        (609, 3, "triangle"),
    ]
    # In its triangle slot, 3 m to robot 2's right, robot 3 meets the right-hand
    # obstacle (measured: at tick 507, x = 3.02 m, 4 ticks after it took the line,
    # too late to get out of the way): followers do not sense obstacles, the
    # leader's code is what steers them through the gap.
    assert s["obstacle_collisions"] == 1
    assert s["collisions"] == 0
    assert s["followers"]["3"]["max_m"] > 4.0
    assert s["followers"]["2"]["max_m"] < 2.0


def test_the_console_says_a_link_fault_as_the_run_passes_its_start_and_end(
    swarm_run: Callable[..., RunResult],
) -> None:
    """Process faults had their live lines; a partition only its line after the run."""
    said: list[str] = []
    faults = ["partition 2@30s for=5s from=leader", "drop obs:2@50s p=0.2", "drop obs:3@54s p=0.2"]
    swarm_run(FIG11, mode="lockstep", logger=False, progress=said.append, faults=faults)
    windows = [line for line in said if line.startswith("[swarm] fault ")]
    assert windows == [
        "[swarm] fault on from tick 600, sim t=30.00 s ('partition 2@30s for=5s from=leader')",
        "[swarm] fault off from tick 700, sim t=35.00 s ('partition 2@30s for=5s from=leader')",
        "[swarm] fault on from tick 1000, sim t=50.00 s ('drop obs:2@50s p=0.2')",
    ]  # the one after the run's end (tick 1080 of 1061, the leader's path done) never comes
