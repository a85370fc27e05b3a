"""examples/ros2_follower's law flying robot 3 of fig11 in-process (the
Engine, robot 3's wheels replaced each tick), as the ROS node does in
lockstep: tick t answered from the odometry of tick t - 1 (poses, and the
motion into them), the formation flown, the Twist turned into wheel speeds
by the bridge's drive model."""

from __future__ import annotations

import math

import pytest

from formation_swarm import Engine
from formation_swarm.ros2.topics import twist_to_wheels
from tests.helpers.ros2_example import load

pytestmark = pytest.mark.slow
pursuit = load("pursuit")


def test_the_example_flies_robot_3_through_fig11() -> None:
    engine = Engine("fig11_obstacles", seed=1)
    sc = engine.scenario
    codes = {f.slots[3]: code for code, f in enumerate(sc.formations.values())}
    older = last = None  # the poses of ticks t - 2 and t - 1
    closest_m = math.inf
    while engine.observe():
        now = engine.poses
        twists = {r: _twist(older[r], last[r], sc.dt_s) for r in now} if older and last else {}
        code = codes[engine.inputs[3].slot] if 3 in engine.inputs else 0
        poses = {r: pursuit.Pose(*p) for r, p in last.items()} if last else {}
        wheels = twist_to_wheels(*pursuit.answer(poses, twists, code), sc.width_m, sc.max_wheel_mps)
        engine.step({3: wheels})
        older, last = last, now
        closest_m = min(closest_m, *(math.dist(now[a][:2], now[b][:2]) for a, b in ((1, 2), (1, 3), (2, 3))))
    res = engine.run()
    s = res.summary
    assert (res.exit_code, res.end_reason, s["collisions"], s["obstacle_collisions"]) == (0, "leader_finished", 0, 0)
    assert s["followers"]["3"]["rms_m"] < 1.0  # measured 0.80 m (robot 2, the paper's law: 0.52 m)
    assert closest_m > 0.6  # measured 0.76 m


def _twist(a: tuple[float, float, float], b: tuple[float, float, float], dt_s: float) -> tuple[float, float]:
    turn = (b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi
    mid = a[2] + 0.5 * turn
    return ((b[0] - a[0]) * math.cos(mid) + (b[1] - a[1]) * math.sin(mid)) / dt_s, turn / dt_s
