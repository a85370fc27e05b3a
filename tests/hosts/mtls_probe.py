"""Clients that try a run's router with the wrong certificates, started by
tests/hosts/test_mtls_netns.py on the robots' host while the run flies.

    python mtls_probe.py PLAN.json

PLAN: {"endpoint", "run", "robot", "refused": {name: settings}, "wrong":
{name: settings}, "world": settings, "observer": settings, "budget_s"}.
First each "refused" client tries to open its session (it should fail).
Then the observer (its own certificate), each "wrong" client and the world's
login (its own certificate, from this host) stay connected until stdin
closes or the budget ends: each wrong one subscribes to the robot's inbox,
holds the robot's liveliness token and puts its name on the robot's command
key every 50 ms; the world's subscribes to every command, holds the world's
token, and every 50 ms puts its name on the robot's observation key and a
"done" on the run's status. The observer counts the robot's observations
and any of those puts. Prints one JSON object of counts and exits 0.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from typing import Any

import zenoh

from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Status
from formation_swarm.protocol.session import make_config

PERIOD_S = 0.05


def _open(endpoint: str, settings: dict[str, Any], timeout_s: float) -> zenoh.Session:
    return zenoh.open(make_config("client", [endpoint], connect_timeout_s=timeout_s, settings=settings))


def _try_refused(plan: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for name, settings in plan["refused"].items():
        t0 = time.monotonic()
        try:
            _open(plan["endpoint"], settings, 3.0).close()
            out[name] = {"opened": True, "error": None, "s": round(time.monotonic() - t0, 2)}
        except zenoh.ZError as exc:
            out[name] = {"opened": False, "error": str(exc).split(" at ")[0], "s": round(time.monotonic() - t0, 2)}
    return out


class Wrong:
    """A client with another certificate: what it sent and what reached it."""

    def __init__(self, name: str, session: zenoh.Session, keys: Keys, robot: int) -> None:
        self.name, self.session = name, session
        self.mark = f"wrong:{name}".encode()
        self.puts = self.received = 0
        self.listen(keys.inbox(robot))
        session.liveliness().declare_token(keys.alive("agent", robot))
        self.publishers = [session.declare_publisher(keys.cmd(robot))]

    def listen(self, key: str) -> None:
        self.session.declare_subscriber(key, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        if not sample.payload.to_bytes().startswith(b"wrong:"):  # a session hands its own puts to its subscribers
            self.received += 1

    def put(self) -> None:
        for publisher in self.publishers:
            publisher.put(self.mark)
        self.puts += 1


class FarWorld(Wrong):
    """The world's login, with its certificate, from another host than the
    router's: it hears the commands and says the run is done, if let."""

    def __init__(self, session: zenoh.Session, keys: Keys, robot: int) -> None:
        self.name, self.session = "world from afar", session
        self.mark = f"wrong:{self.name}".encode()
        self.puts = self.received = 0
        self.listen(keys.all_cmd)
        session.liveliness().declare_token(keys.alive("world", 0))
        self.publishers = [session.declare_publisher(keys.obs(robot))]
        self.status = session.declare_publisher(keys.status)
        self.done = Status(sender=0, seq=2**53, tick=10**6, time_s=0.0, state="done", total_ticks=1).to_bytes()

    def put(self) -> None:
        super().put()
        self.status.put(self.done)


class Observer:
    """The run's observer login: what it hears on the robot's keys."""

    def __init__(self, session: zenoh.Session, keys: Keys, robot: int) -> None:
        self.obs_key = keys.obs(robot)
        self.observations = self.wrong_puts = 0
        session.declare_subscriber(keys.inbox(robot), self._on)  # the robot's keys, its command's too

    def _on(self, sample: zenoh.Sample) -> None:
        if sample.payload.to_bytes().startswith(b"wrong:"):
            self.wrong_puts += 1
        elif str(sample.key_expr) == self.obs_key:
            self.observations += 1


def main() -> int:
    with open(sys.argv[1]) as f:
        plan = json.load(f)
    keys, robot = Keys(plan["run"]), plan["robot"]
    result: dict[str, Any] = {"refused": _try_refused(plan)}
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    sessions = [_open(plan["endpoint"], plan["observer"], 30.0)]
    try:
        observer = Observer(sessions[0], keys, robot)
        wrong = []
        for name, settings in plan["wrong"].items():
            sessions.append(_open(plan["endpoint"], settings, 30.0))
            wrong.append(Wrong(name, sessions[-1], keys, robot))
        if "world" in plan:
            sessions.append(_open(plan["endpoint"], plan["world"], 30.0))
            wrong.append(FarWorld(sessions[-1], keys, robot))
        print(json.dumps({"connected": len(sessions)}), flush=True)
        deadline = time.monotonic() + plan["budget_s"]
        while not stop.wait(PERIOD_S) and time.monotonic() < deadline:
            for w in wrong:
                w.put()
    finally:
        for s in reversed(sessions):
            s.close()
    result["wrong"] = {w.name: {"puts": w.puts, "received": w.received} for w in wrong}
    result["observer"] = {"observations": observer.observations, "wrong_puts": observer.wrong_puts}
    print(json.dumps(result), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
