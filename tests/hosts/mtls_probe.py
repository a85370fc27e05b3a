"""Clients that try a run's router with the wrong certificates, started by
tests/hosts/test_mtls_netns.py on the robots' host while the run flies.

    python mtls_probe.py PLAN.json

PLAN: {"endpoint", "run", "robot", "refused": {name: settings}, "wrong":
{name: settings}, "observer": settings, "budget_s"}. First each "refused"
client tries to open its session (it should fail). Then the observer (its
own certificate) and each "wrong" client stay connected until stdin closes
or the budget ends: each wrong one subscribes to the robot's inbox, holds
the robot's liveliness token and puts its name on the robot's command key
every 50 ms; the observer counts the robot's observations and any of those
puts. Prints one JSON object of counts and exits 0.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from typing import Any

import zenoh

from formation_swarm.protocol.keys import Keys
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
        session.declare_subscriber(keys.inbox(robot), self._on)
        session.liveliness().declare_token(keys.alive("agent", robot))
        self.publisher = session.declare_publisher(keys.cmd(robot))

    def _on(self, sample: zenoh.Sample) -> None:
        if sample.payload.to_bytes() != self.mark:  # a session hands its own puts to its subscribers
            self.received += 1

    def put(self) -> None:
        self.publisher.put(self.mark)
        self.puts += 1


class Observer:
    """The run's observer login: what it hears on the robot's keys."""

    def __init__(self, session: zenoh.Session, keys: Keys, robot: int) -> None:
        self.obs_key = keys.obs(robot)
        self.observations = self.wrong_puts = 0
        session.declare_subscriber(keys.inbox(robot), self._on)  # the robot's keys, its command's too

    def _on(self, sample: zenoh.Sample) -> None:
        if str(sample.key_expr) == self.obs_key:
            self.observations += 1
        elif sample.payload.to_bytes().startswith(b"wrong:"):
            self.wrong_puts += 1


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
