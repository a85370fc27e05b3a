"""swarm report: figures for every shipped scenario, not blank."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from formation_swarm.launcher import RunResult
from formation_swarm.report import FIGURES, main, make_report
from tests.conftest import SCENARIOS


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sorted(p.name for p in SCENARIOS.glob("*.toml")))
def test_figures_for_every_shipped_scenario(swarm_run: Callable[..., RunResult], scenario: str) -> None:
    import matplotlib.image

    res = swarm_run(SCENARIOS / scenario)
    assert res.exit_code == 0
    out = make_report(res.run_dir)
    for name in FIGURES:
        img = matplotlib.image.imread(out / name)[..., :3]
        assert img.shape[0] > 200, name
        assert img.shape[1] > 400, name
        ink = np.mean(np.any(img < 0.9, axis=-1))  # share of pixels that are not (near) white
        assert ink > 0.03, (name, ink)
        colours = len(np.unique((img.reshape(-1, 3) * 255).astype(np.uint8), axis=0))
        assert colours > 20, (name, colours)  # data lines in several colours, not only axes
    md = (out / "report.md").read_text()
    assert all(f"]({name})" in md for name in FIGURES)
    assert "| R2 |" in md


def test_clear_errors_for_folders_it_cannot_use(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(tmp_path)]) == 2
    assert "no summary.json" in capsys.readouterr().err
    (tmp_path / "summary.json").write_text("{}")
    assert main([str(tmp_path)]) == 2
    assert "no recording.rrd" in capsys.readouterr().err


FAULTED = {
    "faults": [
        {"fault": "kill agent-3@20s", "kind": "kill", "target": "agent-3", "at_s": 20.0, "for_s": None,
         "start_tick": 400, "end_tick": None, "counts": {},
         "events": [{"tick": 400, "time_s": 20.0, "event": "killed", "robot": 3}]},
        {"fault": "drop obs:2@10s for=5s p=0.3", "kind": "drop", "target": "obs:2", "at_s": 10.0, "for_s": 5.0,
         "start_tick": 200, "end_tick": 300, "counts": {"dropped": 31}, "events": []},
        {"fault": "wheel_noise *@0s sigma_mps=0.1", "kind": "wheel_noise", "target": "*", "at_s": 0.0,
         "for_s": None, "start_tick": 0, "end_tick": None, "counts": {}, "events": []},
    ],
    "events": [
        {"event": "killed", "process": "agent-3", "sim_time_s": 20.0},
        {"event": "exited", "process": "agent-3", "code": -9, "sim_time_s": 20.0},
        {"event": "exited", "process": "logger", "code": 1, "sim_time_s": 31.5},
    ],
    "deaths": [{"robot": 3, "tick": 400, "time_s": 20.0}],
}  # fmt: skip


def test_faults_are_marked_on_the_time_axes_and_listed() -> None:
    from formation_swarm.report import _faults_markdown, fault_marks

    marks = fault_marks(FAULTED)
    # A kill is an instant; a windowed fault its window; an open-ended one runs to the end;
    # the logger's own exit is marked, agent 3's is the kill's doing.
    assert marks == [(20.0, None, "kill agent-3"), (10.0, 15.0, "drop obs:2"), (0.0, math.inf, "wheel_noise *"),
                     (31.5, None, "logger exited")]  # fmt: skip
    text = "\n".join(_faults_markdown(FAULTED))
    assert "| `kill agent-3@20s` | from 400 | killed R3 at tick 400 (20.00 s) | - |" in text
    assert "| `drop obs:2@10s for=5s p=0.3` | 200-300 | - | dropped 31 |" in text
    assert "- logger exited with code 1 at sim t=31.50 s" in text
    assert "agent-3 was killed by SIGKILL" not in text  # said once, by the kill
    assert "- robot 3 lost its agent at tick 400 (20.00 s)" in text
