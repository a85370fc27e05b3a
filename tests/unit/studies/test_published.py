"""What the project publishes, recomputed from the code: a change of the maths
that would move a figure of docs/results.md or README fails here, in seconds.

The lockstep runs behind the table are replayed in one process
(tests/helpers/replica.py, checked against a real run in tests/system/test_distributed.py).
When a change of the controller is meant, `make results` rewrites the table
and these tests follow it: they read the figures from docs/results.md.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import re
import statistics
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import pytest

from formation_swarm.agents.ekf import EkfParams
from formation_swarm.agents.fuzzy import FuzzyParams
from formation_swarm.studies import results
from formation_swarm.world.camera import CameraParams
from tests.helpers import ROOT
from tests.helpers.replica import replay

SEEDS = range(10)
_REPLAYS: dict[tuple[int, str], dict[str, Any]] = {}  # (seed, overrides) -> the replay's summary, for the table


def _key(seed: int, overrides: Mapping[str, Any]) -> tuple[int, str]:
    return seed, repr(sorted(overrides.items()))


def _replay_job(seed: int, overrides: dict[str, Any]) -> dict[str, Any]:
    return replay(results.SCENARIO, seed, overrides)


def _published_cells() -> dict[tuple[str, str], list[str]]:
    """(controller, noise) -> the table's cells, as published in docs/results.md."""
    doc = (ROOT / "docs" / "results.md").read_text()
    table = doc.split(results.BEGIN)[1].split(results.END)[0]
    out = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 2 + len(results.DROPS) and cells[0] in results.CONTROLLERS:
            out[(cells[0], cells[1])] = cells[2:]
    return out


@pytest.mark.slow  # ten lockstep runs in one process each: about 3 s
@pytest.mark.parametrize("controller", list(results.CONTROLLERS))
def test_the_no_drop_column_of_the_results_table_is_what_the_code_computes(controller: str) -> None:
    """Mean RMS, CI half-width and mean max error of the follower over seeds 0-9,
    low camera noise, no drops (the drop columns depend on the link layer too)."""
    overrides = {**results.CONTROLLERS[controller], **results.NOISE["low"], "links.obs_drop": 0.0}
    for seed in SEEDS:
        _REPLAYS[_key(seed, overrides)] = replay(results.SCENARIO, seed, overrides)
    runs = [_REPLAYS[_key(seed, overrides)]["followers"]["2"] for seed in SEEDS]
    rms = [r["rms_m"] for r in runs]
    half = 2.262 * statistics.stdev(rms) / math.sqrt(len(rms))  # t(0.975, 9 dof)
    mx = statistics.fmean(r["max_m"] for r in runs)
    published = _published_cells()[(controller, "low")][0]
    mean_rms, half_rms, max_error = re.fullmatch(r"(\S+) ± (\S+) \[(\S+)\]", published).groups()
    assert (mean_rms, half_rms, max_error) == (f"{statistics.fmean(rms):.2f}", f"{half:.2f}", f"{mx:.2f}")


@pytest.mark.slow  # 180 replays, about 17 s of CPU: spread over the machine's cores
def test_the_whole_results_table_is_what_the_code_computes() -> None:
    """Every cell, the drop columns too: a drop is decided on (seed, link, seq),
    so the replay drops the messages the processes dropped. README carries the
    same table. The replays of the no-drop column's test are not made twice;
    the others are made by as many processes as the machine has cores (started
    fresh: this process may hold Zenoh's threads)."""
    jobs = results.jobs(SEEDS)
    todo = [j for j in jobs if _key(j.seed, j.overrides) not in _REPLAYS]
    with ProcessPoolExecutor(os.cpu_count() or 1, mp_context=multiprocessing.get_context("spawn")) as pool:
        made = pool.map(_replay_job, [j.seed for j in todo], [dict(j.overrides) for j in todo], chunksize=5)
        _REPLAYS.update((_key(j.seed, j.overrides), s) for j, s in zip(todo, made, strict=True))
    rows = []
    for job in jobs:
        s = _REPLAYS[_key(job.seed, job.overrides)]
        rows.append(
            {
                "combination": job.label,
                "seed": job.seed,
                "run": job.name,
                "exit_code": 0,
                "lockstep_misses": 0,
                "r2_rms_m": s["followers"]["2"]["rms_m"],
                "r2_max_m": s["followers"]["2"]["max_m"],
            }
        )
    table = results.table(rows, len(SEEDS))
    for doc in ("docs/results.md", "README.md"):
        published = (ROOT / doc).read_text().split(results.BEGIN)[1].split(results.END)[0]
        assert published.strip() == table, doc


def test_claim_d_obstacle_run_in_one_process() -> None:
    """docs/results.md claim d, seed 1 (the shipped scenario's): triangle, line,
    triangle for every robot, no collision, and the clearance it publishes."""
    s = replay(ROOT / "scenarios" / "fig11_obstacles.toml", seed=1)
    by_robot: dict[int, list[str]] = {}
    for e in s["formation_events"]:
        by_robot.setdefault(e["robot"], []).append(e["formation"])
    assert by_robot == {1: ["line", "triangle"], 2: ["line", "triangle"], 3: ["line", "triangle"]}
    assert s["collisions"] == 0
    assert s["obstacle_collisions"] == 0
    published = re.search(r"minimum distance (\d+\.\d+) m", (ROOT / "docs" / "results.md").read_text())
    assert published
    assert s["min_distance_m"] >= float(published[1]) - 0.005  # the smallest over seeds 0-9


def test_the_paper_parameters_are_the_defaults() -> None:
    """Sec. 5 of the paper: gamma 15 deg, a = 0.5, V_N 1.5 / 1.7 / 2; the
    distance breakpoints are ours (docs/paper.md)."""
    p = FuzzyParams()
    assert p.gamma_rad == pytest.approx(math.radians(15.0), abs=1e-15)
    assert (p.a_mps, p.vn_min, p.vm, p.vn_max) == (0.5, 1.5, 1.7, 2.0)
    assert (p.d0_m, p.dn_m, p.d1_m, p.dmax_m, p.drho_rate_tol_mps) == (0.1, 0.5, 1.0, 2.0, 0.5)


def test_the_ekf_is_told_the_cameras_noise() -> None:
    cam, ekf = CameraParams(), EkfParams()
    assert (ekf.sigma_rho_m, ekf.sigma_phi_rad, ekf.sigma_beta_rad) == (
        cam.sigma_rho_m,
        cam.sigma_phi_rad,
        cam.sigma_beta_rad,
    )


@pytest.mark.slow  # 30-robot runs in one process: about 3 s
def test_the_look_ahead_row_of_paper_md_for_fig11_is_what_the_code_computes() -> None:
    """docs/paper.md, "The steering look-ahead": `fig11_obstacles` seed 1 without
    and with `controller.lookahead_m = 1`, at the doc's precision. The run changes
    formation twice, so the look-ahead steers at eq. 13's avoidance targets too:
    aimed at the slot's target instead during a change, the row would move."""
    doc = (ROOT / "docs" / "paper.md").read_text()
    row = re.search(
        r"\| `fig11_obstacles` \(the paper's three robots\) \| (\d+) -> (\d+) \| (\d+\.\d+) -> (\d+\.\d+) "
        r"\| R2 (\d+\.\d+) -> (\d+\.\d+), R3 (\d+\.\d+) -> (\d+\.\d+) \|",
        doc,
    )
    assert row, "the look-ahead table of docs/paper.md has no fig11_obstacles row"
    contacts, closest, r2, r3 = row.groups()[0:2], row.groups()[2:4], row.groups()[4:6], row.groups()[6:8]
    for k, lookahead_m in enumerate((0.0, 1.0)):
        s = replay(
            ROOT / "scenarios" / "fig11_obstacles.toml", seed=1, overrides={"controller.lookahead_m": lookahead_m}
        )
        assert [e["formation"] for e in s["formation_events"] if e["robot"] == 3] == ["line", "triangle"]
        assert str(s["collisions"]) == contacts[k]
        assert f"{s['min_distance_m']:.2f}" == closest[k], lookahead_m
        assert f"{s['followers']['2']['rms_m']:.3f}" == r2[k], lookahead_m
        assert f"{s['followers']['3']['rms_m']:.3f}" == r3[k], lookahead_m
