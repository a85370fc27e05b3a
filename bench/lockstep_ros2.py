"""bench/lockstep.py --ros2: the full lockstep run without and with its ROS 2
bridge (``swarm run --ros2``), alternating in one invocation, so that their
ratio holds on a loaded machine. The bridge publishes every tick's topics
(/clock, /tf, each robot's odometry and camera, the formation and its
errors) on rmw_zenoh's keys; no robot is driven from ROS, so the world does
not wait for it."""

from __future__ import annotations

import os
import statistics
from collections.abc import Callable
from typing import Any


def ros2_rounds(repeat: int, duration_s: float, robots: int, measure_full: Callable[..., tuple[float, Any]]) -> None:
    plain: list[float] = []
    bridged: list[float] = []
    for i in range(repeat):
        plain.append(measure_full(duration_s, robots)[0])
        rate, summary = measure_full(duration_s, robots, ros2=True)
        bridged.append(rate)
        published = (summary.get("ros2") or {}).get("ticks_published")
        print(
            f"  round {i + 1}: full {plain[-1]:7.0f} ticks/s   with --ros2 {bridged[-1]:7.0f} ticks/s "
            f"({published} of {summary['ticks']} ticks published by the bridge)   "
            f"load average {os.getloadavg()[0]:.2f}",
            flush=True,
        )
    ratio = statistics.median(b / p for b, p in zip(bridged, plain, strict=True))
    print(
        f"median: full {statistics.median(plain):.0f} ticks/s, with --ros2 {statistics.median(bridged):.0f} "
        f"ticks/s: {ratio:.2f} of the rate without (median of the rounds' ratios)"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")
