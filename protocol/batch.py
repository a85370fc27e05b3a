"""Batches: streams off the control path (telemetry, ground truth) travel as
several encoded messages in one payload, ``[BATCH_TAG, version, [msg, ...]]``.

:class:`BatchPublisher` is the sending side; the receiving side is
:meth:`protocol.codec.Rejections.decode_batch`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import msgpack

from formation_swarm.protocol.codec import BATCH_TAG, MAX_BATCH_ITEMS, MAX_PAYLOAD_BYTES, VERSION


def pack_batch(encoded: list[bytes]) -> bytes:
    """Encoded messages in one payload (see :class:`BatchPublisher`)."""
    return msgpack.packb([BATCH_TAG, VERSION, encoded], use_bin_type=True)


class BatchPublisher:
    """Puts to one key gathered into batches, for streams off the control path.

    A message goes out with the ones before it once ``window_s`` of wall time
    has passed since the last put, or when the batch is full, so at 20 Hz every
    message leaves at once and in a fast lockstep run one put carries many
    ticks. ``flush`` sends what is held; ``close`` flushes and then sends an
    empty batch, which tells the receiver that the stream has ended (it comes
    after the data, whereas a liveliness token's end may overtake it).
    """

    def __init__(
        self,
        pub: Any,
        window_s: float = 0.02,
        max_bytes: int = MAX_PAYLOAD_BYTES // 2,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not window_s >= 0.0:
            raise ValueError(f"window_s must be >= 0, got {window_s!r}")
        if not 0 < max_bytes <= MAX_PAYLOAD_BYTES // 2:
            raise ValueError(f"max_bytes must be in (0, {MAX_PAYLOAD_BYTES // 2}], got {max_bytes!r}")
        self.pub = pub
        self.window_s = window_s
        self.max_bytes = max_bytes
        self.clock = clock
        self.items: list[bytes] = []
        self.size = 0
        self.last_put = -math.inf

    def put(self, payload: bytes) -> None:
        if self.size + len(payload) > self.max_bytes:
            self.flush()
        self.items.append(payload)
        self.size += len(payload)
        if len(self.items) >= MAX_BATCH_ITEMS or self.clock() - self.last_put >= self.window_s:
            self.flush()

    def flush(self) -> None:
        if self.items:  # the window runs from the last put: flushing nothing leaves it as it is
            self.pub.put(pack_batch(self.items))
            self.items, self.size = [], 0
            self.last_put = self.clock()

    def close(self) -> None:
        self.flush()
        self.pub.put(pack_batch([]))
