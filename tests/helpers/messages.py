"""Messages for tests, by keyword: each factory fills the fields a test does
not name with a plain default, so a test names only what it is about
(``telemetry(steering_to=3)``). A field the message has not is a TypeError.
(tests.helpers.fakes.observation is the world's observation of a tick, as an
agent's loop gets it.)"""

from __future__ import annotations

from typing import Any

from formation_swarm.protocol.messages import WORLD_ID, Command, FaultCall, Observation, Telemetry


def observation(**fields: Any) -> Observation:
    """The world's observation at tick 0 (seq 1, t=0 s) of a robot at the
    origin facing x, with no readings and no obstacles; ``fields`` override these."""
    defaults: dict[str, Any] = {
        "sender": WORLD_ID,
        "seq": 1,
        "tick": 0,
        "time_s": 0.0,
        "pose": (0.0, 0.0, 0.0),
        "readings": (),
        "obstacles": (),
    }
    return Observation(**(defaults | fields))


def telemetry(**fields: Any) -> Telemetry:
    """Robot 2's telemetry at tick 1 (seq 1, t=0 s), following robot 1 in
    formation 0, nothing measured or estimated yet, wheels at rest, nothing
    dropped or rejected; ``fields`` override these."""
    defaults: dict[str, Any] = {
        "sender": 2,
        "seq": 1,
        "tick": 1,
        "time_s": 0.0,
        "reference": 1,
        "formation": 0,
        "measured": None,
        "estimate": None,
        "target_cov": None,
        "rho_m": None,
        "alpha_rad": None,
        "vn": None,
        "left_mps": 0.0,
        "right_mps": 0.0,
        "steering_to": 0,
        "changing": False,
        "obs_dropped": 0,
        "formation_dropped": 0,
        "rejected": 0,
    }
    return Telemetry(**(defaults | fields))


def command(**fields: Any) -> Command:
    """Robot 2's command at tick 0 (seq 1): wheels at rest, formation 0, not
    done; ``fields`` override these."""
    defaults: dict[str, Any] = {
        "sender": 2,
        "seq": 1,
        "tick": 0,
        "left_mps": 0.0,
        "right_mps": 0.0,
        "formation": 0,
        "done": False,
    }
    return Command(**(defaults | fields))


def fault_call(**fields: Any) -> FaultCall:
    """The world's call at tick 1 (seq 1, t=0.05 s) to kill agent-2 for the
    schedule's first fault; ``fields`` override these."""
    defaults: dict[str, Any] = {
        "sender": 0,
        "seq": 1,
        "tick": 1,
        "time_s": 0.05,
        "action": "kill",
        "process": "agent-2",
        "index": 0,
    }
    return FaultCall(**(defaults | fields))
