"""Extended Kalman filter of paper section 3 (eq. 14-21) on filterpy.

State, in the follower frame: the reference robot's centre (x_r, y_r) in m,
its orientation relative to the follower phi in rad, its speed v_r in m/s and
its turn rate w_r in rad/s.
The virtual target is the fixed function P_g = P_r + R_z(phi) P_vt (eq. 2) of
this state, so a formation change (a new P_vt) does not disturb the filter
and eq. 11-12 get P_r directly (docs/paper.md, section 3).

Prediction (eq. 14, 17-18) moves the reference at v_r along its heading,
turning at w_r, and applies the follower's own motion from its wheel speeds
(eq. 7-10, the paper's B u term): the frame translates and turns under the
point. Correction (eq. 19-21) uses the camera reading z = (rho_r, beta, phi)
through the nonlinear h of eq. 1 and its Jacobian; angle residuals wrap.
A missing reading (dropped, out of view) only predicts.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from formation_swarm.agents.geometry import MarkerReading, Point, leader_point, rotate
from formation_swarm.common.checks import finite, non_negative, positive
from formation_swarm.world.kinematics import body_twist, wrap_angle


@dataclass(frozen=True)
class EkfParams:
    """Noise model. Measurement sigmas should match the camera's."""

    sigma_rho_m: float = 0.05
    sigma_phi_rad: float = math.radians(3.0)
    sigma_beta_rad: float = math.radians(1.5)
    # Process noise densities: unmodelled reference motion per sqrt(s).
    q_pos_m: float = 0.02
    q_phi_rad: float = 0.02
    q_speed_mps: float = 0.5
    # The scenario leaders ramp their turn rate 0 -> 0.25 rad/s in about 0.5 s.
    q_turn_rps: float = 0.5
    initial_speed_sigma_mps: float = 1.0
    initial_turn_sigma_rps: float = 0.5

    def __post_init__(self) -> None:
        for name in ("sigma_rho_m", "sigma_phi_rad", "sigma_beta_rad"):
            positive(name, getattr(self, name))
        for name in ("q_pos_m", "q_phi_rad", "q_speed_mps", "q_turn_rps"):
            non_negative(name, getattr(self, name))
        positive("initial_speed_sigma_mps", self.initial_speed_sigma_mps)
        positive("initial_turn_sigma_rps", self.initial_turn_sigma_rps)


def _residual(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    y = a - b
    y[1, 0] = wrap_angle(y.item(1))  # item: a Python float, the same number, faster arithmetic
    y[2, 0] = wrap_angle(y.item(2))
    return y


@functools.cache
def _scipy_inverse() -> tuple[Callable[[np.ndarray], np.ndarray], Callable[..., Any] | None]:
    """scipy.linalg.inv and the compiled routine it hands a checked float64
    matrix to (None where this scipy has none: scipy.linalg.inv is then used)."""
    import scipy.linalg

    try:
        from scipy.linalg import _batched_linalg  # scipy >= 1.15: what inv calls once its checks pass

        routine = _batched_linalg._inv
    except (ImportError, AttributeError):
        routine = None
    return scipy.linalg.inv, routine


def _inverse(s: np.ndarray) -> np.ndarray:
    """``scipy.linalg.inv(s)``, the same numbers: for a finite 3 x 3 float64
    matrix, the routine it calls, without its Python-level checks and
    dispatch (30 of its 40 us under load, a tenth of a follower's tick);
    anything else, and any matrix the routine finds singular or ill-conditioned,
    through ``scipy.linalg.inv`` itself, which raises or warns as ever."""
    inv, routine = _scipy_inverse()
    if routine is not None and s.dtype == np.float64 and s.shape == (3, 3) and math.isfinite(s.sum()):
        out, errors = routine(s, -1, False, False)  # structure found by scipy, a copy, upper triangle
        if not errors:
            return out
    return inv(s)


def _update(  # noqa: PLR0913, PLR0917 - filterpy's signature
    kf: Any,
    z: np.ndarray | None,
    HJacobian: Callable[..., np.ndarray],  # noqa: N803 - filterpy's names
    Hx: Callable[..., np.ndarray],  # noqa: N803
    R: Any = None,  # noqa: N803
    args: Any = (),
    hx_args: Any = (),
    residual: Callable[[np.ndarray, np.ndarray], np.ndarray] = np.subtract,
) -> None:
    """filterpy 1.4.5's ``ExtendedKalmanFilter.update`` line for line (eq.
    19-21), the same numbers, with :func:`_inverse` for its ``scipy.linalg.inv``
    and a copy of ``z`` for its ``deepcopy``; other calls go to filterpy's own."""
    if z is None or R is not None or type(args) is not tuple or type(hx_args) is not tuple:
        from filterpy.kalman import ExtendedKalmanFilter  # imported already: filter_class

        ExtendedKalmanFilter.update(kf, z, HJacobian, Hx, R, args, hx_args, residual)
        return
    dot = np.dot
    H = HJacobian(kf.x, *args)  # noqa: N806
    PHT = dot(kf.P, H.T)  # noqa: N806
    kf.S = dot(H, PHT) + kf.R
    kf.SI = _inverse(kf.S)
    kf.K = PHT.dot(kf.SI)
    kf.y = residual(z, Hx(kf.x, *hx_args))
    kf.x = kf.x + dot(kf.K, kf.y)
    I_KH = kf._I - dot(kf.K, H)  # noqa: N806
    kf.P = dot(I_KH, kf.P).dot(I_KH.T) + dot(kf.K, kf.R).dot(kf.K.T)
    kf._log_likelihood = kf._likelihood = kf._mahalanobis = None
    kf.z = z.copy()
    kf.x_post = kf.x.copy()
    kf.P_post = kf.P.copy()


@functools.cache
def filter_class() -> type:
    """filterpy's EKF with the nonlinear prediction of this model, made on
    first use: filterpy imports scipy.stats (about 0.6 s), which the
    commands that only read a scenario never need. The agents' spawner
    makes it before it forks (formation_swarm.nodes.preload)."""
    from filterpy.kalman import ExtendedKalmanFilter

    class _Filter(ExtendedKalmanFilter):
        """filterpy's EKF with the nonlinear prediction of this model and a cheaper update (:func:`_update`)."""

        update = _update

        def predict_x(self, u: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
            v_f, dth, dt = u
            x, y, phi, v, w = self.x[:, 0].tolist()
            # The follower's own displacement over the step, on its arc (eq. 7).
            if abs(dth) < 1e-9:
                tx, ty = 0.0, v_f * dt
            else:
                radius = v_f * dt / dth
                tx, ty = -radius * (1.0 - math.cos(dth)), radius * math.sin(dth)
            # Reference moves along its mid-step heading R(phi_m)[0, 1] = (-sin, cos).
            phi_m = phi + 0.5 * w * dt
            x1 = x - v * dt * math.sin(phi_m) - tx
            y1 = y + v * dt * math.cos(phi_m) - ty
            # The follower turns by dth: points rotate by -dth in its frame.
            c = math.cos(dth)
            s = math.sin(dth)
            # In place: filterpy keeps copies (x_prior, x_post), never this array.
            state = self.x
            state[0, 0] = c * x1 + s * y1
            state[1, 0] = -s * x1 + c * y1
            state[2, 0] = wrap_angle(phi + w * dt - dth)

    return _Filter


def _hx(state: np.ndarray, d: float, out: np.ndarray | None = None) -> np.ndarray:
    """Eq. 1, h(x) = (rho_r, beta, phi), written into ``out`` (3 x 1) if given."""
    if out is None:
        out = np.zeros((3, 1))
    x, y, phi = state.item(0), state.item(1), state.item(2)
    mx = x + d * math.sin(phi)
    my = y - d * math.cos(phi)
    out[0, 0] = math.hypot(mx, my)
    out[1, 0] = math.atan2(mx, my)
    out[2, 0] = phi
    return out


def _h_jacobian(state: np.ndarray, d: float, out: np.ndarray | None = None) -> np.ndarray:
    """The Jacobian of eq. 1, written into ``out`` if given (3 x 5, holding
    the constant entries, 0 and 1, of :func:`jacobian_template`)."""
    if out is None:
        out = jacobian_template()
    x, y, phi = state.item(0), state.item(1), state.item(2)
    mx = x + d * math.sin(phi)
    my = y - d * math.cos(phi)
    r2 = max(mx * mx + my * my, 1e-12)
    r = math.sqrt(r2)
    dmx_dphi = d * math.cos(phi)
    dmy_dphi = d * math.sin(phi)
    out[0, 0] = mx / r
    out[0, 1] = my / r
    out[0, 2] = (mx * dmx_dphi + my * dmy_dphi) / r
    out[1, 0] = my / r2
    out[1, 1] = -mx / r2
    out[1, 2] = (my * dmx_dphi - mx * dmy_dphi) / r2
    return out


def jacobian_template() -> np.ndarray:
    """A 3 x 5 array with the constant entries of :func:`_h_jacobian`."""
    h = np.zeros((3, 5))
    h[2, 2] = 1.0
    return h


# Beyond these the filter has diverged: no camera sees a marker a kilometre
# away, no robot of ours moves at 100 m/s, and a real run's covariance stays
# far under 1e6 (its diagonal: m^2, rad^2, (m/s)^2, (rad/s)^2).
MAX_POSITION_M = 1e3
MAX_SPEED = 1e2  # m/s and rad/s
MAX_COVARIANCE_TRACE = 1e6


class TargetEKF:
    """Tracks one reference robot from marker readings and the own wheel speeds."""

    def __init__(self, params: EkfParams, marker_offset_m: float, width_m: float) -> None:
        self.params = params
        self.marker_offset_m = non_negative("marker_offset_m", marker_offset_m)
        self.width_m = positive("width_m", width_m)
        self._kf = filter_class()(dim_x=5, dim_z=3)
        self._kf.R = np.diag([params.sigma_rho_m**2, params.sigma_beta_rad**2, params.sigma_phi_rad**2])
        self._q_dt = math.nan
        self._q = np.zeros((5, 5))
        # Filled in place every tick (filterpy reads them, keeps no reference):
        # the motion Jacobian F, the measurement Jacobian H, h(x) and z.
        self._kf.F = np.eye(5)
        self._h = jacobian_template()
        self._hx = np.zeros((3, 1))
        self._z = np.zeros((3, 1))
        # Eq. 2's Jacobian with respect to the state, filled in place by target().
        self._j = np.array([[1.0, 0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0, 0.0]])
        self.initialized = False
        self.resets = 0  # divergences: a state or covariance no longer finite and bounded

    def reset(self) -> None:
        self.initialized = False

    def _check(self) -> None:
        """After a step: a filter that diverged (a reading far outside the model,
        numbers overflowing) starts again from the next reading instead of
        raising or steering on garbage."""
        x, y, phi, v, w = self._kf.x[:, 0].tolist()
        p = self._kf.P.item  # P's trace, summed in numpy's order (ndarray.trace costs more than the step)
        trace = (((p(0) + p(6)) + p(12)) + p(18)) + p(24)
        # Written out (a tick's hot path); a nan fails every comparison.
        if not (
            0.0 <= trace < MAX_COVARIANCE_TRACE
            and abs(x) < MAX_POSITION_M
            and abs(y) < MAX_POSITION_M
            and math.isfinite(phi)
            and abs(v) < MAX_SPEED
            and abs(w) < MAX_SPEED
        ):
            self.initialized = False
            self.resets += 1

    def predict(self, v_left_mps: float, v_right_mps: float, dt_s: float) -> None:
        """Eq. 17-18 with the follower's own wheel speeds (eq. 8-9)."""
        if not self.initialized:
            return
        dt = positive("dt_s", dt_s)
        v_f, w_f = body_twist(finite("v_left_mps", v_left_mps), finite("v_right_mps", v_right_mps), self.width_m)
        dth = w_f * dt
        kf = self._kf
        _, _, phi, v, w = kf.x[:, 0].tolist()
        c = math.cos(dth)
        s = math.sin(dth)
        phi_m = phi + 0.5 * w * dt
        sp = math.sin(phi_m)
        cp = math.cos(phi_m)
        # Jacobian of predict_x with respect to the state: the frame's rotation
        # R(-dth) on (x, y) times the motion's Jacobian J, written out.
        # J rows 0-1: d(x1, y1)/d(x, y, phi, v, w); J rows 2-4: phi += w dt, v, w.
        j0 = (-v * dt * cp, -dt * sp, -0.5 * v * dt * dt * cp)
        j1 = (-v * dt * sp, dt * cp, -0.5 * v * dt * dt * sp)
        f = kf.F  # rows 2-4 are the identity's but for F[2, 4] = dt
        f[0, 0], f[0, 1], f[0, 2] = c, s, c * j0[0] + s * j1[0]
        f[0, 3], f[0, 4] = c * j0[1] + s * j1[1], c * j0[2] + s * j1[2]
        f[1, 0], f[1, 1], f[1, 2] = -s, c, -s * j0[0] + c * j1[0]
        f[1, 3], f[1, 4] = -s * j0[1] + c * j1[1], -s * j0[2] + c * j1[2]
        f[2, 4] = dt
        kf.Q = self._process_noise(dt)
        kf.predict(u=(v_f, dth, dt))
        self._check()

    def _process_noise(self, dt: float) -> np.ndarray:
        """Q for a step of ``dt`` (the same every tick: built once per dt)."""
        if dt != self._q_dt:
            p = self.params
            self._q = np.diag([p.q_pos_m**2, p.q_pos_m**2, p.q_phi_rad**2, p.q_speed_mps**2, p.q_turn_rps**2]) * dt
            self._q_dt = dt
        return self._q

    def update(self, reading: MarkerReading | None) -> None:
        """Eq. 19-21 with z = (rho_r, phi, beta); None only keeps the prediction."""
        if reading is None:
            if self.initialized:
                self._kf.update(None, _h_jacobian, _hx)
            return
        rho = non_negative("rho_m", reading.rho_m)
        phi = finite("phi_rad", reading.phi_rad)
        beta = finite("beta_rad", reading.beta_rad)
        if not self.initialized:
            self._initialize(rho, phi, beta)
            return
        z = self._z
        z[0, 0], z[1, 0], z[2, 0] = rho, beta, phi
        d = self.marker_offset_m
        try:
            self._kf.update(z, _h_jacobian, _hx, args=(d, self._h), hx_args=(d, self._hx), residual=_residual)
        except (ValueError, np.linalg.LinAlgError):  # a singular or non-finite innovation covariance
            self._kf.x[0, 0] = math.inf  # counted and reset by _check
        self._check()
        if self.initialized:
            self._kf.x[2, 0] = wrap_angle(self._kf.x[2, 0])

    def _initialize(self, rho: float, phi: float, beta: float) -> None:
        """Invert eq. 1 for the first reading; speed unknown (0 +- initial sigma)."""
        pr = leader_point(rho, phi, beta, self.marker_offset_m)
        p = self.params
        # First-order covariance of the inverted reading.
        sb, cb = math.sin(beta), math.cos(beta)
        j = np.array([[sb, rho * cb], [cb, -rho * sb]])
        cov_xy = j @ np.diag([p.sigma_rho_m**2, p.sigma_beta_rad**2]) @ j.T
        cov_xy += np.eye(2) * (self.marker_offset_m * p.sigma_phi_rad) ** 2
        self._kf.x = np.array([[pr.x_m], [pr.y_m], [phi], [0.0], [0.0]])
        self._kf.P = np.zeros((5, 5))
        self._kf.P[:2, :2] = cov_xy
        self._kf.P[2, 2] = p.sigma_phi_rad**2
        self._kf.P[3, 3] = p.initial_speed_sigma_mps**2
        self._kf.P[4, 4] = p.initial_turn_sigma_rps**2
        self.initialized = True

    @property
    def state(self) -> np.ndarray:
        """(x_r, y_r, phi, v_r, w_r), a copy."""
        return self._kf.x[:, 0].copy()

    @property
    def speed_mps(self) -> float:
        """v_r, the reference's estimated speed (m/s)."""
        return float(self._kf.x[3, 0])

    @property
    def covariance(self) -> np.ndarray:
        return self._kf.P.copy()

    def leader(self) -> tuple[Point, float]:
        x, y, phi = self._kf.x[:3, 0].tolist()
        return Point(x, y), phi

    def target(self, offset: Point) -> tuple[Point, np.ndarray]:
        """Eq. 2 on the estimate: P_g and its 2x2 covariance (first order)."""
        x, y, phi = self._kf.x[:3, 0].tolist()
        off = rotate(phi, offset[0], offset[1])
        # d/dphi R(phi) P_vt = R(phi + pi/2) P_vt = (-off_y, off_x)
        j = self._j
        j[0, 2] = -off.y_m
        j[1, 2] = off.x_m
        cov = j @ self._kf.P @ j.T
        return Point(x + off.x_m, y + off.y_m), cov
