"""The fault grammar (formation_swarm.common.faults): strings, tables and objects
are one schedule, checked the same way, placed on exact ticks."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import pytest

from formation_swarm.common.faults import (
    ACTUATOR,
    KINDS,
    LINK,
    NETWORK,
    PROCESS,
    SENSOR,
    Fault,
    link_faults,
    of_robot,
    seconds,
)
from formation_swarm.common.faults.doc import reference
from formation_swarm.common.faults.schedule import check_against
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.spec.scenario import ScenarioError
from tests.helpers import ROOT

EXAMPLES = [
    "kill agent-3@20s",
    "kill logger@4s",
    "restart agent-2@20s after=1.5",
    "freeze agent-2@15s for=3s",
    "drop obs:2@10s for=5s p=0.3",
    "burst cmd:2,3@10s loss=0.9 p_bad=0.05 p_good=0.3",
    "delay formation:*@5s for=10s jitter_ticks=2 ticks=4",
    "delay obs:3@5s ms=120",
    "duplicate links:2@1s p=0.2",
    "reorder cmd:*@1s for=2s p=0.1",
    "partition 2,3@12s for=15s from=world",
    "blackout 3@20s for=2s",
    "bias 2@1.5s beta_deg=-2 rho_m=0.2",
    "outliers 3@0s p=0.05",
    "range 2@3s m=4",
    "wheel_noise *@0s sigma_mps=0.1",
    "wheel_bias 2@0s left=0.03 right=-0.03",
    "slip 3@10s for=2s fraction=0.4 wheel=right",
    "stuck 2@30s for=4s wheel=left",
]


@pytest.mark.parametrize("text", EXAMPLES)
def test_string_table_and_object_are_one_fault(text: str) -> None:
    f = Fault.parse(text)
    assert str(f) == text  # canonical form
    assert Fault.from_table(f.to_table()) == f
    assert Fault.coerce(f) is f


def test_every_kind_has_an_example_and_a_doc() -> None:
    assert {t.split()[0] for t in EXAMPLES} == set(KINDS)
    doc = (ROOT / "docs" / "faults.md").read_text()
    assert reference() in doc, "docs/faults.md: its table of kinds is stale (make docs)"


def test_ticks_of_a_fault() -> None:
    f = Fault.parse("freeze agent-2@20s for=3s")
    assert (f.start_tick(0.05), f.end_tick(0.05)) == (400, 460)
    assert [f.active(t, 0.05) for t in (399, 400, 459, 460)] == [False, True, True, False]
    assert Fault.parse("kill agent-2@20s").end_tick(0.05) is None
    assert Fault.parse("restart agent-2@20s after=1").end_tick(0.05) == 420
    assert Fault.parse("bias 2@1500ms rho_m=1").start_tick(0.05) == 30


def test_link_faults_by_link() -> None:
    faults = [
        Fault.parse(t)
        for t in (
            "drop obs:2@1s p=0.1",
            "partition 3@1s for=1s from=leader",
            "delay links:*@1s ticks=1",
            "partition 2@1s for=1s",
        )
    ]
    drop, _leader, delay, partition = faults
    assert link_faults(faults, "obs", 2) == (drop, delay, partition)
    assert [f.kind for f in link_faults(faults, "obs", 3)] == ["delay"]
    assert [f.kind for f in link_faults(faults, "formation", 3)] == ["partition", "delay"]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("kill world@3s", "cannot kill the world"),
        ("restart logger@3s", "only agents restart"),
        ("kill agent-3", "a fault is KIND TARGET@START"),
        ("agent-3@20", "did you mean 'kill agent-3@20'"),
        ("drop obs:2@1s", "needs p=VALUE"),
        ("drop obs:2@1s p=1.5", "p must be in [0, 1]"),
        ("drop obs:2@-1s p=0.5", "the start must be a time >= 0 s, such as 20, 20s or 1500ms"),
        ("drop radio:2@1s p=0.5", "the target is a link class"),
        ("delay obs@1s ticks=1 ms=3", "exactly one of ticks or ms"),
        ("freeze agent-2@1s", "needs a duration"),
        ("kill agent-2@1s for=2s", "takes no duration"),
        ("drop obs:2@1s p=0.1 q=3", "has no parameter 'q'"),
        ("bias 2@1s rho_m=0.5cm", "rho_m must be a number in m, got '0.5cm'"),  # the value as given
        ("restart agent-2@1s after=500mss", "after must be a time such as 20, 20s or 1500ms, got '500mss'"),
        ("drop obs:2@1s for=-1s p=0.1", "for must be a time >= 0 s, such as 20"),
        ("partition 2@1s for=1s from=mars", "from must be one of world, leader, both"),
        ("blackout 2,2@1s", "named twice"),
        ("drop obs:2@1s for=0s p=0.1", "for must be > 0 s"),
    ],
)
def test_bad_faults_name_the_problem(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        Fault.parse(text)


TOML_FAULTS = """
[[faults]]
kind = "kill"
target = "agent-3"
at_s = 20

[[faults]]
kind = "drop"
target = "obs:2"
at_s = 5
for_s = 2.5
p = 0.4
"""


def test_scenario_faults_from_tables_and_the_command_line(tmp_path: Path) -> None:
    src = (ROOT / "scenarios" / "fig11_obstacles.toml").read_text()
    path = tmp_path / "s.toml"
    path.write_text(src + TOML_FAULTS)
    sc = scenario_mod.load(path, faults=["freeze agent-2@1s for=2s"])
    assert list(sc.faults) == [  # the command line's, then the tables' in their order
        Fault.make("freeze", "agent-2", 1, for_s=2),
        Fault.make("drop", "obs:2", 5, for_s=2.5, p=0.4),
        Fault.make("kill", "agent-3", 20),
    ]
    # The scenario as run holds every fault, so each process reads the same schedule.
    from formation_swarm.spec.files import dumps

    again = tmp_path / "again.toml"
    again.write_text(dumps(sc.raw))
    assert scenario_mod.load(again).faults == sc.faults


@pytest.mark.parametrize(
    ("fault", "message"),
    [
        ("kill agent-9@5s", "no robot 9 in this run; robots are 1, 2, 3"),
        ("kill agent-2@99s", "after the run's end"),
        # fig11 runs 56 s: ticks 0-1119, the last at 55.95 s; a start rounded to tick 1120 would never come.
        ("kill agent-2@56s", "starts at 56 s, at or after the run's end (56 s; its last tick is at 55.95 s)"),
        ("kill agent-2@55.99s", "starts at 55.99 s, at or after the run's end"),
        ("drop formation:1@1s p=0.5", "robot 1 is the leader; formation links go to followers"),
        ("partition 1@1s for=2s from=leader", "cannot be cut off from itself"),
        ("wheel_noise 4@0s sigma_mps=0.1", "no robot 4"),
    ],
)
def test_faults_checked_against_the_run(fault: str, message: str) -> None:
    with pytest.raises(ScenarioError) as err:
        scenario_mod.load("fig11_obstacles", faults=[fault])
    assert message in str(err.value)


def test_a_faults_entry_that_is_not_a_table(tmp_path: Path) -> None:
    src = (ROOT / "scenarios" / "fig11_obstacles.toml").read_text()
    path = tmp_path / "s.toml"
    path.write_text("faults = 3\n" + src)
    with pytest.raises(ScenarioError, match="faults must be an array"):
        scenario_mod.load(path)
    path.write_text(src + '\n[[faults]]\nkind = "kill"\nat_s = 3\n')
    with pytest.raises(ScenarioError, match=r"faults\[0\]: faults needs target"):
        scenario_mod.load(path)


def test_summary_gathers_each_faults_ticks_events_and_counts() -> None:
    from formation_swarm.runtime.summary.faults import fault_effects

    restart, drop = "restart agent-3@20s after=1", "drop obs:2@10s for=5s p=0.3"  # as the summary names them
    sc = scenario_mod.load("fig11_obstacles", faults=[restart, drop])
    parts = {
        "world": {
            "fault_log": [
                {"tick": 400, "time_s": 20.0, "fault": restart, "event": "killed", "robot": 3},
                {"tick": 420, "time_s": 21.0, "fault": restart, "event": "rejoined", "robot": 3},
            ]
        },
    }
    # The link layer's per-fault counts, summed over the fault's links (summary._link_sums).
    link_faults = {"0": {"fault": drop, "dropped": 30}}
    out = fault_effects(sc, parts, link_faults=link_faults)
    assert [(f["fault"], f["start_tick"], f["end_tick"]) for f in out] == [(drop, 200, 300), (restart, 400, 420)]
    assert out[0]["counts"] == {"dropped": 30}
    assert [e["event"] for e in out[1]["events"]] == ["killed", "rejoined"]


def test_a_faults_counts_are_grouped_by_robot_each_with_its_ticks_first() -> None:
    from formation_swarm.launch.words import Counts, counts_of

    counts = {"R3 ticks": 40, "R3 moving_ticks": 38, "dropped": 1, "R2 moving_ticks": 0, "R2 ticks": 40, "held": 2}
    assert counts_of(counts) == Counts(
        plain=(("dropped", 1), ("held", 2)),
        robots=((2, (("ticks", 40), ("moving_ticks", 0))), (3, (("ticks", 40), ("moving_ticks", 38)))),
    )
    assert counts_of({}) == Counts()


def test_a_faults_counts_read_as_words_on_the_console() -> None:
    from formation_swarm.launch.console import describe_counts

    counts = {"dropped": 1, "partitioned": 40, "held": 2, "R3 ticks": 40, "R3 moving_ticks": 38, "R2 ticks": 40}
    assert describe_counts({**counts, "R2 moving_ticks": 0}) == (
        "1 message dropped; 40 messages lost to the partition; held 2; "
        "R2: on for 40 ticks, 0 of them with the robot told to move; "
        "R3: on for 40 ticks, 38 of them with the robot told to move"
    )


def test_a_faults_line_says_its_counts_and_whose_killed_agent_left_them_partial_or_unwritten() -> None:
    from formation_swarm.launch.console import describe_counts, describe_fault
    from formation_swarm.launch.words import Counts, FaultSaid, fault_said

    fault = {"fault": "partition 2@5s for=2s", "start_tick": 100, "events": [], "counts": {"partitioned": 40}}
    assert fault_said(fault, ticks=400) == FaultSaid(fault["fault"], 100, counts=Counts((("partitioned", 40),)))
    assert describe_fault(fault, ticks=400) == f"{fault['fault']}: {describe_counts(fault['counts'])}"
    # The receiving agent was killed inside the window: a lower bound, or nothing it wrote.
    fault["counts_partial_for"] = [2]
    assert fault_said(fault, ticks=400).partial_for == (2,)
    assert describe_fault(fault, ticks=400) == (
        "partition 2@5s for=2s: 40 messages lost to the partition"
        " (at least: R2's agent was killed, and its counts end at its last stats write)"
    )
    fault["counts"] = {}
    assert fault_said(fault, ticks=400) == FaultSaid(fault["fault"], 100, partial_for=(2,))
    unwritten = describe_fault(fault, ticks=400)
    assert unwritten.startswith(f"{fault['fault']}: not counted: ")
    assert "R2's agent was killed before it wrote" in unwritten
    assert "messages" not in unwritten


def test_a_fault_cut_by_the_runs_end_lists_its_ticks_in_the_run_and_events_of_one_tick_read_as_one() -> None:
    import warnings

    from formation_swarm.launch.console import describe_fault
    from formation_swarm.launch.words import fault_said
    from formation_swarm.runtime.summary.faults import fault_effects

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # lasting past the end is warned of
        sc = scenario_mod.load("fig11_obstacles", {"run.duration_s": 15}, faults=["partition 2@14s for=10s"])
    assert [(f["start_tick"], f["end_tick"]) for f in fault_effects(sc, {})] == [(280, 300)]  # not 480
    events = [
        {"event": "killed", "robot": 2, "tick": 240},
        {"event": "started", "robot": 2, "tick": 260},
        {"event": "readmitted", "robot": 2, "tick": 260},
        {"event": "rejoined", "robot": 2, "tick": 260},
    ]
    restart = {"fault": "restart agent-2@12s after=1", "events": events, "counts": {}}
    assert fault_said(restart).events == ((2, 240, ("killed",)), (2, 260, ("started", "readmitted", "rejoined")))
    said = describe_fault(restart)
    assert said.startswith(f"{restart['fault']}: killed R2 at tick 240; ")
    assert said.endswith("; started, readmitted and rejoined R2 at tick 260")


def test_report_md_says_partition_losses_rejection_reasons_and_a_killed_followers_error_until_then() -> None:
    from formation_swarm.report.markdown import report_markdown

    summary = {
        "ticks": 400,
        "mode": "lockstep",
        "drops_total": 0,
        "rejected_total": 1,
        "lockstep_misses": 0,
        "link_totals": {"cmd": {"partitioned": 40}},
        "rejected": {"world": {"replayed or reordered": 1}},
        "followers": {"3": {"rms_m": 22.75, "until_stopped": {"time_s": 20.0, "rms_m": 0.8, "max_m": 1.5}}},
    }
    text = report_markdown(summary, [3])
    assert (
        "Link layer: messages dropped 0, lost to partitions 40; lockstep misses 0; rejected payloads 1 "
        "(replayed or reordered 1)."
    ) in text
    assert (
        "R3 stopped at t=20.00 s (its agent killed or lost): its figures above include the robot after that; "
        "until then RMS 0.800 m, max 1.500 m."
    ) in text
    # Restarted: when its fresh agent started (the console says it; report.md did not).
    summary["events"] = [
        {"event": "killed", "process": "agent-3", "sim_time_s": 20.0},
        {"event": "started", "process": "agent-3.2", "sim_time_s": 21.0},
    ]
    text = report_markdown(summary, [3])
    assert "R3 stopped at t=20.00 s (its agent killed or lost, a fresh agent started at t=21.00 s): " in text


def test_the_results_line_says_why_messages_were_rejected() -> None:
    import io
    from pathlib import Path

    from formation_swarm.launch.console import print_result
    from formation_swarm.launch.launcher import RunResult

    summary = {
        "ticks": 5,
        "mode": "lockstep",
        "followers": {},
        "rejected_total": 3,
        "lockstep_misses": 0,
        "drops_total": 0,
        "rejected": {"world": {"replayed or reordered": 2}, "agent-2": {"unknown key": 1}},
    }
    out = io.StringIO()
    print_result(RunResult(Path("."), summary, 0), out)
    assert (
        "lockstep misses 0, messages dropped 0, rejected 3 (replayed or reordered 2, unknown key 1)" in out.getvalue()
    )


def test_a_killed_logger_says_the_recording_is_cut_short_and_a_sweep_does_not_retry_it() -> None:
    from formation_swarm.runtime.summary.recording import recording_cut, recording_gap

    kill = {"event": "killed", "process": "logger", "sim_time_s": 3.0, "fault": "kill logger@3s"}
    summary = {"mode": "lockstep", "events": [kill], "parts": {}, "messages": {}}
    assert recording_cut(summary) == (
        "the logger was killed at sim t=3.00 s: the recording ends before that, without what the logger had not "
        "yet written (up to its last second of wall time; a lockstep run passes many ticks in a second, so it may "
        "hold none)"
    )
    assert recording_gap(summary) is None  # swarm sweep runs a run with a gap again; this one would lose it again
    assert recording_cut({**summary, "mode": "realtime"}).endswith("(up to its last second of wall time)")
    assert recording_cut({**summary, "events": [{**kill, "process": "agent-3"}]}) is None


def test_a_fault_that_lasts_past_the_runs_end_is_warned_of_not_refused() -> None:
    from formation_swarm.spec.keys import ScenarioWarning

    with pytest.warns(ScenarioWarning, match="lasts past the run's end"):
        sc = scenario_mod.load("fig11_obstacles", {"run.duration_s": 15}, faults=["partition 2@14s for=10s"])
    assert "fault 'partition 2@14s for=10s' lasts past the run's end (15 s): it is cut there, after 1 s" in sc.warnings
    exact = scenario_mod.load(
        "fig11_obstacles", {"run.duration_s": 15}, faults=["partition 2@14s for=1s", "kill agent-3@14s"]
    )
    assert not [w for w in exact.warnings if "past the run's end" in w]  # ends on the end; a kill has no window


# -- exact boundaries, without a scenario ------------------------------------------------


def _check(*texts: str, duration_s: float = 60.0) -> None:
    check_against([Fault.parse(t) for t in texts], robots=(1, 2, 3), leader_id=1, duration_s=duration_s, dt_s=0.05)


@pytest.mark.parametrize(
    ("value", "expected"), [("1500ms", 1.5), ("0", 0.0), ("1e3s", 1000.0), ("20s", 20.0), (3, 3.0), (0.0, 0.0)]
)
def test_seconds_reads_units_and_zero(value: object, expected: float) -> None:
    assert seconds("t", value) == expected


@pytest.mark.parametrize("value", [-0.5, -1e-9, math.inf, math.nan, "1e400s", "-1s", True, "abc"])
def test_seconds_refuses_negative_infinite_and_non_times(value: object) -> None:
    with pytest.raises(ValueError, match="^t must be a time"):
        seconds("t", value)


def test_start_and_end_ticks_round_and_last_at_least_one_tick() -> None:
    assert Fault.parse("freeze agent-2@1.02s for=0.01s").start_tick(0.05) == 20  # 20.4 -> 20
    assert Fault.parse("freeze agent-2@1.03s for=0.01s").start_tick(0.05) == 21  # 20.6 -> 21
    assert Fault.parse("freeze agent-2@1s for=0.01s").end_tick(0.05) == 21  # 0.2 tick -> one tick
    assert Fault.parse("restart agent-2@1s after=0").end_tick(0.05) == 21
    assert Fault.parse("freeze agent-2@1s for=0.04s").end_tick(0.05) == 21  # 0.8 tick -> one tick


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("drop obs:2@1s p=-0.5", "p must be in [0, 1], got -0.5"),
        ("drop obs:2@1s p=abc", "p must be a number, got 'abc'"),
        ("drop obs:2@1s p=nan", "p must be a finite number, got nan"),
        ("drop obs:2@1s p=inf", "p must be a finite number, got inf"),
        ("drop obs:2@1s p=", "'p=' is not PARAM=VALUE"),
        ("drop obs:2@1s =0.5", "'=0.5' is not PARAM=VALUE"),
        ("range 2@1s m=0", "m must be in (0, inf], got 0.0"),
    ],
)
def test_bad_values_name_the_problem(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        Fault.parse(text)


def test_a_lone_word_gets_a_hint_only_when_it_looks_like_a_target() -> None:
    with pytest.raises(ValueError, match="a fault is KIND TARGET@START") as err:
        Fault.parse("kill")
    assert "did you mean" not in str(err.value)
    with pytest.raises(ValueError, match=re.escape("did you mean 'kill agent-3@20'")):
        Fault.parse("agent-3@20")


def test_values_on_the_bounds_are_taken() -> None:
    assert Fault.parse("drop obs:2@1s p=0").param("p") == 0.0
    assert Fault.parse("drop obs:2@1s p=1").param("p") == 1.0
    assert Fault.parse("wheel_bias 2@1s left=-1 right=1").params == (("left", -1.0), ("right", 1.0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        KINDS["drop"].params["p"].low = -1.0  # type: ignore[misc]


def test_which_robots_and_links_a_fault_names() -> None:
    stuck, partition = Fault.parse("stuck 2,3@1s"), Fault.parse("partition *@1s for=1s")
    assert (stuck.link_classes, stuck.robots, stuck.applies_to(2), stuck.applies_to(1)) == ((), (2, 3), True, False)
    assert (partition.link_classes, partition.robots, partition.applies_to(7)) == ((), None, True)
    kill, logger = Fault.parse("kill agent-3@1s"), Fault.parse("kill logger@1s")
    assert (kill.link_classes, kill.robots, kill.robot, kill.process) == ((), (3,), 3, "agent-3")
    assert (logger.robots, logger.robot, logger.process, logger.applies_to(2)) == (None, None, "logger", True)
    links = Fault.parse("delay links:2@1s ticks=1")
    assert (links.link_classes, links.robots, links.process) == (("obs", "cmd", "formation"), (2,), None)


def test_link_faults_take_only_faults_on_that_link() -> None:
    faults = [
        Fault.parse(t)
        for t in (
            "drop cmd:2@1s p=0.1",
            "blackout 2@1s",
            "stuck 2@1s",
            "kill agent-2@1s",
            "partition 2@1s for=1s from=world",
        )
    ]
    drop, _blackout, _stuck, _kill, partition = faults
    assert link_faults(faults, "obs", 2) == (partition,)
    assert link_faults(faults, "cmd", 2) == (drop, partition)
    assert link_faults(faults, "formation", 2) == ()
    assert link_faults(faults, "cmd", 3) == ()


def test_of_robot_takes_one_group_for_one_robot() -> None:
    texts = (
        "blackout 2@1s",
        "stuck 2@1s",
        "drop obs:2@1s p=0.1",
        "kill agent-2@1s",
        "partition 2@1s for=1s",
        "bias 3@1s rho_m=1",
        "slip *@1s fraction=0.1",
    )
    faults = [Fault.parse(t) for t in texts]

    def kinds(group: str, rid: int) -> list[str]:
        return [f.kind for f in of_robot(faults, group, rid)]

    assert kinds(SENSOR, 2) == ["blackout"]
    assert kinds(ACTUATOR, 2) == ["stuck", "slip"]
    assert kinds(ACTUATOR, 3) == ["slip"]
    assert kinds(LINK, 2) == ["drop"]
    assert kinds(NETWORK, 2) == ["partition"]
    assert kinds(PROCESS, 2) == ["kill"]
    assert kinds(PROCESS, 3) == []


def test_formation_links_to_the_leader_are_refused_but_other_links_of_it_are_not() -> None:
    _check("drop links:1@1s p=0.5", "drop obs:1@1s p=0.5", "drop formation:2,3@1s p=0.5", "drop formation:*@1s p=0.5")
    with pytest.raises(ValueError, match="robot 1 is the leader; formation links go to followers"):
        _check("drop formation:1,2@1s p=0.5")


def test_process_faults_overlap_only_when_their_ticks_do() -> None:
    # Ticks past 256 (20 s at 0.05 s): the comparison is of values, not of objects.
    _check("freeze agent-2@0s for=20s", "freeze agent-2@20s for=1s")  # ends at 400, the next starts at 400
    _check("freeze agent-2@20s for=1s", "freeze agent-2@0s for=20s")  # either order
    _check("freeze agent-2@0s for=20s", "kill agent-3@10s", "restart agent-2@20s after=1", "kill agent-2@21s")
    for texts in (
        ("freeze agent-2@0s for=20s", "freeze agent-2@19.95s for=1s"),  # starts at 399, before the end
        ("freeze agent-2@19.95s for=1s", "freeze agent-2@0s for=20s"),
        ("freeze agent-2@30s for=1s", "freeze agent-2@0s for=40s"),  # inside
        ("kill agent-2@20s", "freeze agent-2@30s for=1s"),  # a kill lasts to the end
        ("freeze agent-2@30s for=1s", "kill agent-2@20s"),
        ("restart agent-2@20s after=1", "freeze agent-2@20.95s for=1s"),
    ):
        with pytest.raises(ValueError, match="overlaps '.*' on the same process"):
            _check(*texts)


def test_at_most_256_faults() -> None:
    faults = [f"drop obs:2@{k * 0.1:g}s p=0.1" for k in range(256)]
    _check(*faults)
    with pytest.raises(ValueError, match="at most 256 faults, got 257"):
        _check(*faults, "drop obs:3@0s p=0.1")


def test_update_doc_rewrites_between_the_markers_only(tmp_path: Path) -> None:
    from formation_swarm.common.faults.doc import BEGIN, END, update_doc

    doc = tmp_path / "faults.md"
    doc.write_text(f"head\n{BEGIN}\nold\n{END}\ntail\n")
    update_doc(str(doc))
    assert doc.read_text().splitlines() == ["head", BEGIN, *reference().splitlines(), END, "tail"]
    assert reference().endswith("\n")  # END on a line of its own
    for text in (f"head\n{BEGIN}\nold\n", f"head\nold\n{END}\n"):
        doc.write_text(text)
        with pytest.raises(SystemExit, match="no .* markers"):
            update_doc(str(doc))
        assert doc.read_text() == text


def test_a_parameter_in_seconds_takes_the_units_the_times_do() -> None:
    assert Fault.parse("restart agent-2@1s after=500ms").param("after") == 0.5
    assert Fault.parse("restart agent-2@1s after=2s").param("after") == 2.0
    assert Fault.parse("restart agent-2@1s after=1.5").param("after") == 1.5


def test_one_fault_given_alone_is_one_fault(tmp_path: Path) -> None:
    from formation_swarm.common.faults import parse_all
    from formation_swarm.launch.launcher import Launch

    assert [str(f) for f in parse_all("kill agent-3@5s")] == ["kill agent-3@5s"]
    assert [str(f) for f in parse_all({"kind": "kill", "target": "agent-3", "at_s": 5})] == ["kill agent-3@5s"]
    launch = Launch("fig11_obstacles", out=tmp_path / "run", faults="kill agent-3@5s", kills="agent-2@7")
    assert sorted(str(f) for f in launch.sc.faults) == ["kill agent-2@7s", "kill agent-3@5s"]


def test_report_md_marks_the_counts_a_killed_agent_left_partial_or_unwritten() -> None:
    from formation_swarm.report.faults import faults_markdown

    fault = {
        "fault": "partition 2@5s for=2s",
        "start_tick": 100,
        "end_tick": 140,
        "events": [],
        "counts": {"partitioned": 12},
        "counts_partial_for": [2],
    }
    rows = [line for line in faults_markdown({"faults": [fault]}) if line.startswith("| `")]
    assert rows == [
        "| `partition 2@5s for=2s` | 100-139 | - | at least 12 messages lost to the partition "
        "(killed agents' counts end at their last stats write) |"
    ]
    fault["counts"] = {}
    (row,) = [_cells(line) for line in faults_markdown({"faults": [fault]}) if line.startswith("| `")]
    assert row[:3] == [f"`{fault['fault']}`", "100-139", "-"]
    assert row[3].startswith("not counted: R2's agent")


def test_a_killed_agents_counts_are_partial_only_if_it_lived_in_the_fault_and_wrote_them_before_final() -> None:
    from formation_swarm.runtime.summary.links import counts_cut

    # A fault over ticks 600-699; counts final at 701 (two ticks after its end).
    assert counts_cut([(516, 900)], 600, 700)  # killed after it, last wrote before it
    assert not counts_cut([(702, 900)], 600, 700)  # wrote them once final, killed later
    assert not counts_cut([(300, 400)], 600, 700)  # killed before it began: counted none of it
    assert counts_cut([(650, 660)], 600, 700)  # killed inside it
    assert counts_cut([(None, 660)], 600, 700)  # killed before its first write
    assert counts_cut([(900, 950)], 600, None)  # a fault to the run's end is never final
    assert not counts_cut([], 600, 700)
    # Two agents of the robot: one partial is enough.
    assert counts_cut([(300, 400), (650, 660)], 600, 700)


def test_report_md_says_a_fault_the_run_never_reached_never_started() -> None:
    """As the console does; its table row gave the ticks as if it had run."""
    from formation_swarm.report.faults import faults_markdown

    fault = {"fault": "freeze agent-2@54s for=1s", "start_tick": 1080, "end_tick": 1100, "events": [], "counts": {}}
    (row,) = [_cells(line) for line in faults_markdown({"ticks": 1061, "faults": [fault]}) if line.startswith("| `")]
    assert [row[0], row[1], row[3]] == [f"`{fault['fault']}`", "1080-", "-"]
    assert row[2].startswith("never started")
    assert row[2].endswith(" 1061")  # the run's last tick


def _cells(row: str) -> list[str]:
    """A markdown table's row, its cells."""
    return [c.strip() for c in row.strip().strip("|").split("|")]
