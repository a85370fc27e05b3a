"""A scenario's ``[formations]``: each named formation built from its shape
(or its custom slots) over the run's robots, the leader's two formations
named among them, and every follower's reference in sight of its camera,
in each formation and at a switch between the leader's two.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from formation_swarm.agents.follower import FollowerParams
from formation_swarm.agents.formation import Formation, Slot, abreast, grid, line, wedge
from formation_swarm.agents.geometry import Point
from formation_swarm.agents.sight import Camera, check_sight, check_switch
from formation_swarm.spec.checking import check_name, check_table, id_ranges, is_point, suggest, wrapped
from formation_swarm.spec.keys import FORMATION_KEYS, SHAPES, SLOT_KEYS, ScenarioError
from formation_swarm.world.camera import CameraParams

MAX_FORMATIONS = 256  # a formation code is one byte


def parse_formations(raw: Any, robots: tuple[int, ...], leader: Mapping[str, Any]) -> dict[str, Formation]:
    """Every named formation, in file order (codes are their indices), each
    over all the robots and led by the leader; ``leader`` is the checked
    [leader] table, whose formations must be among them."""
    if not isinstance(raw, dict) or not raw:
        raise ScenarioError("[formations] must hold at least one named formation")
    if len(raw) > MAX_FORMATIONS:
        raise ScenarioError(f"at most {MAX_FORMATIONS} formations, got {len(raw)}")
    for name in raw:  # any other text is a name: the scenario as run writes it back quoted
        check_name("a formation's name", name, key=f"formations.{name}")
    formations = {name: _formation(name, spec, robots) for name, spec in raw.items()}
    for key in ("formation", "avoid_formation"):
        val = leader[key]
        if key == "avoid_formation" and val == "":
            continue
        if val not in formations:
            raise ScenarioError(f"leader.{key} = {val!r} is not a formation" + suggest(val, tuple(formations)))
    for name, form in formations.items():
        if form.leader != leader["id"]:
            raise ScenarioError(f"formations.{name} is led by robot {form.leader}, leader.id is {leader['id']}")
    return formations


def _formation(name: str, raw: Any, robots: tuple[int, ...]) -> Formation:
    where = f"formations.{name}"
    t = check_table(raw, where, FORMATION_KEYS)
    form = Formation(name, _shaped(where, name, t, robots).slots)
    if sorted(form.robots) != list(robots):
        hint = (
            (
                f'; a custom formation places the robots its slots name, a shape (e.g. {where}.shape = "wedge")'
                " places any number"
            )
            if t["shape"] == "custom"
            else ""
        )
        raise ScenarioError(
            f"{where} covers robots {id_ranges(form.robots)}, the run has robots {id_ranges(robots)}{hint}"
        )
    return form


def _shaped(where: str, name: str, t: Mapping[str, Any], robots: Sequence[int]) -> Formation:
    """The formation a checked table's shape makes of ``robots``."""
    n, first = len(robots), robots[0]
    shape = t["shape"]
    if shape == "wedge":
        return wrapped(where, wedge, n, t["lateral_m"], t["back_m"], first_id=first)
    if shape == "line":
        return wrapped(where, line, n, t["spacing_m"], first_id=first, follow=t["follow"])
    if shape == "abreast":
        return wrapped(where, abreast, n, t["spacing_m"], first_id=first)
    if shape == "grid":
        return wrapped(where, grid, n, t["columns"], t["lateral_m"], t["back_m"], first_id=first)
    if shape == "custom":
        return wrapped(where, Formation, name, _custom_slots(where, t["slots"]))
    raise ScenarioError(
        f"{where}.shape must be one of {', '.join(map(repr, SHAPES))}, got {shape!r}" + suggest(str(shape), SHAPES)
    )


def _custom_slots(where: str, raw: Mapping[str, Any]) -> dict[int, Slot]:
    """A custom formation's slots: per follower id, its reference and offset."""
    slots = {}
    for rid_text, slot in raw.items():
        sw = f"{where}.slots.{rid_text}"
        if not str(rid_text).isdigit():
            raise ScenarioError(f"{sw}: slot keys are robot ids, got {rid_text!r}")
        st = check_table(slot, sw, SLOT_KEYS)
        off = st["offset"]
        if not is_point(off):
            raise ScenarioError(f"{sw}.offset must be [x_m, y_m], got {off!r}")
        slots[int(rid_text)] = Slot(st["reference"], Point(float(off[0]), float(off[1])))
    return slots


def check_in_sight(
    ld: Mapping[str, Any],
    formations: Mapping[str, Formation],
    camera: CameraParams,
    followers: Mapping[int, FollowerParams],
    forms_raw: Mapping[str, Any],
) -> None:
    """Every follower sees its reference from its slot, and at a switch between
    the leader's two formations its new reference from its old slot, with a
    margin: the fuzzy controller's dmax_m in range (a follower that far from
    its slot is at full "Far" and still sees its reference) and its heading
    tolerance gamma in the field of view (the largest of the followers')."""
    cam = Camera(
        range_m=camera.range_m,
        fov_rad=camera.fov_rad,
        marker_offset_m=camera.marker_offset_m,
        range_margin_m=max(fp.fuzzy.dmax_m for fp in followers.values()),
        fov_margin_rad=max(fp.fuzzy.gamma_rad for fp in followers.values()),
    )
    for name, form in formations.items():
        wrapped(f"formations.{name}", check_sight, form, cam)
    if ld["avoid_formation"]:
        normal, avoid = formations[ld["formation"]], formations[ld["avoid_formation"]]
        try:
            check_switch(normal, avoid, cam)
            check_switch(avoid, normal, cam)
        except ValueError as exc:
            pair = (forms_raw[ld["formation"]], forms_raw[ld["avoid_formation"]])
            lines = [
                n
                for n, t in zip((ld["formation"], ld["avoid_formation"]), pair, strict=True)
                if t.get("shape") == "line" and t.get("follow", "ahead") == "ahead"
            ]
            hint = _switch_hint(lines[0], ld["avoid_formation"]) if lines else ""
            raise ScenarioError(f"leader.avoid_formation: {exc}{hint}") from None


def _switch_hint(line: str, avoid: str) -> str:
    """The ways past a refused switch to a line that follows the robot ahead:
    the line alone (measured to hold), or the line on pairs (accepted, not safe)."""
    alone = f"--set leader.formation={line}" + ("" if avoid == line else " --set leader.avoid_formation=''")
    return (
        f"; to keep the {line!r} throughout: {alone} (with --set controller.lookahead_m=1 for a long chain; "
        f"docs/running.md#many-robots); or a {line!r} with follow = 'pairs', which has the references of a wedge "
        f"(--set formations.{line}.follow=pairs): the switch is then accepted, but measured with 30 robots it "
        "let them touch (docs/paper.md, 'Beyond the paper: formations of many robots')"
    )
