"""A leader that flies a figure-eight and changes formation once: an example
of formation-swarm's leader policy API (docs/controllers.md, "The leader's
policy").

The eight is two circles of ``radius_m`` that touch where the leader starts:
the left one counter-clockwise, then the right one clockwise. Where they
meet, after the first loop, the formation changes to ``second`` (by name;
empty: leader.avoid_formation). After the second loop the leader stops and
says its path is done. It steers on its odometry: toward the circle's
tangent, corrected by its distance from the circle.
"""

from __future__ import annotations

import math

from formation_swarm import LeaderMove, LeaderSensing, LeaderSetup

TWO_PI = 2.0 * math.pi


def wrap(angle_rad: float) -> float:
    """An angle in [-pi, pi)."""
    return (angle_rad + math.pi) % TWO_PI - math.pi


class FigureEight:
    # [leader.params] sets them; the speed is leader.speed_mps.
    PARAMS = {"radius_m": 6.0, "gain": 2.0, "lookahead_m": 2.0, "second": ""}

    def __init__(self, setup: LeaderSetup) -> None:
        p = setup.policy_params
        self.radius_m = float(p["radius_m"])
        self.gain = float(p["gain"])  # 1/s: the turn rate per rad of heading error
        self.lookahead_m = float(p["lookahead_m"])  # m: how soon it steers back onto the circle
        if self.radius_m <= 0 or self.lookahead_m <= 0:
            raise ValueError(f"radius_m and lookahead_m must be > 0, got {self.radius_m!r}, {self.lookahead_m!r}")
        second = str(p["second"])
        if second and second not in setup.formations:
            raise ValueError(f"second: no formation {second!r}; the scenario's are {list(setup.formations)}")
        self.first = setup.formation
        self.second = setup.formations.index(second) if second else setup.avoid_formation
        self.speed_mps = setup.params.speed_mps
        self.half_width_m = setup.width_m / 2.0
        # The fastest turn the wheels allow at this speed (max_wheel_mps: the world refuses more).
        self.max_turn_rps = (setup.max_wheel_mps - self.speed_mps) / self.half_width_m
        if self.max_turn_rps <= 0:
            raise ValueError(f"leader.speed_mps {self.speed_mps:g} leaves no wheel speed to turn with")
        self.burst = max(1, round(setup.params.code_burst_s / setup.dt_s))  # ticks the code is sent after a change
        self.period = max(1, round(setup.params.code_period_s / setup.dt_s))  # then once every this many
        self.reset()

    def reset(self) -> None:
        """Start the eight afresh at the next pose sensed."""
        self.centres: list[tuple[float, float]] = []  # the two circles', found at the first pose
        self.loop = 0  # 0: the left circle, 1: the right one, 2: done
        self.swept_rad = 0.0  # around the circle flown
        self.last_angle: float | None = None
        self.code = self.first
        self.since_change = 0  # ticks since the code changed (or the start)
        self.wheels = (0.0, 0.0)

    def step(self, sensed: LeaderSensing | None) -> LeaderMove:
        if sensed is not None and self.loop < 2:
            self.wheels = self._steer(sensed.pose.x_m, sensed.pose.y_m, sensed.pose.theta_rad)
        send = self.since_change < self.burst or (self.since_change - self.burst) % self.period == 0
        self.since_change += 1
        done = self.loop == 2
        left, right = (0.0, 0.0) if done else self.wheels
        return LeaderMove(left_mps=left, right_mps=right, formation=self.code, send_code=send, finished=done)

    def _steer(self, x: float, y: float, theta: float) -> tuple[float, float]:
        """The wheel speeds at (x, y, theta), the loop and its progress updated."""
        if not self.centres:  # the left circle's centre R to the left, the right one's R to the right
            lx, ly = -math.sin(theta) * self.radius_m, math.cos(theta) * self.radius_m
            self.centres = [(x + lx, y + ly), (x - lx, y - ly)]
        turn = 1.0 if self.loop == 0 else -1.0  # counter-clockwise, then clockwise
        cx, cy = self.centres[self.loop]
        angle = math.atan2(y - cy, x - cx)
        if self.last_angle is not None:
            self.swept_rad += turn * wrap(angle - self.last_angle)
        self.last_angle = angle
        if self.swept_rad >= TWO_PI:  # a loop done: where the circles meet
            self.loop += 1
            self.swept_rad, self.last_angle = 0.0, None
            if self.loop == 1 and self.second is not None and self.second != self.code:
                self.code, self.since_change = self.second, 0
            if self.loop == 2:
                return (0.0, 0.0)
            return self._steer(x, y, theta)
        off_m = math.hypot(x - cx, y - cy) - self.radius_m  # > 0: outside the circle
        heading = angle + turn * (math.pi / 2.0 + math.atan(off_m / self.lookahead_m))
        omega = turn * self.speed_mps / self.radius_m + self.gain * wrap(heading - theta)
        omega = max(-self.max_turn_rps, min(self.max_turn_rps, omega))  # rad/s, counter-clockwise
        return (self.speed_mps - omega * self.half_width_m, self.speed_mps + omega * self.half_width_m)
