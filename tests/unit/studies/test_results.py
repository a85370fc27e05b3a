"""`swarm results`: the table of docs/results.md and README checked against an
independent computation (scipy's Student t), and the runs it refuses."""

from __future__ import annotations

import math
import re
import statistics
from pathlib import Path

import pytest
from scipy import stats

from formation_swarm.studies import claims, results, sections, sweep
from formation_swarm.studies.tables import aggregate

ROWS_PER_SEED = [1.0, 2.5, 0.5, 3.0, 1.5]  # one metric over five seeds
LABEL = "fuzzy, dynamic V_N | noise low | obs drop 10%"


def _rows(values: list[float], label: str = LABEL, **extra: object) -> list[dict]:
    return [
        {
            "combination": label,
            "seed": s,
            "run": f"r{s}",
            "exit_code": 0,
            "lockstep_misses": 0,
            "r2_rms_m": v,
            "r2_max_m": 2 * v,
            **extra,
        }
        for s, v in enumerate(values)
    ]


def _t_half_width(values: list[float]) -> float:
    n = len(values)
    return stats.t.ppf(0.975, n - 1) * statistics.stdev(values) / math.sqrt(n)


@pytest.mark.parametrize("n", range(2, 32))
def test_aggregate_interval_is_students_t(n: int) -> None:
    values = [math.sin(3.7 * i) + 0.1 * i for i in range(n)]
    (agg,) = [a for a in aggregate(_rows(values)) if a["metric"] == "r2_rms_m"]
    half = (agg["ci95_high"] - agg["ci95_low"]) / 2
    assert agg["mean"] == pytest.approx(statistics.fmean(values), rel=1e-12)
    assert agg["std"] == pytest.approx(statistics.stdev(values), rel=1e-12)
    # The quantile used, back out of the half-width: scipy's, to the t table's 3 decimals.
    assert half * math.sqrt(n) / statistics.stdev(values) == pytest.approx(stats.t.ppf(0.975, n - 1), abs=5e-4)
    assert agg["n"] == n
    assert (agg["min"], agg["max"]) == (min(values), max(values))


def test_aggregate_skips_what_is_not_a_finite_number() -> None:
    rows = _rows([1.0, 2.0, 3.0])
    rows[0]["r2_rms_m"] = math.nan
    rows[1]["r2_max_m"] = None
    rows[2]["ok"] = True  # a boolean is not a metric
    agg = {a["metric"]: a for a in aggregate(rows)}
    assert agg["r2_rms_m"]["n"] == 2
    assert agg["r2_max_m"]["n"] == 2
    assert "ok" not in agg
    one = aggregate(_rows([4.0]))
    assert math.isnan([a for a in one if a["metric"] == "r2_rms_m"][0]["ci95_low"])  # no interval from one run


def test_table_cell_is_the_mean_plus_minus_the_half_width() -> None:
    text = results.table(_rows(ROWS_PER_SEED), seeds=5)
    (line,) = [ln for ln in text.splitlines() if ln.startswith("| fuzzy, dynamic V_N | low |")]
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[2] == "-"  # obs drop 0%: no runs
    assert cells[4] == "-"
    m = re.fullmatch(r"(\d+\.\d\d) ± (\d+\.\d\d) \[(\d+\.\d\d)\]", cells[3])
    assert m, cells[3]
    assert float(m[1]) == round(statistics.fmean(ROWS_PER_SEED), 2)
    assert float(m[2]) == round(_t_half_width(ROWS_PER_SEED), 2)  # 1.29 (not the whole interval, 2.57)
    assert float(m[3]) == round(2 * statistics.fmean(ROWS_PER_SEED), 2)  # the max error, mean over seeds
    assert "mean over 5 seeds" in text


def test_the_grid_is_the_published_one() -> None:
    """Controllers x noise x drops, as the table's rows and columns say."""
    jobs = results.jobs(range(3))
    assert len(jobs) == 3 * 2 * 3 * 3
    assert results.DROPS == (0.0, 0.1, 0.3)
    labels = sorted({j.label for j in jobs})
    assert len(labels) == 18
    by_label = {j.label: j.overrides for j in jobs}
    dyn_high_30 = by_label["fuzzy, dynamic V_N | noise high | obs drop 30%"]
    assert dyn_high_30["controller.vn"] == "dynamic"
    assert dyn_high_30["links.obs_drop"] == 0.3
    assert by_label["fuzzy, static V_N = 1.5 | noise low | obs drop 0%"] == {
        "controller.vn": 1.5,
        "links.obs_drop": 0.0,
    }
    assert by_label["l-psi (Desai et al.) | noise low | obs drop 10%"]["controller.law"] == "lpsi"
    # High noise: the EKF is told the camera's sigmas (Fig. 9's noise).
    high = results.NOISE["high"]
    assert high["controller.ekf.sigma_rho_m"] == high["camera.sigma_rho_m"]
    assert high["controller.ekf.sigma_phi_rad"] == pytest.approx(math.radians(high["camera.sigma_phi_deg"]), abs=1e-4)
    assert high["controller.ekf.sigma_beta_rad"] == pytest.approx(math.radians(high["camera.sigma_beta_deg"]), abs=1e-4)
    assert sorted({j.seed for j in jobs}) == [0, 1, 2]


def test_write_into_replaces_only_between_the_markers(tmp_path: Path) -> None:
    doc = tmp_path / "doc.md"
    doc.write_text(f"before\n{results.BEGIN}\nold\n{results.END}\nafter\n")
    sections.write_into(doc, "new table")
    assert doc.read_text().splitlines() == ["before", results.BEGIN, "new table", results.END, "after"]
    assert doc.read_text().endswith("after\n")
    for text in ("no markers", f"only {results.BEGIN}", f"only {results.END}"):
        (tmp_path / "none.md").write_text(text)
        with pytest.raises(ValueError, match="markers"):
            sections.write_into(tmp_path / "none.md", "x")


def test_failed_runs_and_runs_with_lockstep_misses_are_unfit() -> None:
    rows = _rows([1.0, 1.0, 1.0, 1.0])
    rows[1]["exit_code"] = 1
    rows[2]["lockstep_misses"] = 3
    del rows[3]["lockstep_misses"]  # a run that does not say: not trusted either
    assert sweep.unfit_of(rows) == [
        sweep.Unfit(run="r1", exit_code=1, lockstep_misses=0),
        sweep.Unfit(run="r2", exit_code=0, lockstep_misses=3),
        sweep.Unfit(run="r3", exit_code=0, lockstep_misses=None),
    ]
    assert sweep.unfit_of(_rows([1.0, 2.0])) == []
    # Each with its reason: a failed run's exit code, else its misses.
    whys = sweep.unfit_runs(rows)
    assert [why.partition(": ")[0] for why in whys] == ["r1", "r2", "r3"]
    assert whys[0].endswith("exit code 1")
    assert whys[1].endswith("3 lockstep misses")
    assert whys[2].endswith("None lockstep misses")


class _FakeSweep:
    rows: list[dict] = []

    def __init__(self, *_args: object, **_kwargs: object) -> None:
        pass

    def run(self) -> list[dict]:
        return self.rows


def test_results_refuses_to_write_a_table_with_a_missed_tick(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = tmp_path / "results.md"
    doc.write_text(f"{results.BEGIN}\nold\n{results.END}\n")
    monkeypatch.setattr(results, "Sweep", _FakeSweep)
    _FakeSweep.rows = _rows([1.0, 2.0], lockstep_misses=0)
    _FakeSweep.rows[1]["lockstep_misses"] = 2
    assert results.main(["--seeds", "2", "--out", str(tmp_path), "--write", str(doc)]) == 1
    assert "r1: 2 lockstep misses" in capsys.readouterr().err
    assert "old" in doc.read_text()  # not written
    _FakeSweep.rows = _rows([1.0, 2.0])
    assert results.main(["--seeds", "2", "--out", str(tmp_path), "--write", str(doc)]) == 0
    assert "1.50 ±" in doc.read_text()


def test_beyond_31_runs_the_interval_uses_the_normal_quantile() -> None:
    values = [math.cos(1.3 * i) for i in range(40)]
    for n in (32, 40):
        (agg,) = [a for a in aggregate(_rows(values[:n])) if a["metric"] == "r2_rms_m"]
        half = (agg["ci95_high"] - agg["ci95_low"]) / 2
        assert half == pytest.approx(1.96 * statistics.stdev(values[:n]) / math.sqrt(n), rel=1e-12)


def test_one_run_has_no_spread_and_no_interval() -> None:
    (agg,) = [a for a in aggregate(_rows([4.0])) if a["metric"] == "r2_rms_m"]
    assert (agg["n"], agg["mean"], agg["std"]) == (1, 4.0, 0.0)
    assert math.isnan(agg["ci95_high"])


def test_a_metric_is_aggregated_over_the_runs_that_have_it() -> None:
    rows = _rows([1.0, 2.0, 3.0])
    rows[0]["r2_formations_changes"] = 2  # only the first run has it
    rows[0]["note"] = "n/a"  # a column with no number at all, before one with numbers
    rows[0]["r3_rms_m"] = None
    rows[1]["r3_rms_m"] = 5.0
    rows[2]["r3_rms_m"] = 7.0
    agg = {a["metric"]: a for a in aggregate(rows)}
    assert agg["r2_formations_changes"]["n"] == 1
    assert (agg["r3_rms_m"]["n"], agg["r3_rms_m"]["mean"]) == (2, 6.0)
    assert (agg["r2_rms_m"]["n"], agg["r2_max_m"]["n"]) == (3, 3)
    assert "note" not in agg


def test_a_setting_goes_into_every_run_its_labels_and_its_own_markers(tmp_path: Path) -> None:
    noisy = {"robot.wheel_noise_mps": 0.1}
    jobs = results.jobs(range(2), noisy)
    assert len(jobs) == 36
    assert all(j.overrides["robot.wheel_noise_mps"] == 0.1 for j in jobs)
    assert not {j.name for j in jobs} & {j.name for j in results.jobs(range(2))}  # other run folders
    rows = [{**r, "combination": f"{LABEL} | robot.wheel_noise_mps=0.1"} for r in _rows(ROWS_PER_SEED)]
    text = results.table(rows, seeds=5, settings=noisy)
    assert "with robot.wheel_noise_mps=0.1." in text
    assert "| fuzzy, dynamic V_N | low | - | 1.70 ± 1.29 [3.40] | - |" in text
    with pytest.raises(ValueError, match="--set links.obs_drop: the table varies that key itself"):
        results.jobs(range(2), {"links.obs_drop": 0.5})
    begin, end = results.markers("claims", "robot.wheel_noise_mps=0.1")
    assert (begin.split()[:3], end.split()[:3]) == (["<!--", "claims", "(robot.wheel_noise_mps=0.1):"],) * 2
    assert (begin, end) != results.markers("claims")  # its own: not the baseline's
    doc = tmp_path / "doc.md"
    doc.write_text(f"{results.BEGIN}\nbaseline\n{results.END}\n{begin}\nold\n{end}\n")
    sections.write_into(doc, "noisy claims", begin, end)
    assert doc.read_text().splitlines() == [results.BEGIN, "baseline", results.END, begin, "noisy claims", end]


def _claim_rows(n: int = 3) -> dict[str, list[dict]]:
    def rows(**metrics: object) -> list[dict]:
        return [{"seed": s, **metrics} for s in range(n)]

    swap = {f"r{i}_formations": "rank_left>rank_right" for i in (1, 2, 3)}
    turning = {"r2_turn_rms_m": 1.27, "r2_straight_rms_m": 0.8, "r2_turn_mean_lag_m": 1.04, "r2_max_ahead_m": 0.0}
    return {
        "static 1.5": rows(r2_rms_m=1.15, r2_max_m=1.93, **turning),
        "static 2": rows(r2_rms_m=1.25, r2_max_m=2.5, **{**turning, "r2_max_ahead_m": 0.55}),
        "dynamic": rows(r2_rms_m=0.72, r2_max_m=1.35, **turning),
        "ekf": rows(r2_ekf_rms_m=0.1, r2_measured_rms_m=0.23, r2_ekf_ratio=0.1 / 0.23),
        "obstacles": rows(
            **{f"r{i}_formations": "line>triangle" for i in (1, 2, 3)},
            collisions=0,
            obstacle_collisions=0,
            min_distance_m=1.3,
            r3_max_m=4.0,
        ),
        "obstacles, no avoidance": rows(
            **{f"r{i}_formations": "line>triangle" for i in (1, 2, 3)},
            collisions=0,
            obstacle_collisions=0,
            min_distance_m=1.4,
            r3_max_m=4.0,
        ),
        "rank swap": rows(**swap, collisions=0, obstacle_collisions=0, min_distance_m=1.2),
        "rank swap, no avoidance": rows(**swap, collisions=2, obstacle_collisions=0, min_distance_m=0.35),
    }


def test_a_claims_verdict_says_in_how_many_seeds_it_holds() -> None:
    assert [claims.Claim("a", "", holds, 3).verdict for holds in (3, 0)] == ["yes", "no"]
    assert claims.Claim("a", "", 2, 3).verdict == "in 2 of 3 seeds"


def test_the_claims_hold_seed_by_seed_on_the_criteria_of_test_claims() -> None:
    rows = _claim_rows()
    assert [c.verdict for c in claims.measure(rows)] == ["yes"] * 5
    assert claims.rank_swap(rows).verdict == "yes"  # the avoidance's statement, not a claim
    # One seed where dynamic V_N's max error is not the lowest: claim a holds in 2 of 3 seeds.
    rows["dynamic"][1] = {**rows["dynamic"][1], "r2_max_m": 2.0}
    # Static 1.5 a hair ahead of its target once: "never ahead" fails in that seed only.
    rows["static 1.5"][2] = {**rows["static 1.5"][2], "r2_max_ahead_m": 0.01}
    rows["ekf"] = [{**r, "r2_ekf_rms_m": 0.2, "r2_ekf_ratio": 0.87} for r in rows["ekf"]]  # no seed halves it
    rows["obstacles"][0] = {**rows["obstacles"][0], "collisions": 1}
    rows["dynamic"][0] = {**rows["dynamic"][0], "r2_rms_m": 0.70}
    rows["dynamic"][2] = {**rows["dynamic"][2], "r2_rms_m": 0.74}
    got = {c.name[:12]: c for c in claims.measure(rows)}
    assert (got["a. dynamic V"].holds, got["a. dynamic V"].seeds) == (2, 3)
    assert "Both lower in 2 of 3 seeds" in got["a. dynamic V"].measured
    assert "dynamic 1.350-2.000 m" in got["a. dynamic V"].measured
    assert (got["b. static 1."].holds, got["b. static 1."].seeds) == (2, 3)
    assert "ahead by up to 0.000-0.010 m" in got["b. static 1."].measured
    assert (got["c. the EKF's"].holds, got["c. the EKF's"].verdict) == (0, "no")
    assert "ratio 0.87" in got["c. the EKF's"].measured
    assert (got["d. the obsta"].holds, got["d. the obsta"].seeds) == (2, 3)
    rows["rank swap"][1] = {**rows["rank swap"][1], "min_distance_m": 0.39}  # a graze with eq. 11-13
    assert not [c for c in claims.measure(rows) if "rank" in c.measured]  # not among the paper's claims
    swap = claims.rank_swap(rows)
    assert (swap.holds, swap.seeds) == (2, 3)
    assert "Without eq. 11-13 (`controller.avoidance = false`): two robots touch in 3 of 3 seeds (6 contacts)" in (
        swap.measured
    )
    text = claims.table(rows, "robot.wheel_noise_mps=0.1")
    assert text.startswith("The paper's claims with robot.wheel_noise_mps=0.1: seeds 0-2, runs in one process")
    assert "rank" not in text
    assert "| b. static 2 overshoots | gets 0.550 m (mean 0.550 ± 0.000) ahead of its target" in text
    assert "RMS: dynamic 0.700-0.740 m (mean 0.720 ± 0.050)" in text  # t(2) 4.303 x 0.02 / sqrt 3


def test_claim_rows_go_to_csv_and_back_exactly(tmp_path: Path) -> None:
    rows = _claim_rows()
    rows["dynamic"][1] = {**rows["dynamic"][1], "r2_rms_m": 0.1 + 0.2, "note": None}  # 0.30000000000000004
    path = tmp_path / "claims.csv"
    claims.write_rows(path, rows)
    back = claims.read_rows(path)
    assert list(back) == list(rows)
    assert back["dynamic"][1]["r2_rms_m"] == 0.1 + 0.2  # every digit of the float
    assert back["dynamic"][1]["note"] is None
    assert back["obstacles"][2]["r1_formations"] == "line>triangle"
    assert back["obstacles"][2]["collisions"] == 0
    assert [c.verdict for c in claims.measure(back)] == [c.verdict for c in claims.measure(rows)]
    assert not list(tmp_path.glob("*.tmp"))
