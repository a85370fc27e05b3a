"""swarm sweep: the grid, the tables, resuming."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from formation_swarm.sweep import Job, Sweep, aggregate, grid, parse_set
from tests.conftest import SCENARIOS


def test_set_values_are_toml_or_bare_strings() -> None:
    assert parse_set("controller.vn=1.5,dynamic") == ("controller.vn", [1.5, "dynamic"])
    assert parse_set("links.obs_drop = 0, 0.1 ,0.3") == ("links.obs_drop", [0, 0.1, 0.3])
    assert parse_set("controller.use_ekf=true,false") == ("controller.use_ekf", [True, False])
    for bad in ("controller.vn", "=1,2", "controller.vn="):
        with pytest.raises(ValueError, match="key=v1,v2"):
            parse_set(bad)


def test_grid_is_the_product() -> None:
    g = grid([("a", [1, 2]), ("b", ["x", "y", "z"])])
    assert len(g) == 6
    assert g[0] == ("a=1 b=x", {"a": 1, "b": "x"})
    assert grid([]) == [("", {})]


def test_aggregate_mean_std_and_t_interval() -> None:
    rows = [{"combination": "c", "seed": s, "run": str(s), "m": v} for s, v in enumerate([1.0, 2.0, 3.0, 4.0])]
    (agg,) = aggregate(rows)
    assert agg["n"] == 4
    assert agg["mean"] == 2.5
    assert agg["std"] == pytest.approx(math.sqrt(5 / 3))
    half = 3.182 * math.sqrt(5 / 3) / 2  # t(0.975, 3 dof) * s / sqrt(n)
    assert agg["ci95_low"] == pytest.approx(2.5 - half)
    assert agg["ci95_high"] == pytest.approx(2.5 + half)


def test_bad_set_value_fails_before_any_run(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="controller.vn"):
        Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", [Job("controller.vn=fast", {"controller.vn": "fast"}, 0)],
              tmp_path)  # fmt: skip


def test_sweep_writes_tables_and_resumes(tmp_path: Path) -> None:
    jobs = [Job("controller.vn=1.5", {"controller.vn": 1.5, "run.duration_s": 5.0}, s) for s in (0, 1)]
    lines: list[str] = []
    sweep = Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", jobs, tmp_path, workers=2, progress=lines.append)
    rows = sweep.run()
    jobs = sweep.jobs  # named after the scenario as run, too
    assert [r["seed"] for r in rows] == [0, 1]
    assert all(r["exit_code"] == 0 and r["ticks"] == 100 for r in rows)
    assert sum("2/2" in line for line in lines) == 1  # progress, one line per finished run
    with (tmp_path / "runs.csv").open() as f:
        table = list(csv.DictReader(f))
    assert [int(r["seed"]) for r in table] == [0, 1]
    assert float(table[0]["r2_rms_m"]) > 0
    with (tmp_path / "aggregate.csv").open() as f:
        agg = {r["metric"]: r for r in csv.DictReader(f)}
    assert int(agg["r2_rms_m"]["n"]) == 2
    # A lost or failed run is run again; finished ones are not.
    first = json.loads((tmp_path / "runs" / jobs[0].name / "summary.json").read_text())
    (tmp_path / "runs" / jobs[1].name / "summary.json").unlink()
    lines.clear()
    again = Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", jobs, tmp_path, workers=2, progress=lines.append).run()
    assert "1/2 runs already done" in lines[0]
    assert len(again) == 2
    assert json.loads((tmp_path / "runs" / jobs[0].name / "summary.json").read_text()) == first
    assert again[1]["r2_rms_m"] == rows[1]["r2_rms_m"]  # lockstep: the rerun is the same run
    # The same combination with a fault (or a changed scenario) is another run, never a finished one reused.
    lines.clear()
    blind = Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", jobs[:1], tmp_path, workers=1, progress=lines.append,
                  faults=["blackout 2@1s"]).run()  # fmt: skip
    assert not any("already done" in line for line in lines)
    assert blind[0]["run"] != jobs[0].name
    assert blind[0]["r2_rms_m"] != rows[0]["r2_rms_m"]
