"""What the launcher makes of the world's stats about outside agents and
robot logins: the end reason of a world that gave up, the outside slot it
waited for in vain, the second sessions it saw, the losses it counted."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from formation_swarm.launch.external import LEFT, ExternalAgent, Outside, never_came
from formation_swarm.launch.logins import USED_TWICE, say_second_sessions
from formation_swarm.launch.record import Journal
from formation_swarm.launch.result import Ending, end_reason
from formation_swarm.protocol.keys import Keys
from formation_swarm.runtime.summary.end_reason import describe_waited

WAITED = {"waited_for": {"robots": [3], "missing": "no agent for robot 3", "timeout_s": 5.0}}
SECOND = {"robot": 3, "login": "agent-3", "tick": 44, "time_s": 2.2, "wall_s": 1.0}


def _outside(tmp_path: Path, lines: list[str]) -> Outside:
    agent = ExternalAgent(robot=3, endpoint="tcp/127.0.0.1:9", run_id="r1", scenario=tmp_path, login=None)
    return Outside({3: agent}, {}, Journal(lines.append), Keys("r1"))


def test_a_world_that_gave_up_is_the_end_reason_not_the_agents_that_left_after() -> None:
    events = [{"event": "exited", "process": "agent-1", "code": 3}]
    assert end_reason({"end_reason": "peers_timeout"}, 3, None, events, Ending(start_failed=True)) == (
        "peers_timeout",
        None,
    )
    assert end_reason({}, 3, None, events, Ending(start_failed=True))[0] == "role_failed"


def test_the_outside_slot_waited_for_is_named_with_its_deadline() -> None:
    said = never_came(WAITED, [3])
    assert said is not None
    assert [w in said for w in ("robot 3", "outside agent", "5 s", "--peers-timeout")] == [True] * 4
    assert never_came(WAITED, [2]) is None  # robot 3 was ours: not an outside slot
    assert never_came({"waited_for": {"robots": "3", "timeout_s": 5.0}}, [3]) is None  # malformed: nothing said
    assert never_came({}, [3]) is None
    waited = describe_waited(WAITED)
    assert waited is not None
    assert waited.endswith(": no agent for robot 3")
    assert describe_waited({"waited_for": None}) is None


def test_each_login_used_twice_is_an_event_and_a_warning() -> None:
    lines: list[str] = []
    journal = Journal(lines.append)
    world: dict[str, Any] = {
        "duplicate_agents": {"3": 158, "2": 0, "x": 4, "1": "7"},
        "second_sessions": [SECOND, {"robot": "3"}, "junk"],
    }
    say_second_sessions(world, journal)
    assert [(e["robot"], e.get("answers_refused"), e.get("kept_token"), e.get("tick")) for e in journal.events] == [
        (3, 158, None, None),
        (3, None, True, 44),
    ]
    assert len(lines) == 2
    assert "(158 answers refused)" in lines[0]
    assert "sim t=2.20 s" in lines[1]
    say_second_sessions({"second_sessions": "junk", "duplicate_agents": []}, journal)
    assert len(journal.events) == 2


def test_a_loss_the_token_showed_is_placed_at_the_worlds_tick(tmp_path: Path) -> None:
    lines: list[str] = []
    outside = _outside(tmp_path, lines)
    outside.journal.add(LEFT, robot=3, sim_time_s=4.0, wall_s=4.1)
    death = {"robot": 3, "tick": 81, "time_s": 4.05, "cause": "lost"}
    outside.settle({"deaths": [death, {"robot": 2, "tick": 90, "time_s": 4.5, "cause": "lost"}]})
    assert [(e["robot"], e["tick"], e["sim_time_s"], e["placed_by"]) for e in outside.journal.events] == [
        (3, 81, 4.05, "the world")
    ]
    assert len(lines) == 0  # said when the token went


def test_a_loss_a_second_session_hid_from_the_tokens_is_added_and_said(tmp_path: Path) -> None:
    lines: list[str] = []
    outside = _outside(tmp_path, lines)
    death = {"robot": 3, "tick": 81, "time_s": 4.05, "cause": "lost"}
    outside.settle({"deaths": [death, "junk"], "second_sessions": [SECOND]})
    assert [(e["event"], e.get("tick")) for e in outside.journal.events] == [(USED_TWICE, 44), (LEFT, 81)]
    assert len(lines) == 2
    assert "kept its token" in lines[1]


def test_outside_and_login_events_read_as_sentences_with_their_numbers() -> None:
    from formation_swarm.launch.words import describe_event

    came = describe_event({"event": "outside agent connected", "robot": 3, "sim_time_s": 39.400000000000006})
    twice = describe_event({"event": "robot login used twice", "robot": 3, "login": "agent-3", "answers_refused": 158})
    kept = describe_event(
        {"event": "robot login used twice", "robot": 2, "login": "agent-2", "kept_token": True, "sim_time_s": 2.0}
    )
    assert re.findall(r"\d+(?:\.\d+)?", came) == ["3", "39.40"]  # rounded as every event's time is
    assert "event" not in came
    assert re.findall(r"\d+", twice) == ["3", "3", "158"]
    assert "kept its token" in kept
    assert re.findall(r"\d+(?:\.\d+)?", kept) == ["2", "2", "2.00"]
