"""Memory a flood took, given back once it ends.

A flood of messages (a stolen login's, a broken peer's) fills a process's
inbox up to its capacity (a Zenoh FIFO channel: the world's commands, an
agent's inbox) and Zenoh's own buffers with it. Once handled, that memory
goes back to the C allocator, which keeps it: measured with 40,000 messages
of 30 kB on robot 2's keys, the world (also the router) held 64 MB more and
agent 2 40 MB more, for the rest of the run. So a process that rejected at
least ``FLOOD_REJECTIONS`` messages in one ``FLOOD_CHECK_S`` gives memory
back in the first such period with fewer: a garbage collection, then
glibc's ``malloc_trim(0)``, which returns the allocator's free pages. A run
without a flood never does either (no rejections).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import time
from collections.abc import Callable

FLOOD_CHECK_S = 2.0  # wall seconds between two looks at the rejections
FLOOD_REJECTIONS = 500  # rejections in one look that make a flood (an honest run has none)


def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's malloc_trim, or None where there is none (another C library)."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return libc.malloc_trim  # type: ignore[no-any-return]
    except (OSError, AttributeError):
        return None


# Allocations between two young collections of the cyclic collector (Python's default: 700).
# The logger allocates thousands of containers a tick at 200 robots (decoded messages, their
# fields), each gone or kept by the next send: at 700 it collected every tick and moved what
# it had not freed yet into older scans; fed 200 robots (bench/logger_tick.py) it spent
# 4.27 ms of CPU a tick at 10,000 against 4.55 at 700 (three runs each, same sitting).
YOUNG_COLLECTION = 10_000


def steady_collector() -> None:
    """For a process's loop, once its start-up is over: what exists now leaves the
    collector's scans for good (``gc.freeze``), and a young collection comes every
    ``YOUNG_COLLECTION`` allocations. Garbage in cycles still goes, a little later."""
    gc.freeze()
    gc.set_threshold(YOUNG_COLLECTION, *gc.get_threshold()[1:])


def give_back() -> None:
    """Free what Python no longer uses, and return the allocator's free pages to the system."""
    gc.collect()
    if (trim := _malloc_trim()) is not None:
        trim(0)


class FloodRelief:
    """Watches a process's count of rejected messages; gives memory back once a flood has ended."""

    def __init__(self, period_s: float = FLOOD_CHECK_S, flood: int = FLOOD_REJECTIONS) -> None:
        self.period_s = period_s
        self.flood = flood
        self.next_s = time.monotonic() + period_s
        self.seen = 0  # rejections at the last look
        self.flooded = False  # the last look saw a flood
        self.given_back = 0  # times memory was given back

    def check(self, rejected: int) -> bool:
        """``rejected``: the process's rejections so far; whether memory was given back now."""
        now = time.monotonic()
        if now < self.next_s:
            return False
        self.next_s = now + self.period_s
        burst, self.seen = rejected - self.seen, rejected
        if burst >= self.flood:
            self.flooded = True
            return False
        if not self.flooded:
            return False
        self.flooded = False
        give_back()
        self.given_back += 1
        return True
