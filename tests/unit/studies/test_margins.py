"""The margins study's sections of docs/results.md are its tables of the rows
in docs/results/margins.csv, and its figures follow from those rows by hand;
tests/system/test_margins.py reruns a sample of the rows themselves."""

from __future__ import annotations

import statistics

import pytest

from formation_swarm.studies.margins import CLAIM_A, avoidance, runs, text
from formation_swarm.studies.margins.__main__ import SECTIONS
from formation_swarm.studies.sections import markers
from formation_swarm.studies.tables import half_width
from tests.helpers import ROOT

CSV = ROOT / "docs" / "results" / "margins.csv"


@pytest.fixture(scope="module")
def rows() -> list[dict]:
    return runs.read_csv(CSV)


def test_every_section_in_the_docs_is_the_table_of_the_committed_rows(rows: list[dict]) -> None:
    doc = (ROOT / "docs" / "results.md").read_text()
    for what, make in SECTIONS:
        begin, end = markers(what)
        assert doc.split(begin)[1].split(end)[0].strip() == make(rows), what


def test_claim_a_at_1_6_mps_by_hand(rows: list[dict]) -> None:
    at = {g: sorted((r for r in rows if r["group"] == f"{g} at 1.6 m/s"), key=lambda r: r["seed"]) for g in CLAIM_A}
    margins = [
        d["r2_max_m"] - min(a["r2_max_m"], b["r2_max_m"])
        for d, a, b in zip(at["dynamic"], at["static 1.5"], at["static 2"], strict=True)
    ]
    assert len(margins) == 30
    mean, hw = statistics.fmean(margins), half_width(margins)
    assert mean + hw < 0  # the interval excludes zero: the band holds at 1.6 m/s ...
    assert max(margins) > 0  # ... though not in every seed
    row = next(line for line in text.claim_a_table(rows).splitlines() if line.startswith("| 1.6 m/s"))
    assert f"{mean:+.3f} [{mean - hw:+.3f}, {mean + hw:+.3f}]" in row


def test_claim_c_on_matching_ticks_is_lower_under_drops(rows: list[dict]) -> None:
    drops = [r for r in rows if r["group"] == "drops 30%"]
    seen = [r["r2_ekf_rms_seen_m"] / r["r2_measured_rms_m"] for r in drops]
    every = [r["r2_ekf_rms_m"] / r["r2_measured_rms_m"] for r in drops]
    assert all(s < e for s, e in zip(seen, every, strict=True))
    assert statistics.fmean(seen) + half_width(seen) < 0.5 < statistics.fmean(every) + half_width(every)


def test_the_paper_change_and_rank_swap_tables_name_every_case(rows: list[dict]) -> None:
    paper, swap = avoidance.paper_change_table(rows), avoidance.rank_swap_table(rows)
    assert paper.count("| on |") == paper.count("| off |") == 2
    assert swap.count("| on |") == swap.count("| off |") == 5
