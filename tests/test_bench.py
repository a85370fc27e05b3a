"""The benchmarks' own machinery: what bench/lockstep.py compares a run with
must itself run, and end."""

from __future__ import annotations

import importlib.util
import math
import time

from tests.conftest import ROOT


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
    rate, cpu = bench.measure_bare(200)
    # 200 ticks of five processes; about 2 s here with their start, 3x for a loaded machine.
    assert time.monotonic() - t0 < 30
    assert rate > 0
    assert math.isfinite(rate)
    # Every role reported its CPU (a role that did not makes it NaN), and five
    # processes exchanging six messages a tick use some.
    assert math.isfinite(cpu)
    assert cpu > 0
