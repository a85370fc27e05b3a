"""How far the paper's claims hold: claims a-d measured seed by seed at every
value of one setting at a time (``swarm results --sensitivity``).

The settings are the leader's speed, the observations' drops, the camera's
noise, and the wheels' noise and speed bias; at each value the claims' own runs are repeated
(the scenarios and criteria of tests/system/test_claims.py, formation_swarm.studies.claims),
with, beside the paper's controllers, the l-psi baseline on every axis and
the static V_N values 1.7 and 1.8 on the leader-speed axis. The shipped value
of an axis is the claims' own runs (no setting changed), so those runs are
shared with ``swarm results --claims``.

``plan`` names the sweeps of a point, ``measure`` reads their rows into one
``Point`` per value, ``sensitivity_text`` says them and ``sensitivity_figure``
draws them.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from formation_swarm.studies import claims

if TYPE_CHECKING:
    from formation_swarm.studies.engine_sweep import EngineSweep

ROOT = Path(__file__).resolve().parents[3]
# Controllers flown beside the claims' own runs, on the path of claims a-b (the dynamic run's scenario).
EXTRAS: dict[str, dict[str, Any]] = {
    "static 1.7": {"controller.vn": 1.7},
    "static 1.8": {"controller.vn": 1.8},
    "l-psi": {"controller.law": "lpsi"},
}
EXTRA_SCENARIO = "fig7_turn_vn_dynamic.toml"
# The controllers of the figures' lines, in legend order: claims' sweep or extra name -> legend.
LINES = {
    "dynamic": "fuzzy, dynamic V_N",
    "static 1.5": "fuzzy, V_N = 1.5",
    "static 1.7": "fuzzy, V_N = 1.7",
    "static 1.8": "fuzzy, V_N = 1.8",
    "static 2": "fuzzy, V_N = 2",
    "l-psi": "l-psi",
}
SHORT = {c.__name__: name for c, name in zip(claims.CLAIMS, ("a", "b, behind", "b, overshoot", "c", "d"), strict=True)}


def _camera(sigma_rho_m: float) -> dict[str, Any]:
    """The camera's three sigmas at one level (phi and beta from the table below), the EKF told them."""
    phi_deg, beta_deg = CAMERA_LEVELS[sigma_rho_m]
    return {
        "camera.sigma_rho_m": sigma_rho_m,
        "camera.sigma_phi_deg": phi_deg,
        "camera.sigma_beta_deg": beta_deg,
        "controller.ekf.sigma_rho_m": sigma_rho_m,
        "controller.ekf.sigma_phi_rad": math.radians(phi_deg),
        "controller.ekf.sigma_beta_rad": math.radians(beta_deg),
    }


# sigma_rho (m) -> (sigma_phi, sigma_beta) in degrees: half the scenarios' default, the default
# (claims a, b, d), Fig. 9's (claim c), and twice Fig. 9's.
CAMERA_LEVELS = {0.025: (1.5, 0.75), 0.05: (3.0, 1.5), 0.1: (5.0, 2.5), 0.2: (10.0, 5.0)}


@dataclass(frozen=True)
class Axis:
    name: str  # file and marker name
    title: str  # what varies, for a person
    unit: str
    values: tuple[float, ...]
    shipped: float | None  # the value of the shipped scenarios: its point is the claims' own runs
    settings: Callable[[float], dict[str, Any]]
    faults: Callable[[float], list[str]] = lambda _v: []
    extras: tuple[str, ...] = ("l-psi",)
    note: str = ""
    marks: tuple[tuple[float, str], ...] = ()  # values drawn dotted, with what they are; default: the shipped one

    @property
    def dotted(self) -> tuple[tuple[float, str], ...]:
        return self.marks or (((self.shipped, "the shipped value"),) if self.shipped is not None else ())

    def point(self, value: float) -> tuple[dict[str, Any], list[str]]:
        """The scenario keys and the faults of one value; none at the shipped value."""
        return ({}, []) if value == self.shipped else (self.settings(value), self.faults(value))

    def label(self, value: float) -> str:
        return f"{value:g} {self.unit}".strip()


AXES: tuple[Axis, ...] = (
    Axis(
        "leader_speed",
        "leader speed",
        "m/s",
        # The paper's band 1.0-2.0 m/s, and every 0.05 m/s from 1.3 to 1.8 where claims a and b change.
        (1.0, 1.25, 1.3, 1.35, 1.4, 1.45, 1.5, 1.55, 1.6, 1.65, 1.7, 1.75, 1.8, 2.0),
        1.5,
        lambda v: {"leader.speed_mps": v},
        extras=tuple(EXTRAS),
        note="every scenario's leader at this speed (shipped: 1.5 m/s); the turn rate stays 0.25 rad/s",
    ),
    Axis(
        "obs_drop",
        "observation drops",
        "%",
        (0.0, 10.0, 20.0, 30.0, 40.0, 50.0),
        0.0,
        lambda v: {"links.obs_drop": v / 100},
        note="links.obs_drop: this share of the world's observations to every robot is lost on the way "
        "(a drop decided per message from the seed); a follower without a reading predicts with its EKF",
    ),
    Axis(
        "camera_noise",
        "camera noise, sigma of rho",
        "m",
        tuple(CAMERA_LEVELS),
        None,
        _camera,
        note="sigma of phi and beta "
        + ", ".join(f"{p:g} and {b:g} deg at {r:g} m" for r, (p, b) in CAMERA_LEVELS.items())
        + ", the EKF told them, in every scenario (shipped: 0.05 m, claim c's 0.1 m)",
        marks=((0.05, "the shipped 0.05 m (claims a, b, d)"), (0.1, "claim c's 0.1 m (fig9_ekf_noise)")),
    ),
    Axis(
        "wheel_noise",
        "wheel noise",
        "m/s",
        (0.0, 0.05, 0.1),
        0.0,
        lambda v: {"robot.wheel_noise_mps": v},
        note="robot.wheel_noise_mps: Gaussian noise on every wheel of every robot, drawn per tick; "
        "the EKF is not told of it",
    ),
    Axis(
        "wheel_bias",
        "left wheel speed bias",
        "%",
        (0.0, 1.0, 2.0, 3.0),
        0.0,
        lambda _v: {},
        faults=lambda v: [f"wheel_bias *@0s left={v / 100:g}"],
        note="every robot's left wheel turns this much faster than commanded (fault wheel_bias), as with "
        "unequal wheel diameters: a drift of heading that a follower's EKF, predicting its own motion "
        "from its commands, does not know",
    ),
)
AXIS_NAMES = {a.name: a for a in AXES}


def plan(
    seeds: Sequence[int],
    settings: Mapping[str, Any],
    faults: Sequence[str],
    out: Path,
    *,
    workers: int | None,
    extras: Sequence[str] = (),
) -> dict[str, EngineSweep]:
    """The sweeps of one point: the claims' (one per ``claims.SWEEPS``, in ``out/<its folder>``) and the extra
    controllers' (in ``out/<scenario>-<extra>``). Every run's label names the settings and the faults,
    so the points of an axis share those folders and a point without either is the claims' own runs.
    Their runs are stepped in one process (studies.engine_sweep): the lockstep runs' very rows."""
    from formation_swarm.studies.engine_sweep import EngineSweep as Sweep
    from formation_swarm.studies.jobs import Job, settings_text

    label = "; ".join(t for t in (settings_text(settings), ", ".join(faults)) if t)
    out_sweeps = {
        name: Sweep(
            ROOT / "scenarios" / src.file,
            [Job(label, {**settings, **src.overrides}, s) for s in seeds],
            out / src.folder,
            workers=workers,
            logger=src.logger,
            faults=list(faults),
        )
        for name, src in claims.SWEEPS.items()
    }
    for name in extras:
        ov = {**EXTRAS[name], **settings}
        out_sweeps[name] = Sweep(
            ROOT / "scenarios" / EXTRA_SCENARIO,
            [Job(label, ov, s) for s in seeds],
            out / f"{Path(EXTRA_SCENARIO).stem}-{name.replace(' ', '-')}",
            workers=workers,
            faults=list(faults),
        )
    return out_sweeps


@dataclass(frozen=True)
class Stat:
    mean: float
    half: float  # 95% confidence half-width of the mean (Student t); nan for one seed
    n: int


def stat(values: Sequence[float]) -> Stat:
    from formation_swarm.studies.tables import half_width

    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    if not vals:
        return Stat(math.nan, math.nan, 0)
    return Stat(statistics.fmean(vals), half_width(vals), len(vals))


# The figures' metrics: (panel title, row key, sweeps it is read from, the claim's threshold if any).
METRICS: tuple[tuple[str, str, tuple[str, ...], float | None], ...] = (
    ("formation error RMS, m (claim a)", "r2_rms_m", tuple(LINES), None),
    ("largest formation error, m (claim a)", "r2_max_m", tuple(LINES), None),
    ("mean lag in the turns, m (claim b: > 0.5 at V_N 1.5)", "r2_turn_mean_lag_m", tuple(LINES), 0.5),
    ("largest lead on the target, m (claim b: > 0.25 at V_N 2)", "r2_max_ahead_m", tuple(LINES), 0.25),
    ("EKF / raw target error RMS (claim c: <= 0.5)", "r2_ekf_ratio", ("ekf",), 0.5),
)


# Claim d's runs and the rank swap's, flown with and without eq. 11-13: in Point.counts, "robot contact,
# <sweep>" and "obstacle contact, <sweep>" count the runs in which two robots, or a robot and an obstacle, touched.
CONTACT_SWEEPS = ("obstacles", "obstacles, no avoidance", "rank swap", "rank swap, no avoidance")
# The leader's distance from its path, on the path of claims a-c (the dynamic run's).
LEADER = ("leader_off_path_m", "leader_end_m")


@dataclass
class Point:
    value: float
    claims: list[claims.Claim]
    stats: dict[tuple[str, str], Stat] = field(default_factory=dict)  # (sweep, metric) -> over the seeds
    # Claim d's runs in which something touched (CONTACT_SWEEPS), and the runs of each sweep ("runs <sweep>").
    counts: dict[str, int] = field(default_factory=dict)
    # The avoidance's statement on the rank swap (claims.rank_swap): not one of the paper's claims.
    swap: claims.Claim | None = None


def measure(value: float, rows: claims.Rows) -> Point:
    """The claims, the rank swap's statement and the figures' statistics of one point, from its sweeps' rows."""
    pt = Point(value, claims.measure(rows), swap=claims.rank_swap(rows))
    for _title, key, sweeps, _thr in METRICS:
        for name in sweeps:
            if name in rows:
                pt.stats[name, key] = stat([r.get(key) for r in rows[name]])
    for name in CONTACT_SWEEPS:
        pt.stats[name, "min_distance_m"] = stat([r["min_distance_m"] for r in rows[name]])
        pt.counts[f"runs {name}"] = len(rows[name])
        pt.counts[f"robot contact, {name}"] = sum(1 for r in rows[name] if r["collisions"])
        pt.counts[f"obstacle contact, {name}"] = sum(1 for r in rows[name] if r["obstacle_collisions"])
    for key in LEADER:
        pt.stats["dynamic", key] = stat([r.get(key) for r in rows["dynamic"]])
    return pt
