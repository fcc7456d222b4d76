r"""Single-axis complementary Kalman filter (FKC; seed 000 §2.1.4, Algorithm 1; seed 002 §2.2).

One angle :math:`\theta` about one sensor axis from a gyroscope rate :math:`\omega` (rad/s) and an
absolute angle :math:`\theta_a` (rad), usually the accelerometer angle (eq. 8,
:math:`\hat\theta_a = \arcsin(a_x/g)`, or the more robust :func:`accelerometer_angles`).

* gyroscope angle (eq. 7): :math:`\hat\theta_g[k] = \hat\theta_g[k-1] + T\omega[k]`, from ``theta0_rad``
  (the angle one sample before the first);
* error state :math:`x = [\Delta\theta, \Delta b]` (eqs. 17–19), :math:`F = I + AT`,
  :math:`G = A^{-1}(F-I)B = T I` (eq. 21; see :mod:`estimators.markov.core`);
* measurement :math:`z = \hat\theta_a - \hat\theta_g = \Delta\theta + \eta_a`, :math:`H = [1\ 0]` (eqs. 9, 20);
* output :math:`\hat\theta = \hat\theta_g + \Delta\hat\theta` (eq. 10).

Noise (eqs. 23–24) is given rate-independently: :math:`q_\theta` (rad²/s) and :math:`q_b` (rad²/s³)
are spectral densities, :math:`Q_d = T\,\mathrm{diag}(q_\theta, q_b)`, :math:`R = \sigma_a^2` (rad²).
Samples where the absolute angle is not valid (NaN or ``abs_ok`` false) are predictions only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from estimators.markov.core import FilterState, FloatArray, initial_state, run_filter, run_filter_reference
from estimators.physics import GRAVITY_M_S2

__all__ = ["FkcParams", "FkcResult", "fkc", "accelerometer_angles", "GRAVITY_M_S2"]



def _positive(value: float, name: str, allow_zero: bool = False) -> float:
    v = float(value)
    ok = np.isfinite(v) and (v >= 0.0 if allow_zero else v > 0.0)
    if not ok:
        raise ValueError(f"{name} must be a finite number {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return v


@dataclass(frozen=True)
class FkcParams:
    """Parameters of the single-axis complementary Kalman filter.

    q_angle_rad2_s : angle random-walk density of the gyroscope, squared, rad²/s (default 4.9e-7:
        7e-4 rad/s/√Hz, a BMI160).
    q_bias_rad2_s3 : bias random-walk density squared, rad²/s³ (default 1e-8).
    tau_gyro_s : Gauss–Markov correlation time of the bias, s (default 1000; eq. 2).
    r_acc_rad2 : variance of the absolute (accelerometer) angle, rad² (default 0.0014, seed 000 Table 5).
    p0_angle_rad2, p0_bias_rad2_s2 : initial variances of the angle and bias errors (defaults 1.0, 1e-4).
    """

    q_angle_rad2_s: float = 4.9e-7
    q_bias_rad2_s3: float = 1e-8
    tau_gyro_s: float = 1000.0
    r_acc_rad2: float = 0.0014
    p0_angle_rad2: float = 1.0
    p0_bias_rad2_s2: float = 1e-4

    def __post_init__(self) -> None:
        _positive(self.q_angle_rad2_s, "q_angle_rad2_s", allow_zero=True)
        _positive(self.q_bias_rad2_s3, "q_bias_rad2_s3", allow_zero=True)
        _positive(self.tau_gyro_s, "tau_gyro_s")
        _positive(self.r_acc_rad2, "r_acc_rad2")
        _positive(self.p0_angle_rad2, "p0_angle_rad2", allow_zero=True)
        _positive(self.p0_bias_rad2_s2, "p0_bias_rad2_s2", allow_zero=True)


@dataclass
class FkcResult:
    """theta_rad : (N,) estimated angle.  gyro_bias_rad_s : (N,) estimated gyroscope bias.
    state : :class:`~estimators.markov.core.FilterState` to continue with (pass it as ``state``)."""

    theta_rad: FloatArray
    gyro_bias_rad_s: FloatArray
    state: FilterState


def fkc(omega_rad_s: ArrayLike, theta_abs_rad: ArrayLike, *, fs_hz: float, params: FkcParams | None = None,
        theta0_rad: float | None = None, abs_ok: ArrayLike | None = None, state: FilterState | None = None,
        reference: bool = False) -> FkcResult:
    """Fuse a rate (N,) rad/s and an absolute angle (N,) rad into an angle (N,) rad (Algorithm 1).

    ``theta0_rad`` defaults to the first valid absolute angle; ``state`` continues a previous run
    (then ``theta0_rad`` is ignored).  ``reference=True`` runs the numpy reference.
    """
    params = FkcParams() if params is None else params
    fs = _positive(fs_hz, "fs_hz")
    w = np.asarray(omega_rad_s, dtype=np.float64).reshape(-1)
    za = np.asarray(theta_abs_rad, dtype=np.float64).reshape(-1)
    if w.shape != za.shape:
        raise ValueError(f"omega_rad_s and theta_abs_rad must have the same length, got {w.size} and {za.size}")
    if not np.all(np.isfinite(w)):
        raise ValueError("omega_rad_s must be finite")
    ok = np.isfinite(za) if abs_ok is None else (np.asarray(abs_ok, dtype=bool).reshape(-1) & np.isfinite(za))
    za = np.where(ok, za, 0.0)
    if state is None:
        if theta0_rad is None:
            theta0_rad = float(za[ok][0]) if ok.any() else 0.0
        state = initial_state(np.array([theta0_rad]), params.p0_angle_rad2, params.p0_bias_rad2_s2)
    run = run_filter_reference if reference else run_filter
    th, b, st = run(w[:, None], za[:, None], params.r_acc_rad2, ok[:, None], np.zeros((w.size, 0)),
                    np.zeros((0, 2)), 1.0, np.zeros((w.size, 0), bool), dt_s=1.0 / fs,
                    tau_s=params.tau_gyro_s, q_angle_rad2_s=params.q_angle_rad2_s,
                    q_bias_rad2_s3=params.q_bias_rad2_s3, state=state)
    return FkcResult(th[:, 0], b[:, 0], st)


def accelerometer_angles(acc: ArrayLike, gravity_ref: ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
    r"""Per-axis tilt angles from an accelerometer (N, 3) m/s² and the projected magnitude.

    The angle about sensor axis :math:`x` is the rotation that carries the reference gravity
    direction's projection on the :math:`(y, z)` plane to the measured one; the specific force turns
    opposite to the body, so :math:`\theta_{a,x} = -(\operatorname{atan2}(a_z, a_y) -
    \operatorname{atan2}(g_{0z}, g_{0y}))`, and cyclically :math:`(z, x)` for :math:`y`, :math:`(x, y)` for
    :math:`z`.  It generalises eq. 8 (:math:`\arcsin(a_x/g)` for a rotation about one axis) to every
    attitude and is exact for rotations about one axis.  ``gravity_ref`` (3,) is the specific force
    at the zero angle (default: the first sample).  Returns ``(angles_rad (N, 3), projected_m_s2
    (N, 3))``: the magnitude of the projection on each plane; where it is small the angle about that
    axis is unobservable (scale its variance by :math:`(g/\text{projected})^2`).  Angles are wrapped
    to :math:`(-\pi, \pi]` (not unwrapped: strong dynamic accelerations can flip the projection, and
    unwrapping would then add spurious turns); limb segments stay well inside that range.
    """
    a = np.asarray(acc, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"acc must have shape (N, 3), got {a.shape}")
    g0 = a[0] if gravity_ref is None else np.asarray(gravity_ref, dtype=np.float64)
    out = np.empty_like(a)
    proj = np.empty_like(a)
    for axis, (u, v) in enumerate(((1, 2), (2, 0), (0, 1))):
        ang = -(np.arctan2(a[:, v], a[:, u]) - np.arctan2(g0[v], g0[u]))
        out[:, axis] = np.angle(np.exp(1j * ang))
        proj[:, axis] = np.hypot(a[:, u], a[:, v])
    return out, proj
