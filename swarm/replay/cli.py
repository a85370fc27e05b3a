"""``swarm replay RUN --robot N``: one robot's role fed again, in this process,
what it took in the run (from the run's ``wire.mcap``, formation_swarm.replay.feed),
its commands compared with the recorded ones tick by tick (replay.compare);
with ``--set``, a what-if: another law's or other parameters' answers to the
same inputs, and a figure of both wheel-speed series (replay.figure)."""

from __future__ import annotations

import hashlib
import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from formation_swarm.protocol.keys import MAX_ROBOT_ID, Keys
from formation_swarm.replay.compare import Comparison, compare, describe
from formation_swarm.replay.feed import Inputs, Replayed, inputs_of, replay, scenario_of
from formation_swarm.replay.wire import Wire, WireError, read_wire
from formation_swarm.runtime import wirefile
from formation_swarm.runtime.cliargs import USAGE_ERROR, Parser, integer
from formation_swarm.runtime.wirefile import FILE_NAME
from formation_swarm.spec.scenario import Scenario

DIFFER = 1
PROGRESS_EVERY_S = 2.0  # a progress line on stderr at most this often

DESCRIPTION = """\
Replay one robot of a run of swarm run (its wire.mcap, recorded unless
--no-record-wire; a run whose launcher was killed has its spools merged
first): its role
(the leader's policy or a follower's controller, built as its agent built
it, from the scenario and seed the recording holds) is fed, in this
process, the observations and formation codes it took in the run, in the
order they arrived, and answers the ticks it answered. Its commands are
compared with the recorded ones, tick by tick, to the bit.

With --set (another law, other parameters: the scenario keys of swarm run
--set) it is a what-if: the other controller's answers to the same inputs.
It prints the RMS difference of the wheel speeds and draws both series."""

EPILOG = """\
It prints "robot N: identical over K ticks", or the first tick whose
commands differ, with both; then, when they differ or with --set, the RMS
difference of the wheel speeds and where the figure went (default:
RUN/replay/robot-N.png). Progress goes to stderr on long replays.

exit codes: 0 the commands are identical; 1 they differ; 2 a bad command
line, no such run folder, no wire.mcap in it, a robot not in the run, or a
wire.mcap that does not read (one line on stderr, nothing written but the
merge of a run's spools).

examples:
  swarm run fig11_obstacles --out runs/fig11
  swarm replay runs/fig11 --robot 2
  swarm replay runs/fig11 --robot 2 --set controller.law=lpsi"""


class UsageError(ValueError):
    """Input swarm replay cannot use (exit code 2)."""


def build_parser() -> Parser:
    ap = Parser(prog="swarm replay", description=DESCRIPTION, epilog=EPILOG)
    ap.add_argument("run_dir", metavar="RUN", help="a run's folder with its wire recording (runs/<run id>)")
    ap.add_argument(
        "--robot", required=True, type=integer(1, MAX_ROBOT_ID), metavar="N", help="the robot to replay (its id)"
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a what-if: this scenario key changed for the replayed role (repeatable), e.g. controller.law=lpsi",
    )
    ap.add_argument(
        "--out",
        metavar="FILE",
        help="the figure's file (PNG; default: RUN/replay/robot-N.png, or robot-N-whatif-SETTINGS.png with --set)",
    )
    return ap


@dataclass(frozen=True)
class Job:
    """A replay, its inputs checked."""

    run_dir: Path
    wire: Wire
    sc: Scenario  # as the replayed role is built: the run's, with --set
    seed: int
    inputs: Inputs
    what_if: tuple[str, ...]  # the --set texts (empty: a plain replay)


def prepare(run_dir: Path, robot: int, sets: list[str], say: Callable[[str], None] = print) -> Job:
    """Everything a replay needs, read and checked; UsageError saying what is wrong.
    A run whose launcher did not merge its receivers' spools has them merged first (said)."""
    from formation_swarm.spec.files import parse_overrides

    if not run_dir.is_dir():
        raise UsageError(f"no run folder at {run_dir}")
    path = run_dir / FILE_NAME
    if not path.exists() and wirefile.spools_of(run_dir):
        try:
            wirefile.merge_spools(run_dir, say)
        except (OSError, ValueError) as exc:
            raise UsageError(f"cannot merge the wire spools of {run_dir} into {FILE_NAME}: {exc}") from None
        say(f"{run_dir}: its wire spools merged into {FILE_NAME} (its launcher did not finish)")
    if not path.is_file():
        raise UsageError(f"{run_dir} has no {FILE_NAME}: record the run with swarm run --record-wire")
    try:
        overrides = parse_overrides(sets)
        ends = (f"/robot/{robot}/obs", f"/robot/{robot}/cmd", "/robot/*/formation")
        wire = read_wire(path, keep=lambda key: key.endswith(ends))
        keys = Keys(wire.run_id)
        as_run = scenario_of(wire)
        sc = scenario_of(wire, overrides) if overrides else as_run
    except (WireError, ValueError) as exc:  # ScenarioError too: a --set or the recorded scenario
        raise UsageError(str(exc)) from None
    for which in (as_run, sc):
        if robot not in which.robots:
            robots = ", ".join(map(str, which.robots))
            raise UsageError(f"robot {robot} is not in run {keys.run_id} (robots {robots})")
    inputs = inputs_of(wire, robot, takes_codes=robot != as_run.leader.robot_id)
    if not inputs.inbox and any(h.receiver == "bridge" and h.key == keys.obs(robot) for h in wire.messages):
        raise UsageError(
            f"{path}: robot {robot} was driven from ROS 2 (swarm run --ros2): no agent of ours answered it, "
            f"nothing to replay; its Twists are in swarm export {run_dir} --mcap, /robot{robot}/cmd_vel"
        )
    if not inputs.recorded:
        raise UsageError(f"{path}: robot {robot} answered no tick in it")
    seed = sc.seed if "run.seed" in overrides else wire.seed  # the run's, unless the what-if changes it
    return Job(run_dir, wire, sc, seed, inputs, tuple(sets))


def _progress(total: int, say: Callable[[str], None]) -> Callable[[int], None]:
    """Told each tick answered: a line every PROGRESS_EVERY_S, from the first one on."""
    state = {"n": 0, "next": time.monotonic() + PROGRESS_EVERY_S}

    def tick(k: int) -> None:
        state["n"] += 1
        now = time.monotonic()
        if now >= state["next"]:
            state["next"] = now + PROGRESS_EVERY_S
            say(f"replay: tick {k}, {state['n']} of {total} answered ({100 * state['n'] // total}%)")

    return tick


def report(job: Job, replayed: Replayed, cmp: Comparison) -> list[str]:
    """The result's lines."""
    rid, dt, first = job.inputs.robot_id, job.sc.dt_s, cmp.first
    if first is None:
        lines = [f"robot {rid}: identical over {cmp.ticks} ticks"]
    else:
        lines = [
            f"robot {rid}: differs at tick {first.tick} (t = {first.tick * dt:.2f} s), "
            f"{cmp.differing} of {cmp.ticks} ticks differ",
            f"  recorded: {describe(first.recorded)}",
            f"  replayed: {describe(first.replayed)}",
        ]
    if (job.what_if or not cmp.identical) and cmp.rms_left_mps is not None:
        lines.append(
            f"  RMS difference of the wheel speeds: left {cmp.rms_left_mps:.4g} m/s, right "
            f"{cmp.rms_right_mps:.4g} m/s; largest {cmp.max_mps:.4g} m/s at tick {cmp.max_tick}"
        )
    if job.inputs.restarted_at is not None:
        lines.append(f"  its agent was restarted at tick {job.inputs.restarted_at}: replayed up to there")
    return lines


def _figure_path(job: Job, out: str | None) -> Path:
    if out:
        return Path(out)
    # Each what-if its own file: its settings, made safe for a file name; a long list shortened and hashed.
    slug = re.sub(r"[^\w.=+-]+", "_", ",".join(job.what_if))
    if len(slug) > 60:
        slug = f"{slug[:48]}-{hashlib.sha256(slug.encode()).hexdigest()[:8]}"
    tail = f"-whatif-{slug}" if job.what_if else ""
    return job.run_dir / "replay" / f"robot-{job.inputs.robot_id}{tail}.png"


def run(args: Any, say: Callable[[str], None] = print, warn: Callable[[str], None] | None = None) -> int:
    """The command on parsed arguments; UsageError for bad input (nothing written)."""
    warn = warn or (lambda line: print(line, file=sys.stderr, flush=True))
    job = prepare(Path(args.run_dir), args.robot, args.set, warn)
    if args.out and Path(args.out).suffix.lower() != ".png":
        raise UsageError(f"--out {args.out}: the figure is a PNG (name it .png)")
    if not job.wire.complete:
        warn(f"{job.wire.path}: no footer (its merge was cut short): read to its last whole chunk")
    replayed = replay(job.sc, job.seed, job.wire.run_id, job.inputs, _progress(len(job.inputs.recorded), warn))
    for note in replayed.notes[:3]:
        warn(f"replayed robot {job.inputs.robot_id}: {note.splitlines()[0]}")
    cmp = compare(job.inputs.recorded, replayed.commands)
    for line in report(job, replayed, cmp):
        say(line)
    if job.what_if or not cmp.identical:
        from formation_swarm.replay.figure import wheel_speeds

        path = _figure_path(job, args.out)
        what = f" with {', '.join(job.what_if)}" if job.what_if else ""
        title = f"{job.wire.run_id}: robot {job.inputs.robot_id}'s wheel speeds, recorded and replayed{what}"
        try:
            wheel_speeds(
                path, job.inputs.recorded, replayed.commands, robot=job.inputs.robot_id, dt_s=job.sc.dt_s, title=title
            )
        except OSError as exc:
            raise UsageError(f"cannot write the figure {path}: {exc.strerror or exc}") from None
        say(f"  figure: {path}")
    return 0 if cmp.identical else DIFFER


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return run(args)
    except UsageError as exc:
        print(f"swarm replay: {exc}", file=sys.stderr)
        return USAGE_ERROR


if __name__ == "__main__":
    sys.exit(main())
