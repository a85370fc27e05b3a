"""The two-stage fuzzy controller of paper section 4.

FIS-1 (section 4.1, Table 1, eq. 22-23) maps the heading error alpha and the
distance error rho to left and right wheel speeds; FIS-2 (section 4.2,
Table 2) maps rho and its change to V_N, the centre of FIS-1's output sets.

Both are zero-order Sugeno systems as eq. 23 prints them: rule strength
mu_i = min of the antecedent memberships (eq. 22), output the strength-
weighted mean of the rules' consequent values z_i. The membership shapes are
only drawn in the paper (Fig. 5); ours are written out in docs/paper.md.
Every function here works on plain floats: one robot's step (FIS-2 and FIS-1
for both wheels) is on the per-tick hot path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from formation_swarm.common.checks import finite, positive
from formation_swarm.world.kinematics import wrap_angle

# Table 1, rows Close / Enough / Far, columns alpha = Left / Center / Right.
# "Left" means the follower's heading is too far left of the target, i.e. the
# target is to its right (alpha > 0), so the left wheel must run faster.
S, M, F = 0, 1, 2
TABLE1_LEFT = ((S, S, S), (M, M, S), (F, F, M))
TABLE1_RIGHT = ((S, S, S), (S, M, M), (M, F, F))
# Table 2, rows drho = Positive / Zero / Negative, columns Close / Enough / Far.
LOW, MIDDLE, HIGH = 0, 1, 2
TABLE2 = ((MIDDLE, HIGH, HIGH), (MIDDLE, MIDDLE, MIDDLE), (LOW, LOW, MIDDLE))


@dataclass(frozen=True)
class FuzzyParams:
    """Membership parameters; defaults are the paper's where it gives them.

    gamma_rad: heading tolerance (paper: 15 deg).
    d0_m < dn_m <= d1_m < dmax_m: distance-error breakpoints (section 4.1).
    a_mps: width of the Medium wheel-speed set (paper: 0.5).
    vn_min/vm/vn_max: FIS-2's Low/Middle/High V_N (paper: 1.5/1.7/2).
    drho_rate_tol_mps: |drho|/dt at which Positive/Negative saturate.
    """

    gamma_rad: float = math.radians(15.0)
    d0_m: float = 0.1
    dn_m: float = 0.5
    d1_m: float = 1.0
    dmax_m: float = 2.0
    a_mps: float = 0.5
    vn_min: float = 1.5
    vm: float = 1.7
    vn_max: float = 2.0
    drho_rate_tol_mps: float = 0.5

    def __post_init__(self) -> None:
        positive("gamma_rad", self.gamma_rad)
        if self.gamma_rad > math.pi:
            raise ValueError(f"gamma_rad must be <= pi, got {self.gamma_rad!r}")
        d0 = finite("d0_m", self.d0_m)
        if d0 < 0.0:
            raise ValueError(f"d0_m must be >= 0, got {d0!r}")
        if not finite("dn_m", self.dn_m) > d0:
            raise ValueError(f"dn_m must be > d0_m ({d0!r}), got {self.dn_m!r}")
        if not finite("d1_m", self.d1_m) >= self.dn_m:
            raise ValueError(f"d1_m must be >= dn_m ({self.dn_m!r}), got {self.d1_m!r}")
        if not finite("dmax_m", self.dmax_m) > self.d1_m:
            raise ValueError(f"dmax_m must be > d1_m ({self.d1_m!r}), got {self.dmax_m!r}")
        positive("a_mps", self.a_mps)
        positive("vn_min", self.vn_min)
        if not finite("vm", self.vm) >= self.vn_min:
            raise ValueError(f"vm must be >= vn_min ({self.vn_min!r}), got {self.vm!r}")
        if not finite("vn_max", self.vn_max) >= self.vm:
            raise ValueError(f"vn_max must be >= vm ({self.vm!r}), got {self.vn_max!r}")
        positive("drho_rate_tol_mps", self.drho_rate_tol_mps)


class Wheels(NamedTuple):
    left_mps: float
    right_mps: float


def _clip01(x: float) -> float:
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


def alpha_memberships(alpha_rad: float, gamma_rad: float) -> tuple[float, float, float]:
    """(Left, Center, Right) of the heading error; a partition of unity.

    Center is a triangle on [-gamma, gamma]; Left rises from 0 at alpha = 0
    to 1 at +gamma and stays 1; Right mirrors it for alpha < 0.
    """
    r = alpha_rad / gamma_rad
    return _clip01(r), max(0.0, 1.0 - abs(r)), _clip01(-r)


def rho_memberships(rho_m: float, p: FuzzyParams) -> tuple[float, float, float]:
    """(Close, Enough, Far) of the distance error; a partition of unity.

    Close is 1 up to d0 (and for every negative, behind-the-robot rho) and
    falls to 0 at dn; Enough rises d0..dn, is 1 on
    [dn, d1] and falls to 0 at dmax; Far rises d1..dmax and stays 1.
    """
    close = _clip01((p.dn_m - rho_m) / (p.dn_m - p.d0_m))
    far = _clip01((rho_m - p.d1_m) / (p.dmax_m - p.d1_m))
    return close, 1.0 - close - far, far


def drho_memberships(drho_rate_mps: float, tol_mps: float) -> tuple[float, float, float]:
    """(Positive, Zero, Negative) of the distance-error rate (eq. 6 over dt)."""
    r = drho_rate_mps / tol_mps
    return _clip01(r), max(0.0, 1.0 - abs(r)), _clip01(-r)


def fis1(alpha_rad: float, rho_m: float, vn: float, p: FuzzyParams) -> Wheels:
    """FIS-1: wheel speeds from alpha and rho, output sets centred on V_N.

    Slow, Medium and Fast are the triangles peaking at V_N - a, V_N and
    V_N + a; with eq. 23 a rule contributes its set's peak, weighted by its
    strength min(mu_rho, mu_alpha) (eq. 22). 9 rules per wheel, 18 in all.
    """
    ma = alpha_memberships(alpha_rad, p.gamma_rad)
    mr = rho_memberships(rho_m, p)
    levels = (vn - p.a_mps, vn, vn + p.a_mps)
    num_l = num_r = den = 0.0
    for i in range(3):
        mri = mr[i]
        if mri == 0.0:
            continue
        row_l = TABLE1_LEFT[i]
        row_r = TABLE1_RIGHT[i]
        for j in range(3):
            w = mri if mri < ma[j] else ma[j]
            if w == 0.0:
                continue
            num_l += w * levels[row_l[j]]
            num_r += w * levels[row_r[j]]
            den += w
    return Wheels(num_l / den, num_r / den)


def fis2(drho_rate_mps: float, rho_m: float, p: FuzzyParams) -> float:
    """FIS-2: V_N from the distance-error rate and rho (Table 2)."""
    md = drho_memberships(drho_rate_mps, p.drho_rate_tol_mps)
    mr = rho_memberships(rho_m, p)
    levels = (p.vn_min, p.vm, p.vn_max)
    num = den = 0.0
    for i in range(3):
        mdi = md[i]
        if mdi == 0.0:
            continue
        row = TABLE2[i]
        for j in range(3):
            w = mdi if mdi < mr[j] else mr[j]
            if w == 0.0:
                continue
            num += w * levels[row[j]]
            den += w
    return num / den


@dataclass(frozen=True)
class SpeedMode:
    """V_N source: the paper's static baselines (a fixed V_N) or dynamic FIS-2."""

    static_vn: float | None = None

    def __post_init__(self) -> None:
        if self.static_vn is not None:
            positive("static_vn", self.static_vn)

    @property
    def dynamic(self) -> bool:
        return self.static_vn is None


def control(
    alpha_rad: float, rho_m: float, drho_m: float, dt_s: float, *, p: FuzzyParams, mode: SpeedMode
) -> tuple[float, Wheels]:
    """One robot's fuzzy step: V_N (FIS-2 or static), then FIS-1 for both wheels.

    Inputs are validated here, once per tick, so the inner functions stay lean.
    """
    alpha = finite("alpha_rad", alpha_rad)
    if abs(alpha) > math.pi:
        # Wrapped, not saturated: alpha = pi + 0.3 is a target behind-left (Right), not Left.
        # Eq. 4's atan2 stays in [-pi, pi], so the shipped runs never get here.
        alpha = wrap_angle(alpha)
    rho = finite("rho_m", rho_m)  # signed: < 0 when the target is behind (eq. 5)
    drho = finite("drho_m", drho_m)
    dt = positive("dt_s", dt_s)
    vn = fis2(drho / dt, rho, p) if mode.static_vn is None else mode.static_vn
    return vn, fis1(alpha, rho, vn, p)


class SpeedRange(NamedTuple):
    """Forward speeds (m/s) of a follower driving straight (alpha = 0)."""

    steady_low_mps: float  # at a constant distance to its target (drho = 0)
    steady_high_mps: float
    floor_mps: float  # the slowest it ever drives
    ceiling_mps: float  # the fastest


def speed_range(p: FuzzyParams, mode: SpeedMode) -> SpeedRange:
    """The speeds at which a follower can hold its slot behind a reference that
    drives straight, read off the rule tables.

    Going straight, alpha is Center only, so FIS-1 (Table 1, middle column)
    gives both wheels V_N - a when the target is Close, V_N when Enough and
    V_N + a when Far. At a constant distance drho = 0, and FIS-2's Zero row
    (Table 2) is Middle throughout: V_N = vm. The speeds held steadily are
    therefore [vm - a, vm + a] (a static V_N: [V_N - a, V_N + a]); with drho
    away from 0 FIS-2 moves V_N within [vn_min, vn_max], so the follower never
    drives slower than vn_min - a nor faster than vn_max + a. A reference
    slower than the steady range is overrun (the target falls behind, rho < 0
    is Close, and the follower still drives at V_N - a); a faster one is lost.
    """
    if mode.static_vn is not None:
        vn = mode.static_vn
        return SpeedRange(vn - p.a_mps, vn + p.a_mps, vn - p.a_mps, vn + p.a_mps)
    return SpeedRange(p.vm - p.a_mps, p.vm + p.a_mps, p.vn_min - p.a_mps, p.vn_max + p.a_mps)
