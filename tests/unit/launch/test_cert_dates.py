"""``swarm secure`` refuses a certificate that has expired or is not valid
yet, in one line naming the file and the date, exit 2, nothing written:
TLS would refuse it later, and the clients would only find that no router
answered."""

from __future__ import annotations

import re
import shutil
import ssl
import subprocess
from datetime import UTC, datetime
from pathlib import Path

import pytest

from formation_swarm.launch import certs, secure

CA_CONFIG = """\
[ca]
default_ca = dated
[dated]
database = index.txt
new_certs_dir = .
serial = serial
default_md = sha256
policy = any
unique_subject = no
[any]
commonName = supplied
"""
EXPIRED = ("20200101000000Z", "20210101000000Z")
NOT_YET = ("20900101000000Z", "20910101000000Z")


def dated(folder: Path, name: str, dates: tuple[str, str]) -> tuple[Path, Path]:
    """A self-signed certificate naming 127.0.0.1 with these not-before and
    not-after dates (``openssl ca`` sets both; ``req -days`` takes no past)."""
    folder.mkdir()
    (folder / "ca.cnf").write_text(CA_CONFIG)
    (folder / "index.txt").write_text("")
    (folder / "serial").write_text("01\n")
    (folder / "ext").write_text("subjectAltName=IP:127.0.0.1\n")
    cert, key = folder / f"{name}.pem", folder / f"{name}.key"
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    run = {"cwd": folder, "check": True, "capture_output": True, "timeout": 30}
    subprocess.run(["openssl", "req", "-new", *ec, "-keyout", key, "-out", "req.csr", "-subj", f"/CN={name}"], **run)
    subprocess.run(
        ["openssl", "ca", "-batch", "-config", "ca.cnf", "-selfsign", "-keyfile", key, "-in", "req.csr"]
        + ["-out", cert, "-startdate", dates[0], "-enddate", dates[1], "-notext", "-extfile", "ext"],
        **run,
    )
    return cert, key


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path]]:
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make certificates")
    root = tmp_path_factory.mktemp("certs")
    (root / "ca").mkdir()
    return {
        "ca": certs.make_ca(root / "ca"),  # valid now, for a year
        "expired": dated(root / "expired", "router", EXPIRED),
        "not_yet": dated(root / "not_yet", "router", NOT_YET),
    }


def test_the_dates_are_read_by_python_and_by_openssl_alike(
    made: dict[str, tuple[Path, Path]], monkeypatch: pytest.MonkeyPatch
) -> None:
    want = (datetime(2020, 1, 1, tzinfo=UTC), datetime(2021, 1, 1, tzinfo=UTC))
    assert certs.validity(made["expired"][0]) == want
    monkeypatch.delattr(ssl._ssl, "_test_decode_cert")  # a Python without CPython's decoder: openssl reads them
    assert certs.validity(made["expired"][0]) == want
    start, end = certs.validity(made["ca"][0]) or (None, None)
    assert start is not None
    assert end is not None
    assert (end - start).days == certs.VALID_DAYS
    assert certs.validity(made["ca"][1]) is None  # a key: no dates, nothing claimed


def _secure(tmp_path: Path, capsys: pytest.CaptureFixture[str], *extra: str | Path) -> tuple[int, str]:
    argv = ["fig11_obstacles", "--run", "r1", "--out", str(tmp_path / "out"), *map(str, extra)]
    with pytest.raises(SystemExit) as left:
        secure.main(argv)
    return int(left.value.code or 0), capsys.readouterr().err


def test_an_expired_router_certificate_is_refused_naming_it_and_its_date(
    made: dict[str, tuple[Path, Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cert, key = made["expired"]
    code, err = _secure(tmp_path, capsys, "--tls-ca", made["ca"][0], "--tls-cert", cert, "--tls-key", key)
    assert code == 2
    assert err.strip().splitlines() == [
        f"swarm secure: TLS file {cert} (--tls-cert): expired on 2021-01-01 00:00 UTC: give a certificate valid now "
        "(see swarm secure --help)"
    ]
    assert not (tmp_path / "out").exists()


def test_a_certificate_not_valid_yet_is_refused(
    made: dict[str, tuple[Path, Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cert, key = made["not_yet"]
    code, err = _secure(tmp_path, capsys, "--tls-ca", made["ca"][0], "--tls-cert", cert, "--tls-key", key)
    assert code == 2
    assert f"TLS file {cert} (--tls-cert): is not valid before 2090-01-01 00:00 UTC" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("mode", ["tls", "mtls", "hosts"])
def test_an_expired_ca_is_refused_whatever_it_is_given_for(
    made: dict[str, tuple[Path, Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str], mode: str
) -> None:
    ca, ca_key = made["expired"]
    extra: dict[str, list[str | Path]] = {
        "tls": ["--tls-ca", ca, "--tls-cert", made["ca"][0], "--tls-key", made["ca"][1]],
        "mtls": ["--mtls", "--router-address", "10.0.0.1", "--tls-ca", ca, "--tls-ca-key", ca_key],
        "hosts": ["--tls-ca", ca],
    }
    argv: list[str | Path] = ["--out", tmp_path / "out", *extra[mode]]
    argv = ["--hosts", "a", *argv] if mode == "hosts" else ["fig11_obstacles", "--run", "r1", *argv]
    with pytest.raises(SystemExit) as left:
        secure.main(list(map(str, argv)))
    assert left.value.code == 2
    assert f"TLS file {ca} (--tls-ca): expired on 2021-01-01 00:00 UTC" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_valid_certificate_passes(made: dict[str, tuple[Path, Path]], tmp_path: Path) -> None:
    certs.check_dates(made["ca"][0], "argument --tls-ca")
    before = datetime(2020, 6, 1, tzinfo=UTC)  # within the dated certificate's year
    certs.check_dates(made["expired"][0], "argument --tls-cert", now=before)
    with pytest.raises(ValueError, match=r"expired on 2021-01-01 00:00 UTC"):
        certs.check_dates(made["expired"][0], "argument --tls-cert")


def test_a_process_refuses_an_expired_certificate_it_is_handed(made: dict[str, tuple[Path, Path]]) -> None:
    # The router and every client check their TLS files before their session opens (protocol.tls).
    from formation_swarm.protocol import tls

    cert = made["expired"][0]
    with pytest.raises(ValueError, match="expired") as refused:
        tls.check_certificate(str(cert), tls.LISTEN_CERTIFICATE)
    said = re.findall(r"^TLS file (.+) \(([^)]+)\): expired on (\S+ \S+) UTC", str(refused.value))
    assert said == [(str(cert), tls.LISTEN_CERTIFICATE, "2021-01-01 00:00")]  # the file, its setting, its date
    assert "\n" not in str(refused.value)
    tls.check_certificate(str(made["ca"][0]), tls.ROOT_CA)  # valid now: accepted
