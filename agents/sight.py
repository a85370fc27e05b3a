"""What a follower's camera sees of its reference's marker when the
formation stands at its slots, and the checks that every follower of a
formation (a custom one too) sees its reference within a camera's range and
field of view, with margins."""

from __future__ import annotations

import math
from typing import NamedTuple

from formation_swarm.agents.formation import Formation
from formation_swarm.common.checks import non_negative


class Sight(NamedTuple):
    """What a follower's camera sees of its reference's marker when both are
    at their slots with the leader's heading (camera.true_reading)."""

    rho_m: float  # distance to the marker
    beta_rad: float  # bearing from the follower's heading, positive to its right


def sights(form: Formation, marker_offset_m: float) -> dict[int, Sight]:
    """Per follower, its reference's marker as seen from its slot.

    The follower sits at its reference's centre plus its offset (eq. 2 with
    phi = 0); the marker ``marker_offset_m`` behind the reference's centre."""
    d = non_negative("marker_offset_m", marker_offset_m)
    out = {}
    for rid, slot in sorted(form.slots.items()):
        x, y = -slot.offset[0], -slot.offset[1] - d  # follower -> marker, follower frame
        out[rid] = Sight(math.hypot(x, y), math.atan2(x, y))
    return out


class Camera(NamedTuple):
    """What the sight checks need of a camera, and the margins they keep (see
    ``check_sight``)."""

    range_m: float
    fov_rad: float
    marker_offset_m: float
    range_margin_m: float
    fov_margin_rad: float


RANGE, FOV = "range", "fov"  # the limits of a camera's sight a marker may break


def _broken_limit(cam: Camera, rho_m: float, beta_rad: float) -> str | None:
    """The limit of the camera's sight with its margins a marker at (rho_m,
    beta_rad) breaks: RANGE, else FOV; None if it breaks neither."""
    reach = cam.range_m - non_negative("range_margin_m", cam.range_margin_m)
    half = 0.5 * cam.fov_rad - non_negative("fov_margin_rad", cam.fov_margin_rad)
    if rho_m > reach:
        return RANGE
    if cam.fov_rad < 2.0 * math.pi and abs(beta_rad) > half:
        return FOV
    return None


def _sight_error(cam: Camera, rho_m: float, beta_rad: float) -> tuple[str, str] | None:
    """Where a marker at (rho_m, beta_rad) is and why it is out of the camera's
    sight with its margins, or None."""
    limit = _broken_limit(cam, rho_m, beta_rad)
    if limit == RANGE:
        reach = cam.range_m - cam.range_margin_m
        return (
            f"{rho_m:.1f} m away",
            f"beyond the camera's {cam.range_m:g} m range (margin {cam.range_margin_m:g} m: at most {reach:g} m)",
        )
    if limit == FOV:
        half = 0.5 * cam.fov_rad - cam.fov_margin_rad
        return (
            f"at a bearing of {math.degrees(beta_rad):.1f} deg",
            f"outside the camera's {math.degrees(cam.fov_rad):g} deg field of view"
            f" (margin {math.degrees(cam.fov_margin_rad):g} deg: at most {math.degrees(half):g} deg either side)",
        )
    return None


class SightFailure(NamedTuple):
    """A follower that does not see its reference's marker from its slot
    (``sight_failures``): the marker as seen there, and the limit it breaks."""

    robot: int
    reference: int
    rho_m: float
    beta_rad: float
    limit: str  # RANGE or FOV


def sight_failures(form: Formation, cam: Camera) -> list[SightFailure]:
    """Every follower that does not see its reference from its slot, by id:
    the record ``check_sight``'s error says in words."""
    return [
        SightFailure(rid, form.slots[rid].reference, sight.rho_m, sight.beta_rad, limit)
        for rid, sight in sights(form, cam.marker_offset_m).items()
        if (limit := _broken_limit(cam, sight.rho_m, sight.beta_rad)) is not None
    ]


SIGHT_LISTED = 8  # followers named per limit in check_sight's error


def check_sight(form: Formation, cam: Camera) -> None:
    """Raise ValueError unless every follower, at its slot, sees its reference's
    marker within ``range_m - range_margin_m`` and within ``fov_rad / 2 -
    fov_margin_rad`` of its heading.

    A follower away from its slot by e sees the marker at most e farther
    (triangle inequality); the margin is the error up to which it must still
    see it. The field of view is not checked when it is a full circle. The
    error names every follower that does not (SIGHT_LISTED per limit).
    """
    bad = [(f.robot, why) for f in sight_failures(form, cam) if (why := _sight_error(cam, f.rho_m, f.beta_rad))]
    if len(bad) == 1:
        rid, (where, limit) = bad[0]
        raise ValueError(
            f"formation {form.name!r}: robot {rid}'s reference robot {form.slots[rid].reference} is {where}"
            f" at its slot, {limit}"
        )
    if bad:  # every one, grouped by the limit it breaks: a layout is mended in one go
        by_limit: dict[str, list[str]] = {}
        for rid, (where, limit) in bad:
            by_limit.setdefault(limit, []).append(f"robot {rid}'s reference robot {form.slots[rid].reference} {where}")
        parts = [
            f"{limit}: {', '.join(refs[:SIGHT_LISTED])}"
            + (f" and {len(refs) - SIGHT_LISTED} more" if len(refs) > SIGHT_LISTED else "")
            for limit, refs in by_limit.items()
        ]
        raise ValueError(
            f"formation {form.name!r}: {len(bad)} followers do not see their reference from their slot; "
            + "; ".join(parts)
        )


def check_switch(old: Formation, new: Formation, cam: Camera) -> None:
    """Raise ValueError unless every follower whose reference changes from
    ``old`` to ``new`` sees its new reference from its slot in ``old``, where
    the switch finds it (``check_sight``'s rule, with the new reference at its
    own slot in ``old``)."""
    places = old.slot_positions()
    for rid, slot in sorted(new.slots.items()):
        if rid not in old.slots or old.slots[rid].reference == slot.reference:
            continue
        here, there = places[rid], places[slot.reference]
        x, y = there.x_m - here.x_m, there.y_m - here.y_m - cam.marker_offset_m
        if (why := _sight_error(cam, math.hypot(x, y), math.atan2(x, y))) is not None:
            raise ValueError(
                f"switching from formation {old.name!r} to {new.name!r}: robot {rid}'s new reference robot"
                f" {slot.reference} is {why[0]} from its slot in {old.name!r}, {why[1]}"
            )
