"""A centred moving average taken while a run goes: the recording's 1 s
means of V_N and of the wheel speeds.

It is the report's (formation_swarm.report.figures.series.moving_average):
a window of ``round(window_s / dt_s)`` samples centred on each one, shorter
at the ends of each unbroken stretch, never across a gap of more than
GAP_TICKS ticks. A sample's mean is given once the samples after it in its
window have come (half a window later) or its stretch has ended.
"""

from __future__ import annotations

GAP_TICKS = 1.5  # as the report's: a longer silence ends a stretch


class CentredMean:
    """One series' centred moving average, fed in time order."""

    def __init__(self, window_s: float, dt_s: float) -> None:
        n = max(1, round(window_s / dt_s))
        self.ahead = (n - 1) // 2  # samples after one in its window (numpy's "same" convolution)
        self.behind = n - 1 - self.ahead
        self.gap_s = GAP_TICKS * dt_s
        self.t: list[float] = []  # the stretch's last samples: ``behind`` already given, then those waiting
        self.v: list[float] = []
        self.given = 0  # samples of self.t whose mean is given

    def add(self, times: list[float], values: list[float]) -> tuple[list[float], list[float]]:
        """Take samples (a time not after the last one is left out); return
        the (times, means) now complete."""
        out_t: list[float] = []
        out_v: list[float] = []
        for t, v in zip(times, values, strict=True):
            if self.t and t <= self.t[-1]:
                continue
            if self.t and t - self.t[-1] > self.gap_s:
                self._give_rest(out_t, out_v)
            self.t.append(t)
            self.v.append(v)
            while self.given < len(self.t) and len(self.t) - 1 - self.given >= self.ahead:
                self._give(out_t, out_v)
            if (drop := self.given - self.behind) > 0:  # no window reaches them any more
                del self.t[:drop], self.v[:drop]
                self.given -= drop
        return out_t, out_v

    def end(self) -> tuple[list[float], list[float]]:
        """The means still waiting for samples that will not come: the run ended."""
        out_t: list[float] = []
        out_v: list[float] = []
        self._give_rest(out_t, out_v)
        return out_t, out_v

    def _give(self, out_t: list[float], out_v: list[float]) -> None:
        i = self.given
        lo, hi = max(0, i - self.behind), min(len(self.t), i + self.ahead + 1)
        out_t.append(self.t[i])
        out_v.append(sum(self.v[lo:hi]) / (hi - lo))
        self.given += 1

    def _give_rest(self, out_t: list[float], out_v: list[float]) -> None:
        while self.given < len(self.t):
            self._give(out_t, out_v)
        self.t, self.v, self.given = [], [], 0
