"""Mutual TLS without a network: the settings of a login and of the router,
the rules keyed on certificate names, and the check of TLS files that names
the file at fault (tests/system/test_mtls.py opens sessions with them)."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from formation_swarm.launch import certs
from formation_swarm.protocol import acl, tls, trust
from formation_swarm.protocol.session import make_config

ROBOTS = (1, 2, 3)
TLS_EP = ["tls/127.0.0.1:7447"]


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> tls.Tls:
    """A CA (its key kept, as ca.key) and the certificates of a three-robot run's logins."""
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make certificates")
    folder = tmp_path_factory.mktemp("pki")
    users = list(acl.grants("r1", ROBOTS, 1))
    return certs.make_run_certificates(folder, users, ["127.0.0.1", "router.lan"])


def test_the_rules_match_user_and_certificate_name_both() -> None:
    plain = acl.access_control("r1", ROBOTS, 1)
    mutual = acl.access_control("r1", ROBOTS, 1, mtls=True)
    assert {s["id"] for s in mutual["subjects"]} == set(acl.grants("r1", ROBOTS, 1))
    for s in mutual["subjects"]:
        assert s == {"id": s["id"], "usernames": [s["id"]], "cert_common_names": [s["id"]]}
    # The same grants: only the subjects differ.
    assert {k: v for k, v in mutual.items() if k != "subjects"} == {k: v for k, v in plain.items() if k != "subjects"}


def test_a_login_and_the_router_with_mutual_tls(tmp_path: Path, made: tls.Tls) -> None:
    files = trust.write_run_secrets(tmp_path / "s", "r1", ROBOTS, 1, world="anywhere", tls=made)
    folder = tmp_path / "s"
    for user in ("world", "logger", "launcher", "agent-1", "agent-2", "agent-3"):
        login = json.loads(files[user].read_text())
        assert {k: v for k, v in login.items() if k != "transport/auth/usrpwd"} == {
            "transport/link/tls/root_ca_certificate": "ca.pem",
            "transport/link/tls/connect_certificate": f"{user}.pem",
            "transport/link/tls/connect_private_key": f"{user}.key",
            "transport/link/tls/enable_mtls": True,
        }
        assert (folder / f"{user}.pem").read_text() == made.clients[user][0].read_text()
        # Read back, every file is named from the login's folder.
        read = trust.read_settings(files[user])
        assert read[tls.CONNECT_PRIVATE_KEY] == str(folder / f"{user}.key")
    router = json.loads(files["router"].read_text())
    assert router["transport/link/tls/root_ca_certificate"] == "ca.pem"
    assert router["transport/link/tls/enable_mtls"] is True
    assert router["access_control"] == acl.access_control("r1", ROBOTS, 1, mtls=True)
    assert not (folder / "ca.key").exists()


def test_mutual_tls_needs_a_certificate_for_every_login(tmp_path: Path, made: tls.Tls) -> None:
    short = tls.Tls(made.ca, made.certificate, made.private_key, {"world": made.clients["world"]})
    with pytest.raises(ValueError, match="^mutual TLS: no certificate for logger, launcher, agent-1"):
        trust.write_run_secrets(tmp_path / "s", "r1", ROBOTS, 1, world="anywhere", tls=short)


def _client(made: tls.Tls, cert: Path, key: Path, ca: Path | None = None) -> dict[str, object]:
    return tls.client_settings(str(ca or made.ca), (str(cert), str(key)))


def test_good_files_pass_and_tcp_links_are_not_checked(made: tls.Tls, tmp_path: Path) -> None:
    make_config("client", TLS_EP, settings=_client(made, *made.clients["agent-2"]))
    make_config("router", listen=TLS_EP, settings=tls.router_settings(str(made.certificate), str(made.private_key)))
    missing = _client(made, tmp_path / "gone.pem", tmp_path / "gone.key")
    make_config("client", ["tcp/127.0.0.1:7447"], settings=missing)  # Zenoh reads them only for tls/


def _refused(settings: dict[str, object], mode: str = "client") -> str:
    endpoints = {"connect": TLS_EP} if mode == "client" else {"listen": TLS_EP}
    with pytest.raises(ValueError, match="^TLS") as err:
        make_config(mode, settings=settings, **endpoints)
    message = str(err.value)
    assert "\n" not in message
    return message


def _file_refused(settings: dict[str, object], mode: str = "client") -> tuple[str, str, str]:
    """A refused TLS file's one line, as (the file, its setting, why)."""
    said = re.fullmatch(r"TLS file (.+) \((\w+)\): (.+)", _refused(settings, mode))
    assert said is not None
    file, setting, why = said.groups()
    return file, setting, why


def test_each_bad_file_is_named_in_one_line(made: tls.Tls, tmp_path: Path) -> None:
    cert2, key2 = (str(p) for p in made.clients["agent-2"])
    key3 = str(made.clients["agent-3"][1])
    gone = str(tmp_path / "gone.pem")
    file, setting, why = _file_refused(_client(made, Path(cert2), Path(key3)))
    assert (file, setting, why.rpartition(" ")[2]) == (key3, "connect_private_key", cert2)  # the key, its certificate
    assert why.startswith("not the private key")
    file, setting, why = _file_refused(_client(made, Path(gone), Path(key2)))
    assert (file, setting) == (gone, "connect_certificate")
    assert why.startswith("No such file")
    file, setting, why = _file_refused(_client(made, Path(cert2), Path(key2), ca=Path(gone)))
    assert (file, setting) == (gone, "root_ca_certificate")
    assert why.startswith("No such file")
    file, setting, why = _file_refused(_client(made, Path(key2), Path(key2)))
    assert (file, setting) == (key2, "connect_certificate")
    assert why.startswith("not a certificate")
    file, setting, why = _file_refused(_client(made, Path(cert2), Path(cert2)))
    assert (file, setting) == (cert2, "connect_private_key")
    assert why.startswith("not a private key")
    router_key = str(made.private_key)
    wrong = tls.router_settings(str(made.certificate), key2, str(made.ca))
    file, setting, why = _file_refused(wrong, "router")
    assert (file, setting) == (key2, "listen_private_key")
    assert why.startswith("not the private key of the certificate ")
    assert why.endswith(str(made.certificate))
    assert router_key != key2


def test_mutual_tls_without_its_other_half_is_refused(made: tls.Tls) -> None:
    message = _refused({tls.ROOT_CA: str(made.ca), tls.ENABLE_MTLS: True})
    assert message.startswith("TLS: enable_mtls is set but no connect_certificate: ")
    assert message.endswith("its own certificate")  # why a client needs one
    key = str(made.clients["agent-2"][1])
    alone = _refused({tls.ROOT_CA: str(made.ca), tls.CONNECT_PRIVATE_KEY: key})
    assert alone.startswith(f"TLS: connect_private_key {key} ")  # the key named, with the file
    assert "without connect_certificate" in alone
    no_ca = {tls.LISTEN_CERTIFICATE: str(made.certificate), tls.LISTEN_PRIVATE_KEY: str(made.private_key)}
    router = _refused(no_ca | {tls.ENABLE_MTLS: True}, "router")
    assert router.startswith("TLS: enable_mtls is set but no root_ca_certificate")


def test_a_router_address_is_an_ip_or_a_host_name() -> None:
    assert certs.subject_alt_name("10.1.2.3") == "IP:10.1.2.3"
    assert certs.subject_alt_name("[::1]") == "IP:::1"
    assert certs.subject_alt_name("router.example.org") == "DNS:router.example.org"
    for bad in ("", "a b", "x\nsubjectAltName=DNS:evil", "-a.org", "a" * 254):
        with pytest.raises(ValueError, match=re.escape(f"{bad!r} is neither an IP address nor a host name")):
            certs.subject_alt_name(bad)
