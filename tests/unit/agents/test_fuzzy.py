"""FIS-1 and FIS-2 against simpful (an independent Sugeno engine) and Tables 1-2."""

from __future__ import annotations

import math

import numpy as np
import pytest

from formation_swarm.agents import fuzzy
from formation_swarm.agents.fuzzy import FuzzyParams, SpeedMode

simpful = pytest.importorskip("simpful")

P = FuzzyParams()
BIG = 1e6
SETS_ALPHA = ("Left", "Center", "Right")
SETS_RHO = ("Close", "Enough", "Far")
SETS_DRHO = ("Positive", "Zero", "Negative")
LEVEL1 = ("S", "M", "F")
LEVEL2 = ("L", "Mid", "H")


def _oracle(p: FuzzyParams) -> tuple[object, object]:
    """The same rule base, written in simpful's own terms."""
    T, LV = simpful.Trapezoidal_MF, simpful.LinguisticVariable
    FS = simpful.FuzzySet
    g = p.gamma_rad
    rho_sets = [
        FS(function=T(-BIG - 1, -BIG, p.d0_m, p.dn_m), term="Close"),
        FS(function=T(p.d0_m, p.dn_m, p.d1_m, p.dmax_m), term="Enough"),
        FS(function=T(p.d1_m, p.dmax_m, BIG, BIG + 1), term="Far"),
    ]
    fis1 = simpful.FuzzySystem(show_banner=False, verbose=False)
    fis1.add_linguistic_variable(
        "alpha",
        LV(
            [
                FS(function=T(0.0, g, BIG, BIG + 1), term="Left"),
                FS(function=simpful.Triangular_MF(-g, 0.0, g), term="Center"),
                FS(function=T(-BIG - 1, -BIG, -g, 0.0), term="Right"),
            ],
            universe_of_discourse=[-4, 4],
        ),
    )
    fis1.add_linguistic_variable("rho", LV(rho_sets, universe_of_discourse=[-100, 100]))
    rules = []
    # Table 1 transcribed from the paper, row by row, independently of agents.fuzzy.
    left = {"Close": "SSS", "Enough": "MMS", "Far": "FFM"}
    right = {"Close": "SSS", "Enough": "SMM", "Far": "MFF"}
    for r in SETS_RHO:
        for j, a in enumerate(SETS_ALPHA):
            rules.append(f"IF (rho IS {r}) AND (alpha IS {a}) THEN (vl IS {left[r][j]})")
            rules.append(f"IF (rho IS {r}) AND (alpha IS {a}) THEN (vr IS {right[r][j]})")
    fis1.add_rules(rules, verbose=False)

    fis2 = simpful.FuzzySystem(show_banner=False, verbose=False)
    tol = p.drho_rate_tol_mps
    fis2.add_linguistic_variable(
        "drho",
        LV(
            [
                FS(function=T(0.0, tol, BIG, BIG + 1), term="Positive"),
                FS(function=simpful.Triangular_MF(-tol, 0.0, tol), term="Zero"),
                FS(function=T(-BIG - 1, -BIG, -tol, 0.0), term="Negative"),
            ],
            universe_of_discourse=[-10, 10],
        ),
    )
    fis2.add_linguistic_variable("rho", LV(rho_sets, universe_of_discourse=[-100, 100]))
    table2 = {"Positive": ("Mid", "H", "H"), "Zero": ("Mid", "Mid", "Mid"), "Negative": ("L", "L", "Mid")}
    fis2.add_rules(
        [
            f"IF (drho IS {d}) AND (rho IS {r}) THEN (vn IS {table2[d][j]})"
            for d in SETS_DRHO
            for j, r in enumerate(SETS_RHO)
        ],
        verbose=False,
    )
    fis2.set_crisp_output_value("L", p.vn_min, verbose=False)
    fis2.set_crisp_output_value("Mid", p.vm, verbose=False)
    fis2.set_crisp_output_value("H", p.vn_max, verbose=False)
    return fis1, fis2


def _oracle_fis1(sys1: object, alpha: float, rho: float, vn: float, p: FuzzyParams) -> tuple[float, float]:
    sys1.set_crisp_output_value("S", vn - p.a_mps, verbose=False)
    sys1.set_crisp_output_value("M", vn, verbose=False)
    sys1.set_crisp_output_value("F", vn + p.a_mps, verbose=False)
    sys1.set_variable("alpha", alpha, verbose=False)
    sys1.set_variable("rho", rho, verbose=False)
    out = sys1.Sugeno_inference(["vl", "vr"], ignore_warnings=True)
    return out["vl"], out["vr"]


@pytest.fixture(scope="module")
def oracle() -> tuple[object, object]:
    return _oracle(P)


def test_fis1_matches_simpful_on_random_inputs(oracle: tuple[object, object]) -> None:
    rng = np.random.default_rng(20121)
    n = 1500
    alphas = rng.uniform(-math.pi, math.pi, n)
    # Half the draws inside the interesting band, half anywhere up to 3 m.
    rhos = np.where(rng.random(n) < 0.5, rng.uniform(-0.5, 0.6, n), rng.uniform(-3.0, 3.0, n))
    alphas[: n // 4] = rng.uniform(-0.4, 0.4, n // 4)
    vns = rng.uniform(1.5, 2.0, n)
    worst = 0.0
    for a, r, vn in zip(alphas, rhos, vns, strict=True):
        ours = fuzzy.fis1(float(a), float(r), float(vn), P)
        ref = _oracle_fis1(oracle[0], float(a), float(r), float(vn), P)
        worst = max(worst, abs(ours.left_mps - ref[0]), abs(ours.right_mps - ref[1]))
    assert worst < 1e-9


def test_fis2_matches_simpful_on_random_inputs(oracle: tuple[object, object]) -> None:
    rng = np.random.default_rng(20122)
    worst = 0.0
    for d, r in zip(rng.uniform(-1.5, 1.5, 1500), rng.uniform(-3.0, 3.0, 1500), strict=True):
        oracle[1].set_variable("drho", float(d), verbose=False)
        oracle[1].set_variable("rho", float(r), verbose=False)
        ref = oracle[1].Sugeno_inference(["vn"], ignore_warnings=True)["vn"]
        worst = max(worst, abs(fuzzy.fis2(float(d), float(r), P) - ref))
    assert worst < 1e-9


# Inputs at which exactly one set of each variable has membership 1.
ALPHA_AT = {"Left": 2 * P.gamma_rad, "Center": 0.0, "Right": -2 * P.gamma_rad}
RHO_AT = {"Close": 0.5 * P.d0_m, "Enough": 0.5 * (P.dn_m + P.d1_m), "Far": 2 * P.dmax_m}
DRHO_AT = {"Positive": 2 * P.drho_rate_tol_mps, "Zero": 0.0, "Negative": -2 * P.drho_rate_tol_mps}

TABLE1 = [  # (rho, alpha, left wheel, right wheel) as printed in the paper
    ("Close", "Left", "S", "S"),
    ("Close", "Center", "S", "S"),
    ("Close", "Right", "S", "S"),
    ("Enough", "Left", "M", "S"),
    ("Enough", "Center", "M", "M"),
    ("Enough", "Right", "S", "M"),
    ("Far", "Left", "F", "M"),
    ("Far", "Center", "F", "F"),
    ("Far", "Right", "M", "F"),
]


@pytest.mark.parametrize(("rho_set", "alpha_set", "left", "right"), TABLE1)
def test_table1_rule_by_rule(rho_set: str, alpha_set: str, left: str, right: str) -> None:
    vn = 1.7
    level = {"S": vn - P.a_mps, "M": vn, "F": vn + P.a_mps}
    out = fuzzy.fis1(ALPHA_AT[alpha_set], RHO_AT[rho_set], vn, P)
    assert out.left_mps == pytest.approx(level[left], abs=1e-12)
    assert out.right_mps == pytest.approx(level[right], abs=1e-12)


TABLE2 = [
    ("Positive", "Close", "M"),
    ("Positive", "Enough", "H"),
    ("Positive", "Far", "H"),
    ("Zero", "Close", "M"),
    ("Zero", "Enough", "M"),
    ("Zero", "Far", "M"),
    ("Negative", "Close", "L"),
    ("Negative", "Enough", "L"),
    ("Negative", "Far", "M"),
]


@pytest.mark.parametrize(("drho_set", "rho_set", "vn"), TABLE2)
def test_table2_rule_by_rule(drho_set: str, rho_set: str, vn: str) -> None:
    level = {"L": P.vn_min, "M": P.vm, "H": P.vn_max}
    assert fuzzy.fis2(DRHO_AT[drho_set], RHO_AT[rho_set], P) == pytest.approx(level[vn], abs=1e-12)


def test_memberships_partition_unity() -> None:
    for x in np.linspace(-4, 4, 401):
        assert sum(fuzzy.alpha_memberships(float(x), P.gamma_rad)) == pytest.approx(1.0, abs=1e-12)
        assert sum(fuzzy.drho_memberships(float(x), 0.5)) == pytest.approx(1.0, abs=1e-12)
    for r in np.linspace(0, 4, 401):
        ms = fuzzy.rho_memberships(float(r), P)
        assert min(ms) >= 0.0
        assert sum(ms) == pytest.approx(1.0, abs=1e-12)


def test_static_mode_uses_fixed_vn_and_dynamic_uses_fis2() -> None:
    vn, w = fuzzy.control(0.0, 5.0, 0.0, 0.05, p=P, mode=SpeedMode(1.5))
    assert vn == 1.5
    assert w == (2.0, 2.0)  # Far + Center: both wheels Fast = V_N + a
    vn, _ = fuzzy.control(0.0, 5.0, 0.05, 0.05, p=P, mode=SpeedMode())
    assert vn == pytest.approx(P.vn_max)  # Far and growing: High


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"d0_m": 0.6}, "dn_m"),
        ({"d1_m": 0.2}, "d1_m"),
        ({"dmax_m": 0.5}, "dmax_m"),
        ({"d0_m": -0.1}, "d0_m"),
        ({"gamma_rad": 0.0}, "gamma_rad"),
        ({"gamma_rad": math.nan}, "gamma_rad"),
        ({"a_mps": -1.0}, "a_mps"),
        ({"vm": 1.4}, "vm"),
        ({"vn_max": 1.6}, "vn_max"),
        ({"drho_rate_tol_mps": math.inf}, "drho_rate_tol_mps"),
    ],
)
def test_bad_parameters_name_the_field(kwargs: dict[str, float], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        FuzzyParams(**kwargs)


@pytest.mark.parametrize(
    ("args", "name"),
    [
        ((math.nan, 1.0, 0.0, 0.05), "alpha_rad"),
        ((0.0, math.nan, 0.0, 0.05), "rho_m"),
        ((0.0, 1.0, math.inf, 0.05), "drho_m"),
        ((0.0, 1.0, 0.0, 0.0), "dt_s"),
    ],
)
def test_bad_inputs_name_the_parameter(args: tuple[float, ...], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        fuzzy.control(*args, p=P, mode=SpeedMode())


def test_non_number_input_is_a_type_error() -> None:
    with pytest.raises(TypeError, match="alpha_rad"):
        fuzzy.control("0.1", 1.0, 0.0, 0.05, p=P, mode=SpeedMode())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="static_vn"):
        SpeedMode(-1.0)


def test_parameters_are_frozen_and_ordered() -> None:
    import dataclasses

    with pytest.raises(dataclasses.FrozenInstanceError):
        FuzzyParams().a_mps = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        SpeedMode().static_vn = 1.0  # type: ignore[misc]
    # The breakpoints' order is strict where the sets need a width, loose where they may touch.
    FuzzyParams(d1_m=0.5)  # dn = d1: Enough is a triangle's top, allowed
    FuzzyParams(vm=1.5, vn_max=1.5)  # one V_N for all three levels, allowed
    for kwargs, name in (
        ({"dn_m": 0.1}, "dn_m"),
        ({"dmax_m": 1.0}, "dmax_m"),
        ({"d1_m": 0.4}, "d1_m"),
        ({"vm": 1.4}, "vm"),
        ({"vn_max": 1.6}, "vn_max"),
    ):
        with pytest.raises(ValueError, match=name):
            FuzzyParams(**kwargs)
    assert SpeedMode().dynamic
    assert not SpeedMode(static_vn=1.5).dynamic


def test_a_rule_whose_strength_ties_its_other_input_still_fires_once() -> None:
    """min(mu_drho, mu_rho) with the two equal: the rule counts its strength once."""
    p = P
    rho = 0.5 * (p.d0_m + p.dn_m)  # Close 0.5, Enough 0.5
    rate = 0.5 * p.drho_rate_tol_mps  # Positive 0.5, Zero 0.5
    # Positive/Close -> Middle, Positive/Enough -> High, Zero/* -> Middle: all at 0.5.
    assert fuzzy.fis2(rate, rho, p) == pytest.approx((3 * p.vm + p.vn_max) / 4, abs=1e-12)
    assert fuzzy.fis2(-rate, rho, p) == pytest.approx((p.vn_min * 2 + p.vm * 2) / 4, abs=1e-12)


def test_dynamic_vn_takes_the_rate_of_change_of_rho() -> None:
    """FIS-2's input is drho / dt (m/s), not drho (m): 0.01 m in 0.02 s is 0.5 m/s."""
    vn, _ = fuzzy.control(0.0, 1.0, 0.01, 0.02, p=P, mode=SpeedMode())
    assert vn == pytest.approx(fuzzy.fis2(0.5, 1.0, P), abs=1e-12)
    assert vn == pytest.approx(P.vn_max, abs=1e-12)  # Positive (saturated) and Enough: High
