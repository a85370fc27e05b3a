"""Cost of one robot's fuzzy step (FIS-2, then FIS-1 for both wheels).

Prints the median over repeated batches, beside the EKF step, a whole
follower tick and, if scikit-fuzzy is installed, scikit-fuzzy's control
system computing one wheel: the figures are measured in the same run, so
their ratio holds on a busy machine too.

    python bench/fuzzy_step.py [--repeat 15]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from collections.abc import Callable

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import numpy as np  # noqa: E402

from formation_swarm import ControllerSetup, FollowerInput, FollowerParams, MarkerReading, Point, Slot  # noqa: E402
from formation_swarm.agents import fuzzy  # noqa: E402
from formation_swarm.agents.ekf import EkfParams, TargetEKF  # noqa: E402
from formation_swarm.agents.follower import FuzzyController  # noqa: E402


def median_us(fn: Callable[[int], None], n: int, repeat: int) -> float:
    per_call = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(n)
        per_call.append((time.perf_counter() - t0) / n * 1e6)
    return statistics.median(per_call)


def whole_ticks(readings: list[MarkerReading]) -> Callable[[int], None]:
    """``count`` whole follower ticks (EKF, fuzzy, geometry) on the first ``count`` readings."""
    slot = Slot(1, Point(-1.5, -1.5))
    fol = FuzzyController(ControllerSetup(robot_id=2, params=FollowerParams(), slot=slot, max_wheel_mps=3.0))
    inputs = [FollowerInput(reading=r, slot=slot, dt_s=0.05) for r in readings]

    def ticks(count: int) -> None:
        for i in range(count):
            fol.step(inputs[i])

    return ticks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    n = 4000
    alphas = [float(a) for a in rng.uniform(-math.pi, math.pi, n)]
    rhos = [float(r) for r in rng.uniform(0.0, 2.5, n)]
    drhos = [float(d) for d in rng.uniform(-0.05, 0.05, n)]
    p = fuzzy.FuzzyParams()
    mode = fuzzy.SpeedMode()

    def fuzzy_steps(count: int) -> None:
        for i in range(count):
            fuzzy.control(alphas[i], rhos[i], drhos[i], 0.05, p=p, mode=mode)

    ekf = TargetEKF(EkfParams(), 0.1, 0.5)
    ekf.update(MarkerReading(rho_m=2.0, phi_rad=0.1, beta_rad=0.05))
    readings = [
        MarkerReading(rho_m=2.0 + 0.05 * float(a), phi_rad=0.1, beta_rad=0.05 + 0.02 * float(b))
        for a, b in rng.standard_normal((n, 2))
    ]

    def ekf_steps(count: int) -> None:
        for i in range(count):
            ekf.predict(1.5, 1.5, 0.05)
            ekf.update(readings[i])

    follower_ticks = whole_ticks(readings[:1000])

    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; median of {args.repeat} batches")
    print(f"fuzzy step (FIS-2 + FIS-1 both wheels): {median_us(fuzzy_steps, n, args.repeat):8.2f} us")
    print(f"EKF predict + update:                   {median_us(ekf_steps, 1000, args.repeat):8.2f} us")
    print(f"whole follower tick (EKF+fuzzy+geom):   {median_us(follower_ticks, 1000, args.repeat):8.2f} us")
    try:
        import skfuzzy as skf
        from skfuzzy import control as ctrl
    except ImportError:
        print("scikit-fuzzy not installed: pip install '.[bench]' for the reference figure")
        return
    g = p.gamma_rad
    alpha = ctrl.Antecedent(np.linspace(-math.pi, math.pi, 721), "alpha")
    rho = ctrl.Antecedent(np.linspace(0.0, 3.0, 301), "rho")
    vl = ctrl.Consequent(np.linspace(0.5, 3.0, 251), "vl")
    alpha["Right"] = skf.trapmf(alpha.universe, [-10, -9, -g, 0])
    alpha["Center"] = skf.trimf(alpha.universe, [-g, 0, g])
    alpha["Left"] = skf.trapmf(alpha.universe, [0, g, 9, 10])
    rho["Close"] = skf.trapmf(rho.universe, [-2, -1, p.d0_m, p.dn_m])
    rho["Enough"] = skf.trapmf(rho.universe, [p.d0_m, p.dn_m, p.d1_m, p.dmax_m])
    rho["Far"] = skf.trapmf(rho.universe, [p.d1_m, p.dmax_m, 9, 10])
    vn = 1.7
    for name, c in (("S", vn - p.a_mps), ("M", vn), ("F", vn + p.a_mps)):
        vl[name] = skf.trimf(vl.universe, [c - p.a_mps, c, c + p.a_mps])
    rows = {"Close": "SSS", "Enough": "MMS", "Far": "FFM"}
    rules = [
        ctrl.Rule(rho[r] & alpha[a], vl[rows[r][j]]) for r in rows for j, a in enumerate(("Left", "Center", "Right"))
    ]
    sim = ctrl.ControlSystemSimulation(ctrl.ControlSystem(rules), cache=False)

    def skf_steps(count: int) -> None:
        for i in range(count):
            sim.input["alpha"] = alphas[i]
            sim.input["rho"] = rhos[i]
            sim.compute()

    print(f"scikit-fuzzy control system, one wheel: {median_us(skf_steps, 100, max(3, args.repeat // 3)):8.2f} us")


if __name__ == "__main__":
    main()
