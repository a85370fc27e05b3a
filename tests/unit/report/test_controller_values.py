"""load_run and swarm export hold the controllers' named values: rho_m and
alpha_rad of every law, and a law's own, by name, per follower per tick."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest

from formation_swarm import load_run
from formation_swarm.report import data as data_mod
from formation_swarm.report.export import export, table
from tests.helpers.run_folder import DT_S, fake_run

TICKS = 20


@pytest.fixture
def run(tmp_path: Path) -> Path:
    steps = np.arange(1, TICKS + 1, dtype=float)
    return fake_run(tmp_path / "run", TICKS, own={"steps": steps, "gain": np.full(TICKS, 0.5)})


def test_load_run_holds_each_value_per_follower_per_tick(run: Path) -> None:
    r = load_run(run)
    assert list(r.controller) == ["rho_m", "alpha_rad", "gain", "steps"]
    t = np.arange(TICKS) * DT_S
    follower, leader = r.index(2), r.index(1)
    np.testing.assert_allclose(r.controller["rho_m"][follower], 0.1 + t)
    np.testing.assert_allclose(r.controller["alpha_rad"][follower], -t)
    np.testing.assert_array_equal(r.controller["steps"][follower], np.arange(1, TICKS + 1))
    assert all(a.shape == (2, TICKS) for a in r.controller.values())
    assert all(np.isnan(a[leader]).all() for a in r.controller.values())  # a leader has no controller
    assert (r.scenario, r.seed) == ("turn-vn-dynamic", 1)


def test_export_writes_them_as_named_columns(run: Path, tmp_path: Path) -> None:
    path = export(run, "csv", tmp_path / "run.csv")
    rows = list(csv.DictReader(path.open()))
    assert list(rows[0])[-4:] == ["rho_m", "alpha_rad", "controller_gain", "controller_steps"]
    r2 = [row for row in rows if row["robot"] == "2"]
    assert [float(row["controller_steps"]) for row in r2] == list(range(1, TICKS + 1))
    assert {row["controller_gain"] for row in r2} == {"0.5"}
    assert {row["controller_steps"] for row in rows if row["robot"] == "1"} == {""}  # none recorded
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run", "run.csv"]  # no partial file left


def test_a_recording_of_names_no_controller_sends_keeps_them_out(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    odd = {"rho_m": np.zeros(TICKS), "1x": np.zeros(TICKS), "a" * 40: np.zeros(TICKS), "ok": np.zeros(TICKS)}
    r = load_run(fake_run(tmp_path / "run", TICKS, own=odd))
    assert list(r.controller) == ["rho_m", "alpha_rad", "ok"]  # rho_m the wire's, from fis/rho
    np.testing.assert_allclose(r.controller["rho_m"][r.index(2)], 0.1 + np.arange(TICKS) * DT_S)
    assert "controller_ok" in table(r)
    monkeypatch.setattr(data_mod, "MAX_OWN_VALUES", 0)
    rrd = tmp_path / "run" / "recording.rrd"
    with pytest.raises(ValueError, match=re.escape(str(rrd))) as err:
        load_run(tmp_path / "run")
    assert re.findall(r"^(.+) holds (\d+) names\b.* (\d+)$", str(err.value)) == [(str(rrd), "1", "0")]  # found, allowed


def test_the_wires_other_values_when_the_recording_holds_them(tmp_path: Path) -> None:
    """steering_to and changing travel in the telemetry; a recording with
    their series (fis/steering_to, fis/changing) gives them as columns too."""
    steering = np.arange(TICKS) % 4
    run = fake_run(tmp_path / "run", TICKS, more={"fis/steering_to": steering})
    r = load_run(run)
    assert list(r.controller) == ["rho_m", "alpha_rad", "steering_to"]
    np.testing.assert_array_equal(r.controller["steering_to"][r.index(2)], steering)
    assert "steering_to" in table(r)  # a wire value: its own name, not controller_steering_to
