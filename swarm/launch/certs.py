"""A run's own certificate authority and certificates, made with openssl
(``swarm secure --mtls``): the router's, naming the addresses the clients
reach it at, and one per login, its common name the login's user.

EC P-256 keys, which Zenoh's TLS (rustls) takes. openssl rather than a
Python library: the package depends on no cryptography library, and openssl
is on every machine that makes certificates.
"""

from __future__ import annotations

import ipaddress
import re
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

from formation_swarm.protocol.tls import Tls, check_dates, validity

__all__ = ["Tls", "check_dates", "validity"]  # the dates' checks live with the TLS files' others

VALID_DAYS = 365
_EC_KEY = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
_LABEL = r"[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?"
_DNS_NAME = re.compile(rf"{_LABEL}(?:\.{_LABEL})*")
_TIMEOUT_S = 30.0


def subject_alt_name(address: str) -> str:
    """``IP:...`` or ``DNS:...`` for a router's address, as its certificate names
    it; ValueError for what is neither an IP address nor a host name."""
    try:
        return f"IP:{ipaddress.ip_address(address.strip('[]'))}"
    except ValueError:
        pass
    if len(address) > 253 or not _DNS_NAME.fullmatch(address):
        raise ValueError(f"{address!r} is neither an IP address nor a host name")
    return f"DNS:{address}"


def openssl_missing() -> str | None:
    """Why certificates cannot be made here, or None."""
    return None if shutil.which("openssl") else "needs openssl on the PATH to make the certificates"


def _openssl(*argv: str | Path | int) -> None:
    try:
        subprocess.run(["openssl", *map(str, argv)], check=True, capture_output=True, text=True, timeout=_TIMEOUT_S)
    except subprocess.CalledProcessError as exc:
        said = (exc.stderr or "").strip().splitlines()
        raise OSError(f"openssl {argv[0]} failed: {said[-1] if said else f'exit {exc.returncode}'}") from None
    except subprocess.TimeoutExpired:
        raise OSError(f"openssl {argv[0]} did not finish within {_TIMEOUT_S:g} s") from None


def make_ca(folder: Path, name: str = "swarm run CA") -> tuple[Path, Path]:
    """A self-signed CA in ``folder``: (ca.pem, ca.key)."""
    ca, key = folder / "ca.pem", folder / "ca.key"
    _openssl("req", "-x509", *_EC_KEY, "-keyout", key, "-out", ca, "-days", VALID_DAYS, "-subj", f"/CN={name}")
    return ca, key


def make_certificate(
    folder: Path, common_name: str, ca: tuple[Path, Path], addresses: Sequence[str] = ()
) -> tuple[Path, Path]:
    """A certificate and key signed by ``ca`` (its certificate and key), in
    ``folder`` as ``<common_name>.pem``/``.key``. With ``addresses``, a
    server's, naming them; without, a client's."""
    cert, key, request = (folder / f"{common_name}{ext}" for ext in (".pem", ".key", ".csr"))
    extensions = folder / f"{common_name}.ext"
    usage = "serverAuth" if addresses else "clientAuth"
    lines = [f"extendedKeyUsage={usage}", "basicConstraints=CA:FALSE"]
    if addresses:
        lines.append("subjectAltName=" + ",".join(subject_alt_name(a) for a in addresses))
    extensions.write_text("\n".join(lines) + "\n")
    _openssl("req", *_EC_KEY, "-keyout", key, "-out", request, "-subj", f"/CN={common_name}")
    serial = ["-CAserial", folder / "ca.srl", "-CAcreateserial"]  # beside the certificates, not the CA
    signing = ["-CA", ca[0], "-CAkey", ca[1], *serial, "-days", VALID_DAYS, "-extfile", extensions]
    _openssl("x509", "-req", "-in", request, "-out", cert, *signing)
    return cert, key


def make_run_certificates(
    folder: Path, users: Sequence[str], router_addresses: Sequence[str], own_ca: Tls | None = None
) -> Tls:
    """In ``folder``, the router's certificate naming ``router_addresses`` and
    one client certificate per user (common name: the user), signed by a
    fresh CA, or by ``own_ca`` (its ``ca`` and ``private_key``). ``folder``
    keeps a fresh CA's key: delete it once copied, and no other certificate
    of the run can be made."""
    ca = (own_ca.ca, own_ca.private_key) if own_ca is not None else make_ca(folder)
    router = make_certificate(folder, "router", ca, router_addresses)
    clients = {user: make_certificate(folder, user, ca) for user in users}
    return Tls(ca[0], router[0], router[1], clients)
