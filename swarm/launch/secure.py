"""``swarm secure``: credentials and access rules for a run spread over machines.

Writes, for one scenario and run id, a folder with one login per role (the
world, the logger, the launcher, each robot's agent, and with --observer a
read-only one), the router's password list and access rules, and optionally
the TLS files: given (--tls-*), or made for the run with a certificate per
login (--mtls). Every file 0600, the folder 0700. Copy to each machine the
files its processes need.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from formation_swarm.launch import certs
from formation_swarm.protocol import acl, tls, trust
from formation_swarm.protocol.keys import check_host_name, check_run_id
from formation_swarm.runtime import cliargs

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

LOOPBACK = "127.0.0.1"  # where the world reaches the router, on its machine

DESCRIPTION = """\
Make the credentials and access rules of one run spread over machines: a
folder with a login per role (world.json, logger.json, launcher.json,
agent-N.json, and with --observer observer.json), the router's password list
and access rules (router.json), and with --tls-* the CA, certificate and key
for TLS links. Every file is readable by its owner only. A certificate given
(--tls-ca, --tls-cert) must be valid now: one expired or not valid yet is
refused, naming its date (TLS would refuse it, and clients find no router).

The router enforces the rules: without a login nothing connects, and each
login may only publish and subscribe what its role does (only agent N drives
robot N, only the leader sends formation codes, only the world ends the run;
the observer hears the whole run and can send nothing). The world's login
is granted over loopback only: start the world on the router's machine,
connected to its loopback address (127.0.0.1), so that the login is worth
nothing on any other machine; --world-anywhere lifts that.
Start each process with --auth FILE, its own file; copy to each machine only
the files its processes need. The passwords are fresh each time: make a new
folder for each run.

With --mtls (mutual TLS) it also makes a CA for this run alone, the
router's certificate naming --router-address (and 127.0.0.1, for the
world), and a certificate per login
(agent-2.pem and agent-2.key, ...) whose common name is the login's user.
The router then lets in only clients holding a certificate of that CA, and
grants each what its login may do only when the certificate's name is the
login's user: a password without its certificate's key, or a certificate
of another name, is granted nothing. The CA's key is discarded once every
certificate is signed: no other certificate can join the run."""

EPILOG = """\
examples:
  swarm secure fig11_obstacles --run field-1 --out secure-field-1
  swarm secure fig11_obstacles --run field-1 --out secure-field-1 \\
      --tls-ca ca.pem --tls-cert router.pem --tls-key router.key
  swarm secure fig11_obstacles --run field-1 --out secure-field-1 \\
      --mtls --router-address 192.168.1.10

then, on the router's machine and on each robot's (see deploy/README.md):
  swarm router --listen tls/0.0.0.0:7447 --auth secure-field-1/router.json
  swarm world --scenario fig11_obstacles --run field-1 --zenoh-mode client \\
      --connect tls/127.0.0.1:7447 --auth secure-field-1/world.json --auth-once \\
      --expect-logger --out runs/field-1
  swarm agent --id 2 --scenario fig11_obstacles --run field-1 \\
      --connect tls/ROUTER:7447 --auth secure-field-1/agent-2.json

(the world on the router's machine; a --tls-cert must name 127.0.0.1 or
localhost too, or give --world-anywhere)

exit codes: 0 written; 1 openssl failed (--mtls); 2 a bad command line,
scenario or TLS file, or a folder that already holds files (nothing
written)."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(prog="swarm secure", description=DESCRIPTION, epilog=EPILOG)
    ap.add_argument(
        "scenario", metavar="SCENARIO", nargs="?", help="a shipped scenario's name or a scenario file (TOML)"
    )
    ap.add_argument("--run", metavar="ID", help="the run id every process of the run will use")
    ap.add_argument(
        "--hosts",
        metavar="NAME[,NAME...]",
        help="instead of a run's logins: a lasting login per machine's swarm host (host-NAME.json, "
        "its --auth) and hosts.txt, swarm run --hosts's --host-logins",
    )
    ap.add_argument("--out", required=True, metavar="DIR", help="the folder to write (created; must be empty)")
    ap.add_argument(
        "--observer",
        action="store_true",
        help="also a read-only login, observer.json: it may subscribe to the whole run's keys and watch its "
        "liveliness tokens, and publish nothing (an operator's dashboard, your own monitor)",
    )
    ap.add_argument("--tls-ca", metavar="FILE", help="TLS: the CA certificate clients check the router against (PEM)")
    ap.add_argument("--tls-cert", metavar="FILE", help="TLS: the router's certificate, naming its host (PEM)")
    ap.add_argument("--tls-key", metavar="FILE", help="TLS: the router's private key (PEM)")
    ap.add_argument(
        "--tls-ca-key",
        metavar="FILE",
        help="with --mtls and --tls-ca: sign the run's certificates with your CA (its key, PEM; read, not "
        "copied) instead of a fresh one",
    )
    ap.add_argument(
        "--mtls",
        action="store_true",
        help="mutual TLS: make a CA for this run, the router's certificate and one per login (its common "
        "name the login's user); the router's rules then require both the password and the certificate "
        "(needs openssl; instead of --tls-cert and --tls-key)",
    )
    ap.add_argument(
        "--router-address",
        metavar="ADDR[,ADDR...]",
        help="with --mtls: the router's IP addresses or host names, as the others' tls/ endpoints give "
        "them (its certificate names them)",
    )
    ap.add_argument(
        "--world-anywhere",
        action="store_true",
        help="grant the world's login on any link, so the world may run on another machine than the router "
        "(default: over the router's loopback only, where a stolen copy of world.json is worth nothing)",
    )
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    from formation_swarm.spec import scenario as scenario_mod

    if args.hosts is not None:
        return _hosts(ap, args)
    if args.scenario is None or args.run is None:
        ap.error("give a SCENARIO and --run ID (or --hosts NAMES for the hosts' logins)")
    try:
        check_run_id(args.run)
    except ValueError as exc:
        ap.error(f"argument --run: {exc}")
    given, addresses = _tls_options(ap, args)
    world_at = _world_address(ap, args, given, addresses)
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        ap.error(f"argument --out: {out} already holds files; secrets are never overwritten: give a new folder")
    try:
        sc = scenario_mod.load(args.scenario)
    except ValueError as exc:
        ap.error(str(exc))
    users = list(acl.grants(args.run, sc.robots, sc.leader.robot_id, observer=args.observer))
    with tempfile.TemporaryDirectory(prefix="swarm-ca-") as made:  # the run's CA key, gone with it
        try:
            run_tls = certs.make_run_certificates(Path(made), users, addresses, given) if args.mtls else given
        except OSError as exc:
            print(f"swarm secure: cannot make the certificates: {exc}", file=sys.stderr)
            return 1
        try:
            files = trust.write_run_secrets(
                out,
                args.run,
                sc.robots,
                sc.leader.robot_id,
                world="anywhere" if args.world_anywhere else "loopback",
                tls=run_tls,
                observer=args.observer,
            )
        except OSError as exc:
            print(f"swarm secure: cannot write {out}: {exc}", file=sys.stderr)
            return cliargs.USAGE_ERROR
    _say_commands(args, sc, files, "tls" if run_tls else "tcp", world_at)
    return 0


def _world_address(ap: cliargs.Parser, args: argparse.Namespace, given: tls.Tls | None, addresses: list[str]) -> str:
    """Where the world connects to the router: "ROUTER" with --world-anywhere,
    else a loopback name the router's certificate names (with --mtls, 127.0.0.1
    is added to ``addresses``; a given --tls-cert must name one already)."""
    if args.world_anywhere:
        return "ROUTER"
    if args.mtls:
        addresses += [] if LOOPBACK in addresses else [LOOPBACK]
        return LOOPBACK
    names = tls.certificate_names(given.certificate) if given is not None else None
    if names is None:  # plain TCP, or this Python cannot tell: the world's connect will
        return LOOPBACK
    for name in (LOOPBACK, "::1", "localhost"):
        if name in names:
            return f"[{name}]" if ":" in name else name
    ap.error(
        f"argument --tls-cert: {args.tls_cert} names {', '.join(sorted(names)) or 'no address'}, not 127.0.0.1 or "
        "localhost: the world's login is granted over the router's loopback only, so the world connects there; "
        "add IP:127.0.0.1 to the certificate's names, or give --world-anywhere"
    )


def _tls_options(ap: cliargs.Parser, args: argparse.Namespace) -> tuple[tls.Tls | None, list[str]]:
    """The TLS files given: the CA and the router's certificate and key, or
    with --mtls the CA to sign with (or none) and the router's addresses."""
    if args.mtls:
        return _mtls_options(ap, args)
    if args.router_address or args.tls_ca_key:
        ap.error("arguments --router-address and --tls-ca-key: only with --mtls")
    tls_files = (args.tls_ca, args.tls_cert, args.tls_key)
    if any(tls_files) and not all(tls_files):
        ap.error("arguments --tls-ca, --tls-cert and --tls-key: give all three or none")
    if not any(tls_files):
        return None, []
    try:
        tls.check_certificate(args.tls_ca, "--tls-ca")
        tls.check_certificate(args.tls_cert, "--tls-cert")
        tls.check_key(args.tls_cert, args.tls_key, "--tls-key")
        certs.check_dates(args.tls_ca, "--tls-ca")
        certs.check_dates(args.tls_cert, "--tls-cert")
    except ValueError as exc:
        ap.error(str(exc))
    return tls.Tls(Path(args.tls_ca), Path(args.tls_cert), Path(args.tls_key)), []


def _mtls_options(ap: cliargs.Parser, args: argparse.Namespace) -> tuple[tls.Tls | None, list[str]]:
    """With --mtls: your CA to sign with (--tls-ca and --tls-ca-key; its key
    stands in for the router's), else None; the router's addresses."""
    if args.tls_cert or args.tls_key:
        ap.error("argument --mtls: it makes the router's certificate; give no --tls-cert or --tls-key")
    if bool(args.tls_ca) != bool(args.tls_ca_key):
        ap.error("arguments --tls-ca and --tls-ca-key: with --mtls, give both (your CA) or neither (a fresh one)")
    if not args.router_address:
        ap.error("argument --mtls: give --router-address ADDR, the router's address in the others' tls/ endpoints")
    if problem := certs.openssl_missing():
        ap.error(f"argument --mtls: {problem}")
    addresses = [a.strip() for a in args.router_address.split(",") if a.strip()]
    try:
        for a in addresses:
            certs.subject_alt_name(a)
    except ValueError as exc:
        ap.error(f"argument --router-address: {exc}")
    if not args.tls_ca:
        return None, addresses
    try:
        tls.check_certificate(args.tls_ca, "--tls-ca")
        tls.check_key(args.tls_ca, args.tls_ca_key, "--tls-ca-key")
        certs.check_dates(args.tls_ca, "--tls-ca")
    except ValueError as exc:
        ap.error(str(exc))
    return tls.Tls(Path(args.tls_ca), Path(args.tls_ca), Path(args.tls_ca_key)), addresses


def _say_commands(args: argparse.Namespace, sc: Scenario, files: dict[str, Path], scheme: str, world_at: str) -> None:
    """What was written, and each process's command line with its login."""
    print(f"swarm secure: run {args.run} ({sc.name}, robots {', '.join(map(str, sc.robots))}): wrote {args.out}/")
    print(f"  router:   swarm router --listen {scheme}/0.0.0.0:7447 --auth {files['router']}")
    common = f"--scenario {args.scenario} --run {args.run}"
    print(
        f"  world:    swarm world {common} --zenoh-mode client --connect {scheme}/{world_at}:7447 "
        f"--auth {files['world']} --auth-once --expect-logger --out runs/{args.run}"
        + ("" if args.world_anywhere else "  (on the router's machine: granted there only)")
    )
    print(
        f"  logger:   swarm logger {common} --out recording.rrd --connect {scheme}/ROUTER:7447 --auth {files['logger']}"
    )
    for rid in sc.robots:
        print(
            f"  agent {rid}:  swarm agent --id {rid} {common} --connect {scheme}/ROUTER:7447 "
            f"--auth {files[acl.agent_user(rid)]}"
        )
    if args.observer:
        observer = files[acl.OBSERVER]
        print(f"  observer: --connect {scheme}/ROUTER:7447 --auth {observer} (hears the whole run, sends nothing)")
    if args.mtls:
        signer = (
            f"your CA {args.tls_ca} signed them: keep its key off the network"
            if args.tls_ca
            else f"the CA's key is gone, so no other certificate joins run {args.run}"
        )
        print(
            f"  each login's own certificate is beside it (agent-2.json: agent-2.pem, agent-2.key): copy the three "
            f"and {tls.CA} to its machine; {signer}"
        )
    if scheme != "tls":
        print("  links are plain TCP: the run's data crosses the network unencrypted; see deploy/README.md for TLS")


def _hosts(ap: cliargs.Parser, args: argparse.Namespace) -> int:
    names = [n.strip() for n in args.hosts.split(",") if n.strip()]
    try:
        for n in names:
            check_host_name(n)
    except ValueError as exc:
        ap.error(f"argument --hosts: {exc}")
    if not names or len(set(names)) != len(names):
        ap.error(f"argument --hosts: distinct host names separated by commas, got {args.hosts!r}")
    run_options = (args.scenario, args.run, args.tls_cert, args.tls_key, args.observer, args.mtls, args.router_address)
    if any(run_options) or args.world_anywhere:
        ap.error(
            "argument --hosts: takes no SCENARIO, --run, --observer, --tls-cert, --tls-key, --mtls, "
            "--router-address or --world-anywhere (only --tls-ca)"
        )
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        ap.error(f"argument --out: {out} already holds files; secrets are never overwritten: give a new folder")
    if args.tls_ca and not Path(args.tls_ca).is_file():
        ap.error(f"argument --tls-ca: no such file: {args.tls_ca}")
    try:
        if args.tls_ca:
            certs.check_dates(args.tls_ca, "--tls-ca")
    except ValueError as exc:
        ap.error(str(exc))
    files = trust.write_host_logins(out, names, Path(args.tls_ca) if args.tls_ca else None)
    scheme = "tls" if args.tls_ca else "tcp"
    print(f"swarm secure: logins for hosts {', '.join(names)}: wrote {out}/")
    for n in names:
        print(f"  host {n}:  swarm host --name {n} --connect {scheme}/ROUTER:7447 --auth {files[acl.host_user(n)]}")
    tls = " --tls-ca CA --tls-cert CERT --tls-key KEY" if args.tls_ca else ""
    print(
        f"  swarm run S --hosts {','.join(names)} --listen {scheme}/0.0.0.0:7447 --host-logins "
        f"{files[trust.HOST_LOGINS]}{tls}"
    )
    if args.tls_ca:
        print(f"  copy {out / trust.CA} beside each host-NAME.json: the login names it relative to itself")
    else:
        print(
            "  links are plain TCP: each run sends the hosts its agents' passwords, and its data, unencrypted; "
            "see deploy/README.md for TLS (--tls-ca)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
