"""What `swarm run` prints at the end of a run: the result block, its sums
over many followers, the first contacts, a run that ended early, faults
the run never reached."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import RunResult
from formation_swarm.report import markdown


def test_print_result_sums_up_many_followers_and_lists_the_worst(tmp_path: Path) -> None:
    """Beyond 10 followers: their spread on one line, the 5 worst by RMS, then
    every other one never acquired or killed; formation events grouped."""
    followers: dict[str, dict[str, Any]] = {str(r): {"rms_m": r / 100, "max_m": r / 50} for r in range(2, 14)}
    followers["5"] = {"rms_m": 0.9, "max_m": 1.0}  # the worst
    followers["7"] = {"acquired": False, "rms_m": None, "max_m": None}
    followers["3"].update(seen_ticks=180, frames=200)  # lost sight of its reference in 10% of its frames
    followers["4"].update(seen_ticks=195, frames=200)  # 2.5%: said on its line only, were it listed
    events = [{"robot": r, "formation": "line", "time_s": 5.0} for r in range(1, 14)]
    events.append({"robot": 4, "formation": "triangle", "time_s": 9.05})
    summary = {
        "run_id": "r1",
        "ticks": 200,
        "sim_time_s": 10.0,
        "followers": followers,
        "formation_events": events,
        "events": [{"event": "killed", "process": "agent-2", "tick": 40, "sim_time_s": 2.0}],
    }
    out = io.StringIO()
    print_result(RunResult(tmp_path, summary, 0), out)
    lines = out.getvalue().splitlines()
    # Measured: R2-4, R6 and R8-13 at r/100, R5 at 0.9; sorted, the 6th of these 11 is R9's 0.09.
    assert (
        "  12 followers: formation error RMS median 0.090 m, best 0.020 m, worst 0.900 m (R5), "
        "largest error 1.000 m (R5)" in lines
    )
    assert (
        "  the 5 worst by RMS over the whole run, then 3 more that lost sight of their reference or were killed"
        ' (all 12: summary.json, "followers"):'
    ) in lines
    listed = [line.split(":")[0].strip() for line in lines if line.startswith("  follower R")]
    assert listed == [
        "follower R5",
        "follower R13",
        "follower R12",
        "follower R11",
        "follower R10",
        "follower R2",
        "follower R3",
        "follower R7",
    ]
    assert (
        "  follower R3: formation error RMS 0.030 m, max 0.060 m (its reference in view in 180 of 200 camera"
        " frames)" in lines
    )
    assert "  formation changes: line at 5.00 s: robots 1-13; triangle at 9.05 s: R4" in lines
    # Up to 10 followers, each has its line and the events are listed one by one.
    few = {**summary, "followers": {k: followers[k] for k in list(followers)[:10]}}
    out = io.StringIO()
    print_result(RunResult(tmp_path, few, 0), out)
    assert sum(line.startswith("  follower R") for line in out.getvalue().splitlines()) == 10
    said = out.getvalue()
    assert "follower R4: formation error RMS 0.040 m, max 0.080 m (its reference in view in 195 of 200" in said
    assert "followers: formation error RMS median" not in out.getvalue()
    assert "formation changes: R1 line at 5.00 s, R2 line at 5.00 s," in out.getvalue()


def test_print_result_and_the_report_text_take_a_run_that_ended_early(tmp_path: Path) -> None:
    """A summary without ticks or metrics, with None and missing values."""
    summary = {
        "run_id": "r1",
        "ticks": None,
        "sim_time_s": None,
        "followers": None,
        "min_distance_m": None,
        "formation_events": None,
        "events": [
            {"event": "exited", "process": "world", "code": 1, "sim_time_s": -1.0, "log_tail": ["ValueError: boom"]}
        ],
        "recording": "recording.rrd",
    }
    out = io.StringIO()
    print_result(RunResult(tmp_path, summary, 1), out)
    text = out.getvalue()
    assert "run r1: exit 1, no ticks, sim - s" in text
    assert "no metrics: the run ended before its first tick" in text
    assert "event: world exited with code 1 before the run started" in text
    assert "open it" not in text  # no recording.rrd in the folder
    (tmp_path / "recording.rrd").write_bytes(b"")  # one, from a run stopped before its first tick
    out = io.StringIO()
    print_result(RunResult(tmp_path, summary, 1), out)
    assert f"  recording: {tmp_path / 'recording.rrd'} (empty: the run ended before its first tick)" in out.getvalue()
    assert "open it" not in out.getvalue()
    (tmp_path / "recording.rrd").unlink()
    out = io.StringIO()
    ticked = {**summary, "ticks": 5, "followers": {"2": {"rms_m": None}}, "formation_events": [{"robot": 2}]}
    print_result(RunResult(tmp_path, ticked, 1), out)
    assert "follower R2: formation error RMS - m, max - m" in out.getvalue()
    assert "formation changes: R2 None at - s" in out.getvalue()
    md = markdown.report_markdown({**ticked, "parts": None}, [2])
    assert "| R2 | - | - |" in md
    out = io.StringIO()
    many = {**ticked, "followers": {str(r): {"rms_m": 0.1} for r in (100, 10, 2, 11)}}  # JSON's keys are text
    print_result(RunResult(tmp_path, many, 0), out)
    listed = [line.split(":")[0].strip() for line in out.getvalue().splitlines() if "follower R" in line]
    assert listed == ["follower R2", "follower R10", "follower R11", "follower R100"]
    out = io.StringIO()
    kill = {"event": "killed", "process": "agent-10", "tick": 40, "sim_time_s": 2.0}
    until = {"time_s": 2.0, "rms_m": 0.05, "max_m": 0.2}  # the world's figures up to the kill
    stopped = {**many, "followers": {**many["followers"], "10": {"rms_m": 0.1, "until_stopped": until}}}
    print_result(RunResult(tmp_path, {**stopped, "events": [kill]}, 0), out)
    lines = {line.split(":")[0].strip(): line for line in out.getvalue().splitlines() if "follower R" in line}
    said = (
        "follower R10: formation error RMS 0.050 m, max 0.200 m until its agent was killed at t=2.00 s; over "
        "the whole run, the robot after that included: RMS 0.100 m, max - m"
    )
    assert lines["follower R10"].strip() == said
    assert "killed" not in lines["follower R2"]
    out = io.StringIO()  # lost otherwise (its host gone, a crash): the world's death, the same way
    death = {"robot": 10, "tick": 40, "time_s": 2.0}
    print_result(RunResult(tmp_path, {**stopped, "deaths": [death]}, 1), out)
    lines = {line.split(":")[0].strip(): line for line in out.getvalue().splitlines() if "follower R" in line}
    assert lines["follower R10"].strip() == said.replace("was killed", "was lost")
    out = io.StringIO()  # real time: its late ticks, not lockstep's misses
    realtime = {**ticked, "mode": "realtime", "late_ticks": 3, "max_tick_lateness_s": 0.0551, "lockstep_misses": 0}
    print_result(RunResult(tmp_path, realtime, 1), out)
    assert "late ticks 3 (worst 55.1 ms), messages dropped -" in out.getvalue()
    assert "lockstep misses" not in out.getvalue()
    out = io.StringIO()  # a world left in the normal class says so beside its late ticks
    why = "normal (real-time priority 10 refused: Operation not permitted; it needs root or CAP_SYS_NICE)"
    print_result(RunResult(tmp_path, {**realtime, "world_scheduling": why}, 1), out)
    assert f"late ticks 3 (worst 55.1 ms) (world scheduling {why}), messages dropped -" in out.getvalue()
    out = io.StringIO()  # the followers' skipped observations (the leader's are not theirs)
    parts = {
        "agent-1": {"role": "leader", "answered": 100, "superseded": 50},
        "agent-2": {"role": "follower", "answered": 80, "superseded": 20},
        "agent-3": {"role": "follower", "answered": 90, "superseded": 10},
        "world": {"ticks": 5},
    }
    print_result(RunResult(tmp_path, {**realtime, "parts": parts}, 1), out)
    said = "late ticks 3 (worst 55.1 ms), followers skipped 15.0% of their observations, messages dropped -"
    assert said in out.getvalue()
    out = io.StringIO()  # a lockstep recording that misses ticks: the console and the report say which
    gap = "the logger recorded 715 of the 880 ticks the world sent (missing: truth ticks 100-264)"
    print_result(RunResult(tmp_path, {**ticked, "mode": "lockstep", "recording_gap": gap}, 0), out)
    assert f"  RECORDING INCOMPLETE: {gap}\n" in out.getvalue()
    assert f"**The recording is incomplete:** {gap};" in markdown.report_markdown({**ticked, "recording_gap": gap}, [2])
    assert "incomplete" not in markdown.report_markdown(ticked, [2]) + text


def test_print_result_names_the_first_contacts(tmp_path: Path) -> None:
    contacts = [
        {"tick": 489, "time_s": 24.45, "robots": [3, 15]},
        {"tick": 490, "time_s": 24.5, "robot": 7, "obstacle": 0},
        {"tick": 508, "time_s": 25.4, "robots": [1, 19]},
        {"tick": 600, "time_s": 30.0, "robots": [4, 5]},
    ]
    base = {"run_id": "r1", "ticks": 700, "sim_time_s": 35.0, "followers": {}, "min_distance_m": 0.01}
    out = io.StringIO()
    print_result(RunResult(tmp_path, {**base, "collisions": 3, "obstacle_collisions": 1, "contacts": contacts}, 0), out)
    assert (
        "  first contacts: R3 and R15 at 24.45 s, R7 and obstacle 0 at 24.50 s, R1 and R19 at 25.40 s"
        ' (all 4 in summary.json, "contacts")\n'
    ) in out.getvalue()
    out = io.StringIO()  # more contacts counted than the world lists
    many = {**base, "collisions": 70, "obstacle_collisions": 1, "contacts": contacts}
    print_result(RunResult(tmp_path, many, 0), out)
    assert '(the first 4 of 71 in summary.json, "contacts")\n' in out.getvalue()
    out = io.StringIO()
    print_result(
        RunResult(tmp_path, {**base, "collisions": 1, "obstacle_collisions": 0, "contacts": contacts[:1]}, 0), out
    )
    assert "  first contact: R3 and R15 at 24.45 s\n" in out.getvalue()
    out = io.StringIO()  # none, or a summary from before contacts were listed: no line
    print_result(RunResult(tmp_path, {**base, "collisions": 0, "obstacle_collisions": 0}, 0), out)
    assert "contact" not in out.getvalue()


def test_a_fault_the_run_never_reached_says_so(tmp_path: Path) -> None:
    """A run ends early when the leader's path is done (fig11: tick 1061 of 1120):
    a fault timed after that never starts, and its line says so."""
    fault = {"fault": "kill agent-3@54s", "start_tick": 1080, "end_tick": None, "events": [], "counts": {}}
    base = {"run_id": "r1", "ticks": 1061, "sim_time_s": 53.05, "followers": {}, "faults": [fault]}
    out = io.StringIO()
    print_result(RunResult(tmp_path, base, 0), out)
    assert "  fault: kill agent-3@54s: never started: the run ended at tick 1061, before its tick 1080\n" in (
        out.getvalue()
    )
