"""A logger that left before tick 0, after the world gave up waiting, lost no
recording (runtime.summary.recording.logger_lost): the run's end says why."""

from __future__ import annotations

from formation_swarm.runtime.summary.recording import logger_lost, recording_cut


def test_a_logger_that_left_before_the_first_tick_is_not_lost() -> None:
    exited = {"event": "exited", "process": "logger", "code": 3, "sim_time_s": -1.0}
    assert logger_lost({}, [exited]) is None
    assert recording_cut({"mode": "lockstep", "events": [exited], "parts": {"world": {}}}) is None
    during = {**exited, "sim_time_s": 4.5}  # during the run: lost, and said so
    assert (logger_lost({}, [during]) or "").startswith("the logger exited with code 3 at sim t=4.50 s")
