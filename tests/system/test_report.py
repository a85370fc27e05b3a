"""swarm report: figures for every shipped scenario, not blank, and what they mark."""

from __future__ import annotations

import json
import math
import re
import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from formation_swarm.launch.launcher import RunResult
from formation_swarm.report.build import FIGURES, main, make_report
from tests.helpers import SCENARIOS


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sorted(p.name for p in SCENARIOS.glob("*.toml")))
def test_figures_for_every_shipped_scenario(swarm_run: Callable[..., RunResult], scenario: str) -> None:
    import matplotlib.image

    res = swarm_run(SCENARIOS / scenario)
    assert res.exit_code == 0
    out = make_report(res.run_dir)
    for name in FIGURES:
        img = matplotlib.image.imread(out / f"{name}.png")[..., :3]
        assert img.shape[0] > 200, name
        assert img.shape[1] > 400, name
        ink = np.mean(np.any(img < 0.9, axis=-1))  # share of pixels that are not (near) white
        assert ink > 0.03, (name, ink)
        rgb = (img.reshape(-1, 3) * 255).astype(np.uint8).astype(np.uint32)
        colours = len(np.unique(rgb[:, 0] << 16 | rgb[:, 1] << 8 | rgb[:, 2]))  # a colour as one number: 40x faster
        assert colours > 20, (name, colours)  # data lines in several colours, not only axes
    md = (out / "report.md").read_text()
    assert all(f"]({name}.png)" in md for name in FIGURES)
    assert "| R2 |" in md


def test_clear_errors_for_folders_it_cannot_use(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(tmp_path)]) == 2
    assert "no summary.json" in capsys.readouterr().err
    (tmp_path / "summary.json").write_text("{}")
    assert main([str(tmp_path)]) == 2
    assert "summary.json is not a run summary (a JSON object with the run's run_id)" in capsys.readouterr().err


def test_a_run_without_a_recording_gets_report_md_and_says_why_no_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = {"run_id": "r1", "scenario": "s", "recording": None, "followers": {"2": {"rms_m": 0.521}}}
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    assert main([str(tmp_path)]) == 0
    why = "the run had no logger (--no-logger), so it has no recording"
    (said,) = capsys.readouterr().out.splitlines()
    assert said.startswith(f"[report] {tmp_path / 'report'}: ")
    assert said.endswith(f"no figures: {why}")
    md = (tmp_path / "report" / "report.md").read_text()
    assert "| R2 | 0.521 |" in md
    assert f"No figures and no measured or EKF target errors (the last two columns): {why}." in md
    assert "![" not in md
    assert not list((tmp_path / "report").glob("*.png"))
    # A run stopped before its first tick: why nothing was drawn, and no raw None in report.md.
    stopped = {**summary, "ticks": None, "followers": {}, "exit_code": 130, "recording": "recording.rrd"}
    (tmp_path / "summary.json").write_text(json.dumps(stopped))
    assert main([str(tmp_path)]) == 0
    assert capsys.readouterr().out.endswith(
        "report.md only, no figures: nothing was recorded: the run ended before its first tick (exit code 130); "
        "it has no logs/ (the folder holds summary.json)\n"  # a pointer only to what is there
    )
    md = (tmp_path / "report" / "report.md").read_text()
    assert "No follower metrics: the run ended before its first tick." in md
    assert "no ticks (- s simulated)" in md
    assert "collisions -, with obstacles -." in md
    assert "None ticks" not in md
    assert "collisions None" not in md
    # A run that had a logger, whose recording is gone:
    (tmp_path / "summary.json").write_text(json.dumps({**summary, "recording": "recording.rrd", "ticks": 100}))
    assert main([str(tmp_path)]) == 0
    assert "no figures: its recording.rrd is missing from the folder" in capsys.readouterr().out


FAULTED = {
    "faults": [
        {
            "fault": "kill agent-3@20s",
            "kind": "kill",
            "target": "agent-3",
            "at_s": 20.0,
            "for_s": None,
            "start_tick": 400,
            "end_tick": None,
            "counts": {},
            "events": [{"tick": 400, "time_s": 20.0, "event": "killed", "robot": 3}],
            "recoveries": [
                {
                    "watched": [2],
                    "since_tick": 400,
                    "since_s": 20.0,
                    "bound_m": 0.5,
                    "first_below_after_s": 1.25,
                    "settled_after_s": None,
                    "window_s": 5.0,
                    "max_in_window_m": 0.99,
                }
            ],
        },
        {
            "fault": "drop obs:2@10s for=5s p=0.3",
            "kind": "drop",
            "target": "obs:2",
            "at_s": 10.0,
            "for_s": 5.0,
            "start_tick": 200,
            "end_tick": 300,
            "counts": {"dropped": 31},
            "events": [],
        },
        {
            "fault": "wheel_noise *@0s sigma_mps=0.1",
            "kind": "wheel_noise",
            "target": "*",
            "at_s": 0.0,
            "for_s": None,
            "start_tick": 0,
            "end_tick": None,
            "counts": {},
            "events": [],
        },
    ],
    "events": [
        {"event": "killed", "process": "agent-3", "sim_time_s": 20.0},
        {"event": "exited", "process": "agent-3", "code": -9, "sim_time_s": 20.0},
        {"event": "exited", "process": "logger", "code": 1, "sim_time_s": 31.5},
    ],
    "deaths": [{"robot": 3, "tick": 400, "time_s": 20.0}],
}


def test_faults_are_marked_on_the_time_axes_and_listed() -> None:
    from formation_swarm.report.faults import fault_marks, faults_markdown

    marks = fault_marks(FAULTED)
    # A kill is an instant; a windowed fault its window; an open-ended one runs to the end;
    # the logger's own exit is marked, agent 3's is the kill's doing.
    assert marks == [
        (20.0, None, "kill agent-3"),
        (10.0, 15.0, "drop obs:2"),
        (0.0, math.inf, "wheel_noise *"),
        (31.5, None, "logger exited"),
    ]
    text = "\n".join(faults_markdown(FAULTED))
    assert (
        "| `kill agent-3@20s` | from 400 | killed R3 at tick 400 (20.00 s); R2 below 0.5 m 1.25 s after the return "
        "at t=20.00 s, never settled (below it for 1 s in a row) by the end; largest error in the 5 s after: "
        "0.99 m | - |" in text
    )
    # its last tick, not the first after
    assert "| `drop obs:2@10s for=5s p=0.3` | 200-299 | - | 31 messages dropped |" in text
    assert "- logger exited with code 1 at sim t=31.50 s" in text
    assert "agent-3 was killed by SIGKILL" not in text  # said once, by the kill
    assert "- robot 3 lost its agent at tick 400 (20.00 s)" in text


def test_switches_snapshots_and_limits() -> None:
    from formation_swarm.report.figures import moving_average, robust_top, snapshot_times, switches

    events = [
        {"tick": 392, "time_s": 19.6, "robot": 1, "formation": "line"},
        {"tick": 393, "time_s": 19.65, "robot": 3, "formation": "line"},
        {"tick": 608, "time_s": 30.4, "robot": 1, "formation": "triangle"},
    ]
    assert switches(events) == [(19.6, "line"), (30.4, "triangle")]  # a leader's and its followers' change: one
    # At the start, each switch and mid-way through each formation: the line between the obstacles at 25 s.
    assert snapshot_times([19.6, 30.4], 53.0, 6) == [
        (0.0, "start"),
        (19.6, "switch"),
        (25.0, "held"),
        (30.4, "switch"),
        (41.7, "held"),
    ]
    assert [t for t, _ in snapshot_times([], 40.0, 5)] == [0.0, 10.0, 20.0, 30.0, 40.0]
    # A formation flown less than 2 s (a 20 s run that switches at 19.6 s) gets no mid-way snapshot,
    # whose label fell on the switch's.
    assert snapshot_times([19.6], 20.0, 6) == [(0.0, "start"), (19.6, "switch")]
    assert snapshot_times([], 40.0, 0) == []
    # A few outliers do not set the axis: it is cut, and says where the largest value is.
    top, cut = robust_top([np.r_[np.full(998, 0.1), np.full(2, 9.0)]])
    assert top == pytest.approx(0.115)
    assert cut == 9.0
    assert robust_top([np.array([0.0, 1.0, 2.0])]) == (pytest.approx(2.1), None)
    # V_N's moving average (display only): a 0.2 s window of 0.05 s ticks averages 4 ticks.
    vn = np.array([1.5, 2.0] * 10)
    assert moving_average(np.arange(20) * 0.05, vn, 0.2, 0.05)[5:15] == pytest.approx(np.full(10, 1.75))


def test_fault_lane_rows_keep_every_bar_and_label_apart() -> None:
    from formation_swarm.report.figures import lane_rows

    # Labels 2 s wide. 3 s alone; 6-8 s and an instant at 6 s overlap: two rows; 6.5 s
    # (its label to 8.5 s) overlaps both: a third; 12 s is clear of all: row 0 again.
    spans = [(3.0, 4.0), (6.0, 8.0), (6.0, None), (6.5, 7.0), (12.0, None)]
    assert lane_rows(spans, [2.0] * 5) == [0, 0, 1, 2, 0]
    # A window longer than its label keeps its row to its end; one to the run's end, to the axis's.
    assert lane_rows([(0.0, 30.0), (10.0, None), (31.0, None)], [1.0] * 3) == [0, 1, 0]
    assert lane_rows([], []) == []


def test_snapshots_of_a_long_column_are_drawn_apart() -> None:
    from formation_swarm.report.figures import apart

    def column(t: float, robots: int) -> dict[int, np.ndarray]:  # 1.5 m apart, the head at 1.5 t m
        return {r: np.array([0.0, 1.5 * t - 1.5 * (r - 1), 0.0]) for r in range(1, robots + 1)}

    every = [0.0, 10.6, 21.2, 31.8, 42.4, 53.0]
    # 30 robots span 43.5 m (44.5 with the gap) and travel 15.9 m between snapshots:
    # 0 s spans -43.5..0, 31.8 s spans 4.2..47.7, 53.0 s spans 36..79.5 (overlapping 31.8 s).
    assert apart([(t, "even", column(t, 30)) for t in every]) == [(0.0, "even"), (31.8, "even")]
    # three robots span 3 m: every snapshot is kept
    assert apart([(t, "even", column(t, 3)) for t in every]) == [(t, "even") for t in every]


def test_cf_paper_only_for_a_shipped_scenario_as_shipped(tmp_path: Path) -> None:
    from formation_swarm.report.paper import paper_figures
    from formation_swarm.spec.files import shipped

    text = shipped()["fig7_turn_vn_dynamic"].read_text()
    (tmp_path / "a.toml").write_text(text.replace("seed = 1", "seed = 7"))
    assert paper_figures(tmp_path / "a.toml") == {
        "trajectories": "Fig. 7a",
        "formation_error": "Fig. 7b",
        "vn": "Fig. 8",
    }
    (tmp_path / "b.toml").write_text(text.replace('vn = "dynamic"', "vn = 1.5"))
    assert paper_figures(tmp_path / "b.toml") == {}
    (tmp_path / "c.toml").write_text(text + '\n[[faults]]\nfault = "kill agent-2@5s"\n')
    assert paper_figures(tmp_path / "c.toml") == {}
    # The scenario as shipped, but the run cut short: not the paper's figure either.
    from formation_swarm.report.build import _context
    from formation_swarm.report.data import RunFolder
    from formation_swarm.report.inputs import read_scenario

    run = tmp_path / "run"
    run.mkdir()
    (run / "scenario.toml").write_text(text)
    config, sc = read_scenario(run / "scenario.toml") or ({}, None)
    whole = _context(RunFolder(run, {"end_reason": "duration_reached"}, config, sc, {}), [], [2])
    assert whole.paper == {"trajectories": "Fig. 7a", "formation_error": "Fig. 7b", "vn": "Fig. 8"}
    ended = "stopped by a signal (Ctrl-C, SIGINT or SIGTERM) at t=2.55 s"
    cut = _context(RunFolder(run, {"end_reason": "interrupted", "ended": ended}, config, sc, {}), [], [2])
    assert cut.paper == {}
    assert (cut.changes or "").endswith(f": {ended}")  # how it ended, given as the change
    assert "did not end" in (cut.changes or "")


@pytest.mark.slow
def test_formats_dpi_and_the_events_listed(swarm_run: Callable[..., RunResult]) -> None:
    import matplotlib.image

    res = swarm_run(SCENARIOS / "fig11_obstacles.toml", overrides={"run.duration_s": 32.0})
    assert main([str(res.run_dir), "--dpi", "80"]) == 0
    small = matplotlib.image.imread(res.run_dir / "report" / "vn.png")
    assert main([str(res.run_dir), "--dpi", "160"]) == 0
    big = matplotlib.image.imread(res.run_dir / "report" / "vn.png")
    assert big.shape[1] == pytest.approx(2 * small.shape[1], abs=2)  # 10 in wide at the dpi asked
    for fmt, magic in (("svg", b"<?xml"), ("pdf", b"%PDF")):
        assert main([str(res.run_dir), "--format", fmt]) == 0
        for name in FIGURES:
            assert (res.run_dir / "report" / f"{name}.{fmt}").read_bytes().startswith(magic)
    md = (res.run_dir / "report" / "report.md").read_text()
    assert "![vn](vn.pdf)" in md
    assert "| 393 | 19.65 | R2 | line |" in md
    assert "| 608 | 30.40 | R1 | triangle |" in md
    assert "Ended: the scenario's duration was reached at t=32.00 s." in md
    assert "Reproduces no figure of the paper as it is (fig11_obstacles with run.duration_s changed)." in md


def test_a_changed_paper_scenario_is_named_with_what_changed(tmp_path: Path) -> None:
    from formation_swarm.report.paper import paper_changed, paper_changes, paper_figures
    from formation_swarm.spec.files import dumps

    raw = tomllib.loads((SCENARIOS / "fig11_obstacles.toml").read_text())
    run = tmp_path / "scenario.toml"
    run.write_text(dumps({**raw, "run": {**raw["run"], "seed": 7}}))
    assert paper_figures(run) == {"trajectories": "Fig. 11"}  # another seed is still the figure
    assert paper_changes(run) is None
    kill = {"kind": "kill", "target": "agent-3", "at_s": 20.0}
    faulted = {**raw, "run": {**raw["run"], "robots": 5}, "faults": [kill]}
    run.write_text(dumps(faulted))
    assert paper_figures(run) == {}
    assert paper_changed(run) == ("fig11_obstacles", ["[[faults]]", "run.robots"])  # report.md says it in words
    run.write_text(dumps({**raw, "run": {**raw["run"], "name": "mine"}}))
    assert paper_changes(run) is None  # not a paper's scenario: nothing to compare with


def test_a_gap_in_a_series_breaks_its_line_and_its_average() -> None:
    from formation_swarm.report.figures import gapped, moving_average, stretches

    t = np.r_[np.arange(0, 10) * 0.05, np.arange(30, 40) * 0.05]  # ticks 0-9, then 30-39: an agent away
    assert stretches(t, 0.05) == [slice(0, 10), slice(10, 20)]
    gt, gv = gapped(t, np.ones(20), 0.05)
    assert len(gt) == 21
    assert np.isnan(gv[10])
    assert gt[10] == pytest.approx(0.5 * (0.45 + 1.5))
    unbroken = t[:10]
    assert gapped(unbroken, np.ones(10), 0.05)[0] is unbroken  # as it was
    # Each stretch averaged alone: a step across the gap does not leak into either side.
    v = np.r_[np.zeros(10), np.ones(10)]
    assert moving_average(t, v, 0.2, 0.05) == pytest.approx(v)


def test_a_swarm_figure_draws_the_median_and_names_the_worst(monkeypatch: pytest.MonkeyPatch) -> None:
    """12 followers: no legend entry each, but their median and the worst; the
    targets figure shows the 4 of largest error, not 12 rows."""
    import matplotlib

    matplotlib.use("Agg")
    from formation_swarm.report import figures
    from formation_swarm.report.data import Series
    from formation_swarm.report.figures import drawing

    saved = []
    monkeypatch.setattr(drawing, "save", lambda fig, path, dpi: saved.append(fig))
    followers = list(range(2, 14))
    t = np.arange(100) * 0.05
    data = {}
    for r in followers:
        data[f"/robots/r{r}/error/formation"] = Series(t, np.full(100, r / 10))  # R13 the worst, 1.3 m
        data[f"/robots/r{r}/fis/v_n"] = Series(t, np.full(100, 1.5 + r / 100))
        xy = np.c_[np.zeros(100), t]
        for path in ("target/true", "target/measured", "ekf/target"):
            data[f"/robots/r{r}/{path}"] = Series(t, xy)
    ctx = figures.Context(scenario="s", seed=1, robots=[1, *followers], followers=followers, t_end=5.0)
    rms = {r: r / 10 for r in followers}
    figures.formation_error("unused", data, ctx, rms, 50)
    labels = [x.get_text() for x in saved[-1].axes[0].get_legend().get_texts()]
    said = [re.findall(r"R\d+|\d+(?:\.\d+)?|faint|median|largest", label) for label in labels]
    assert said == [["12", "faint"], ["median", "12"], ["largest", "R13", "1.30"]]
    median = saved[-1].axes[0].get_lines()[13]  # after the 12 faint ones and the legend's proxy
    assert np.nanmedian(median.get_ydata()) == pytest.approx(0.75)  # of 0.2 ... 1.3
    figures.vn("unused", data, ctx, 50)
    labels = [x.get_text() for x in saved[-1].legends[0].get_texts()]  # under the figure
    said = [re.findall(r"\d+ s|\d+|faint|median|average", label) for label in labels]
    assert said == [["1 s", "average", "12", "faint"], ["median", "12", "average"]]  # of 1 s averages
    figures.targets("unused", data, ctx, {}, dpi=50, rms=rms)
    rows = [a.get_title() for a in saved[-1].axes if a.get_title().endswith("whole run")]
    assert rows == [f"R{r}: virtual target, whole run" for r in (13, 12, 11, 10)]  # the worst first
    assert "the 4 of the 12 followers with the largest formation error" in saved[-1]._suptitle.get_text()
    # Up to 8 followers, each has its own entry.
    few = figures.Context(scenario="s", seed=1, robots=[1, 2, 3], followers=[2, 3], t_end=5.0)
    figures.formation_error("unused", data, few, rms, 50)
    labels = [x.get_text() for x in saved[-1].axes[0].get_legend().get_texts()]
    assert [re.findall(r"R\d+|\d+\.\d+", label) for label in labels] == [["R2", "0.20"], ["R3", "0.30"]]


def test_the_report_names_the_first_contacts_and_the_scenario_warnings() -> None:
    from formation_swarm.report.markdown import report_markdown

    summary = {
        "run_id": "r1",
        "collisions": 2,
        "obstacle_collisions": 0,
        "contacts": [
            {"tick": 489, "time_s": 24.45, "robots": [3, 15]},
            {"tick": 490, "time_s": 24.5, "robots": [7, 11]},
        ],
        "scenario_warnings": ["formation 'two': robots 10-30 sit up to 22.5 m to the side"],
    }
    md = report_markdown(summary, [])
    assert "First contacts: R3 and R15 at 24.45 s, R7 and R11 at 24.50 s.\n" in md
    assert "## Scenario warnings\n\n- formation 'two': robots 10-30 sit up to 22.5 m" in md
    quiet = report_markdown({"run_id": "r1", "collisions": 0, "obstacle_collisions": 0}, [])
    assert "contact" not in quiet.lower().replace("collisions 0", "")
    assert "Scenario warnings" not in quiet


def test_faults_get_a_lane_under_the_time_axis_with_their_labels(monkeypatch: pytest.MonkeyPatch) -> None:
    """The labels stand in their own lane, each in full, not over the data; the
    lane carries the time axis."""
    import matplotlib

    matplotlib.use("Agg")
    from formation_swarm.report import figures
    from formation_swarm.report.data import Series
    from formation_swarm.report.figures import drawing

    saved = []
    monkeypatch.setattr(drawing, "save", lambda fig, path, dpi: saved.append(fig))
    t = np.arange(400) * 0.05
    data = {f"/robots/r{r}/error/formation": Series(t, np.full(400, r / 10)) for r in (2, 3)}
    ctx = figures.Context(scenario="s", seed=1, robots=[1, 2, 3], followers=[2, 3], t_end=20.0)
    ctx.fault_marks = [(5.0, 7.0, "partition 2"), (5.0, None, "kill agent-3"), (12.0, math.inf, "blackout 3")]
    figures.formation_error("unused", data, ctx, {2: 0.2, 3: 0.3}, 50)
    ax, lane = saved[-1].axes  # the lane: the bottom of the axes' own cell, laid out with them
    assert [x.get_text() for x in lane.texts] == [" partition 2", " kill agent-3", " blackout 3"]
    rows = [round(x.get_position()[1]) for x in lane.texts]
    assert rows == [0, 1, 0]  # the kill at the partition's start: a row of its own
    assert lane.get_ylim() == (1.5, -0.5)
    assert lane.get_xlabel() == "time, s"
    assert ax.get_xlabel() == ""
    # The window to the end is shaded to the axis's end on the lane.
    (bar,) = [p for p in lane.patches if p.get_x() == 12.0]
    assert bar.get_width() == pytest.approx(8.0)
    assert lane.get_subplotspec().get_gridspec() is ax.get_subplotspec().get_gridspec()
    # A label that would run off the axis's end ends there instead.
    ctx.fault_marks = [(19.5, None, "kill agent-3")]
    figures.formation_error("unused", data, ctx, {2: 0.2, 3: 0.3}, 50)
    (text,) = saved[-1].axes[1].texts
    assert (text.get_position()[0], text.get_horizontalalignment()) == (20.0, "right")
