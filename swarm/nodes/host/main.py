"""``swarm host``: one per machine that runs agents for runs started elsewhere.

    swarm host --connect tcp/ROUTER:7447 [--name NAME] [--robots 2,3] [--auth host-NAME.json]

A Zenoh client that holds the liveliness token ``swarmhost/NAME/alive`` and
answers the requests of protocol.hostmsg on ``swarmhost/NAME/ctl``: who it is
(host name, cores, free memory, package version, the robots it may run), and
start, signal, poll, collect (the log tail and stats of an agent) and end the
agents of a run (formation_swarm.nodes.host.runs). Agents are forked from the
spawner (formation_swarm.runtime.spawner) as ``swarm run`` forks them, each
with the login the launcher sent for it, and connect where the host does.

It outlives runs: its session retries the router for as long as it runs (the
router of a ``swarm run --hosts`` is that run's world), and it is let in by
each run's router with its own lasting login (``swarm secure --hosts``).

A run's agents are stopped (SIGTERM, then SIGKILL) when the launcher asks,
when the launcher's token goes (the launcher died or its machine left), when
that token has not come within ``--launcher-wait`` s of the run's first agent,
and when the host itself stops (SIGINT/SIGTERM). Requests from another package
version are refused, saying which.
"""

from __future__ import annotations

import shutil
import socket
import sys
import threading
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.common.version import __version__
from formation_swarm.nodes.host.runs import LAUNCHER_WAIT_S, Host
from formation_swarm.protocol import acl, session, tls, trust
from formation_swarm.protocol.keys import check_host_name
from formation_swarm.runtime import cliargs, spawner
from formation_swarm.runtime.proc import SIGNAL_CHECK_S, StopEvent, install_stop_handlers

DESCRIPTION = """\
Serve this machine to runs started elsewhere: connect to the router, announce
this host (a liveliness token and a queryable: its name, cores, free memory,
package version, the robots it may run) and start, watch and stop agents when
a launcher (swarm run --hosts) asks. It runs until SIGINT or SIGTERM, and
stops a run's agents when that run's launcher goes away."""
EPILOG = """\
examples:
  swarm host --connect tcp/192.168.1.10:7447 --name b --auth secure/host-b.json
  swarm host --connect tls/192.168.1.10:7447 --name c --robots 3,4 --auth host-c.json

exit codes: 0 stopped by SIGINT or SIGTERM; 1 the session could not be opened;
2 bad flags or credentials file."""


def default_name() -> str:
    """This machine's name as a host name (lowercase, letters, digits, '-')."""
    raw = socket.gethostname().split(".")[0].lower()
    name = "".join(ch if ch.isalnum() or ch == "-" else "-" for ch in raw).strip("-")[:27]
    return name if name and name[0].isalpha() else f"h{name}"[:27]


def _robot_ids(text: str) -> tuple[int, ...]:
    try:
        ids = tuple(sorted({int(p) for p in text.split(",") if p.strip()}))
    except ValueError:
        ids = ()
    if not ids or ids[0] < 1:
        raise ValueError(f"--robots must be robot ids separated by commas, e.g. 2,3, got {text!r}")
    return ids


def _own_workdir(workdir: Path) -> Any:
    """Lock ``workdir`` for this host process (an open file holding an
    exclusive flock, released when the process ends, however it ends);
    ValueError when another host holds it."""
    import fcntl

    try:
        workdir.mkdir(parents=True, exist_ok=True)
        lock = (workdir / ".lock").open("w")
    except OSError as exc:
        raise ValueError(f"--workdir {workdir}: cannot use it: {exc}") from None
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        raise ValueError(f"--workdir {workdir} is in use by another swarm host: give each its own") from None
    return lock


def _remove_stale_secrets(workdir: Path) -> int:
    """The runs' logins a host killed before its runs' end left behind (a run
    removes its own when it ends); with the workdir locked, none is in use."""
    stale = [d for d in workdir.glob("*/secrets") if d.is_dir()]
    for d in stale:
        shutil.rmtree(d, ignore_errors=True)
    return len(stale)


def _check_login(settings: dict[str, Any], name: str, path: str | None) -> None:
    """A login must be this host's (``host-NAME``): the run's router would let
    another one in only on another host's key, where no launcher asks for it.
    A credentials file without a login is no credentials file."""
    user = trust.login_user(settings)
    if path is not None and user is None:
        raise ValueError(
            f"--auth {path}: holds no login (transport/auth/usrpwd): give host-{name}.json of swarm secure --hosts"
        )
    if user is not None and user != acl.host_user(name):
        whose = f"host {user[5:]}" if str(user).startswith("host-") else f"user {user!r}, not a host's"
        raise ValueError(
            f"--auth {path}: this login is for {whose}, not for host {name} (--name): give the file of "
            f"host {name} (host-{name}.json of swarm secure --hosts) or --name to match"
        )


def open_session(conf: zenoh.Config, stop: StopEvent) -> zenoh.Session | None:
    """``zenoh.open(conf)``, or None once ``stop`` is set first. A client's open
    returns only when a router answered (here it retries for ever) and no signal
    handler runs meanwhile, so it runs on a thread of its own; one left behind
    by a stop is a daemon, ended with the process."""
    done = threading.Event()
    out: list[zenoh.Session] = []
    failed: list[zenoh.ZError] = []

    def run() -> None:
        try:
            out.append(zenoh.open(conf))
        except zenoh.ZError as exc:
            failed.append(exc)
        finally:
            done.set()

    threading.Thread(target=run, name="zenoh-open", daemon=True).start()
    while not stop.is_set() and not done.is_set():
        done.wait(SIGNAL_CHECK_S)
    if failed:
        raise failed[0]
    if out and not stop.is_set():
        return out[0]
    if out:  # opened as the stop came
        out[0].close()
    return None


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(prog="swarm host", description=DESCRIPTION, epilog=EPILOG)
    ap.add_argument(
        "--name",
        default=None,
        metavar="NAME",
        help="this host's name in swarm run --hosts: 1-27 lowercase letters, digits or '-' "
        "(default: the machine's host name)",
    )
    ap.add_argument(
        "--robots", default=None, metavar="IDS", help="the only robot ids this host may run, e.g. 2,3 (default: any)"
    )
    ap.add_argument(
        "--workdir",
        default=None,
        metavar="DIR",
        help="where the agents' scenario, logs and stats go, a folder per run (default: ~/.cache/swarm-host/NAME)",
    )
    ap.add_argument(
        "--launcher-wait",
        type=cliargs.seconds(),
        default=LAUNCHER_WAIT_S,
        metavar="S",
        help=f"stop a run's agents when its launcher's token has not appeared within S s of its "
        f"first agent (default: {LAUNCHER_WAIT_S:g})",
    )
    session.add_arguments(ap)
    return ap


def _configure(ap: cliargs.Parser, args: Any) -> tuple[str, tuple[int, ...] | None, dict[str, Any], zenoh.Config]:
    """The host's name, robots, login settings and Zenoh configuration from
    its flags; a bad one is a usage error (exit 2, through ``ap.error``)."""
    try:
        name = check_host_name(args.name or default_name())
        robots = _robot_ids(args.robots) if args.robots else None
        settings = trust.read_settings(args.auth) if args.auth else {}
        _check_login(settings, name, args.auth)
        if not args.connect and args.config is None:
            raise ValueError("--connect ENDPOINT: the router to serve runs through (scouting is off)")
        plain = [e for e in args.connect if not e.startswith("tls/") and not session.loopback(e)]
        if settings.get(tls.ROOT_CA) and plain:  # on this machine, a router's local endpoint may be tcp/
            raise ValueError(
                f"--connect {plain[0]}: this login ({args.auth}) names a CA, for TLS: connect with "
                "tls/ROUTER:PORT, or the agents' passwords would cross the network in clear"
            )
        conf = session.make_config("client", args.connect, config_file=args.config, settings=settings)
        # The router may come and go (a run's world is one): keep trying, in the background.
        conf.insert_json5("connect/exit_on_failure", "false")
        conf.insert_json5("connect/timeout_ms", "-1")
    except ValueError as exc:
        ap.error(str(exc))
    return name, robots, settings, conf


def _serve(sess: zenoh.Session, host: Host, stop: StopEvent, where: str) -> None:
    """Answer requests and watch the runs until ``stop``; then end every run."""
    queryable = sess.declare_queryable(host.keys.ctl)
    token = sess.liveliness().declare_token(host.keys.alive)
    robots = ", ".join(map(str, host.robots)) if host.robots else "any"
    host.say(f"connected to a router at {where}; serving robots {robots} (formation_swarm {__version__})")
    try:
        while not stop.is_set():
            query = queryable.try_recv()
            if query is not None:
                host.answer(query)
                continue
            host.watch()
            stop.wait(0.02)
    finally:
        for run in list(host.runs.values()):
            host.end(run, "the host stopped")
        token.undeclare()
        queryable.undeclare()


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    name, robots, settings, conf = _configure(ap, args)
    workdir = Path(args.workdir) if args.workdir else Path.home() / ".cache" / "swarm-host" / name
    try:
        lock = _own_workdir(workdir)  # held while this host runs
    except ValueError as exc:
        print(f"swarm host: {exc}", file=sys.stderr, flush=True)
        return 2
    if stale := _remove_stale_secrets(workdir):
        print(
            f"host {name}: removed the logins of {stale} run(s) a previous host process left in {workdir}", flush=True
        )
    stop = install_stop_handlers()
    spawner.warm()  # the agents' modules imported once, before any launcher waits for a start
    where = ", ".join(args.connect) or args.config
    # A router that refuses this host's login looks, from here, like no router: say so once.
    login = "" if not args.auth else "; a router that refuses this host's login (--auth) looks the same from here"
    print(f"host {name}: waiting for a router at {where} (retrying{login}); stop it with Ctrl-C or SIGTERM", flush=True)
    try:
        sess = open_session(conf, stop)
    except zenoh.ZError as exc:
        print(f"host {name}: cannot open a Zenoh session: {session.zenoh_reason(exc)}", file=sys.stderr, flush=True)
        return 1
    if sess is None:
        print(f"host {name}: stopped before a router answered", flush=True)
        return 0
    with sess:
        host = Host(
            sess,
            name,
            robots=robots,
            connect=list(args.connect),
            settings=settings,
            workdir=workdir,
            launcher_wait_s=args.launcher_wait,
        )
        _serve(sess, host, stop, where)
    host.say("stopped")
    lock.close()  # the workdir is free for the next host (an exit of any kind frees it too)
    return 0


if __name__ == "__main__":
    sys.exit(main())
