"""The benchmarks' own machinery: what bench/lockstep.py compares a run with
must itself run, and end."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
import time

import pytest

from tests.helpers import ROOT


def _lockstep_bench():
    spec = importlib.util.spec_from_file_location("bench_lockstep", ROOT / "bench" / "lockstep.py")
    assert spec is not None
    assert spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_bare_exchange_runs_its_ticks_and_reports_every_process_cpu():
    bench = _lockstep_bench()
    t0 = time.monotonic()
    rate, cpu = bench.measure_bare(200, 3)
    # 200 ticks of five processes; about 2 s here with their start, 3x for a loaded machine.
    assert time.monotonic() - t0 < 30
    assert rate > 0
    assert math.isfinite(rate)
    # Every role reported its CPU (a role that did not makes it NaN), and five
    # processes exchanging six messages a tick use some.
    assert math.isfinite(cpu)
    assert cpu > 0


def test_bare_exchange_with_the_controller_steps_the_followers_filter():
    """The floor variant's followers run the paper's controller on each reading:
    the EKF starts on the first, tracks the reference (about 2 m ahead) and the
    wheels turn; and the exchange with it runs its ticks."""
    bench = _lockstep_bench()
    brain = bench._Brain()
    for reading in bench.READINGS[:40]:
        brain.step(reading)
        brain.prepare()
    assert brain.ticks == 40
    assert brain.follower.ekf.initialized
    x, y, _phi, _v, _w = brain.follower.ekf.state
    assert 1.5 < math.hypot(x, y) < 2.5
    decision = brain.step(bench.READINGS[40])
    assert decision.left_mps > 0.5
    assert decision.right_mps > 0.5
    rate, cpu = bench.measure_bare(200, 5, control=True)  # four followers
    assert math.isfinite(rate)
    assert rate > 0
    assert math.isfinite(cpu)
    assert cpu > 0


@pytest.mark.parametrize(
    ("script", "argv", "said"),
    [
        ("scale.py", ["--robots", "1"], "argument --robots: must be in [2, 500], got '1'"),
        ("scale.py", ["--robots", "abc"], "argument --robots: must be an integer in [2, 500], got 'abc'"),
        ("scale.py", ["--duration", "0"], "argument --duration: must be a number of seconds > 0, got '0'"),
        ("scale.py", ["--lockstep-duration", "-1"], "argument --lockstep-duration: must be a number of seconds > 0"),
        ("lockstep.py", ["--repeat", "0"], "argument --repeat: must be >= 1, got '0'"),
        ("lockstep.py", ["--ticks", "50"], "argument --ticks: must be >= 100, got '50'"),
        ("lockstep.py", ["--robots", "2"], "argument --robots: must be in [3, 500], got '2'"),
    ],
)
def test_a_benchmark_refuses_bad_flags_on_one_line(script: str, argv: list[str], said: str) -> None:
    """Before anything runs: exit 2 and argparse's one line, not a traceback."""
    proc = subprocess.run(
        [sys.executable, str(ROOT / "bench" / script), *argv], capture_output=True, text=True, timeout=60, check=False
    )
    assert proc.returncode == 2, proc.stderr
    assert said in proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stdout == ""  # nothing measured
