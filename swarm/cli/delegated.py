"""The ``swarm`` commands with their own parser in their own module: ``swarm
report ...`` is that module's ``main(["..."])``."""

from __future__ import annotations

# name -> (module, one-line summary)
DELEGATED = {
    "report": ("formation_swarm.report.build", "figures (PNG, SVG or PDF) and a markdown summary of a run's folder"),
    "export": (
        "formation_swarm.report.export",
        "a run's folder as a table, one row per robot per tick (CSV or Parquet), or as ROS 2 topics (MCAP)",
    ),
    "compare": (
        "formation_swarm.report.compare",
        "one figure overlaying several runs: formation error and trajectories",
    ),
    "sweep": (
        "formation_swarm.studies.sweep",
        "many lockstep runs of a scenario (seeds x parameter values), in parallel",
    ),
    "results": ("formation_swarm.studies.results", "recompute the baseline comparison table of docs/results.md"),
    "replay": (
        "formation_swarm.replay.cli",
        "one robot of a run recorded with --record-wire, fed its inputs again and its commands compared",
    ),
    "world": ("formation_swarm.nodes.world.main", "role: the world alone (physics, cameras, clock; a Zenoh router)"),
    "agent": ("formation_swarm.nodes.agent.main", "role: one robot's agent alone, a client of a router"),
    "logger": ("formation_swarm.nodes.logger.main", "role: the Rerun logger alone (to a file or a viewer)"),
    "router": ("formation_swarm.nodes.router", "role: a Zenoh router for agents on other machines"),
    "bridge": ("formation_swarm.nodes.bridge.main", "role: a run's ROS 2 bridge alone (rmw_zenoh's topics)"),
    "secure": ("formation_swarm.launch.secure", "credentials and access rules for a run spread over machines"),
    "host": ("formation_swarm.nodes.host.main", "serve this machine to runs started elsewhere (swarm run --hosts)"),
    "doctor": ("formation_swarm.launch.doctor", "check that the hosts of a run spread over machines are there and fit"),
}


def run(argv: list[str]) -> int:
    """``argv[0]``'s module's main on the rest of the command line."""
    import importlib

    return int(importlib.import_module(DELEGATED[argv[0]][0]).main(argv[1:]))
