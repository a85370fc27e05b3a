"""swarm: an emulator of vision-based leader-follower formation control, where
every robot is its own process and every exchange crosses Eclipse Zenoh.

The robots fly the controller of "Modeling of vision based robot formation
control using fuzzy logic controller and extended Kalman filter" (IJFIS 12(3),
2012): a camera sees the marker of the robot ahead, an EKF smooths what it
sees, and a two-stage fuzzy controller (FIS-2 sets the normal speed V_N, FIS-1
the wheel speeds) drives a differential-drive robot.

Start with:
  swarm scenarios                   the shipped scenarios
  swarm run fig11_obstacles         one run: world, logger and one process per robot
  swarm report runs/<run id>        figures and a summary of that run
  swarm COMMAND --help              what a command does, its flags, units and defaults
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

from formation_swarm.cli import interrupts
from formation_swarm.cli.delegated import DELEGATED
from formation_swarm.cli.delegated import run as run_delegated

if TYPE_CHECKING:
    from formation_swarm.runtime.cliargs import Parser


def build_parser() -> Parser:
    # Imported here, not with this module: they bring numpy (formation_swarm.common.checks),
    # which a Ctrl-C must not cut in the middle (see main).
    from formation_swarm.cli.check import add_check
    from formation_swarm.cli.run import add_run
    from formation_swarm.cli.scenarios import add_scenarios
    from formation_swarm.cli.sim import add_sim
    from formation_swarm.common.version import __version__
    from formation_swarm.runtime.cliargs import Parser

    parser = Parser(prog="swarm", description=__doc__)
    parser.add_argument(
        "--version", action="version", version=f"formation-swarm {__version__}", help="print the version and exit"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", title="commands")
    add_scenarios(sub)
    add_run(sub)
    for name in ("report", "export", "compare", "sweep", "results", "replay"):
        sub.add_parser(name, help=DELEGATED[name][1], add_help=False)
    add_sim(sub)
    add_check(sub)
    for name in ("world", "agent", "logger", "router", "bridge", "secure", "host", "doctor"):
        sub.add_parser(name, help=DELEGATED[name][1], add_help=False)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """The swarm command. With ``argv`` None it is this program's command line,
    and its Ctrl-C is the command's to the end (formation_swarm.cli.interrupts);
    otherwise the signal handlers are put back when it returns."""
    program = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in DELEGATED:
        code = run_delegated(argv)
        if program:  # its work is done: a signal now (a second Ctrl-C) must not kill it as it exits
            from formation_swarm.runtime.proc import ignore_stop_signals

            ignore_stop_signals()
        return code
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    interrupts.hold()  # while the first modules load (interrupts)
    try:
        code = _command(argv)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        code = interrupts.INTERRUPTED
    finally:
        interrupts.release()
        if not program:
            for sig, handler in handlers.items():
                if handler is not None:
                    signal.signal(sig, handler)
    if program:
        interrupts.exit_at_once()
    return code


def _command(argv: list[str]) -> int:
    from formation_swarm.runtime.cliargs import USAGE_ERROR

    parser = build_parser()
    if not argv:
        parser.print_help()
        return USAGE_ERROR
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # said by the command's parser, which knows its flags, rather than by swarm's
        args.parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    from formation_swarm.runtime.proc import OutlivesItsReader

    # A reader that leaves early (swarm run ... | head) must not cut a run short.
    stdout, sys.stdout = sys.stdout, OutlivesItsReader(sys.stdout)
    interrupts.release()  # from here a Ctrl-C is the command's (a KeyboardInterrupt, unless it says otherwise)
    try:
        return int(args.func(args))
    finally:
        sys.stdout = stdout
