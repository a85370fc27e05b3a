"""A pure-pursuit follower for formation_swarm.

Each tick it turns the camera's reading of its reference's marker into the
point of its slot (the virtual target), aims at the point ``lookahead_m``
ahead of that target along the reference's heading, and drives the circular
arc through it (pure pursuit). Its speed is the reference's plus ``gain``
times how far the target is ahead; an alpha-beta filter on that distance
(given its own speed) smooths it and estimates the reference's speed. It
never reverses, slows down when its reference is nearer than
``clearance_m``, and keeps its wheels within the robot's limit.

Frames as in formation_swarm (docs/protocol.md, Observation): the follower
at the origin, y ahead, x to its right, angles counter-clockwise.
"""

from __future__ import annotations

import math

from formation_swarm import ControllerSetup, FollowerInput, FollowerOutput

__all__ = ["PurePursuit"]


class PurePursuit:
    """A follower controller of formation_swarm's API (docs/controllers.md)."""

    PARAMS = {
        "gain": 2.0,  # 1/s: speed added per metre the target is ahead
        "alpha": 0.3,  # the filter's share of a new reading in the distance (0-1]
        "beta": 0.02,  # and in the reference's speed (0-1)
        "lookahead_m": 1.0,  # aim this far ahead of the target, along the reference's heading
        "max_speed_mps": 2.5,
        "clearance_m": 1.0,  # slow down when the reference's centre is nearer than this
        "min_speed_ratio": 0.7,  # with its target to one side, it drives at least this share of the reference's speed
        "side_m": 0.5,  # "to one side": more than this across the reference's heading
    }

    def __init__(self, setup: ControllerSetup) -> None:
        p = setup.law_params
        self.gain = float(p["gain"])
        self.alpha, self.beta = float(p["alpha"]), float(p["beta"])
        self.lookahead_m = float(p["lookahead_m"])
        self.max_speed_mps = float(p["max_speed_mps"])
        self.clearance_m = float(p["clearance_m"])
        self.min_speed_ratio = float(p["min_speed_ratio"])
        self.side_m = float(p["side_m"])
        self.half_width_m = setup.params.width_m / 2.0
        self.marker_offset_m = setup.params.marker_offset_m
        self.lost_after_s = setup.params.lost_after_s
        self.max_wheel_mps = setup.max_wheel_mps
        self.along_m: float | None = None  # the filter: how far the target is ahead, smoothed
        self.reference_mps = 0.0  # and the reference's speed
        self.unseen_s = math.inf  # since the last reading
        self.last = (0.0, 0.0)  # the last wheel speeds, kept while the marker is briefly out of sight

    def step(self, inp: FollowerInput) -> FollowerOutput:
        r = inp.reading
        if r is None:
            self.unseen_s += inp.dt_s
            if self.unseen_s > self.lost_after_s:
                self.last = (0.0, 0.0)  # lost: stop and wait
                return FollowerOutput(left_mps=0.0, right_mps=0.0, stop="lost")
            return FollowerOutput(left_mps=self.last[0], right_mps=self.last[1])
        self.unseen_s = 0.0
        # The reference's heading (hx, hy) and centre in our frame (eq. 1), then the target (eq. 2).
        hx, hy = -math.sin(r.phi_rad), math.cos(r.phi_rad)
        cx = r.rho_m * math.sin(r.beta_rad) + self.marker_offset_m * hx
        cy = r.rho_m * math.cos(r.beta_rad) + self.marker_offset_m * hy
        ox, oy = inp.slot.offset
        tx, ty = cx + ox * hy + oy * hx, cy - ox * hx + oy * hy
        along = self._track(tx * hx + ty * hy, hy, inp.dt_s)  # how far the target is ahead, along the reference
        across = tx * hy - ty * hx  # and to our right, across it
        speed = self._speed(along, across, math.hypot(cx, cy) if cy > 0.0 else math.inf)
        ax, ay = tx + self.lookahead_m * hx, ty + self.lookahead_m * hy
        curvature = -2.0 * ax / max(ax * ax + ay * ay, 1e-6)  # 1/m, counter-clockwise positive
        self.last = left, right = self._wheels(speed, curvature)
        values = {
            "measured_x_m": tx,
            "measured_y_m": ty,
            "rho_m": math.copysign(math.hypot(tx, ty), along),
            "alpha_rad": math.atan2(ax, ay),
            "along_m": along,
            "reference_mps": self.reference_mps,
            "curvature_1pm": curvature,
        }
        return FollowerOutput(left_mps=left, right_mps=right, values=values)

    def _track(self, along_m: float, cos_phi: float, dt_s: float) -> float:
        """The alpha-beta filter: the along-track distance smoothed, and the
        reference's speed, from the distance read and our own speed."""
        if self.along_m is None:
            self.along_m = along_m
            return along_m
        mine = (self.last[0] + self.last[1]) / 2.0 * cos_phi  # our speed along the reference's heading
        predicted = self.along_m + (self.reference_mps - mine) * dt_s
        surprise = along_m - predicted
        self.along_m = predicted + self.alpha * surprise
        self.reference_mps = max(self.reference_mps + self.beta * surprise / dt_s, 0.0)
        return self.along_m

    def _speed(self, along_m: float, across_m: float, reference_m: float) -> float:
        """The reference's speed plus gain * along_m, never backwards. With its
        target well to one side (a formation change) at least min_speed_ratio
        of the reference's speed, so that it can steer there. Within
        clearance_m of its reference ahead, slower, down to a stop at half of it."""
        floor = self.min_speed_ratio * self.reference_mps if abs(across_m) > self.side_m else 0.0
        speed = min(max(self.reference_mps + self.gain * along_m, floor), self.max_speed_mps)
        half = self.clearance_m / 2.0
        return speed * min(max((reference_m - half) / half, 0.0), 1.0) if half > 0.0 else speed

    def _wheels(self, speed_mps: float, curvature_1pm: float) -> tuple[float, float]:
        """Wheel speeds for the arc (eq. 8-9), scaled down together to the wheels' limit."""
        turn = speed_mps * curvature_1pm * self.half_width_m
        left, right = speed_mps - turn, speed_mps + turn
        scale = max(abs(left), abs(right)) / self.max_wheel_mps
        return (left / scale, right / scale) if scale > 1.0 else (left, right)
