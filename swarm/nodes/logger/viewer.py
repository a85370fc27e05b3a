"""Where a run's live data can be watched: the served web viewer's address,
and whether a viewer answers at a --live address. No Rerun import: the
launcher uses it too.
"""

from __future__ import annotations

import socket
import urllib.parse

PROBE_TIMEOUT_S = 1.0


def grpc_address(grpc_port: int) -> str:
    """The logger's gRPC server (--serve-web), as a Rerun viewer connects to it."""
    return f"rerun+http://127.0.0.1:{grpc_port}/proxy"


def web_address(grpc_port: int, web_port: int) -> str:
    """The one address that opens the served web viewer on the run's data
    (the form Rerun 0.41's own ``rerun --serve-web`` prints)."""
    return f"http://127.0.0.1:{web_port}/?url={urllib.parse.quote(grpc_address(grpc_port), safe='')}"


def unreachable(url: str, timeout_s: float = PROBE_TIMEOUT_S) -> str | None:
    """Why no viewer answers at ``url`` (rerun+http://HOST:PORT/proxy), or None
    when something accepts a connection there. Rerun's own sink would retry
    an absent viewer for seconds at its start and again at its end."""
    parts = urllib.parse.urlsplit(url)
    if not parts.hostname or parts.port is None:
        return f"not a viewer address like rerun+http://HOST:PORT/proxy: {url!r}"
    try:
        with socket.create_connection((parts.hostname, parts.port), timeout=timeout_s):
            return None
    except OSError as exc:  # refused, timed out, no route, unknown host
        return exc.strerror or str(exc) or type(exc).__name__


def port_taken(port: int) -> str | None:
    """Why ``port`` cannot be served on (something listens there), or None.
    Rerun's web viewer binds every address; its gRPC server 127.0.0.1."""
    from formation_swarm.protocol.session import listen_problem

    return listen_problem(f"tcp/0.0.0.0:{port}")
