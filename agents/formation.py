"""Formations as data: for each follower, its reference robot and its offset.

An offset is P_vt of eq. 2, in the reference robot's frame (x to its right,
y ahead), in metres. Robot ids are positive integers; the smallest id leads
(paper section 2: R1 leads R2, R2 leads R3).

The shapes (line, wedge, abreast, grid) give every follower a reference that
its camera sees from its slot, close by, and make the references a tree
rooted at the leader whose depth each shape's docstring states;
agents.sight proves a formation, custom ones included, against a camera.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from formation_swarm.agents.geometry import Point
from formation_swarm.common.checks import finite, positive


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
        # Every chain of references must end at the leader (a robot with no slot):
        # each chain is walked once, up to a robot whose root is already known.
        roots: dict[int, int] = {}
        for rid in ids:
            chain, on_chain, ref = [rid], {rid}, self.slots[rid].reference
            while ref in self.slots and ref not in roots:
                if ref in on_chain:
                    raise ValueError(f"formation {self.name!r}: reference cycle through robot {rid}")
                chain.append(ref)
                on_chain.add(ref)
                ref = self.slots[ref].reference
            root = roots.get(ref, ref)
            roots.update(dict.fromkeys(chain, root))
        leaders = set(roots.values())
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

    def depths(self) -> dict[int, int]:
        """Per follower, how many references lead from it to the leader."""
        out: dict[int, int] = {}
        for rid in sorted(self.slots):
            n, ref = 1, self.slots[rid].reference
            while ref in self.slots:
                n, ref = n + 1, self.slots[ref].reference
            out[rid] = n
        return out

    @property
    def depth(self) -> int:
        """The depth of the reference tree: the longest chain of references from
        a follower to the leader (errors add up along it)."""
        return max(self.depths().values())

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


def from_slot_positions(
    name: str, positions: Mapping[int, Point], references: Mapping[int, int] | None = None
) -> Formation:
    """A formation from places in the leader frame (all robots share the leader's
    heading). ``references`` names each follower's reference robot; by default a
    chain, robot i references robot i-1 (in id order)."""
    ids = sorted(positions)
    if len(ids) < 2:
        raise ValueError(f"formation {name!r} needs at least 2 robots, got {len(ids)}")
    refs = dict(zip(ids[1:], ids, strict=False)) if references is None else dict(references)
    slots = {}
    for rid, ref in refs.items():
        if rid not in positions or ref not in positions:
            raise ValueError(f"formation {name!r}: robot {rid} or its reference {ref} has no place")
        here, there = positions[rid], positions[ref]
        slots[rid] = Slot(ref, Point(here[0] - there[0], here[1] - there[1]))
    return Formation(name, slots)


def _check_n(n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise ValueError(f"n must be an integer >= 2, got {n!r}")
    return n


LINE_FOLLOW = ("ahead", "pairs")


def line(n: int, spacing_m: float, first_id: int = 1, follow: str = "ahead") -> Formation:
    """Column behind the leader: robot i (i = 1 .. n-1 after the leader)
    ``i * spacing_m`` behind it.

    ``follow = "ahead"``: each robot references the one ahead of it, one
    chain of depth n - 1 (the paper's R1 <- R2 <- R3). ``follow = "pairs"``:
    robot 2 references the leader, and every other robot the robot two places
    ahead (2 * spacing_m; robot 3 the leader): two interleaved chains of depth
    n // 2 with the references of ``wedge`` and ``abreast``, so
    that a switch between a wedge and a line changes offsets only, which is
    what the partition-zone avoidance of eq. 11-13 is made for; from its wedge
    slot a robot of the "ahead" line would have to find the robot of the other
    wing, 3 * rank metres away. Nothing but their tracking keeps two
    neighbours of different chains apart, and the simulated camera sees
    through the robot in between (a real one needs its marker raised). For 3
    robots both are the paper's chain, as the wedge's references are then.
    """
    s = positive("spacing_m", spacing_m)
    _check_n(n)
    if follow not in LINE_FOLLOW:
        raise ValueError(f"follow must be one of {', '.join(map(repr, LINE_FOLLOW))}, got {follow!r}")
    pos = {first_id + i: Point(0.0, -s * i) for i in range(n)}
    skip = 1 if follow == "ahead" or n == 3 else 2
    refs = {first_id + i: first_id + max(0, i - skip) for i in range(1, n)}
    return from_slot_positions("line", pos, refs)


def wedge(n: int, lateral_m: float, back_m: float, first_id: int = 1) -> Formation:
    """Triangle (wedge, V) behind the leader, alternating left and right by rank.

    Follower i (i = 1 .. n-1 after the leader) flies in rank r = (i + 1) // 2,
    r * lateral_m to the side (odd i left, even i right) and r * back_m behind
    the leader. Two chains of references, one per wing, each rank on the rank
    before it on its side (lateral_m, back_m): the left one starts at the
    leader (robot 2 references robot 1, robot 4 robot 2, ...), and so does the
    right one (robot 3 references robot 1, robot 5 robot 3, ...), so that one
    wing's errors do not pass into the other. The tree's depth is n // 2: 5
    and 15 for 10 and 30 robots. Three robots keep the paper's triangle
    (Fig. 1 and 11): robot 3 references robot 2, two lateral steps to its
    right (2 * lateral_m, 0), the chain R1 <- R2 <- R3 of depth 2. (Measured,
    a 30-robot wedge on the paper's turning path with the right wing on
    robot 2 instead: its two rank-2 robots touch; docs/paper.md.)
    """
    lat = positive("lateral_m", lateral_m)
    back = positive("back_m", back_m)
    _check_n(n)
    pos = {first_id: Point(0.0, 0.0)}
    refs = {}
    for i in range(1, n):
        rank = (i + 1) // 2
        side = -1.0 if i % 2 == 1 else 1.0
        pos[first_id + i] = Point(side * lat * rank, -back * rank)
        refs[first_id + i] = first_id + 1 if (i, n) == (2, 3) else first_id + max(0, i - 2)
    return from_slot_positions("triangle", pos, refs)


def abreast(n: int, spacing_m: float, first_id: int = 1) -> Formation:
    """Line abreast: everyone level with the leader, which flies in the middle.

    Follower i (i = 1 .. n-1) is ``((i + 1) // 2) * spacing_m`` to the leader's
    left (odd i) or right (even i) and references its neighbour toward the
    leader, ``spacing_m`` beside it (robots 2 and 3 reference the leader;
    from robot 4 on, the references of ``wedge``).
    Two chains: the tree's depth is n // 2 (1, 5 and 15 for 3, 10 and 30
    robots). The reference is abeam (bearing about 90 deg): the camera's field
    of view must reach that far to the side.
    """
    s = positive("spacing_m", spacing_m)
    _check_n(n)
    pos = {first_id: Point(0.0, 0.0)}
    refs = {}
    for i in range(1, n):
        rank = (i + 1) // 2
        pos[first_id + i] = Point((-1.0 if i % 2 == 1 else 1.0) * s * rank, 0.0)
        refs[first_id + i] = first_id if rank == 1 else first_id + i - 2
    return from_slot_positions("abreast", pos, refs)


def grid(n: int, columns: int, lateral_m: float, back_m: float, first_id: int = 1) -> Formation:
    """Rows of ``columns`` robots behind the leader, centred on its track.

    Row k (k = 1, 2, ...) is k * back_m behind the leader, its columns lateral_m
    apart; robots fill a row from the centre out, left before right, so a short
    last row stays centred. In each column a robot references the robot ahead
    of it (back_m ahead). In the first row the centre column (with an even
    number of columns: the two centre columns) references the leader, the
    others their neighbour toward the centre (lateral_m beside). The tree's
    depth is (rows - 1) + (columns + 1) // 2 at most: with 3 columns, 2, 4 and
    11 for 3, 10 and 30 robots.
    """
    if isinstance(columns, bool) or not isinstance(columns, int) or columns < 1:
        raise ValueError(f"columns must be an integer >= 1, got {columns!r}")
    lat = positive("lateral_m", lateral_m)
    back = positive("back_m", back_m)
    _check_n(n)
    centre = 0.5 * (columns - 1)
    # Columns from the centre out, left before right: their x in units of lat.
    order = sorted(range(columns), key=lambda c: (abs(c - centre), c))
    pos = {first_id: Point(0.0, 0.0)}
    refs: dict[int, int] = {}
    at: dict[tuple[int, int], int] = {}  # (row, column) -> robot id
    for i in range(n - 1):
        row, col = 1 + i // columns, order[i % columns]
        rid = first_id + 1 + i
        pos[rid] = Point((col - centre) * lat, -back * row)
        at[row, col] = rid
        if row > 1:
            refs[rid] = at[row - 1, col]
        elif abs(col - centre) <= 0.5:
            refs[rid] = first_id
        else:
            refs[rid] = at[row, col + (1 if col < centre else -1)]
    return from_slot_positions("grid", pos, refs)
