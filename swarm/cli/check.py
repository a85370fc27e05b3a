"""``swarm check-controller``: a follower controller checked before it flies
(formation_swarm.engine.check), its problems one line each."""

from __future__ import annotations

import argparse
import sys

from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, integer, seed

CHECK_EPILOG = """\
exit codes: 0 it passes every check; 1 it has problems (one line each, naming
the check); 2 a bad command line, or a law or parameter that cannot be built
(one line on stderr).

examples:
  PYTHONPATH=. swarm check-controller my_controller:Proportional
  PYTHONPATH=. swarm check-controller my_controller:Proportional --set speed_gain=2 --robot 3

docs/controllers.md ("Check your controller") says what each check means.
"""


def _params(texts: list[str]) -> dict[str, object]:
    """Each ``--set NAME=VALUE``, the value read as a scenario's (TOML) value; ValueError if not."""
    from formation_swarm.spec.files import parse_value

    out: dict[str, object] = {}
    for text in texts:
        name, sep, value = text.partition("=")
        name = name.strip()
        if not sep or not name or not value.strip():
            raise ValueError(f"--set takes NAME=VALUE, a parameter of the law (e.g. speed_gain=2), got {text!r}")
        if name in out:
            raise ValueError(f"--set {name} is given twice: give it once")
        try:
            out[name] = parse_value(value)
        except ValueError as exc:
            raise ValueError(f"--set {name}: {exc}") from None
    return out


def _cmd_check(args: argparse.Namespace) -> int:
    from formation_swarm.engine.check import run_checks

    try:
        report = run_checks(args.law, _params(args.set), scenario=args.scenario, robot=args.robot, seed=args.seed)
    except ValueError as exc:  # ScenarioError and LawError too: a law, parameter or scenario that cannot be built
        print(f"swarm check-controller: {' '.join(str(exc).split())}", file=sys.stderr)
        return USAGE_ERROR
    if report.problems:
        for line in report.problems:
            print(line)
        return 1
    print(f"{args.law} passes {len(report.checks)} checks")
    return 0


def add_check(sub: argparse._SubParsersAction[Parser]) -> None:
    check = sub.add_parser(
        "check-controller",
        help="check a follower controller before it flies: its answers, determinism, no global random state",
        description="Build a follower controller as swarm run builds it, then feed fresh instances what a follower's "
        "controller received in a real run of the scenario (recorded in this process), changed as runs change "
        "it: no reading, several ticks at once, its slot moved, a new reference. Each answer must be a "
        "FollowerOutput of finite floats within robot.max_wheel_mps; two instances must answer alike with the "
        "global random states seeded apart, and leave those states alone.",
        epilog=CHECK_EPILOG,
    )
    check.add_argument(
        "law", metavar="MODULE:CLASS", help="the law: module:Class on the Python path, or an installed law's name"
    )
    check.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="one of the law's parameters, as [controller.params] gives it, e.g. speed_gain=2 (repeatable)",
    )
    check.add_argument(
        "--scenario",
        default="fig11_obstacles",
        metavar="NAME",
        help="the scenario whose run is recorded: a shipped scenario's name or a file (default: fig11_obstacles)",
    )
    check.add_argument(
        "--robot",
        type=integer(0),
        default=None,
        metavar="N",
        help="the follower whose inputs are recorded and whose setup builds the law (default: the first follower)",
    )
    check.add_argument("--seed", type=seed, default=0, metavar="N", help="seed of the recorded run (default: 0)")
    check.set_defaults(func=_cmd_check, parser=check)
