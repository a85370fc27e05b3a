"""A run's first line names its robots and, when K of them share a process, K (launch.words)."""

from __future__ import annotations

from formation_swarm.launch.words import describe_robots


def test_the_first_line_names_k_only_when_robots_share_a_process() -> None:
    assert describe_robots(3, 1) == "3 robots"
    assert describe_robots(100, 10).startswith("100 robots, 10 a process")
    assert describe_robots(1, 1) == "1 robot"
