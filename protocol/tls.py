"""TLS of a process's links: the settings that name its files, and their check.

Zenoh reads these files only when a tls/ link opens. A missing file, a file
of the wrong kind or a private key that is not its certificate's then all
end alike: "Unable to connect ... Timeout!" once the connect timeout has
passed (eclipse-zenoh 1.10.2). So a process checks them before it opens its
session, and names the file at fault.

Mutual TLS: the router asks every client for a certificate signed by the
CA it is given, and its access rules match that certificate's common name
(protocol.acl). Both ends set ``enable_mtls``: a client without it sends no
certificate, and the router refuses the link.
"""

from __future__ import annotations

import shutil
import ssl
import subprocess
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

SECTION = "transport/link/tls"
ROOT_CA = f"{SECTION}/root_ca_certificate"  # a client's: the CA of its router; a router's: of its clients
LISTEN_CERTIFICATE, LISTEN_PRIVATE_KEY = f"{SECTION}/listen_certificate", f"{SECTION}/listen_private_key"
CONNECT_CERTIFICATE, CONNECT_PRIVATE_KEY = f"{SECTION}/connect_certificate", f"{SECTION}/connect_private_key"
ENABLE_MTLS = f"{SECTION}/enable_mtls"
CA, CERTIFICATE, PRIVATE_KEY = "ca.pem", "router.pem", "router.key"  # their names in a run's secrets folder
_OPENSSL_TIMEOUT_S = 30.0


@dataclass(frozen=True)
class Tls:
    """TLS for links that leave the machine: the CA every client checks the
    router's certificate against, and the router's certificate and key.
    Endpoints are then ``tls/HOST:PORT``; the certificate must name HOST.
    ``clients`` (mutual TLS): each login's own certificate and key, signed by
    the same CA, its common name the login's user."""

    ca: Path
    certificate: Path
    private_key: Path
    clients: Mapping[str, tuple[Path, Path]] | None = None


def client_files(user: str) -> tuple[str, str]:
    """The names of a login's own certificate and key beside its login file."""
    return f"{user}.pem", f"{user}.key"


def client_settings(ca: str, own: tuple[str, str] | None = None) -> dict[str, Any]:
    """A client's settings: accept only a router certified by ``ca``; with
    ``own`` = (certificate, key), present that certificate (mutual TLS)."""
    out: dict[str, Any] = {ROOT_CA: ca}
    if own is not None:
        out[CONNECT_CERTIFICATE], out[CONNECT_PRIVATE_KEY] = own
        out[ENABLE_MTLS] = True
    return out


def router_settings(certificate: str, private_key: str, client_ca: str | None = None) -> dict[str, Any]:
    """A router's settings: its TLS identity; with ``client_ca``, every client
    must present a certificate signed by that CA (mutual TLS)."""
    out: dict[str, Any] = {LISTEN_CERTIFICATE: certificate, LISTEN_PRIVATE_KEY: private_key}
    if client_ca is not None:
        out[ROOT_CA], out[ENABLE_MTLS] = client_ca, True
    return out


_PAIRS = (("listen_certificate", "listen_private_key"), ("connect_certificate", "connect_private_key"))


def check_files(section: Mapping[str, Any], mode: str) -> None:
    """ValueError, one line naming the file, when a file of ``section`` (the
    values of Zenoh's transport/link/tls) cannot serve: missing or unreadable,
    not a PEM certificate where one is needed, or a private key that is not
    its certificate's. ``mode``: the session's (a client with mutual TLS needs
    its own certificate; a router, its clients' CA)."""
    if isinstance(section.get("root_ca_certificate"), str):
        check_certificate(section["root_ca_certificate"], "root_ca_certificate")
    for cert_key, key_key in _PAIRS:
        cert, key = section.get(cert_key), section.get(key_key)
        if cert is None and key is None:
            continue
        if not (isinstance(cert, str) and isinstance(key, str)):
            given, missing = (cert_key, key_key) if cert else (key_key, cert_key)
            raise ValueError(f"TLS: {given} {cert or key} is given without {missing}: give both")
        check_certificate(cert, cert_key)
        check_key(cert, key, key_key)
    if section.get("enable_mtls") is True:
        if mode == "client" and section.get("connect_certificate") is None:
            raise ValueError("TLS: enable_mtls is set but no connect_certificate: a client needs its own certificate")
        if mode == "router" and section.get("root_ca_certificate") is None:
            raise ValueError("TLS: enable_mtls is set but no root_ca_certificate: the CA of the clients' certificates")


def _readable(path: str, setting: str) -> None:
    try:
        Path(path).open("rb").close()
    except OSError as exc:
        raise ValueError(f"TLS file {path} ({setting}): {exc.strerror or exc}") from None


def check_certificate(path: str, setting: str) -> None:
    """ValueError naming ``path`` (given as ``setting``) unless it holds a PEM certificate."""
    _readable(path, setting)
    try:
        ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT).load_verify_locations(cafile=path)
    except ssl.SSLError:
        raise ValueError(f"TLS file {path} ({setting}): not a certificate in PEM form") from None
    check_dates(path, setting)


def check_key(certificate: str, private_key: str, setting: str) -> None:
    """ValueError naming ``private_key`` (given as ``setting``) unless it is the
    PEM private key of ``certificate`` (a PEM certificate, checked before)."""
    _readable(private_key, setting)
    try:
        ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT).load_cert_chain(certificate, private_key)
    except ssl.SSLError as exc:
        if exc.reason == "KEY_VALUES_MISMATCH":
            raise ValueError(
                f"TLS file {private_key} ({setting}): not the private key of the certificate {certificate}"
            ) from None
        raise ValueError(f"TLS file {private_key} ({setting}): not a private key in PEM form") from None


def certificate_names(path: str | Path) -> set[str] | None:
    """The host names and IP addresses a PEM certificate names (its subject
    alternative names), or None when this Python cannot read them."""
    decode = getattr(getattr(ssl, "_ssl", None), "_test_decode_cert", None)  # CPython's, without a dependency
    if decode is None:
        return None
    try:
        decoded = decode(str(path))
    except (OSError, ssl.SSLError, ValueError):
        return None
    return {str(value).strip() for _kind, value in decoded.get("subjectAltName", ())}


def validity(path: str | Path) -> tuple[datetime, datetime] | None:
    """(not before, not after) of the first certificate of a PEM file, in UTC;
    None when neither this Python nor openssl can read them."""
    decode = getattr(getattr(ssl, "_ssl", None), "_test_decode_cert", None)  # CPython's, without a dependency
    dates: list[str] = []
    if decode is not None:
        try:
            decoded = decode(str(path))
            dates = [decoded["notBefore"], decoded["notAfter"]]
        except (OSError, ssl.SSLError, ValueError, KeyError):
            dates = []
    if not dates and shutil.which("openssl"):
        argv = ["openssl", "x509", "-in", str(path), "-noout", "-startdate", "-enddate"]
        try:
            done = subprocess.run(argv, capture_output=True, text=True, timeout=_OPENSSL_TIMEOUT_S, check=False)
        except (OSError, subprocess.TimeoutExpired):
            return None
        said = dict(line.partition("=")[::2] for line in done.stdout.splitlines())
        dates = [said.get("notBefore", ""), said.get("notAfter", "")]
    try:
        start, end = (datetime.fromtimestamp(ssl.cert_time_to_seconds(d), UTC) for d in dates)
    except ValueError:
        return None
    return start, end


def check_dates(path: str | Path, setting: str, now: datetime | None = None) -> None:
    """ValueError, one line naming the file and the date, for a certificate that
    has expired or is not valid yet: TLS refuses it, and a client then only
    finds that no router answered."""
    label = f"TLS file {path} ({setting}):"
    dates = validity(path)
    if dates is None:
        return  # unreadable here: the TLS check of the file itself reports that
    now = now or datetime.now(UTC)
    start, end = dates
    if now > end:
        raise ValueError(f"{label} expired on {end:%Y-%m-%d %H:%M} UTC: give a certificate valid now")
    if now < start:
        raise ValueError(f"{label} is not valid before {start:%Y-%m-%d %H:%M} UTC: give one valid now")
