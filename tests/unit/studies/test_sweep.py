"""swarm sweep: the grid, the tables, resuming."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from formation_swarm.runtime import summary as summary_mod
from formation_swarm.studies import sweep, tables
from formation_swarm.studies.jobs import Job, grid, parse_set
from formation_swarm.studies.sweep import Sweep
from formation_swarm.studies.tables import aggregate
from tests.helpers import SCENARIOS


def test_set_values_are_toml_or_bare_strings() -> None:
    assert parse_set("controller.vn=1.5,dynamic") == ("controller.vn", [1.5, "dynamic"])
    assert parse_set("links.obs_drop = 0, 0.1 ,0.3") == ("links.obs_drop", [0, 0.1, 0.3])
    assert parse_set("controller.use_ekf=true,false") == ("controller.use_ekf", [True, False])
    for bad in ("controller.vn", "=1,2", "controller.vn="):
        with pytest.raises(ValueError, match="key=v1,v2"):
            parse_set(bad)


def test_a_value_given_twice_or_a_seed_is_refused_before_any_run(tmp_path: Path, capsys) -> None:
    """Two equal values made one run twice, in one folder at once (the second
    overwrote the first with a failure); a --set run.seed was overridden by the
    sweep's own seeds, so both 'seeds' ran seed 0."""
    for text, said in (
        (
            "controller.vn=1.5,1.5",
            "--set controller.vn: the value '1.5' is given twice (as '1.5' before it: the same value)",
        ),
        (
            "controller.vn=1.5,1.50",
            "--set controller.vn: the value '1.50' is given twice (as '1.5' before it: the same value)",
        ),
        (
            "controller.vn=2,2.0",
            "--set controller.vn: the value '2.0' is given twice (as '2' before it: the same value)",
        ),
        ("run.seed=5,6", "--set run.seed: a sweep gives every combination its seeds; use --seeds N and --seed-start S"),
    ):
        with pytest.raises(ValueError, match="^" + said.replace("(", r"\(").replace(")", r"\)") + "$"):
            parse_set(text)
    assert parse_set("controller.use_ekf=true,1") == ("controller.use_ekf", [True, 1])  # not the same value
    out = tmp_path / "sw"
    argv = ["fig7_turn_vn_dynamic", "--seeds", "1", "--out", str(out)]
    assert sweep.main([*argv, "--set", "controller.vn=1.5", "--set", "controller.vn=2"]) == 2
    err = capsys.readouterr().err
    assert err == "swarm sweep: --set controller.vn is given twice: put its values in one, e.g. controller.vn=1.5,2\n"
    assert sweep.main([*argv, "--set", "controller.vn=1.5,1.5"]) == 2
    assert "given twice" in capsys.readouterr().err
    assert not out.exists()  # nothing made


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
        Sweep(
            SCENARIOS / "fig7_turn_vn_dynamic.toml", [Job("controller.vn=fast", {"controller.vn": "fast"}, 0)], tmp_path
        )


def _rows(values: list[object]) -> list[dict[str, object]]:
    """runs.csv rows: two followers, three seeds per value, r2's RMS = value + seed / 10."""
    return [
        {
            "combination": f"links.obs_drop={v}",
            "seed": s,
            "run": f"{v}-{s}",
            "r2_rms_m": (v if isinstance(v, float) else k) + s / 10,
            "r3_rms_m": 1.0 + s,
            "r2_max_m": 2.0,
            "r3_max_m": 3.0,
            "min_distance_m": 1.5,
            "ticks": 100,
        }
        for k, v in enumerate(values)
        for s in range(3)
    ]


def test_sweep_figure_draws_each_metric_with_its_interval() -> None:
    from formation_swarm.studies.sweep.figure import figure

    values = [0.0, 0.1, 0.3]
    jobs = [
        Job(f"links.obs_drop={v}", {"links.obs_drop": v, "run.duration_s": 5.0}, s) for v in values for s in range(3)
    ]
    agg = aggregate(_rows(values))
    fig = figure(agg, jobs, "fig11_obstacles")
    rms, peak, dist = (ax for ax in fig.axes if ax.axison)
    (spare,) = (ax for ax in fig.axes if not ax.axison)  # says why there is no EKF panel
    (note,) = [t.get_text() for t in spare.texts]
    assert note.startswith("no EKF target errors")
    assert "swarm sweep --logger" in note  # how to have them
    assert [c.get_label() for c in rms.containers] == ["R2", "R3"]  # one line per follower
    assert [c.get_label() for c in peak.containers] == ["R2", "R3"]
    assert [c.get_label() for c in dist.containers] == ["all robots"]  # pooled
    assert rms.get_xlabel() == "links.obs_drop"  # the swept key; run.duration_s is the same in every job
    line, _caps, (bars,) = rms.containers[0]
    x, y = line.get_data()
    assert np.allclose(x - x.mean(), np.array(values) - np.mean(values))  # on the values, shifted together
    assert np.allclose(y, np.array(values) + 0.1)  # mean over seeds 0, 1, 2
    half = 4.303 * 0.1 / math.sqrt(3)  # t(0.975, 2 dof) * s / sqrt(n), s = 0.1
    (seg0,) = bars.get_segments()[:1]
    assert seg0[:, 1] == pytest.approx([0.1 - half, 0.1 + half])
    assert fig.get_suptitle().startswith("fig11_obstacles: mean and 95% confidence interval over 3 seeds")


def test_a_sweep_figure_of_many_followers_draws_their_median_and_the_worst_and_one_seed_says_so() -> None:
    from formation_swarm.studies.sweep.figure import figure

    values = [0.0, 0.3]
    jobs = [Job(f"links.obs_drop={v}", {"links.obs_drop": v}, 0) for v in values]
    rows = [
        {
            "combination": f"links.obs_drop={v}",
            "seed": 0,
            "run": f"{v}",
            **{f"r{r}_rms_m": v + r / 100 for r in range(2, 21)},
        }
        for v in values
    ]
    fig = figure(aggregate(rows), jobs)
    (ax,) = (a for a in fig.axes if a.axison)
    median_label, worst_label = [t.get_text() for t in ax.get_legend().get_texts()]
    assert (median_label.split()[0], re.findall(r"\d+", median_label)) == ("median", ["19"])  # of 19 followers
    assert worst_label.endswith(": R20")  # the largest mean
    median = next(line for line in ax.get_lines() if line.get_label() == median_label)
    assert np.allclose(median.get_ydata(), [0.11, 0.41])  # R2..R20: 0.02..0.20 above the value, median 0.11
    assert fig.get_suptitle().startswith("1 seed per value")
    assert "no confidence interval" in fig.get_suptitle()


def test_sweep_figure_puts_non_numeric_values_on_ticks() -> None:
    from formation_swarm.studies.sweep.figure import figure

    values = [1.5, "dynamic"]
    jobs = [Job(f"controller.vn={v}", {"controller.vn": v}, s) for v in values for s in range(3)]
    rows = [dict(r, combination=f"controller.vn={v}") for v in values for r in _rows([v])]
    fig = figure(aggregate(rows), jobs)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["1.5", "dynamic"]
    assert ax.get_xlabel() == "controller.vn"
    assert len(ax.containers) == 2


def test_a_sweep_says_the_loaders_warnings_once_each_in_its_own_words(tmp_path) -> None:
    import warnings as w

    from formation_swarm.spec import scenario as sm

    lines: list[str] = []
    jobs = [Job("leader.speed_mps=1.0", {"leader.speed_mps": 1.0}, s) for s in range(3)]
    with w.catch_warnings():
        w.simplefilter("error", sm.ScenarioWarning)  # none escapes as a Python warning
        Sweep(SCENARIOS / "fig7_turn_vn_dynamic.toml", jobs, tmp_path, progress=lines.append)
    assert len(lines) == 1
    assert lines[0].startswith("[sweep] fig7_turn_vn_dynamic leader.speed_mps=1.0: leader.speed_mps = 1 is below")


def test_a_lockstep_run_whose_recording_misses_ticks_is_not_taken_as_done(tmp_path: Path) -> None:
    follower = {"role": "follower", "answered": 880}
    whole = {
        "mode": "lockstep",
        "exit_code": 0,
        "messages": {"truth_sent": 880},
        "parts": {"logger": {"messages": {"truth": 880, "telemetry": 880}}, "agent-2": follower},
    }
    lossy = {**whole, "parts": {**whole["parts"], "logger": {"messages": {"truth": 715, "telemetry": 880}}}}
    assert summary_mod.recording_gap(whole) is None
    assert _gap(lossy) == ["715", "880"]
    assert "ticks the world sent" in summary_mod.recording_gap(lossy)
    no_tel = {**whole, "parts": {**whole["parts"], "logger": {"messages": {"truth": 880, "telemetry": 820}}}}
    assert _gap(no_tel) == ["820", "880"]
    assert "telemetry messages the followers sent" in summary_mod.recording_gap(no_tel)
    # Where, robot by robot: the logger's per-sender first and last tick and the gaps between.
    ticks = {
        "0": {"first": 0, "last": 879, "missing": 0, "gaps": []},
        "2": {"first": 3, "last": 822, "missing": 0, "gaps": []},
    }
    placed = {**no_tel, "parts": {**no_tel["parts"], "logger": {**no_tel["parts"]["logger"], "ticks": ticks}}}
    assert summary_mod.recording_gap(placed) == (
        "the logger recorded 820 of the 880 telemetry messages R2 sent (one per tick answered) "
        "(missing: R2's telemetry ticks 0-2, 823-879)"
    )
    truth_gap = {"0": {"first": 0, "last": 879, "missing": 165, "gaps": [[100, 264]]}}
    cut = {**lossy, "parts": {**lossy["parts"], "logger": {**lossy["parts"]["logger"], "ticks": truth_gap}}}
    assert _gap(cut) == ["715", "880", "100", "264"]
    assert summary_mod.recording_gap(cut).endswith("(missing: truth ticks 100-264)")
    # A run stopped from outside (Ctrl-C, a timeout): what was in flight is lost with it; nothing to tell.
    assert summary_mod.recording_gap({**cut, "interrupted": True}) is None
    assert summary_mod.recording_gap({**cut, "timed_out": True}) is None
    # A follower a fault killed: the batch it held died with it, by design; not a loss of the recording.
    killed = {**placed, "events": [{"event": "killed", "process": "agent-2", "fault": "kill agent-2@20s"}]}
    assert summary_mod.recording_gap(killed) is None
    silent = {**placed, "parts": {**placed["parts"], "logger": {**placed["parts"]["logger"], "ticks": truth_gap}}}
    silent["parts"]["logger"]["messages"] = {"truth": 880, "telemetry": 0}
    assert _gap(silent) == ["880", "2"]
    assert "recorded none of the 880 telemetry messages R2 sent" in summary_mod.recording_gap(silent)
    assert summary_mod.recording_gap({**lossy, "mode": "realtime"}) is None  # real time may drop by design
    assert summary_mod.recording_gap({**whole, "parts": {}}) is None  # no logger, no recording
    for name, summary in (("whole", whole), ("lossy", lossy)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "summary.json").write_text(json.dumps(summary))
    assert sweep._load_done(tmp_path / "whole") == whole
    assert sweep._load_done(tmp_path / "lossy") is None  # run again on resume


def test_a_sweeps_rows_and_progress_list_followers_by_number() -> None:
    """JSON's keys are text: r10 came before r2 in the tables and on the progress line."""
    row = tables.metrics({"followers": {str(r): {"rms_m": r / 10} for r in (2, 10, 3, 11)}})
    assert [k for k in row if k.endswith("_rms_m") and k.count("_") == 2] == [
        "r2_rms_m",
        "r3_rms_m",
        "r10_rms_m",
        "r11_rms_m",
    ]
    few = tables.metrics({"followers": {str(r): {"rms_m": r / 10} for r in (3, 2)}})
    assert tables.brief_rms(few) == (("2", 0.2), ("3", 0.3))
    assert re.findall(r"r(\d+)_rms ([\d.]+) m", tables.brief(few)) == [("2", "0.20"), ("3", "0.30")]
    # Beyond four followers, one line says their spread, not each.
    five = tables.metrics({"followers": {str(r): {"rms_m": r / 10} for r in (2, 10, 3, 11, 4)}})
    assert tables.brief(five) == "5 followers' RMS: median 0.40 m, worst 1.10 m (R11)"
    none = tables.metrics({"followers": {"2": {"rms_m": None}}})
    assert tables.brief_rms(none) == ()
    assert tables.brief(none).startswith("no follower")


def _gap(summary: dict) -> list[str]:
    """The numbers of what a run's recording misses (summary.recording_gap)."""
    return re.findall(r"\d+", summary_mod.recording_gap(summary) or "")
