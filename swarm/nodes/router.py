"""``swarm router``: a Zenoh router for agents on other machines.

    swarm router --listen tcp/0.0.0.0:7447

A Python session in router mode (protocol.session builds its configuration,
as for every role); it runs until SIGINT/SIGTERM. It has no run of its own:
it prints a line when it listens and one when it stops.
"""

from __future__ import annotations

import math
import time

from formation_swarm.protocol import session
from formation_swarm.runtime import cliargs
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime.proc import exit_after_main, wait_for

DESCRIPTION = """\
Run a Zenoh router, for runs spread over several machines: the world, the
logger and the agents connect to it as clients (--zenoh-mode client
--connect tcp/HOST:7447 for the world; --connect tcp/HOST:7447 for the
others). Without --auth, any number of runs can share it: their keys start
with their run id. With --auth it holds one run's logins and access rules
(swarm secure S --run ID): a second run at the same time needs a second
router, on another port, with that run's --auth.

Without --listen or --config it listens on tcp/0.0.0.0:7447. It runs until
SIGINT (Ctrl-C) or SIGTERM and prints one line when it listens and one when
it stops."""
DEFAULT_LISTEN = "tcp/0.0.0.0:7447"
EXIT_CODES_HELP = """\
exit codes:
  0    stopped by SIGINT (Ctrl-C) or SIGTERM: its normal end
  1    the Zenoh session could not be opened (e.g. the --listen port is taken)
  2    bad flags"""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(
        prog="swarm router",
        description=DESCRIPTION,
        epilog=EXIT_CODES_HELP,
    )
    session.add_arguments(ap, default_mode="router")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not args.listen and args.config is None:
        args.listen = [DEFAULT_LISTEN]
    role = process_mod.Process("router", math.inf)
    started = time.monotonic()
    sess = role.connect(args)
    if isinstance(sess, int):
        # a router stopped while it opens has ended normally
        return process_mod.EXIT_OK if role.stop.is_set() else sess
    with sess:
        where = ", ".join(args.listen) if args.listen else f"the endpoints of {args.config}"
        role.say(f"listening on {where}; stop it with Ctrl-C or SIGTERM")
        if args.auth is None and args.config is None:
            role.say(
                "no --auth: no logins and no access rules; anyone who reaches this port can join any run "
                "through it and drive its robots (swarm secure S --run ID writes a run's --auth)"
            )
        elif args.auth is None:
            role.say(
                f"no --auth: the access rules, logins and TLS are {args.config}'s, as it sets them "
                "(deploy/router.json5 denies everything until --auth gives a run's rules)"
            )
        wait_for(role.stop)
    role.say(f"{role.stopped_by()} after {time.monotonic() - started:.0f} s")
    return process_mod.EXIT_OK


if __name__ == "__main__":
    exit_after_main(main())
