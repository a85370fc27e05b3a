"""deploy/: the systemd units check out with systemd-analyze, and the router
configuration loads in Zenoh."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import zenoh

from tests.helpers import ROOT

DEPLOY = ROOT / "deploy"
INSTALLED = "/opt/formation-swarm/bin/swarm"  # where the units expect the package (deploy/README.md)
UNITS = ("swarm-host.service", "swarm-router.service")


@pytest.mark.parametrize("unit", UNITS)
def test_a_unit_is_valid_for_systemd(unit: str, tmp_path: Path) -> None:
    if shutil.which("systemd-analyze") is None:
        pytest.skip("systemd-analyze is not installed here: cannot check the unit")
    text = (DEPLOY / unit).read_text()
    assert INSTALLED in text
    # systemd-analyze checks that the command exists: point it at this installation's.
    swarm = Path(sys.executable).parent / "swarm"
    if not swarm.is_file():
        pytest.skip(f"no swarm command beside {sys.executable} to stand for {INSTALLED}")
    (tmp_path / unit).write_text(text.replace(INSTALLED, str(swarm)))
    res = subprocess.run(
        ["systemd-analyze", "verify", str(tmp_path / unit)], capture_output=True, text=True, timeout=60, check=False
    )
    assert res.returncode == 0, res.stderr
    mine = [line for line in res.stderr.splitlines() if unit in line]
    assert mine == [], mine  # no unknown key, no warning on this unit


def test_the_host_unit_s_variables_are_those_of_its_example_environment() -> None:
    used = set(re.findall(r"\$\{(\w+)\}", (DEPLOY / "swarm-host.service").read_text()))
    given = {
        line.split("=", 1)[0]
        for line in (DEPLOY / "host.env.example").read_text().splitlines()
        if line and not line.startswith("#")
    }
    assert used == given == {"SWARM_ROUTER", "SWARM_HOST_NAME"}


def test_the_router_configuration_loads_in_zenoh() -> None:
    conf = zenoh.Config.from_file(str(DEPLOY / "router.json5"))
    assert '"router"' in conf.get_json("mode")
    assert "tcp/0.0.0.0:7447" in conf.get_json("listen/endpoints")


@pytest.mark.parametrize("unit", UNITS)
def test_a_unit_runs_as_a_user_the_guide_creates_and_names_no_missing_file(unit: str) -> None:
    text = (DEPLOY / unit).read_text()
    assert "User=swarm" in text
    assert "useradd --system" in text
    assert "Documentation=" not in text  # pip install puts no deploy/README.md under /opt/formation-swarm
    guide = (DEPLOY / "README.md").read_text()
    assert "sudo useradd --system --user-group --no-create-home --shell /usr/sbin/nologin swarm" in guide


def test_the_guide_gives_the_openssl_commands_and_the_ca_beside_each_host_login() -> None:
    guide = (DEPLOY / "README.md").read_text()
    assert "see\n   `tests/hosts/test_multihost.py`" not in guide
    assert guide.count("openssl req ") == 2
    assert guide.count("openssl x509 -req ") == 1
    assert "-extfile router-ext.cnf" in guide
    assert "copy `ca.pem` from the\n   same folder beside each of them" in guide
