"""swarm report: figures for every shipped scenario, not blank."""

from __future__ import annotations

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
