"""``swarm doctor``: would a run on these hosts start? Asked before it is.

    swarm doctor --listen tcp/0.0.0.0:7447 --hosts a,b --host-logins hosts.txt [--scenario S]
    swarm doctor --listen tls/0.0.0.0:7447 --hosts a,b --host-logins hosts.txt --tls-ca CA --tls-cert CERT --tls-key KEY
    swarm doctor --connect tcp/ROUTER:7447 --hosts a,b [--auth launcher.json]

With ``--listen`` it is the router, as ``swarm run --hosts --listen`` will be,
with the same rules, the hosts' logins and (``--tls-ca/--tls-cert/--tls-key``,
as ``swarm run`` takes them) the same TLS identity: a host it hears has reached
this address, trusted its certificate and had its login accepted. With
``--connect`` it asks through a router that runs already. For each host: is
its token there (it reached the router), the round trip of a query (the best
of three), its clock against this one (the host's time in its answer against
the middle of the round trip), its package version against this one, its
cores, free memory and the robots it may run; with ``--scenario``, whether
the hosts may run every robot of it. One line per host, then a verdict; exit
0 when a run would start, 1 when it would not (2 for bad flags).
"""

from __future__ import annotations

import sys
import tempfile
import time
import uuid
from pathlib import Path

import zenoh

from formation_swarm.common.version import __version__
from formation_swarm.launch import remote
from formation_swarm.protocol import session, trust
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import check_host_name
from formation_swarm.runtime import cliargs

CLOCK_WARN_S = 1.0  # lockstep does not need synchronised clocks; logs and realtime runs read better with them

DESCRIPTION = """\
Check, before a run, that the hosts of swarm run --hosts are there and fit:
who hears whom (each host and the router), the round-trip time of a query,
each host's clock offset against this machine, package versions, logins
accepted, cores, free memory and the robots each may run. Prints one line
per host and a verdict; exits 1 when a run would fail."""
EPILOG = """\
examples:
  swarm doctor --listen tcp/0.0.0.0:7447 --hosts a,b --host-logins secure/hosts.txt --scenario fig11_obstacles
  swarm doctor --listen tls/0.0.0.0:7447 --hosts a,b --host-logins secure/hosts.txt
               --tls-ca ca.pem --tls-cert router.pem --tls-key router.key
  swarm doctor --connect tcp/192.168.1.10:7447 --hosts a,b

exit codes: 0 a run would start; 1 it would not (the verdict says why); 2 bad flags."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(prog="swarm doctor", description=DESCRIPTION, epilog=EPILOG)
    ap.add_argument(
        "--hosts", required=True, metavar="NAME[,NAME...]", help="the hosts to check, by their swarm host --name"
    )
    ap.add_argument(
        "--host-logins",
        metavar="FILE",
        help="with --listen: the hosts' logins (hosts.txt of swarm secure --hosts), let in as a run's "
        "router would (default: no logins, for hosts started without --auth)",
    )
    ap.add_argument(
        "--scenario",
        metavar="SCENARIO",
        help="also check that the hosts may run every robot of this scenario (name or file)",
    )
    ap.add_argument(
        "--timeout",
        type=cliargs.seconds(600),
        default=15.0,
        metavar="SECONDS",
        help="how long to wait for the hosts to appear, in s (default: 15)",
    )
    session.add_arguments(ap)
    cliargs.add_tls_arguments(ap.add_argument_group("TLS on --listen tls/... (the files swarm run --hosts takes)"))
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        hosts = [check_host_name(h.strip()) for h in args.hosts.split(",") if h.strip()]
        if not hosts:
            raise ValueError("--hosts: give at least one host name")
        if bool(args.listen) == bool(args.connect):
            raise ValueError("give --listen ENDPOINT (be the router, as swarm run --hosts is) or --connect ENDPOINT")
        robots: tuple[int, ...] = (1,)
        if args.scenario:
            from formation_swarm.spec import scenario as scenario_mod

            sc = scenario_mod.load(args.scenario)
            robots = tuple(sc.robots)
        logins = trust.read_host_logins(args.host_logins, hosts) if args.host_logins else None
        tls = cliargs.tls(args)
        if tls is not None and not (logins and any(ep.startswith("tls/") for ep in args.listen)):
            raise ValueError("TLS files are for --listen tls/ADDRESS:PORT with --host-logins")
    except ValueError as exc:
        ap.error(str(exc))
    with tempfile.TemporaryDirectory(prefix="swarm-doctor-") as tmp:
        if args.listen:
            settings = None
            if logins is not None:  # the rules of a run: the hosts' logins let in, each on its own key
                files = trust.write_run_secrets(
                    Path(tmp) / "s",
                    f"doctor-{uuid.uuid4().hex[:8]}",
                    robots,
                    robots[0],
                    world="loopback",
                    tls=tls,
                    host_logins=logins,
                )
                settings = trust.read_settings(files["router"])
            conf = session.make_config("router", listen=args.listen, config_file=args.config, settings=settings)
            where = f"listening on {', '.join(args.listen)}"
        else:
            settings = trust.read_settings(args.auth) if args.auth else None
            conf = session.make_config(
                "client", args.connect, config_file=args.config, connect_timeout_s=args.timeout, settings=settings
            )
            where = f"connected to {', '.join(args.connect)}"
        try:
            sess = zenoh.open(conf)
        except zenoh.ZError as exc:
            print(f"swarm doctor: cannot open the session ({where}): {session.zenoh_reason(exc)}", flush=True)
            print("verdict: FAIL: no router (check --connect, that the router runs, and --auth)", flush=True)
            return 1
        with sess:
            return _check(sess, hosts, robots if args.scenario else None, args.timeout, where)


def _check(sess: zenoh.Session, hosts: list[str], robots: tuple[int, ...] | None, timeout_s: float, where: str) -> int:
    print(
        f"swarm doctor: {where}; formation_swarm {__version__}; waiting up to {timeout_s:g} s for hosts "
        f"{', '.join(hosts)}",
        flush=True,
    )
    clients = {h: remote.HostClient(sess, h) for h in hosts}
    deadline = time.monotonic() + timeout_s
    problems: list[str] = []
    infos: dict[str, HostReply] = {}
    for h, c in clients.items():
        if not c.present.wait(max(0.0, deadline - time.monotonic())):
            print(
                f"  host {h}: NOT HEARD: its token did not reach the router (check its --connect, the network "
                "and its login)",
                flush=True,
            )
            problems.append(f"host {h} not heard")
        elif (reply := _examine(h, c, problems)) is not None:
            infos[h] = reply
    for c in clients.values():
        c.close()
    if robots is not None and infos and len(infos) == len(hosts):
        try:
            placed = remote.place(robots, hosts, {h: i.robots for h, i in infos.items()}, {})
            print("  placement: " + ", ".join(f"robot {r} -> {h}" for r, h in placed.items()), flush=True)
        except ValueError as exc:
            problems.append(str(exc))
    if problems:
        print(f"verdict: FAIL: {'; '.join(problems)}", flush=True)
        return 1
    print(f"verdict: OK: a run on hosts {', '.join(hosts)} would start", flush=True)
    return 0


def _examine(h: str, c: remote.HostClient, problems: list[str]) -> HostReply | None:
    """Ask a host that is there about itself (three times: the quickest answer
    gives the round trip and the clock offset) and print what it says; its
    answer, or None (said, and added to ``problems``)."""
    best, reply, offset = float("inf"), None, 0.0
    for _ in range(3):
        t0, w0 = time.monotonic(), time.time()
        try:
            r = c.ask(HostRequest("info", __version__, sent_unix=w0), timeout_s=5.0)
        except remote.HostError as exc:
            print(f"  host {h}: heard, but {exc}", flush=True)
            problems.append(f"host {h}: {exc}")
            return None
        rtt = time.monotonic() - t0
        if rtt < best:
            best, reply, offset = rtt, r, r.time_unix - (w0 + rtt / 2)
    assert reply is not None  # three answers
    robots_text = "any robot" if reply.robots is None else "robots " + ",".join(map(str, reply.robots))
    flags = []
    if reply.version != __version__:
        flags.append(f"VERSION {reply.version} != {__version__}")
        problems.append(f"host {h} runs formation_swarm {reply.version}, here {__version__}")
    if abs(offset) > CLOCK_WARN_S:
        flags.append(f"clock off by {offset:+.2f} s (fine for lockstep; sync with NTP for readable logs)")
    print(
        f"  host {h}: heard; round trip {best * 1000:.1f} ms; clock {offset * 1000:+.0f} ms; version "
        f"{reply.version}; {reply.hostname}, {reply.cores} cores, {reply.free_mem_mb} MB free, "
        f"{reply.running} agents running; may run {robots_text}"
        f"{'; ' + '; '.join(flags) if flags else ''}",
        flush=True,
    )
    return reply


if __name__ == "__main__":
    sys.exit(main())
