"""The formation's return after a fault that ends (partition, sensor, link,
actuator), from the summary's 1 s error windows, and how the console says it."""

from __future__ import annotations

import io
from pathlib import Path

from formation_swarm.common.faults import Fault
from formation_swarm.launch.console import describe_fault, print_result
from formation_swarm.launch.launcher import RunResult
from formation_swarm.runtime.summary.recovery import window_recoveries
from formation_swarm.spec import scenario as scenario_mod

SC = scenario_mod.load("fig11_obstacles")  # dt 0.05 s, leader R1, followers R2 and R3
#           window: 0    1    2    3    4    5    6    7    8    9
MEANS = {"2": [0.2, 0.3, 1.5, 2.0, 1.1, 0.7, 0.4, 0.3, 0.3, 0.3], "3": [0.1] * 10}
MAXES = {"2": [0.3, 0.4, 2.0, 2.5, 1.6, 0.9, 0.6, 0.4, 0.4, 0.4], "3": [0.2] * 10}
WINDOWS = {"window_s": 1.0, "mean_m": MEANS, "max_m": MAXES}


def test_a_partition_s_recovery_is_read_from_the_windows_after_its_end() -> None:
    (rec,) = window_recoveries(Fault.parse("partition 2@2s for=2s"), SC, WINDOWS)
    assert rec["since_tick"] == 80
    assert rec["watched"] == [2]
    # Windows 4 (1.1 m) and 5 (0.7 m) are above 0.5 m; window 6 (6-7 s) is the first below.
    assert rec["first_below_after_s"] == 3.0
    assert rec["max_in_window_m"] == 1.6  # windows 4-8
    assert rec["resolution_s"] == 1.0


def test_a_fault_on_the_leader_watches_every_follower_and_one_to_the_end_has_none() -> None:
    (rec,) = window_recoveries(Fault.parse("blackout *@2s for=1s"), SC, WINDOWS)
    assert rec["watched"] == [2, 3]
    assert rec["first_below_after_s"] == 4.0  # the worst of the two per window: R2's
    assert window_recoveries(Fault.parse("blackout 3@2s"), SC, WINDOWS) == []  # never ends
    assert window_recoveries(Fault.parse("blackout 3@8s for=2s"), SC, WINDOWS) == []  # ends with the run
    assert window_recoveries(Fault.parse("blackout 3@2s for=1s"), SC, None) == []


def test_the_console_says_a_window_recovery_and_lists_faults_by_their_start() -> None:
    fault = Fault.parse("partition 2@2s for=2s")
    f = {"fault": str(fault), "start_tick": 40, "recoveries": window_recoveries(fault, SC, WINDOWS)}
    assert describe_fault(f) == (
        "partition 2@2s for=2s: R2 below 0.5 m (1 s mean) within 3.00 s after the fault's end at t=4.00 s; "
        "largest error in the 5 s after: 1.60 m"
    )
    late, early = {"fault": "blackout 3@5s for=1s", "start_tick": 100}, {"fault": "kill agent-2@1s", "start_tick": 20}
    out = io.StringIO()
    print_result(RunResult(Path("/nowhere"), {"faults": [late, early]}, 0), out)
    lines = [line for line in out.getvalue().splitlines() if line.startswith("  fault: ")]
    assert [line.removeprefix("  fault: ") for line in lines] == [early["fault"], late["fault"]]
