"""``swarm router``: a Zenoh router for agents on other machines.

    swarm router --listen tcp/0.0.0.0:7447

Runs until SIGINT/SIGTERM. Start the world with ``--zenoh-mode client --connect``
to it (or let the world be the router, the default) and agents anywhere
with ``--connect tcp/ROUTER_HOST:7447``.
"""

from __future__ import annotations

import argparse
import sys

import zenoh

from formation_swarm.proc import install_stop_handlers
from formation_swarm.protocol import session


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="swarm router", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    session.add_arguments(ap, default_mode="router")
    args = ap.parse_args(argv)
    if not args.listen and args.config is None:
        args.listen = ["tcp/0.0.0.0:7447"]
    stop = install_stop_handlers()
    try:
        conf = session.config_from_args(args)
        sess_cm = zenoh.open(conf)
    except (ValueError, zenoh.ZError) as exc:
        print(f"router: {exc}", file=sys.stderr)
        return 2
    with sess_cm:
        where = ", ".join(args.listen) if args.listen else f"the endpoints of {args.config}"
        print(f"router listening on {where}", flush=True)
        while not stop.wait(0.5):
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
