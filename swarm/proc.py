"""Process plumbing shared by every role: stop signals, atomic JSON files."""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import zenoh

    from formation_swarm.scenario import Scenario


class StopEvent(threading.Event):
    """An event that also calls its wakers when set, for a loop blocked in a
    call no timeout ends (a Zenoh channel's ``recv``): the waker ends it."""

    def __init__(self) -> None:
        super().__init__()
        self._wakers: list[Callable[[], None]] = []

    def add_waker(self, waker: Callable[[], None]) -> None:
        self._wakers.append(waker)
        if self.is_set():
            waker()

    def set(self) -> None:
        super().set()
        for waker in list(self._wakers):
            waker()


def install_stop_handlers() -> StopEvent:
    """SIGINT and SIGTERM set an event that every loop checks."""
    stop = StopEvent()

    def handler(_sig: int, _frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return stop


def interrupt_on_stop_signals() -> None:
    """SIGINT and SIGTERM raise KeyboardInterrupt in the main thread, even when the
    process was started with SIGINT ignored (as a shell's background jobs are):
    for the commands that stop their children cleanly in an ``except``."""

    def handler(_sig: int, _frame: object) -> None:
        raise KeyboardInterrupt

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, handler)


def write_json(path: str | None, data: dict[str, Any]) -> None:
    """Write ``data`` atomically (a crash leaves the old file or none, never half)."""
    if not path:
        return
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(p.suffix + ".tmp")
    tmp.write_text(json.dumps(clean_json(data), indent=2, allow_nan=False))
    tmp.replace(p)


def clean_json(o: Any) -> Any:
    """NaN and inf become None (JSON has neither); tuples become lists."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {str(k): clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean_json(v) for v in o]
    return o


def role_inputs(args: argparse.Namespace, who: str) -> tuple[Scenario, zenoh.Session] | None:
    """A role's scenario and open Zenoh session from its flags, or None after
    printing why not (bad scenario, bad flags, no router)."""
    import zenoh

    from formation_swarm import scenario as scenario_mod
    from formation_swarm.protocol import session

    try:
        sc = scenario_mod.load(args.scenario)
        conf = session.config_from_args(args)
    except ValueError as exc:
        print(f"{who}: {exc}", file=sys.stderr)
        return None
    try:
        return sc, zenoh.open(conf)
    except zenoh.ZError as exc:
        print(f"{who}: cannot open the Zenoh session: {exc}", file=sys.stderr)
        return None
