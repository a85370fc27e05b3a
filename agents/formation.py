"""Formations as data: for each follower, its reference robot and its offset.

An offset is P_vt of eq. 2, in the reference robot's frame (x to its right,
y ahead), in metres. Robot ids are positive integers; the smallest id leads
(paper section 2: R1 leads R2, R2 leads R3).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from formation_swarm.agents.geometry import Point
from formation_swarm.checks import finite, positive


@dataclass(frozen=True)
class Slot:
    reference: int
    offset: Point


@dataclass(frozen=True)
class Formation:
    """A named formation: follower id -> Slot. The leader has no slot."""

    name: str
    slots: Mapping[int, Slot]

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("formation name must not be empty")
        if not self.slots:
            raise ValueError(f"formation {self.name!r} has no follower")
        ids = set(self.slots)
        for rid, slot in self.slots.items():
            if isinstance(rid, bool) or not isinstance(rid, int) or rid < 1:
                raise ValueError(f"formation {self.name!r}: robot id must be an integer >= 1, got {rid!r}")
            if slot.reference == rid:
                raise ValueError(f"formation {self.name!r}: robot {rid} references itself")
            finite(f"formation {self.name!r} robot {rid} offset x", slot.offset[0])
            finite(f"formation {self.name!r} robot {rid} offset y", slot.offset[1])
        # Every chain of references must end at the leader (a robot with no slot).
        for rid in ids:
            seen = {rid}
            ref = self.slots[rid].reference
            while ref in self.slots:
                if ref in seen:
                    raise ValueError(f"formation {self.name!r}: reference cycle through robot {rid}")
                seen.add(ref)
                ref = self.slots[ref].reference
        leaders = {self._root(r) for r in ids}
        if len(leaders) != 1:
            raise ValueError(f"formation {self.name!r}: followers lead back to several leaders {sorted(leaders)}")

    def _root(self, rid: int) -> int:
        while rid in self.slots:
            rid = self.slots[rid].reference
        return rid

    @property
    def leader(self) -> int:
        return self._root(next(iter(self.slots)))

    @property
    def robots(self) -> list[int]:
        return sorted({self.leader, *self.slots})

    def slot_positions(self) -> dict[int, Point]:
        """Every robot's place in the leader's frame when all share its heading."""
        out: dict[int, Point] = {self.leader: Point(0.0, 0.0)}

        def place(rid: int) -> Point:
            if rid not in out:
                slot = self.slots[rid]
                ref = place(slot.reference)
                out[rid] = Point(ref.x_m + slot.offset.x_m, ref.y_m + slot.offset.y_m)
            return out[rid]

        for rid in self.slots:
            place(rid)
        return out


def from_slot_positions(name: str, positions: Mapping[int, Point]) -> Formation:
    """Chain formation (robot i references robot i-1) from places in the leader frame."""
    ids = sorted(positions)
    if len(ids) < 2:
        raise ValueError(f"formation {name!r} needs at least 2 robots, got {len(ids)}")
    slots = {
        rid: Slot(prev, Point(positions[rid][0] - positions[prev][0], positions[rid][1] - positions[prev][1]))
        for prev, rid in zip(ids, ids[1:], strict=False)
    }
    return Formation(name, slots)


def line(n: int, spacing_m: float, first_id: int = 1) -> Formation:
    """Column behind the leader: each robot ``spacing_m`` behind the previous one."""
    s = positive("spacing_m", spacing_m)
    if n < 2:
        raise ValueError(f"n must be >= 2, got {n!r}")
    return from_slot_positions("line", {first_id + i: Point(0.0, -s * i) for i in range(n)})


def wedge(n: int, lateral_m: float, back_m: float, first_id: int = 1) -> Formation:
    """Triangle (wedge) behind the leader, alternating left and right by rank.

    Robot 2 goes left-behind, robot 3 right-behind, robot 4 two ranks back on
    the left, and so on. For n = 3 this is the paper's triangle (Fig. 1, 11).
    """
    lat = positive("lateral_m", lateral_m)
    back = positive("back_m", back_m)
    if n < 2:
        raise ValueError(f"n must be >= 2, got {n!r}")
    pos = {first_id: Point(0.0, 0.0)}
    for i in range(1, n):
        rank = (i + 1) // 2
        side = -1.0 if i % 2 == 1 else 1.0
        pos[first_id + i] = Point(side * lat * rank, -back * rank)
    return from_slot_positions("triangle", pos)
