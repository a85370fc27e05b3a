"""A fault's window in ticks, as docs/faults.md promises it: it starts at tick
round(at_s / dt) and lasts round(for_s / dt) ticks, at least one. Seconds
that are whole ticks on paper are not always whole in binary (0.7 / 0.05 is
13.999999999999998): truncating would lose a tick."""

from __future__ import annotations

import pytest

from formation_swarm.common.faults import Fault
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.engine import WorldEngine


@pytest.mark.parametrize(
    ("text", "dt_s", "start", "ticks"),
    [
        ("freeze agent-2@10s for=0.7s", 0.05, 200, 14),  # 0.7 / 0.05 = 13.999999999999998
        ("freeze agent-2@0.7s for=0.7s", 0.05, 14, 14),
        ("drop obs:2@1s for=0.3s p=0.5", 0.1, 10, 3),  # 0.3 / 0.1 = 2.9999999999999996
        ("blackout 3@1s for=0.07s", 0.05, 20, 1),  # 1.4 ticks: 1
        ("blackout 3@1s for=0.08s", 0.05, 20, 2),  # 1.6 ticks: 2
        ("blackout 3@1s for=0.01s", 0.05, 20, 1),  # 0.2 ticks: at least one
        ("restart agent-3@2s after=0.7s", 0.05, 40, 14),  # a restart's "after" is rounded alike
    ],
)
def test_a_window_starts_and_lasts_the_rounded_number_of_ticks(text: str, dt_s: float, start: int, ticks: int) -> None:
    f = Fault.parse(text)
    assert f.start_tick(dt_s) == start
    assert f.end_tick(dt_s) == start + ticks
    assert sum(f.active(k, dt_s) for k in range(start + ticks + 50)) == ticks


def test_a_blackout_for_0_7_s_hides_the_markers_for_14_ticks_of_a_run() -> None:
    """The world counts the ticks a sensor fault was active on: 14 at dt 0.05 s."""
    sc = scenario_mod.load("fig11_obstacles", faults=["blackout 3@1s for=0.7s"])
    assert sc.dt_s == 0.05
    eng = WorldEngine(sc, 1)
    for _ in range(60):
        eng.observation(3)
        eng.step(eng.time_s)
    assert eng.summary()["sensor_faults"]["blackout 3@1s for=0.7s"]["3"]["ticks"] == 14
