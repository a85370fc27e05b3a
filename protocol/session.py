"""One helper builds the zenoh.Config of every process from the same flags.

    --zenoh-mode client|peer|router   (default: client)
    --connect ENDPOINT          (repeatable), e.g. tcp/127.0.0.1:7447
    --listen ENDPOINT           (repeatable)
    --config FILE               a Zenoh JSON5 configuration, applied first

Multicast scouting is off unless a configuration file turns it on: endpoints
are explicit (a full mesh of peers does not scale, docs in DESIGN).

Zenoh's low-latency unicast transport is on (QoS priorities off, which it
requires): the thread that puts a message writes it to the link, with no
batching queue and no transmit thread in between. A Fig. 11 lockstep run
takes about 20% less CPU per tick with it (bench/lockstep.py gives the
rates). Both ends of a link must enable it; a node that does not gets the
default transport on that link, and both work together.

That transport has no fragmentation: a frame above the link's limit (49,152
bytes, measured with eclipse-zenoh 1.10.2) makes the receiver close the whole
link. Forwarded by a router to an agent, one such message would cut the agent
off and the world would take its robot for dead. So every node drops, on the
way in, any message above ``ROUTED_LIMIT_BYTES`` (a Zenoh low-pass filter),
and no message of ours comes near it (protocol.codec.MAX_PAYLOAD_BYTES).

Shared memory is off: a peer's large messages would otherwise arrive in its
16 MB pool, which the receiver maps and keeps for good (swarm.runtime.memory).

A configuration file replaces these defaults (scouting, transport, filter,
shared memory): deploy/router.json5 sets them for a standalone router.
"""

from __future__ import annotations

import argparse
import ipaddress
import json
import re
import socket
from collections.abc import Mapping, Sequence
from typing import Any

import zenoh

from formation_swarm.protocol import tls, trust
from formation_swarm.protocol.codec import MAX_PAYLOAD_BYTES

# Above our own limit, so an oversized payload still reaches the decoder and is
# counted; below the low-latency transport's 49,152-byte frame, headers included.
ROUTED_LIMIT_BYTES = 40 * 1024
assert MAX_PAYLOAD_BYTES < ROUTED_LIMIT_BYTES
SIZE_FILTER = {
    "id": "size",
    "flows": ["ingress"],
    "messages": ["put", "delete", "query", "reply"],
    "key_exprs": ["**"],
    "size_limit": ROUTED_LIMIT_BYTES,
}


def add_arguments(parser: argparse.ArgumentParser, default_mode: str = "client") -> None:
    group = parser.add_argument_group("Zenoh session")
    group.add_argument(
        "--zenoh-mode",
        choices=("client", "peer", "router"),
        default=default_mode,
        help=f"client: connect to a router (--connect); router: be one (--listen); peer: connect to "
        f"and listen for other peers directly (default {default_mode})",
    )
    group.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="a router to connect to, e.g. tcp/192.168.1.10:7447 (repeatable; a client needs one)",
    )
    group.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="an endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)",
    )
    group.add_argument(
        "--auth",
        metavar="FILE",
        help="this process's credentials (a router's: the password list and access rules), a JSON file "
        "of Zenoh settings readable by its owner only; swarm run writes one per process, swarm secure "
        "writes them for several machines (default: no authentication)",
    )
    group.add_argument(
        "--auth-once",
        action="store_true",
        help="delete the --auth file once the session is open (a router's: its password list and TLS key "
        "too): for one-run logins, as swarm run gives its processes",
    )
    group.add_argument(
        "--config",
        metavar="FILE",
        help="a Zenoh JSON5 configuration file; it replaces this program's defaults "
        "(multicast scouting off, low-latency transport, 40 KiB size filter)",
    )


_RUST_PLACE = re.compile(r" at /\S+?\.rs:\d+\.?")


def zenoh_reason(exc: BaseException) -> str:
    """A Zenoh error's message without the Rust source places it appends (" at
    /root/.cargo/.../tcp.rs:61."), which say nothing to a user."""
    return _RUST_PLACE.sub("", str(exc)).strip()


def check_endpoint(ep: Any) -> str:
    """``ep`` if it reads as a Zenoh endpoint (PROTOCOL/ADDRESS, a port in
    [1, 65535] for tcp, tls, udp and quic), else ValueError saying why."""
    if not isinstance(ep, str) or "/" not in ep:
        raise ValueError(f"endpoint must look like tcp/HOST:PORT, got {ep!r}")
    port = ep.split("#", 1)[0].rpartition(":")[2]
    if ep.split("/", 1)[0] in ("tcp", "tls", "udp", "quic") and not (port.isdigit() and 0 < int(port) < 65536):
        raise ValueError(f"endpoint {ep!r}: the port must be a number in [1, 65535]")
    return ep


def loopback(ep: str) -> bool:
    """Whether an endpoint's address is this machine's loopback (127.0.0.0/8, ::1, localhost)."""
    host = ep.split("/", 1)[-1].split("#", 1)[0].rpartition(":")[0].strip("[]")
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


def listen_problem(ep: str) -> str | None:
    """Why this process cannot listen on a tcp or tls endpoint (the port taken,
    the address not this machine's), or None; other protocols are not tried."""
    proto, _, rest = check_endpoint(ep).split("#", 1)[0].partition("/")
    if proto not in ("tcp", "tls"):
        return None
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    try:
        with socket.socket(family, socket.SOCK_STREAM) as sock:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as Zenoh's listener does
            sock.bind((host, int(port)))
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


def make_config(
    mode: str = "client",
    connect: Sequence[str] = (),
    *,
    listen: Sequence[str] = (),
    config_file: str | None = None,
    connect_timeout_s: float = 30.0,
    lowlatency: bool = True,
    settings: Mapping[str, Any] | None = None,
) -> zenoh.Config:
    """``lowlatency=False`` keeps Zenoh's default transport (the benchmark's bare
    exchange); it and the size filter are only set without a configuration file.
    With a tls/ endpoint, the TLS files of the configuration are checked first
    (protocol.tls): a missing one, or a key not its certificate's, is a
    ValueError naming the file."""
    if mode not in ("client", "peer", "router"):
        raise ValueError(f"mode must be client, peer or router, got {mode!r}")
    for ep in (*connect, *listen):
        check_endpoint(ep)
    if mode == "client" and not connect and config_file is None:
        raise ValueError("a client needs --connect ENDPOINT (scouting is off)")
    try:
        conf = zenoh.Config.from_file(config_file) if config_file else zenoh.Config()
    except zenoh.ZError as exc:
        raise ValueError(
            f"--config {config_file}: not a Zenoh configuration Zenoh accepts: {zenoh_reason(exc)}"
        ) from None
    conf.insert_json5("mode", json.dumps(mode))
    if config_file is None:
        conf.insert_json5("scouting/multicast/enabled", "false")
        if lowlatency:
            conf.insert_json5("transport/unicast/lowlatency", "true")
            conf.insert_json5("transport/unicast/qos/enabled", "false")
        conf.insert_json5("low_pass_filter", json.dumps([SIZE_FILTER]))
        # No shared memory: a message above 3 kB from a peer on this machine would
        # come in its 16 MB pool, which this process then maps and keeps (a flood
        # made every receiver hold that much more, for good); over TCP it is copied.
        conf.insert_json5("transport/shared_memory/enabled", "false")
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
        # The router may start after us: retry for a while instead of failing at once.
        conf.insert_json5("connect/timeout_ms", json.dumps(int(connect_timeout_s * 1000)))
        conf.insert_json5("connect/retry", '{"period_init_ms": 50, "period_max_ms": 500, "period_increase_factor": 2}')
    if listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    for path, value in (settings or {}).items():  # credentials and access rules (protocol.trust)
        try:
            conf.insert_json5(path, json.dumps(value))
        except zenoh.ZError as exc:
            raise ValueError(f"invalid Zenoh setting {path}: {zenoh_reason(exc)}") from None
    if any(ep.startswith(("tls/", "quic/")) for ep in _endpoints(conf)):
        tls.check_files(json.loads(conf.get_json(tls.SECTION)), mode)
    return conf


def _endpoints(conf: zenoh.Config) -> list[str]:
    """Every endpoint a configuration connects to or listens on (a list, or one per mode)."""
    out: list[str] = []
    for path in ("connect/endpoints", "listen/endpoints"):
        value = json.loads(conf.get_json(path))
        for eps in value.values() if isinstance(value, dict) else [value]:
            out += [e for e in eps if isinstance(e, str)] if isinstance(eps, list) else []
    return out


def config_from_args(args: argparse.Namespace, connect_timeout_s: float = 30.0) -> zenoh.Config:
    settings = trust.read_settings(args.auth) if args.auth else None
    return make_config(
        args.zenoh_mode,
        args.connect,
        listen=args.listen,
        config_file=args.config,
        connect_timeout_s=connect_timeout_s,
        settings=settings,
    )
