"""A run's rows as Rerun columns: to the live stream at each send, to the
recording file in batches of FILE_BATCH_S of sim time.

Every ``send_columns`` call makes one chunk of the file, and a chunk costs
about 1.2 kB whatever its rows (measured with rerun-sdk 0.41). The logger
sends every 0.25 s of wall time: a real-time run would get a chunk per
entity every 0.25 s, 4-8 times those of the same run in lockstep (which
passes more sim time per send), for the same rows. Batching by sim time
makes a file's size the same in both modes. A logger killed with SIGKILL
loses the rows of its last batch.

Beyond a dozen robots each robot's own series (a dozen entities per robot)
are not sent to the live stream at each send: they go with the file's batch
(``prompt=False``), which then spans CROWD_BATCH_S, longer beyond
CROWD_BATCH_ROBOTS (``batch_s``). The swarm's drawings and
aggregates stay prompt: a send then costs a few calls, whatever the robots.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr

if TYPE_CHECKING:
    from formation_swarm.nodes.logger.recording import Recording

FILE_BATCH_S = 2.0  # sim time, s, of the rows in one chunk of the file
CROWD_BATCH_S = 10.0  # the same beyond a dozen robots: a robot's series cost a call per entity per batch
# Beyond CROWD_BATCH_ROBOTS robots the batch spans more, in proportion: the calls per second
# stay those of that many (each ~70 us of Rerun's Python; at 200 robots and 10 s, 20 a tick).
CROWD_BATCH_ROBOTS = 100
MAX_BATCH_S = 60.0


def batch_s(robots: int, crowd_robots: int) -> float:
    """The sim time, s, of a file's batch for a run of ``robots`` (a crowd beyond ``crowd_robots``)."""
    if robots <= crowd_robots:
        return FILE_BATCH_S
    return min(MAX_BATCH_S, CROWD_BATCH_S * max(1.0, robots / CROWD_BATCH_ROBOTS))


def columns(kind: str, values: np.ndarray, lengths: np.ndarray | None = None) -> Any:
    """Rerun columns of ``values``, one row each, as ``kind``: scalar (n),
    point (n x 2), arrow (n x 4: origin, vector), strip (n x points x 2:
    one strip per row), text (n strings) or translation (n x 3). With ``lengths``, a row holds
    that many of ``values``' instances (points and arrows of a whole swarm)."""
    if kind == "scalar":
        return rr.Scalars.columns(scalars=values)
    if kind in ("point", "arrow"):
        cols = (
            rr.Points2D.columns(positions=values)
            if kind == "point"
            else rr.Arrows2D.columns(origins=values[:, :2], vectors=values[:, 2:])
        )
        return cols if lengths is None else cols.partition(lengths)
    if kind == "strip":  # an array takes Rerun's numpy path
        return rr.LineStrips2D.columns(strips=values)
    if kind == "text":  # markdown, its media type logged static
        return rr.TextDocument.columns(text=values)
    if kind == "translation":
        return rr.Transform3D.columns(translation=values)
    raise ValueError(f"unknown column kind {kind!r}")


class ColumnSink:
    """Rows of entities on one timeline: the live stream's at once, the file's held for a batch."""

    def __init__(self, rec: Recording, timeline: str, batch_s: float = FILE_BATCH_S) -> None:
        self.rec = rec
        self.timeline = timeline
        self.batch_s = batch_s
        # (entity, kind, prompt) -> its parts: times, values, instances per row (None: one)
        self.held: dict[tuple[str, str, bool], list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]] = {}
        self.span = (math.inf, -math.inf)  # the held rows' first and last sim time, s

    def add(
        self,
        entity: str,
        kind: str,
        times: np.ndarray,
        values: np.ndarray,
        *,
        lengths: np.ndarray | None = None,
        prompt: bool = True,
    ) -> None:
        """Rows of ``entity``: to the live stream now if ``prompt``, else with the file's batch."""
        if len(times) == 0:
            return
        times = np.asarray(times)
        self.held.setdefault((entity, kind, prompt), []).append((times, np.asarray(values), lengths))
        self.span = (min(self.span[0], float(times.min())), max(self.span[1], float(times.max())))
        if prompt and self.rec.live is not None:
            self._send(self.rec.live, (entity, kind), times, values, lengths)

    def due(self) -> bool:
        """The held rows span a batch: the next ``write`` sends them."""
        return bool(self.held) and self.span[1] - self.span[0] >= self.batch_s

    def write(self, final: bool = False) -> None:
        """The held rows to the file (and the rows held back from the live stream
        to it), once they span a batch (or at the end: ``final``)."""
        if not self.held or (not final and self.span[1] - self.span[0] < self.batch_s):
            return
        held, self.held, self.span = self.held, {}, (math.inf, -math.inf)
        for (entity, kind, prompt), parts in held.items():
            times = np.concatenate([t for t, _, _ in parts])
            values = np.concatenate([v for _, v, _ in parts])
            lengths = None if parts[0][2] is None else np.concatenate([n for _, _, n in parts])
            self._send(self.rec.file, (entity, kind), times, values, lengths)
            if not prompt and self.rec.live is not None:
                self._send(self.rec.live, (entity, kind), times, values, lengths)

    def _send(
        self,
        stream: rr.RecordingStream,
        what: tuple[str, str],
        times: np.ndarray,
        values: Any,
        lengths: np.ndarray | None = None,
    ) -> None:
        entity, kind = what
        indexes = [rr.TimeColumn(self.timeline, duration=times)]
        stream.send_columns(entity, indexes=indexes, columns=columns(kind, values, lengths))
