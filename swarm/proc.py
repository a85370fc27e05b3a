"""Process plumbing shared by every role: stop signals, atomic JSON files."""

from __future__ import annotations

import json
import math
import signal
import threading
from pathlib import Path
from typing import Any


def install_stop_handlers() -> threading.Event:
    """SIGINT and SIGTERM set an event that every loop checks."""
    stop = threading.Event()

    def handler(_sig: int, _frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return stop


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
