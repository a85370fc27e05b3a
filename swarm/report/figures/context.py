"""What every figure of one run needs besides the recording: the run's
robots, times, faults, formations, obstacles and laws, and its title."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from formation_swarm.common.palette import robot_colour
from formation_swarm.launch.words import describe_laws

Mark = tuple[float, "float | None", str]

EVENT_GAP_S = 1.0  # formation events closer than this are one switch (leader, then its followers)
# Beyond this many followers a figure draws them together (each faint, their
# median bold, the worst named) rather than one legend entry each.
LEGEND_FOLLOWERS = 8


@dataclass
class Context:
    """What every figure of one run needs besides the recording."""

    scenario: str
    seed: Any
    robots: list[int]
    followers: list[int]
    dt_s: float = 0.05
    t_end: float = 0.0
    paper: Mapping[str, str] = field(default_factory=dict)  # figure stem -> "Fig. 7a", when reproduced
    changes: str | None = None  # else, for a paper's scenario that was changed, what was (report.paper_changes)
    fault_marks: list[Mark] = field(default_factory=list)
    cut: str = ""  # why the lines end early (interrupted, its logger killed): said in every title
    switches: list[tuple[float, str]] = field(default_factory=list)  # (time s, formation)
    formation_events: list[Mapping[str, Any]] = field(default_factory=list)
    formations: Mapping[str, Mapping[int, tuple[int, tuple[float, float]]]] = field(default_factory=dict)
    start_formation: str | None = None
    obstacles: list[tuple[float, float, float]] = field(default_factory=list)
    diameter_m: float = 0.4
    # The leader's policy and each follower's law (spec.laws: the summary's "laws"); {}: not known.
    laws: Mapping[str, Any] = field(default_factory=dict)

    def title(self, stem: str, what: str) -> str:
        """The scenario, seed and what the figure shows; under it the laws
        flown, and under them why the lines end early, if they do."""
        cf = f" (cf. paper {self.paper[stem]})" if stem in self.paper else ""
        flown = f"\n{describe_laws(self.laws)}" if self.laws else ""
        cut = f"\n[{self.cut}]" if self.cut else ""  # a line of its own: it can be long
        return f"{self.scenario}, seed {self.seed}: {what}{cf}{flown}{cut}"

    def laws_of_followers(self) -> list[str]:
        """The laws the followers flew, each once, in the order of their first follower."""
        said = self.laws.get("followers") or {}
        return list(dict.fromkeys(str(said[str(r)]) for r in self.followers if str(r) in said))

    @property
    def many(self) -> bool:
        """A swarm: too many followers for one legend entry each."""
        return len(self.followers) > LEGEND_FOLLOWERS

    def colour(self, rid: int) -> tuple[float, float, float]:
        """The robot's colour, the same as in the Rerun viewer (formation_swarm.common.palette)."""
        return robot_colour(rid)

    def flown(self, rid: int, t: float) -> str | None:
        """The formation robot ``rid`` flies at time ``t``."""
        name = self.start_formation
        for e in self.formation_events:
            if e.get("robot") == rid and isinstance(e.get("time_s"), (int, float)) and e["time_s"] <= t + 1e-9:
                name = str(e.get("formation"))
        return name


def switches(events: Sequence[Mapping[str, Any]]) -> list[tuple[float, str]]:
    """Formation switches of a run: its formation events grouped (a leader's
    change and its followers' within EVENT_GAP_S), each at its first event."""
    out: list[tuple[float, str]] = []
    last = -math.inf
    for e in sorted((e for e in events if isinstance(e.get("time_s"), (int, float))), key=lambda e: e["time_s"]):
        t = float(e["time_s"])
        if t - last > EVENT_GAP_S:
            out.append((t, str(e.get("formation"))))
        last = t
    return out
