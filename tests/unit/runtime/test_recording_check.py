"""How a run says its logger was lost (runtime.summary.recording) and where the
launcher places a process that exited on its own (launch.result.place_exits):
at the tick the world saw its token go."""

from __future__ import annotations

from formation_swarm.launch.result import place_exits
from formation_swarm.runtime.summary.recording import logger_lost, recording_cut

LOST = {"tick": 400, "time_s": 20.0, "wall_s": 3.5}


def test_a_logger_killed_outside_the_schedule_is_placed_at_the_tick_the_world_saw_it_go() -> None:
    exited = {"event": "exited", "process": "logger", "code": -9, "sim_time_s": 16.75}
    events = [exited]
    place_exits(events, {"logger_lost": LOST})
    assert exited == {
        "event": "exited",
        "process": "logger",
        "code": -9,
        "sim_time_s": 20.0,
        "tick": 400,
        "placed_by": "the world",
    }
    said = "the logger was killed by SIGKILL at sim t=20.00 s (tick 400), outside the fault schedule"
    assert logger_lost({"logger_lost": LOST}, events) == said
    summary = {"mode": "realtime", "events": events, "parts": {"world": {"logger_lost": LOST}}}
    cut = recording_cut(summary)
    assert cut.startswith(f"{said}: the recording ends there, ")  # where, as logger_lost says it
    assert "(up to its last second of wall time); " in cut  # real time: no word of lockstep's ticks
    assert "its file has no end" in cut  # lost, not killed by design: the recording was not closed


def test_a_logger_whose_token_went_without_an_exit_is_lost_too() -> None:
    said = logger_lost({"logger_lost": LOST}, [])
    assert said.startswith("the logger's token went ")  # no exit of it known: how the world saw it go
    assert "at sim t=20.00 s (tick 400)" in said  # when, as an exit's


def test_a_logger_killed_by_its_fault_is_a_cut_by_design_not_a_loss() -> None:
    kill = {"event": "killed", "process": "logger", "sim_time_s": 3.0, "tick": 60, "fault": "kill logger@3s"}
    exited = {"event": "exited", "process": "logger", "code": -9, "sim_time_s": 3.0, "tick": 60}
    events = [kill, exited]
    place_exits(events, {"logger_lost": {**LOST, "tick": 62, "time_s": 3.1}})
    assert exited["tick"] == 60  # the kill placed it
    assert logger_lost({"logger_lost": LOST}, events) is None
    assert recording_cut({"mode": "lockstep", "events": events}).startswith("the logger was killed at sim t=3.00 s:")
    assert recording_cut({"mode": "lockstep", "events": []}) is None


def test_a_lost_agents_exits_are_placed_at_its_losses_in_order() -> None:
    deaths = [
        {"robot": 3, "tick": 100, "time_s": 5.0, "cause": "lost"},
        {"robot": 2, "tick": 150, "time_s": 7.5, "cause": "killed"},
        {"robot": 3, "tick": 300, "time_s": 15.0, "cause": "lost"},
    ]
    first = {"event": "exited", "process": "agent-3", "code": 1, "sim_time_s": 4.0}
    second = {"event": "exited", "process": "agent-3.2", "code": -9, "sim_time_s": 14.0}
    host = {"event": "exited", "process": "agent-2", "host_lost": "b", "sim_time_s": 7.0}
    place_exits([first, second, host], {"deaths": deaths})
    assert (first["tick"], first["sim_time_s"]) == (100, 5.0)
    assert (second["tick"], second["sim_time_s"]) == (300, 15.0)
    assert "tick" not in host
