"""``swarm sim``: a scenario in one process, no Zenoh (formation_swarm.engine),
with the result block of ``swarm run`` and the run's trajectory digest."""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from typing import TYPE_CHECKING, Any, TextIO

from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, seconds, seed

if TYPE_CHECKING:
    from formation_swarm.engine import EngineResult

# The paper's two-robot turning run (Fig. 6-7): what swarm sim flew before it took a scenario.
DEFAULT_SCENARIO = "fig7_turn_vn_dynamic"
SIM_MAX_S = 3600.0  # --duration's limit, as before

SIM_EPILOG = """\
exit codes: 0 the run ended normally; 1 it lost its leader or every follower,
or a follower's controller failed; 2 a bad command line (one line on stderr).

examples:
  swarm sim                                   the paper's two-robot turning run
  swarm sim --vn 1.5                          the same with a static V_N of 1.5 m/s
  swarm sim fig11_obstacles --seed 3 --fault "restart agent-3@20s after=1s"
  PYTHONPATH=. swarm sim fig11_obstacles --law my_controller:Proportional

Its digest is swarm run --mode lockstep's for the same scenario, seed and faults.
"""


def _overrides(args: argparse.Namespace) -> dict[str, Any]:
    """``--set`` with the shorthands ``--law``, ``--vn`` and ``--duration``;
    ValueError for a key given twice."""
    from formation_swarm.spec.files import parse_overrides

    out = parse_overrides(args.set)
    for flag, key, value in (
        ("--law", "controller.law", args.law),
        ("--vn", "controller.vn", None if args.vn is None else _vn_value(args.vn)),
        ("--duration", "run.duration_s", args.duration),
    ):
        if value is not None:
            if key in out:
                raise ValueError(f"{flag} and --set {key}: give it once")
            out[key] = value
    return out


def _vn_value(text: str) -> str | float:
    return text if text == "dynamic" else float(text)


def _check_shorthands(args: argparse.Namespace, overrides: dict[str, Any]) -> str | None:
    """What is wrong with --vn or --duration for this scenario, as swarm sim said it before (None: nothing)."""
    if args.vn is None and args.duration is None:
        return None
    from formation_swarm.spec import scenario as scenario_mod

    given = {k: v for k, v in overrides.items() if k not in ("controller.vn", "run.duration_s")}
    sc = scenario_mod.load(args.scenario, given)
    if args.vn not in (None, "dynamic"):
        a_mps = max((sc.followers[rid].fuzzy.a_mps for rid in sc.follower_ids), default=0.0)
        top, limit = float(args.vn) + a_mps, sc.max_wheel_mps
        if top > limit:
            return (
                f"argument --vn: the fuzzy controller would command up to V_N + a = {top:g} m/s, above the "
                f"robots' {limit:g} m/s (robot.max_wheel_mps): at most {limit - a_mps:g}"
            )
    if args.duration is not None and args.duration < sc.dt_s:
        return f"argument --duration: must be at least one control step ({sc.dt_s:g} s), got {args.duration:g}"
    return None


def _cmd_sim(args: argparse.Namespace) -> int:
    from formation_swarm.engine import Engine
    from formation_swarm.launch.words import describe_laws
    from formation_swarm.spec.keys import ScenarioWarning
    from formation_swarm.spec.laws import laws

    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", ScenarioWarning)
            overrides = _overrides(args)
            if (wrong := _check_shorthands(args, overrides)) is not None:
                print(f"swarm sim: {wrong}", file=sys.stderr)
                return USAGE_ERROR
            engine = Engine(args.scenario, seed=args.seed, overrides=overrides, faults=args.fault)
    except ValueError as exc:  # ScenarioError too: a scenario, key, law or fault that cannot run
        print(f"swarm sim: {exc}", file=sys.stderr)
        return USAGE_ERROR
    sc = engine.scenario
    print(
        f"[swarm] sim: {sc.name}, {len(sc.robots)} robots, lockstep in this process, seed {sc.seed}, "
        f"{describe_laws(laws(sc))}",
        flush=True,
    )
    for warning in dict.fromkeys(str(w.message) for w in said if issubclass(w.category, ScenarioWarning)):
        print(f"[swarm] warning: {warning}")
    result = engine.run()
    print_sim_result(result)
    for note in result.notes:  # what an agent process would have logged: a failed controller's traceback
        print(f"[swarm] {note}", file=sys.stderr)
    return result.exit_code


def print_sim_result(res: EngineResult, out: TextIO | None = None) -> None:
    """The result block of ``swarm run`` (launch.console) for an engine's run,
    and its digest, on ``out`` (default: stdout)."""
    from formation_swarm.launch import console
    from formation_swarm.launch.words import num

    s, w = res.summary, (out or sys.stdout).write
    w(f"sim {s.get('scenario')}: exit {res.exit_code}, {res.ticks} ticks, sim {num(s.get('sim_time_s'), '.2f')} s\n")
    w(f"  ended: {s.get('ended')}\n")
    if s.get("failure"):
        w(f"  failed: {s['failure']}\n")
    console._metrics(w, s)
    console._faults_and_events(w, s)
    w(f"  trajectory digest: {res.trajectory_digest}\n")


def _vn(text: str) -> str:
    if text == "dynamic":
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be 'dynamic' or a speed > 0 in m/s, got {text!r}")
    return text


def add_sim(sub: argparse._SubParsersAction[Parser]) -> None:
    sim = sub.add_parser(
        "sim",
        help="run a scenario in one process, no Zenoh: a controller's quick check (swarm run's digest)",
        description="Run a scenario in this one process (formation_swarm.engine): the world's tick, every robot's "
        "role and the link layer, stepped in lockstep without Zenoh, with the faults that need no process of their "
        "own. Prints swarm run's result block (each follower's formation error, collisions, formation changes, "
        "faults) and the trajectory digest, which is swarm run --mode lockstep's for the same run.",
        epilog=SIM_EPILOG,
    )
    sim.add_argument(
        "scenario",
        nargs="?",
        default=DEFAULT_SCENARIO,
        help="a shipped scenario's name (see: swarm scenarios) or a scenario file (TOML) "
        f"(default: {DEFAULT_SCENARIO}, the paper's two-robot turning run)",
    )
    sim.add_argument(
        "--seed",
        type=seed,
        default=None,
        metavar="N",
        help="seed of every random draw, an integer in [0, 2**63 - 1] (default: the scenario's run.seed)",
    )
    sim.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one scenario key, e.g. leader.speed_mps=1.6 (repeatable)",
    )
    sim.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="'KIND TARGET@TIME ...'",
        help="schedule a fault, e.g. 'restart agent-3@20s after=1s', 'drop obs:2@3s for=4s p=0.3' (repeatable; "
        "docs/faults.md). A kill, or a fault of the logger, needs swarm run: refused",
    )
    _add_shorthands(sim)
    sim.set_defaults(func=_cmd_sim, parser=sim)


def _add_shorthands(sim: argparse.ArgumentParser) -> None:
    """Flags that set one scenario key each."""
    sim.add_argument(
        "--law",
        default=None,
        metavar="MODULE:CLASS",
        help="the followers' control law: fuzzy, lpsi, an installed law's name or module:Class on the Python "
        "path (docs/controllers.md); the same as --set controller.law=...",
    )
    sim.add_argument(
        "--vn",
        type=_vn,
        default=None,
        help="the fuzzy controller's normal speed V_N: 'dynamic' (FIS-2) or a static value in m/s, e.g. 1.5; "
        "the same as --set controller.vn=... (default: the scenario's)",
    )
    sim.add_argument(
        "--duration",
        type=seconds(SIM_MAX_S),
        default=None,
        metavar="SECONDS",
        help=f"simulated time in s, at most {SIM_MAX_S:g}; the run ends earlier with the leader's path; the same "
        "as --set run.duration_s=... (default: the scenario's)",
    )
