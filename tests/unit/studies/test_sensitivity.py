"""`swarm results --sensitivity`: the points of each axis, the runs they share
with the claims' own, where a claim is said to hold, and the figure."""

from __future__ import annotations

import math
import re
import statistics
from pathlib import Path

import pytest
from scipy import stats

from formation_swarm.common.faults import Fault
from formation_swarm.studies import claims, results, sensitivity
from formation_swarm.studies.sensitivity import AXIS_NAMES, Axis, Point
from formation_swarm.studies.sensitivity import figure as sensitivity_figure
from formation_swarm.studies.sensitivity import rows as sensitivity_rows
from formation_swarm.studies.sensitivity import run as sensitivity_run
from formation_swarm.studies.sensitivity import text as sensitivity_text
from formation_swarm.studies.sensitivity.text import Band


def _claims(holds: list[int], seeds: int = 10) -> list[claims.Claim]:
    return [claims.Claim(f"claim {k}", "", h, seeds) for k, h in enumerate(holds)]


def _points(axis: sensitivity.Axis, holds_a: list[int]) -> list[Point]:
    return [Point(v, _claims([h, 10, 0, 5, 10])) for v, h in zip(axis.values, holds_a, strict=True)]


SPEED = Axis("s", "leader speed", "m/s", (1.0, 1.25, 1.5, 1.75, 2.0), 1.5, lambda v: {"leader.speed_mps": v})


def test_holds_finds_each_claims_band_with_its_seeds() -> None:
    pts = _points(SPEED, [0, 3, 10, 10, 10])
    assert sensitivity_text.holds(pts, 0) == Band(
        seeds=10, tried=5, every=(1.5, 1.75, 2.0), some=((1.25, 3, 10),), none=(1.0,)
    )
    assert sensitivity_text.holds(pts, 1) == Band(seeds=10, tried=5, every=SPEED.values)
    assert sensitivity_text.holds(pts, 2) == Band(seeds=10, tried=5, none=SPEED.values)
    assert sensitivity_text.holds(pts, 3) == Band(seeds=10, tried=5, some=tuple((v, 5, 10) for v in SPEED.values))
    gaps = _points(SPEED, [10, 0, 10, 0, 10])
    assert sensitivity_text.holds(gaps, 0) == Band(seeds=10, tried=5, every=(1.0, 1.5, 2.0), none=(1.25, 1.75))


def test_holds_for_says_each_claims_band_with_its_seeds() -> None:
    pts = _points(SPEED, [0, 3, 10, 10, 10])
    assert (
        sensitivity_text.holds_for(SPEED, pts, 0)
        == "holds in 10/10 seeds at 1.5-2 m/s; in 3/10 at 1.25 m/s; 0/10 at 1 m/s"
    )
    said = {k: sensitivity_text.holds_for(SPEED, pts, k) for k in (1, 2, 3)}
    assert said[1].startswith("holds in 10/10 seeds at every value tried")
    assert said[1].endswith(" (1-2 m/s)")  # the values tried
    assert said[2] == said[1].replace("10/10", "0/10")  # in none, the same way
    assert said[3].startswith("holds in 5/10 at 1 m/s, ")  # in some seeds only: each value with its count
    assert re.findall(r"(\d+)/(\d+) at ([\d.]+) m/s", said[3]) == [("5", "10", f"{v:g}") for v in SPEED.values]
    gaps = _points(SPEED, [10, 0, 10, 0, 10])
    assert sensitivity_text.holds_for(SPEED, gaps, 0).endswith(" at 1, 1.5, 2 m/s; 0/10 at 1.25, 1.75 m/s")


def test_the_speed_axis_is_fine_where_claims_a_and_b_change_and_drops_go_to_half() -> None:
    speed = AXIS_NAMES["leader_speed"]
    assert speed.values == (1.0, 1.25, 1.3, 1.35, 1.4, 1.45, 1.5, 1.55, 1.6, 1.65, 1.7, 1.75, 1.8, 2.0)
    drops = AXIS_NAMES["obs_drop"]
    assert [drops.point(v) for v in drops.values] == [({}, [])] + [
        ({"links.obs_drop": p}, []) for p in (0.1, 0.2, 0.3, 0.4, 0.5)
    ]
    assert drops.label(30.0) == "30 %"


def test_the_shipped_value_is_the_claims_own_runs() -> None:
    speed = AXIS_NAMES["leader_speed"]
    assert speed.point(1.5) == ({}, [])
    assert speed.point(1.0) == ({"leader.speed_mps": 1.0}, [])
    out = Path("/nonexistent")
    shipped = sensitivity.plan(range(3), {}, [], out, workers=1, extras=speed.extras)
    own = results.claim_sweeps(range(3), {}, out, 1)
    for name, sweep in own.items():  # the same run folders: the claims' runs are not run twice
        assert [j.name for j in shipped[name].jobs] == [j.name for j in sweep.jobs]
        assert shipped[name].out == sweep.out
    slow = sensitivity.plan(range(3), {"leader.speed_mps": 1.0}, [], out, workers=1, extras=speed.extras)
    assert set(slow) == set(claims.SWEEPS) | {"static 1.7", "static 1.8", "l-psi"}
    assert not {j.name for j in slow["dynamic"].jobs} & {j.name for j in own["dynamic"].jobs}
    assert slow["l-psi"].jobs[0].overrides == {"controller.law": "lpsi", "leader.speed_mps": 1.0}


def test_a_bias_is_a_fault_on_every_left_wheel_and_the_camera_noise_is_told_to_the_ekf() -> None:
    bias = AXIS_NAMES["wheel_bias"]
    assert bias.point(0.0) == ({}, [])
    settings, faults = bias.point(3.0)
    left = Fault.make("wheel_bias", "*", 0, left=0.03)  # every robot's left wheel, from the start: 3 %
    assert (settings, [Fault.parse(f) for f in faults]) == ({}, [left])
    sweep = sensitivity.plan(range(1), settings, faults, Path("/nonexistent"), workers=1)["dynamic"]
    assert [Fault.parse(f) for f in sweep.faults] == [left]
    cam, faults = AXIS_NAMES["camera_noise"].point(0.1)  # Fig. 9's camera
    assert faults == []
    assert cam["camera.sigma_rho_m"] == cam["controller.ekf.sigma_rho_m"] == 0.1
    assert cam["camera.sigma_phi_deg"] == 5.0
    assert cam["controller.ekf.sigma_phi_rad"] == pytest.approx(0.0873, abs=1e-4)  # fig9_ekf_noise.toml's
    assert cam["controller.ekf.sigma_beta_rad"] == pytest.approx(0.0436, abs=1e-4)


@pytest.mark.parametrize("n", [2, 5, 30])
def test_a_statistic_is_the_mean_with_students_t_half_width(n: int) -> None:
    values = [math.cos(1.3 * i) + 0.2 * i for i in range(n)]
    st = sensitivity.stat([*values, None, math.nan])  # what is not a number is left out
    assert st.n == n
    assert st.mean == pytest.approx(statistics.fmean(values), rel=1e-12)
    want = stats.t.ppf(0.975, n - 1) * statistics.stdev(values) / math.sqrt(n)
    assert st.half == pytest.approx(want, rel=1e-3)
    assert math.isnan(sensitivity.stat([1.0]).half)


def _row(seed: int, rms: float, ahead: float = 0.0, lag: float = 0.8) -> dict:
    return {
        "seed": seed,
        "exit_code": 0,
        "lockstep_misses": 0,
        "r2_rms_m": rms,
        "r2_max_m": 2 * rms,
        "r2_turn_rms_m": 1.2,
        "r2_straight_rms_m": 0.8,
        "r2_turn_mean_lag_m": lag,
        "r2_max_ahead_m": ahead,
        "r2_ekf_rms_m": 0.1,
        "r2_measured_rms_m": 0.25,
        "r2_ekf_ratio": 0.4,
        "collisions": 0,
        "obstacle_collisions": 0,
        "min_distance_m": 1.3,
        "r3_max_m": 4.0,
        **{f"r{i}_formations": "line>triangle" for i in (1, 2, 3)},
        "leader_off_path_m": 5.05,
        "leader_end_m": 1.9,
    }


def _swap(seed: int, avoidance: bool) -> dict:
    formations = {f"r{i}_formations": "rank_left>rank_right" for i in (1, 2, 3)}
    return {
        **_row(seed, 0.5),
        **formations,
        "collisions": 0 if avoidance else 2,
        "min_distance_m": 1.2 if avoidance else 0.35,
    }


def _rows(dynamic_rms: float) -> dict[str, list[dict]]:
    return {
        "dynamic": [_row(s, dynamic_rms + 0.02 * s) for s in range(3)],
        "static 1.5": [_row(s, 1.1 + 0.01 * s) for s in range(3)],
        "static 2": [_row(s, 1.2, ahead=0.5, lag=0.1) for s in range(3)],
        "ekf": [_row(s, 0.7) for s in range(3)],
        "obstacles": [_row(s, 0.5) for s in range(3)],
        "obstacles, no avoidance": [_row(s, 0.5) for s in range(3)],
        "rank swap": [_swap(s, avoidance=True) for s in range(3)],
        "rank swap, no avoidance": [_swap(s, avoidance=False) for s in range(3)],
        "l-psi": [_row(s, 0.09) for s in range(3)],
    }


def test_a_point_measures_the_claims_and_the_figures_metrics() -> None:
    pt = sensitivity.measure(1.0, _rows(0.7))
    assert [c.holds for c in pt.claims] == [3, 3, 3, 3, 3]  # the paper's a-d
    assert pt.swap is not None
    assert (pt.swap.holds, pt.swap.seeds) == (3, 3)
    assert pt.counts["robot contact, rank swap"] == pt.counts["obstacle contact, rank swap"] == 0
    assert pt.counts["robot contact, rank swap, no avoidance"] == pt.counts["runs rank swap, no avoidance"] == 3
    assert pt.stats["dynamic", "leader_off_path_m"].mean == pytest.approx(5.05)
    assert pt.stats["dynamic", "r2_rms_m"].mean == pytest.approx(0.72)
    assert pt.stats["l-psi", "r2_rms_m"].mean == pytest.approx(0.09)
    assert ("static 1.7", "r2_rms_m") not in pt.stats  # not flown at this point
    assert sensitivity.measure(1.0, _rows(1.09)).claims[0].holds == 1  # dynamic 1.09, 1.11, 1.13 vs 1.10-1.12


def test_the_section_and_the_figure_of_an_axis(tmp_path: Path) -> None:
    axis = AXIS_NAMES["wheel_noise"]
    pts = [sensitivity.measure(v, _rows(rms)) for v, rms in zip(axis.values, (0.7, 0.9, 1.09), strict=True)]
    text = sensitivity_text.markdown(axis, pts, "figures/sensitivity-wheel_noise.png")
    assert (
        "- a. dynamic V_N has lower RMS and max error than static 1.5 and 2: holds in 3/3 seeds at 0-0.05 m/s; " in text
    )
    assert "in 1/3 at 0.1 m/s." in text
    assert "| | 0 m/s (shipped) | 0.05 m/s | 0.1 m/s |" in text
    assert "| claim a: seeds where it holds | 3/3 | 3/3 | 1/3 |" in text
    assert "| formation error RMS, m: fuzzy, dynamic V_N | 0.72 ± 0.05 | 0.92 ± 0.05 | 1.11 ± 0.05 |" in text
    assert "| claim d: runs in which a robot touches an obstacle | 0/3 | 0/3 | 0/3 |" in text
    least = "| least distance between two robots' centres, m (claim d, fig11_obstacles; touching below 0.4) |"
    assert least + " 1.30 ± 0.00 | 1.30 ± 0.00 | 1.30 ± 0.00 |" in text
    assert "rank swap" not in text  # the avoidance's section says it, not the claims'
    assert "| the leader's largest distance from its path, m | 5.05 ± 0.00 | 5.05 ± 0.00 | 5.05 ± 0.00 |" in text
    assert "![wheel noise](figures/sensitivity-wheel_noise.png)" in text
    fig = sensitivity_figure.figure(axis, pts)
    panels = fig.axes
    assert len(panels) == 6
    assert [len(ax.lines) > 0 for ax in panels] == [True] * 6
    legend = [t.get_text() for t in panels[0].get_legend().get_texts()]
    assert legend == [sensitivity.LINES[name] for name in ("dynamic", "static 1.5", "static 2", "l-psi")]
    path = sensitivity_figure.write_figure(tmp_path / "s.png", axis, pts)
    assert path.stat().st_size > 20_000


def test_sensitivity_refuses_claims_set_and_a_missing_marker_before_running(tmp_path: Path, capsys) -> None:
    doc = tmp_path / "r.md"
    doc.write_text("<!-- sensitivity (wheel_noise): begin -->\n<!-- sensitivity (wheel_noise): end -->\n")
    out = tmp_path / "sweeps"
    assert results.main(["--sensitivity", "--claims", "--out", str(out)]) == 2
    assert results.main(["--sensitivity", "--set", "robot.wheel_noise_mps=0.1", "--out", str(out)]) == 2
    assert results.main(["--axis", "wheel_noise", "--out", str(out)]) == 2
    assert results.main(["--sensitivity", "--axis", "wheel_bias", "--write", str(doc), "--out", str(out)]) == 2
    figures = tmp_path / "figs"
    (tmp_path / "taken").write_text("")
    assert results.main(["--sensitivity", "--out", str(tmp_path / "taken"), "--figures", str(figures)]) == 2
    assert not figures.exists()
    err = capsys.readouterr().err
    assert "takes neither --claims nor --set" in err
    assert "--axis needs --sensitivity" in err
    assert "has no <!-- sensitivity (wheel_bias): begin -->" in err
    assert not out.exists()  # nothing made for a bad input


def test_rows_of_an_axis_go_to_the_csv_and_back_and_the_others_are_kept(tmp_path: Path) -> None:
    path = tmp_path / "sensitivity.csv"
    speed, drops = AXIS_NAMES["leader_speed"], AXIS_NAMES["obs_drop"]
    first = {v: _rows(0.7) for v in (1.0, 1.25)}
    first[1.25]["dynamic"][1] = {**first[1.25]["dynamic"][1], "r2_rms_m": 0.1 + 0.2}  # 0.30000000000000004
    sensitivity_rows.merge(path, speed.name, first)
    table = sensitivity_rows.merge(path, drops.name, {0.0: _rows(0.7), 50.0: _rows(1.09)})
    assert sensitivity_rows.read(path) == table
    assert list(table) == ["leader_speed", "obs_drop"]
    back = table["leader_speed"][1.25]
    assert back["dynamic"][1]["r2_rms_m"] == 0.1 + 0.2  # every digit
    assert back["rank swap"][0]["r1_formations"] == "rank_left>rank_right"
    assert "ticks_per_s" not in back["dynamic"][0]  # wall time is no figure of the run
    assert set(back) == set(_rows(0.7))
    sensitivity_rows.merge(path, speed.name, {1.0: _rows(1.09)})  # run again: replaces its own rows only
    again = sensitivity_rows.read(path)
    assert list(again["leader_speed"]) == [1.0]
    assert again["obs_drop"] == table["obs_drop"]
    assert not list(tmp_path.glob("*.tmp"))


def test_where_each_claim_holds_is_written_from_the_csv(tmp_path: Path) -> None:
    path = tmp_path / "sensitivity.csv"
    sensitivity_rows.merge(path, "obs_drop", {0.0: _rows(0.7), 50.0: _rows(1.09)})
    sensitivity_rows.merge(path, "leader_speed", {1.0: _rows(1.09), 1.5: _rows(0.7)})
    text = sensitivity_run.where_text(path)
    lines = text.splitlines()
    assert lines[0].startswith("From the sensitivity runs below (seeds 0-2 at every value")
    speed, drops = AXIS_NAMES["leader_speed"], AXIS_NAMES["obs_drop"]
    say = sensitivity_text.say_band
    a = lines.index("- **a. dynamic V_N has lower RMS and max error than static 1.5 and 2.**")
    assert lines[a + 1 : a + 3] == [  # the axes in AXES' order; claim a held in every seed at the low error only
        f"  - {speed.title}: {say(speed, Band(seeds=3, tried=2, every=(1.5,), some=((1.0, 1, 3),)))}.",
        f"  - {drops.title}: {say(drops, Band(seeds=3, tried=2, every=(0.0,), some=((50.0, 1, 3),)))}.",
    ]
    assert "rank swap" not in text  # not one of the paper's claims
    d = lines.index("- **d. the obstacle run goes triangle, line, triangle, no collision.**")
    assert lines[d + 3].startswith("  - `fig11_obstacles` without eq. 11-13 (`controller.avoidance = false`)")
    swap = sensitivity_run.swap_text(path).splitlines()
    assert swap[0].startswith("`fig11_rank_swap` at every value of the sensitivity axes (seeds 0-2,")
    touch = "two robots touch"  # without eq. 11-13, in every seed at every value
    assert swap[2:7] == [
        f"- {speed.title}:",
        f"  - with eq. 11-13: {say(speed, Band(seeds=3, tried=2, every=(1.0, 1.5)), 'swaps without contact')}; "
        f"{say(speed, Band(seeds=3, tried=2, none=(1.0, 1.5)), touch)}; "
        f"{say(speed, Band(seeds=3, tried=2, none=(1.0, 1.5)), 'a robot touches a post')}.",
        f"  - without: {say(speed, Band(seeds=3, tried=2, every=(1.0, 1.5)), touch)}.",
        "  - closest approach with: 1 m/s 1.20 ± 0.00, 1.5 m/s 1.20 ± 0.00.",
        "  - closest approach without: 1 m/s 0.35 ± 0.00, 1.5 m/s 0.35 ± 0.00.",
    ]
    assert swap[8].startswith("  - with eq. 11-13: swaps without contact in 3/3 seeds at every value tried (0, 50 %); ")


def test_the_ablation_table_says_both_ways_with_closest_approaches() -> None:
    rows = _rows(0.7)
    rows["rank swap, no avoidance"][2] = {**rows["rank swap, no avoidance"][2], "collisions": 0, "min_distance_m": 0.41}
    text = claims.avoidance_table(rows)
    assert text.startswith("Seeds 0-2, runs in one process (`formation_swarm.engine`), with the partition-zone")
    assert "| `fig11_obstacles` | off | 0 of 3 | 0 | 0 | 1.300-1.300 (1.300) |" in text
    assert "| `fig11_rank_swap` | on (as shipped) | 0 of 3 | 0 | 0 | 1.200-1.200 (1.200) |" in text
    assert "| `fig11_rank_swap` | off | 2 of 3 | 4 | 0 | 0.350-0.410 (0.350) |" in text
    assert text.endswith(
        "- `fig11_obstacles`: no two robots touch in any of the 3 seeds, with eq. 11-13 or without them; "
        "the avoidance is not what keeps them apart there.\n"
        "- `fig11_rank_swap`: two robots touch in 2 of 3 seeds without eq. 11-13 and in 0 with them; "
        "the avoidance is what keeps them apart."
    )
    rows["rank swap"][0] = {**rows["rank swap"][0], "collisions": 1}
    assert claims.avoidance_table(rows).endswith(
        "- `fig11_rank_swap`: two robots touch in 2 of 3 seeds without eq. 11-13 and in 1 with them."
    )


def test_rows_need_a_study_and_the_claims_need_the_ablations_markers_before_running(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sweeps"
    assert results.main(["--rows", str(tmp_path / "r.csv"), "--out", str(out)]) == 2
    doc = tmp_path / "r.md"
    doc.write_text("<!-- claims: begin -->\n<!-- claims: end -->\n")  # no ablation markers
    assert results.main(["--claims", "--write", str(doc), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--rows needs --claims or --sensitivity" in err
    assert "has no <!-- avoidance ablation: begin -->" in err
    assert not out.exists()
