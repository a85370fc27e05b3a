"""The Zenoh session configuration a ROS 2 node (rmw_zenoh) needs to join a
swarm run: a client of the run's router, logged in with the login that
``swarm run --ros2 --ros2-login FILE`` writes.

    python3 session_config.py runs/ros2.json ENDPOINT runs/swarm_session.json5
    export ZENOH_SESSION_CONFIG_URI=$PWD/runs/swarm_session.json5

ENDPOINT is the router's, as swarm run prints it (tcp/HOST:PORT, or tls/...
with the run's CA, which the login names). The login is a JSON object of
Zenoh settings by path ("transport/auth/usrpwd": {...}); they are nested
into the configuration. Multicast scouting is off: the router is the only
way in. The file is JSON, which JSON5 reads; it holds the password, so it is
written readable by its owner only.
"""

from __future__ import annotations

import json
import os
import sys
from typing import Any


def session_config(login: dict[str, Any], endpoint: str) -> dict[str, Any]:
    """The configuration, as a dict: client mode, the endpoint, the login's settings."""
    if not isinstance(login, dict) or "transport/auth/usrpwd" not in login:
        raise ValueError("the login must be a JSON object with transport/auth/usrpwd (swarm run --ros2-login)")
    if "/" not in endpoint:
        raise ValueError(f"the endpoint must read PROTOCOL/HOST:PORT, e.g. tcp/127.0.0.1:7447, got {endpoint!r}")
    conf: dict[str, Any] = {
        "mode": "client",
        "connect": {"endpoints": [endpoint]},
        "scouting": {"multicast": {"enabled": False}},
    }
    for path, value in login.items():
        *parents, leaf = path.split("/")
        node = conf
        for name in parents:
            node = node.setdefault(name, {})
        node[leaf] = value
    return conf


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    try:
        with open(argv[0]) as f:
            login = json.load(f)
        conf = session_config(login, argv[1])
        fd = os.open(argv[2], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(json.dumps(conf, indent=2) + "\n")
        os.chmod(argv[2], 0o600)
    except (OSError, ValueError) as exc:
        print(f"session_config: {exc}", file=sys.stderr)
        return 2
    print(f"{argv[2]}: a client of {argv[1]}, logged in as {login['transport/auth/usrpwd'].get('user')}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
