"""swarm report, compare and export on a run folder whose summary.json or
scenario.toml is hostile: one line naming the file, exit 2, nothing
written; and what a report of a run stopped early points to exists."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from formation_swarm.report import build, compare, export
from formation_swarm.report.data import read_files
from formation_swarm.report.markdown import stopped_early
from tests.helpers.run_folder import fake_run, summary_of


def _set(key: str, value: object) -> object:
    def edit(run: Path) -> None:
        summary = json.loads((run / "summary.json").read_text())
        summary[key] = value
        (run / "summary.json").write_text(json.dumps(summary))

    return edit


def _text(name: str, text: str | bytes) -> object:
    def edit(run: Path) -> None:
        (run / name).write_bytes(text.encode() if isinstance(text, str) else text)

    return edit


def _replace(old: str, new: str) -> object:
    def edit(run: Path) -> None:
        path = run / "summary.json"
        path.write_text(path.read_text().replace(old, new, 1))

    return edit


# case: (how the folder is spoilt, the file named, what is said of it)
HOSTILE = {
    "wrong type": (_set("followers", {"2": [1]}), "summary.json", "followers.2 must be an object, got an array"),
    "deep nesting": (_set("x", json.loads("[" * 40 + "]" * 40)), "summary.json", "nested more than 32 deep"),
    "NaN": (_replace('"rms_m": 0.1', '"rms_m": NaN'), "summary.json", "holds NaN, which no run writes"),
    "1e999": (_replace('"rms_m": 0.1', '"rms_m": 1e999'), "summary.json", "holds 1e999, a number too large"),
    "random-byte scenario": (_text("scenario.toml", os.urandom(64) + b"\xff"), "scenario.toml", "is not "),
    "a scenario of wrong types": (_text("scenario.toml", "[run]\nrobots = []\n"), "scenario.toml", "run."),
}


def listing(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_size for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("command", ["report", "compare", "export"])
@pytest.mark.parametrize("case", list(HOSTILE))
def test_a_hostile_file_is_one_line_exit_2_and_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, case: str
) -> None:
    spoil, name, said = HOSTILE[case]
    good = fake_run(tmp_path / "good", recording=False)
    run = fake_run(tmp_path / "run", recording=False)
    spoil(run)  # type: ignore[operator]
    before = listing(tmp_path)
    argv = {
        "report": [str(run)],
        "compare": [str(good), str(run), "--out", str(tmp_path / "c.png")],
        "export": [str(run)],
    }[command]
    code = {"report": build.main, "compare": compare.main, "export": export.main}[command](argv)
    out, err = capsys.readouterr()
    assert (code, out) == (2, "")
    assert len(err.splitlines()) == 1
    assert err.startswith(f"swarm {command}: {run / name}")
    assert said in err
    assert listing(tmp_path) == before  # no report/, no temporary folder, no table or figure


def test_the_report_of_a_run_interrupted_before_its_first_tick_points_to_what_is_there(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C during the start: the launcher wrote summary.json alone."""
    summary = {**summary_of("cut", 0), "ticks": None, "exit_code": 130, "end_reason": "interrupted", "ended_at_s": None}
    run = tmp_path / "run"
    run.mkdir()
    (run / "summary.json").write_text(json.dumps(summary))
    assert build.main([str(run)]) == 0
    out, err = capsys.readouterr()
    why = (
        "nothing was recorded: the run was interrupted before its first tick (exit code 130); "
        "it has no logs/ (the folder holds summary.json)"
    )
    assert out == f"[report] {run / 'report'}: report.md only, no figures: {why}\n"
    (progress,) = err.splitlines()  # its progress, one line
    assert progress.startswith("report: report.md")
    assert "no figures" in progress
    assert f"No figures and no measured or EKF target errors (the last two columns): {why}." in (
        (run / "report" / "report.md").read_text()
    )
    # With its logs/ there, the report sends the reader to them.
    (run / "logs").mkdir()
    assert build.main([str(run)]) == 0
    assert "(exit code 130); see its logs/\n" in capsys.readouterr().out
    assert sorted(p.name for p in run.iterdir()) == ["logs", "report", "summary.json"]  # no temporary folder left


def test_figures_of_a_run_stopped_early_say_so_in_their_titles(tmp_path: Path) -> None:
    run = fake_run(tmp_path / "run", summary=summary_of("cut", 60, end_reason="interrupted", ended_at_s=3.0))
    folder = read_files(run)
    ctx = build._context(folder, [1, 2], [2])
    *lines, last = ctx.title("vn", "V_N").splitlines()
    assert [re.findall(r"turn-vn-dynamic|seed \d+|V_N|path|fuzzy", line) for line in lines] == [
        ["turn-vn-dynamic", "seed 1", "V_N"],
        ["path", "fuzzy", "V_N"],
    ]
    assert re.findall(r"^\[(\w+) at ([\d.]+) s\]$", last) == [("interrupted", "3.0")]  # how and when it stopped
    assert compare.label(load(run)).startswith("run (interrupted at 3.0 s): turn-vn-dynamic, seed 1")


def load(run: Path) -> object:
    from formation_swarm import load_run

    return load_run(run)


@pytest.mark.parametrize(
    ("summary", "said"),
    [
        ({"end_reason": "interrupted", "ended_at_s": 3.0}, "interrupted at 3.0 s"),
        ({"end_reason": "interrupted", "sim_time_s": 2.96}, "interrupted at 3.0 s"),
        ({"end_reason": "timed_out", "ended_at_s": 12.25}, "stopped by its timeout at 12.2 s"),
        ({"interrupted": True}, "interrupted"),  # a summary without end_reason
        ({"end_reason": "leader_finished", "ended_at_s": 53.0}, None),
        ({"end_reason": "role_failed", "interrupted": True}, None),  # its end_reason says how it ended
    ],
)
def test_stopped_early(summary: dict[str, object], said: str | None) -> None:
    assert stopped_early(summary) == said
