"""``swarm scenarios``: the shipped scenarios, each with its description."""

from __future__ import annotations

import argparse

from formation_swarm.runtime.cliargs import Parser


def _cmd_scenarios(_args: argparse.Namespace) -> int:
    from formation_swarm.spec import files as scenario

    known = scenario.shipped()
    width = max(map(len, known))
    for name, path in known.items():
        print(f"{name:<{width}}  {scenario.description(path)}")
    return 0


def add_scenarios(sub: argparse._SubParsersAction[Parser]) -> None:
    scenarios = sub.add_parser(
        "scenarios",
        help="list the shipped scenarios, each with its description",
        description="List the scenarios installed with the package, by the name that "
        "swarm run takes, each with the first comment line of its file.",
    )
    scenarios.set_defaults(func=_cmd_scenarios, parser=scenarios)
