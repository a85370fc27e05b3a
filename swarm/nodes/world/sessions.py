"""A robot whose agent's session closed while its token stays: lost, and the
session that keeps the token, a second one on the robot's login, said.

Only robot N's login may hold ``alive/agent/N`` (protocol.acl). Zenoh merges
the tokens of one key: the world hears the token come when the first session
declares it and go when the last one leaves, so a second session holding it
would hide the agent's death. The world cannot ask which sessions hold a token: Zenoh 1.10.2's admin space
(``@/<id>/router/token/**``) stops its router when a session is declared
while it answers (a read lock taken twice, measured). So the world, when it
is the router, reads the two signs it has of an agent's session:

- its inbox: the world's publisher of the robot's observations is matched by
  the agent's subscription;
- a session closing (a Zenoh transport event, read here on a thread of ours
  from a channel: Zenoh's thread never waits for Python).

``SETTLE_S`` after a session closed (the router has dropped what it held by
then), a live robot whose observations have no subscriber while its token
stays has lost its agent's session, and another session on its login keeps
the token: the robot is lost, as when its token goes, and the second session
is recorded. A leaving agent undeclares its inbox and its token before its
session closes (in order on its link): its token is gone by then. Another
subscriber of the observations (an observer's subscription to the whole
run) hides this sign: the robot then stalls, or goes stale in real time.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh

from formation_swarm.protocol.acl import agent_user

SESSION_CLOSED = "@session-closed"  # the inbox's event when a session of the router closed: look now
SETTLE_S = 0.1  # wall s from a session's closing to the look: the router has dropped its declarations
EVENTS_CAPACITY = 1024  # sessions opened or closed, waiting for the reader


@dataclass
class LoginWatch:
    """The sessions that close, and the robots whose token outlived their agent's session."""

    session: zenoh.Session
    when: Callable[[], dict[str, Any]]  # tick, time_s and wall_s now, for the records
    say: Callable[[str], None]
    wake: Callable[[], None] = lambda: None  # the loop's, once it listens: a session closed
    closed: int = 0  # sessions closed so far
    records: list[dict[str, Any]] = field(default_factory=list)  # one per robot lost so: the world's stats
    listener: Any = None  # the transport events listener, held while the world runs

    def listen(self) -> None:
        """Each session of the router that closes (``wake``). No history: Zenoh
        1.10 lists the transports of a low-latency router only from its own threads."""
        self.listener = self.session.info.declare_transport_events_listener(
            zenoh.handlers.FifoChannel(EVENTS_CAPACITY), history=False
        )
        threading.Thread(target=self._read_events, name="world-sessions", daemon=True).start()

    def _read_events(self) -> None:
        while True:
            try:
                event = self.listener.recv()
            except zenoh.ZError:  # the session closed
                return
            if event.kind == zenoh.SampleKind.DELETE:
                self.closed += 1
                time.sleep(SETTLE_S)
                self.wake()

    def kept(self, unheard: list[int]) -> list[int]:
        """After a session closed: the live robots whose token stays and whose
        observations have no subscriber (``unheard``), lost now. Each is
        recorded and said: a second session on its login keeps its token."""
        for rid in unheard:
            at = self.when()
            self.records.append({"robot": rid, "login": agent_user(rid), **at})
            self.say(
                f"robot {rid}'s agent left (its session closed, its observations unheard) while its token stays: "
                f"a second session on login {agent_user(rid)} holds it, not taken for robot {rid}"
            )
        return unheard
