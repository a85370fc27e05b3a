"""Stand-ins for what a role's process hands it: a stop event, a publisher."""

from __future__ import annotations

from formation_swarm.runtime.proc import StopEvent


class FakeRole:
    """What the roles use of role.Role here: a stop event (and no signal handlers in the test process)."""

    def __init__(self) -> None:
        self.stop = StopEvent()


class FakePub:
    def __init__(self) -> None:
        self.payloads: list[bytes] = []

    def put(self, payload: bytes) -> None:
        self.payloads.append(payload)
