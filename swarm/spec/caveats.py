"""What may make a scenario's run say little, found at load: warnings, not
errors (``Scenario.warnings``; the loader warns with ``ScenarioWarning``,
``swarm run`` prints them). A leader's cruise speed outside what its fuzzy
followers hold, slots beyond the leader's turn radius, long chains of
references steered without look-ahead, faults the run's end cuts short.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from formation_swarm.agents.follower import FollowerParams
from formation_swarm.agents.formation import Formation
from formation_swarm.agents.fuzzy import speed_range
from formation_swarm.common.faults.schedule import past_the_end
from formation_swarm.spec.checking import id_ranges

if TYPE_CHECKING:
    from formation_swarm.spec.model import Scenario


def of(sc: Scenario) -> tuple[str, ...]:
    """Every warning of a scenario, in this order: speeds, turns, chains, faults."""
    ld = sc.leader
    out = speed_warnings(ld.speed_mps, sc.followers)
    # Of the formations the leader flies (a scenario may hold others it never picks).
    flown = {name: sc.formations[name] for name in (ld.formation, ld.avoid_formation) if name}
    if path_turns(ld.waypoints):  # a straight path folds no formation
        out += turn_warnings(ld.speed_mps, ld.turn_rate_rps, flown)
    out += chain_warnings(flown, sc.followers)
    return tuple(out + past_the_end(sc.faults, sc.duration_s, sc.dt_s))


def _who(rids: Sequence[int], one: str, many: str) -> str:
    """The words "robot 5 is" or "robots 5-9 are" (``one`` = "is", ``many`` = "are")."""
    return f"robot {rids[0]} {one}" if len(rids) == 1 else f"robots {id_ranges(rids)} {many}"


def path_turns(waypoints: Sequence[Sequence[float]]) -> bool:
    """Whether the leader's path has a corner: the robots start heading along
    its first leg (world.engine.start_poses), so a path of legs in one
    direction is flown without a turn."""
    headings = [
        math.atan2(b[1] - a[1], b[0] - a[0])
        for a, b in itertools.pairwise(waypoints)
        if math.hypot(b[0] - a[0], b[1] - a[1]) > 1e-9
    ]
    return any(abs(math.remainder(h - g, math.tau)) > 1e-9 for g, h in itertools.pairwise(headings))


def turn_warnings(speed_mps: float, turn_rate_rps: float, formations: Mapping[str, Formation]) -> list[str]:
    """The formations with slots farther to the side of the leader than its turn
    radius (speed / turn rate): in a turn toward them such a slot moves
    backwards, and a robot cannot drive backwards, so the formation folds."""
    radius = speed_mps / turn_rate_rps
    out = []
    for name, form in formations.items():
        side = {rid: abs(p.x_m) for rid, p in form.slot_positions().items() if rid != form.leader}
        beyond = sorted(rid for rid, x in side.items() if x > radius + 1e-6)
        if beyond:
            far = max(side[r] for r in beyond)
            out.append(
                f"formation {name!r}: {_who(beyond, 'sits', 'sit')} up to {far:g} m to the side of the leader, "
                f"beyond its turn radius leader.speed_mps / leader.turn_rate_rps = {radius:g} m: in a turn toward them "
                "their slots move backwards, which the robots cannot do, and the formation folds (closer spacing, "
                "e.g. lateral_m, or a gentler turn keeps every slot inside the radius)"
            )
    return out


# From this many references down a chain the paper's steering makes a weave
# (docs/paper.md, "The steering look-ahead": in a line on a straight path,
# robot 5, four links down, swings its heading 17.3 degrees, robot 2 2.6).
CHAIN_WARN_DEPTH = 4
# The smallest look-ahead measured to keep those swings level (the same
# section: 0.5 m still let them grow, to 13.6 degrees at robot 10).
CHAIN_LOOKAHEAD_M = 1.0


def chain_warnings(formations: Mapping[str, Formation], followers: Mapping[int, FollowerParams]) -> list[str]:
    """The formations with fuzzy followers CHAIN_WARN_DEPTH or more references
    down a chain from the leader that steer at their target itself
    (controller.lookahead_m = 0), or look ahead less than CHAIN_LOOKAHEAD_M:
    each swings more than its reference."""
    out = []
    for name, form in formations.items():
        depths = form.depths()
        steers_short = {rid for rid, f in followers.items() if f.law == "fuzzy" and f.lookahead_m < CHAIN_LOOKAHEAD_M}
        deep = sorted(rid for rid, d in depths.items() if d >= CHAIN_WARN_DEPTH and rid in steers_short)
        if deep:
            low, high = min(depths[r] for r in deep), max(depths[r] for r in deep)
            # Between a follower d references down and the leader: d - 1 other robots.
            links = f"{low - 1}" if low == high else f"{low - 1}-{high - 1}"
            used = sorted({followers[r].lookahead_m for r in deep})
            if used == [0.0]:
                steering = "with the paper's steering (controller.lookahead_m = 0) heading swings grow"
            else:
                values = " and ".join(f"{v:g}" for v in used)
                steering = (
                    f"with controller.lookahead_m = {values}, under {CHAIN_LOOKAHEAD_M:g} m, heading swings still grow"
                )
            out.append(
                f"formation {name!r}: {_who(deep, 'follows', 'follow')} the leader through a chain of "
                f'{links} other robots; {steering} at every link (docs/paper.md, "The steering look-ahead"): '
                f"--set controller.lookahead_m={CHAIN_LOOKAHEAD_M:g} keeps them level"
            )
    return out


def speed_warnings(leader_speed_mps: float, followers: Mapping[int, FollowerParams]) -> list[str]:
    """Why the leader's cruise speed lies outside the speeds its fuzzy
    followers hold steadily (agents.fuzzy.speed_range), one line per group of
    followers with the same range; empty when it lies inside every range."""
    groups: dict[tuple[str, float, float, float], list[int]] = {}
    for rid, fp in followers.items():
        if fp.law != "fuzzy":
            continue
        r = speed_range(fp.fuzzy, fp.speed)
        if leader_speed_mps < r.steady_low_mps - 1e-9:
            key = ("below", r.steady_low_mps, r.steady_high_mps, r.floor_mps)
        elif leader_speed_mps > r.steady_high_mps + 1e-9:
            key = ("above", r.steady_low_mps, r.steady_high_mps, r.ceiling_mps)
        else:
            continue
        groups.setdefault(key, []).append(rid)
    out = []
    for (side, low, high, limit), rids in groups.items():
        one = len(rids) == 1
        who = (
            f"follower {rids[0]}'s fuzzy controller holds"
            if one
            else f"followers {id_ranges(rids)}' fuzzy controllers hold"
        )
        they, their = ("it", "its") if one else ("they", "their")
        drives = ("drives" if one else "drive") + (" slower" if side == "below" else " faster")
        fate = (
            f"will overrun {their} target{'' if one else 's'} and may hit {their} reference{'' if one else 's'}"
            if side == "below"
            else f"will fall behind and may lose {their} reference{'' if one else 's'}"
        )
        out.append(
            f"leader.speed_mps = {leader_speed_mps:g} is {side} the speeds {who} steadily, {low:g}-{high:g} m/s"
            f" (vm -+ a_mps, or a static vn -+ a_mps), and {they} never {drives} than {limit:g} m/s: {they} {fate}"
        )
    return out
