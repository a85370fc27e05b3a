"""A sample of docs/results/margins.csv's rows, run again: each the same
trajectory (the digest the row keeps) and the same figures (the runs
behind the margins, the NEES and the avoidance sections of
docs/results.md), to 1e-9; not the wall-clock ticks_per_s."""

from __future__ import annotations

import math

import pytest

from formation_swarm.studies import margins
from formation_swarm.studies.margins import runs
from tests.helpers import ROOT

SAMPLE = (
    ("dynamic at 1.6 m/s", 7),
    ("static 2 at 1.6 m/s", 7),
    ("drops 30%", 1),
    ("overconfident", 3),
    ("slots 0.5 m ahead, eq. 11-13 on", 0),
    ("`fig11_shallow_triangle`, eq. 11-13 off", 2),
)


@pytest.mark.slow  # six runs in this process: about 10 s
@pytest.mark.parametrize(("group", "seed"), SAMPLE)
def test_a_committed_row_is_this_codes_run(group: str, seed: int) -> None:
    committed = {(r["group"], r["seed"]): r for r in runs.read_csv(ROOT / "docs" / "results" / "margins.csv")}
    run = next(r for r in margins.plan(range(seed, seed + 1)) if r.group == group)
    fresh = runs.row_of(run)
    row = committed[(group, seed)]
    assert fresh["ticks"] == row["ticks"]
    assert fresh["trajectory_digest"] == row["trajectory_digest"]
    for key, value in row.items():
        if isinstance(value, float) and not math.isnan(value) and key != "ticks_per_s":
            assert fresh[key] == pytest.approx(value, rel=1e-9), key
