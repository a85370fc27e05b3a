"""Logins: one identity per process of a run, and the files that hold them.

Every process of a run authenticates to the router with its own user name and
password (Zenoh's usrpwd authentication); the router holds the password list
and the access rules of protocol.acl. A client without credentials cannot
connect at all; one holding a role's credentials can only do what that role
does. A login file is a JSON object of Zenoh settings, readable by its owner
only; the router's names its password list and rules.

A host's login outlives runs (``swarm secure --hosts``): the launcher adds it
to the run's password list and rules (``host_logins``).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from formation_swarm.protocol import tls as tls_mod
from formation_swarm.protocol.acl import RosAccess, access_control, grants, host_user
from formation_swarm.protocol.tls import CA, CERTIFICATE, PRIVATE_KEY, Tls

_USER = re.compile(r"^[a-z][a-z0-9-]{0,31}$")
PASSWORDS = "passwords.txt"  # the router's list of user:password, one per line


@dataclass(frozen=True)
class Credential:
    user: str
    password: str

    def __post_init__(self) -> None:
        if not isinstance(self.user, str) or not _USER.match(self.user):
            raise ValueError(f"user must be 1-32 lowercase letters, digits or '-', got {self.user!r}")
        if not isinstance(self.password, str) or len(self.password) < 16 or ":" in self.password:
            raise ValueError("password must be at least 16 characters without ':'")

    def __repr__(self) -> str:  # never print a password
        return f"Credential(user={self.user!r}, password=***)"


def login_user(settings: Mapping[str, Any]) -> str | None:
    """The user a process's credentials log in as (None: no login in them)."""
    login = settings.get("transport/auth/usrpwd")
    user = login.get("user") if isinstance(login, Mapping) else None
    return user if isinstance(user, str) else None


def new_credentials(users: Iterable[str]) -> dict[str, Credential]:
    """A fresh random password for each user (192 bits each)."""
    return {u: Credential(u, secrets.token_urlsafe(24)) for u in users}


def _write_private(path: Path, text: str) -> None:
    """Create ``path`` readable by its owner only (0600), never visible with wider rights."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.chmod(path, 0o600)


def client_settings(cred: Credential, ca: str | None = None, *, own_certificate: bool = False) -> dict[str, Any]:
    """Zenoh settings (path -> value) that make a session log in as ``cred``
    (and, with ``ca``, accept only a router certified by it; with
    ``own_certificate`` too, present ``<user>.pem``, mutual TLS)."""
    out: dict[str, Any] = {"transport/auth/usrpwd": {"user": cred.user, "password": cred.password}}
    if ca:
        out |= tls_mod.client_settings(ca, tls_mod.client_files(cred.user) if own_certificate else None)
    return out


def router_settings(
    dictionary: str, acl: dict[str, Any], tls: tuple[str, str] | None = None, client_ca: str | None = None
) -> dict[str, Any]:
    """Zenoh settings for the run's router: who may log in, and what each may do
    (and, with ``tls`` = (certificate, key), its TLS identity; with
    ``client_ca`` too, the CA every client's own certificate must be from)."""
    out: dict[str, Any] = {"transport/auth/usrpwd": {"dictionary_file": dictionary}, "access_control": acl}
    if tls:
        out |= tls_mod.router_settings(*tls, client_ca)
    return out


WORLD_PLACES = ("router", "loopback", "anywhere")  # write_run_secrets's world: where its login is granted


def write_run_secrets(  # noqa: PLR0913 -- past the fourth, keywords only
    folder: Path,
    run_id: str,
    robots: Sequence[int],
    leader_id: int,
    *,
    world: str = "router",
    tls: Tls | None = None,
    host_logins: dict[str, Credential] | None = None,
    observer: bool = False,
    ros2: RosAccess | None = None,
) -> dict[str, Path]:
    """Fresh credentials for every role of a run, in ``folder`` (0700, files 0600):
    ``<user>.json`` for each client, ``router.json`` for the router, which
    names the password list beside it. ``world`` (:data:`WORLD_PLACES`):
    "router", the world is the router (a local run) and logs in as nobody,
    so no "world" login exists to be stolen; "loopback", its login is granted
    its keys over loopback only, on the router's machine (acl.access_control's
    ``local``), and so is the logger's in a run placed on hosts
    (``host_logins``: its router is the launcher, the logger beside it);
    "anywhere", on any link. With ``tls``, the CA, the router's certificate
    and key are copied in too. Files name each other relative to the folder.
    ``host_logins`` (host name -> its lasting login, :func:`read_host_logins`)
    are let in too, with their rules; they get no file here (each host has its own).
    ``observer``: an ``observer`` login too (:data:`OBSERVER`); ``ros2``: the
    ROS 2 bridge's login and, if it says so, a ROS node's (acl.RosAccess).
    With ``tls.clients`` (mutual TLS), each login's certificate and key are
    copied in as ``<user>.pem``/``.key`` and named by its login, and the
    router's rules require both the user and the certificate's common name.
    Returns the settings file of each user and of "router"."""
    if world not in WORLD_PLACES:
        raise ValueError(f"world: one of {', '.join(WORLD_PLACES)}, got {world!r}")
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    hosts = sorted(host_logins or {})
    everyone = grants(run_id, robots, leader_id, observer=observer, ros2=ros2)
    users = [u for u in everyone if not (world == "router" and u == "world")]
    clients = tls.clients if tls is not None else None
    mtls = clients is not None
    if clients is not None and (host_logins or any(u not in clients for u in users)):
        missing = [u for u in users if u not in clients]
        raise ValueError(f"mutual TLS: no certificate for {', '.join(missing or sorted(host_logins or {}))}")
    creds = new_credentials(users)
    logins = [*creds.values(), *(host_logins or {}).values()]
    _write_private(folder / PASSWORDS, "".join(f"{c.user}:{c.password}\n" for c in logins))
    if tls is not None:
        _copy_tls_files(folder, tls, users)
    out: dict[str, Path] = {}
    for user, cred in creds.items():
        out[user] = folder / f"{user}.json"
        login = client_settings(cred, CA if tls else None, own_certificate=mtls)
        _write_private(out[user], json.dumps(login, indent=1))
    out["router"] = folder / "router.json"
    local = (("world", "logger") if host_logins else ("world",)) if world == "loopback" else ()
    acl = access_control(run_id, robots, leader_id, hosts, observer=observer, mtls=mtls, local=local, ros2=ros2)
    router = router_settings(PASSWORDS, acl, (CERTIFICATE, PRIVATE_KEY) if tls else None, CA if mtls else None)
    _write_private(out["router"], json.dumps(router, indent=1))
    return out


def _copy_tls_files(folder: Path, tls: Tls, users: Sequence[str]) -> None:
    """The CA, the router's certificate and key and, with mutual TLS, each
    user's certificate and key, copied into ``folder``."""
    for name, src in ((CA, tls.ca), (CERTIFICATE, tls.certificate), (PRIVATE_KEY, tls.private_key)):
        _write_private(folder / name, Path(src).read_text())
    for user in users if tls.clients is not None else ():
        for name, src in zip(tls_mod.client_files(user), tls.clients[user], strict=True):
            _write_private(folder / name, Path(src).read_text())


def forget_router_secrets(folder: Path) -> None:
    """Remove from a run's secrets what lasts beyond it, once the router has read
    it (Zenoh reads both when its session opens): the password list, which
    holds the hosts' lasting logins, and the copy of the router's TLS key. A
    launcher killed with SIGKILL cannot remove its secrets at the end; these
    are the ones worth stealing from a run folder it leaves."""
    for name in (PASSWORDS, PRIVATE_KEY):
        with contextlib.suppress(FileNotFoundError):
            (folder / name).unlink()


def write_settings(path: Path, settings: Mapping[str, Any]) -> Path:
    """A login (settings as :func:`read_settings` gives them) written to ``path``,
    0600: a fresh file for a process started again with a login it read before."""
    _write_private(path, json.dumps(dict(settings), indent=1))
    return path


# A router's settings that name files with secrets in them: gone with the settings once read.
# Not a client's own TLS key: Zenoh reads it again for each link it opens, and a
# client whose link broke reconnects.
_SECRET_FILES = ("dictionary_file", "listen_private_key")


def forget_login(path: str | Path) -> None:
    """Delete a process's login once its session is open (``--auth-once``: a
    run's one-run logins, which nothing needs again): the file, and for a
    router's the password list and TLS key it names (Zenoh read them when the
    session opened). A stolen copy of the run folder then holds no password."""
    p = Path(path)
    named: list[Path] = []
    with contextlib.suppress(ValueError):
        named = [Path(v) for k, v in _flat(read_settings(p)) if k in _SECRET_FILES and isinstance(v, str)]
    for f in (*named, p):
        with contextlib.suppress(FileNotFoundError):
            f.unlink()


def _flat(data: Any) -> list[tuple[str, Any]]:
    """(last path segment, value) of every setting, nested objects included."""
    out: list[tuple[str, Any]] = []
    if isinstance(data, dict):
        for key, value in data.items():
            out += _flat(value) if isinstance(value, dict) else [(str(key).rsplit("/", 1)[-1], value)]
    return out


HOST_LOGINS = "hosts.txt"  # swarm secure --hosts: the hosts' logins, user:password a line, for swarm run


def write_host_logins(folder: Path, names: Sequence[str], tls_ca: Path | None = None) -> dict[str, Path]:
    """A lasting login for each machine's ``swarm host``: ``host-NAME.json``
    (its --auth) and ``hosts.txt``, the list ``swarm run --host-logins`` takes
    (the run's router lets them in). Files 0600, the folder 0700."""
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    creds = new_credentials(host_user(n) for n in names)
    _write_private(folder / HOST_LOGINS, "".join(f"{c.user}:{c.password}\n" for c in creds.values()))
    if tls_ca is not None:
        _write_private(folder / CA, Path(tls_ca).read_text())
    out = {HOST_LOGINS: folder / HOST_LOGINS}
    for cred in creds.values():
        out[cred.user] = folder / f"{cred.user}.json"
        _write_private(out[cred.user], json.dumps(client_settings(cred, CA if tls_ca else None), indent=1))
    return out


def read_host_logins(path: str | Path, names: Sequence[str]) -> dict[str, Credential]:
    """The logins of the hosts ``names`` from a ``hosts.txt`` (user:password a
    line, 0600); ValueError naming a host that has none."""
    p = Path(path)
    try:
        mode = p.stat().st_mode
        lines = p.read_text().splitlines()
    except OSError as exc:
        raise ValueError(f"cannot read the hosts' logins {p}: {exc}") from None
    if mode & 0o077:
        raise ValueError(f"{p} is readable by other users (mode {mode & 0o777:o}): chmod 600 {p}")
    if lines and lines[0].lstrip().startswith("{"):
        raise ValueError(
            f"{p} is a JSON file (a process's login?), not the hosts' list of user:password lines: "
            f"give {HOST_LOGINS} of swarm secure --hosts"
        )
    known: dict[str, Credential] = {}
    for n, line in enumerate(lines, 1):
        user, sep, password = line.strip().partition(":")
        if sep:
            try:
                known[user] = Credential(user, password)
            except ValueError as exc:
                raise ValueError(f"{p}, line {n}: {exc}") from None
    missing = [n for n in names if host_user(n) not in known]
    if missing:
        raise ValueError(f"{p} has no login for host {', '.join(missing)} (swarm secure --hosts writes them)")
    return {n: known[host_user(n)] for n in names}


def read_settings(path: str | Path) -> dict[str, Any]:
    """A settings file written by ``write_run_secrets`` (or by hand): a JSON object
    of Zenoh configuration paths and values. Refused when others may read it."""
    p = Path(path)
    try:
        mode = p.stat().st_mode
        data = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read the credentials file {p}: {exc}") from None
    if mode & 0o077:
        raise ValueError(f"{p} is readable by other users (mode {mode & 0o777:o}): chmod 600 {p}")
    if not isinstance(data, dict) or not all(isinstance(key, str) for key in data):
        raise ValueError(f"{p} must hold a JSON object of Zenoh settings")
    # Absolute: a process may hand these settings on (a host to its agents, whose files are elsewhere).
    return _resolve_files(data, p.absolute().parent)


# Settings that name a file: a relative name is taken from the settings file's folder, made absolute.
_FILE_SETTINGS = (
    "dictionary_file",
    "root_ca_certificate",
    "listen_certificate",
    "listen_private_key",
    "connect_certificate",
    "connect_private_key",
)


def _resolve_files(data: Any, folder: Path) -> Any:
    if isinstance(data, dict):
        out = {}
        for key, value in data.items():
            if isinstance(value, str) and key.rsplit("/", 1)[-1] in _FILE_SETTINGS and not Path(value).is_absolute():
                value = str(folder / value)
            out[key] = _resolve_files(value, folder)
        return out
    return data
