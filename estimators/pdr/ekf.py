r"""Error-state EKF with zero-velocity updates for a foot-mounted INS (seed 001 §3.8.1, eqs. 3.28–3.44).

After Foxlin (2005) and Fischer, Sukumar & Hazas (2013, "Tutorial: implementing a pedestrian tracker
using inertial sensors", IEEE Pervasive Computing 12(2)).  The nominal state (p, v, C, and in the
15-state filter the gyroscope and accelerometer biases) runs the strapdown mechanisation of
:mod:`estimators.pdr.mechanisation`; the filter estimates its errors and feeds them back after every
update (closed loop), then resets the error estimate to zero.

Error state and conventions
---------------------------
Errors are *estimate minus truth*: :math:`\delta p = \hat p - p`, :math:`\delta v = \hat v - v`,
:math:`\hat C = (I + [\delta\phi\times])\,C` (attitude error in the navigation frame),
:math:`\delta b = \hat b - b`.  Internal order (the 9-state filter is the prefix; the thesis orders the
15 states :math:`[\delta\phi, \delta b_\omega, \delta p, \delta v, \delta b_a]`, eq. 3.43, the same states):

.. math:: \delta x = [\delta\phi,\ \delta p,\ \delta v,\ \delta b_\omega,\ \delta b_a]
   \quad\text{(indices 0–2, 3–5, 6–8, 9–11, 12–14)}.

Propagation (3.30–3.32, 3.44)
-----------------------------
With :math:`\hat\omega = \omega_m - \hat b_\omega`, :math:`\hat f = f_m - \hat b_a`,
:math:`S = [(\hat C\hat f)\times]` (the skew matrix of the navigation-frame specific force, eq. 3.32):

.. math::
    \delta\phi_{k+1} &= \delta\phi_k - \hat C\Delta t\,\delta b_\omega\\
    \delta p_{k+1} &= \delta p_k + \Delta t\,\delta v_k\\
    \delta v_{k+1} &= \delta v_k - S\Delta t\,\delta\phi_k - \hat C\Delta t\,\delta b_a\\
    P_{k+1} &= F P_k F^\top + Q\,\Delta t

(the bias columns are the thesis' :math:`C^n_b\Delta t` blocks of eq. 3.44, with the sign of our error
convention).  Optionally ``att_var_body`` (N, 3) adds :math:`\hat C\,\operatorname{diag}(v_k)\,\hat C^\top`
to the attitude block at sample *k*: extra attitude variance about the body axes where the gyroscope
rates are known to be wrong (clipped runs, :func:`estimators.pdr.desaturation.clipped_attitude_variance`).  ``F`` is applied by its block structure (row then column operations), never as a dense
matrix product.  :math:`Q = \operatorname{diag}(q_\omega I, 0, q_a I, q_{b\omega} I, q_{ba} I)` are
intensities (variance per second, so the defaults hold at any rate).  The thesis' text quotes Fischer et
al.'s :math:`\sigma_\omega = 10^{-2}` rad/s, :math:`\sigma_a = 10^{-2}` m/s²; its published code
(github.com/pajaraca/IEZ, ``IEZ-9states.py``) adds :math:`(\sigma\,\Delta t)^2` per sample with
:math:`\sigma_\omega = 0.01`, :math:`\sigma_a = 0.1`, i.e. intensities :math:`q = \sigma^2\Delta t` =
1e-6 rad²/s and 1e-4 (m/s)²/s at 100 Hz — the defaults here (with them the 9-state filter reaches
the thesis' EP on the shared walks; the text's values, read as per-sample variances, are 100–10⁴ times
larger and open the loops by 2–7 %).

Measurements (3.33–3.38), sequential 3-D updates while the stance detector says "still"
---------------------------------------------------------------------------------------
* ZUPT: :math:`z = \hat v - 0 = \delta v + n`, :math:`H = [0\ 0\ I\ 0\ 0]` (3.34), :math:`R = \sigma_v^2 I`.
* ZARU (15 states): the true rate is 0, so :math:`z = \hat b_\omega - \omega_m = \delta b_\omega + n`,
  :math:`H = [0\ 0\ 0\ I\ 0]`.
* optional heuristic heading update (after iHDE, Jiménez et al. 2011, "Improved Heuristic Drift
  Elimination (iHDE) for pedestrian navigation in complex buildings", IPIN, and Borenstein et al. 2009,
  "Heuristic reduction of gyro drift for personnel tracking systems", J. Navigation 62): at the end of a
  stance, the direction :math:`\alpha` of the stride just ended (previous stance end → this one) is
  compared with the dominant directions :math:`\alpha_d = \alpha_{ref} + m\pi/2` (:math:`\alpha_{ref}`
  the first stride's direction: corridors and rooms are rectilinear).  When the walk is straight
  (:math:`\alpha` changed by less than ``hdr_straight_rad`` since the previous stride) and
  :math:`|\operatorname{wrap}(\alpha - \alpha_d)| <` ``hdr_gate_rad``, the stride direction error is
  taken as the current yaw error: :math:`z = \operatorname{wrap}(\alpha - \alpha_d) = \delta\phi_z + n`.
  (Using the foot's own yaw instead, as iHDE does, made the IEZ walks worse: the foot's toe-out varies
  by a few degrees from stride to stride.)
* optional flat-floor height update: at the end of a stance whose height is within
  ``height_gate_m`` of the current floor level, :math:`z = \hat p_z - z_{floor} = \delta p_z + n`
  (otherwise the stance starts a new level, e.g. a stair).

:math:`K = PH^\top(HPH^\top + R)^{-1}` (3.36, the thesis prints −R), :math:`\delta x = Kz` (3.35),
:math:`P \leftarrow P - KHP` (3.38).  Correction (3.39–3.41): :math:`\hat p \mathrel{-}= \delta p`,
:math:`\hat v \mathrel{-}= \delta v`, :math:`\hat C \leftarrow (2I - \delta\Theta)(2I + \delta\Theta)^{-1}\hat C`
(the Padé rotation by :math:`-\delta\phi`, eq. 3.41 with our sign), :math:`\hat b \mathrel{-}= \delta b`.

External attitude (9IEZ+MAD, 9IEZ+KF)
-------------------------------------
With ``c_ext`` the attitude comes from an orientation filter (Madgwick / Kalman, §3.6): the mechanisation
uses :math:`C_k = C^{ext}_k` instead of (3.23), the filter keeps :math:`\delta\phi` in its model (it
drives the velocity error through S) but feeds back only position and velocity.

The readable dense-matrix version of the same filter is :mod:`estimators.pdr.ekf_reference`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from estimators.pdr.mechanisation import GRAVITY_M_S2, _cayley_inplace, _matmul3_inplace

FloatArray = NDArray[np.float64]

__all__ = ["EkfParams", "EkfOutput", "run_ekf"]


@dataclass(frozen=True)
class EkfParams:
    """Parameters of the ZUPT error-state EKF (defaults: Fischer et al. 2013 as used by the thesis).

    n_states : 9 ([δφ, δp, δv]) or 15 (+ gyroscope and accelerometer bias errors).
    zaru : apply zero-angular-rate updates during stance (needs 15 states).
    gyr_noise_rad2_s : attitude random-walk intensity q_ω, rad²/s.  Default 1e-6 (the thesis code).
    acc_noise_m2_s3 : velocity random-walk intensity q_a, (m/s)²/s.  Default 1e-4 (the thesis code).
    gyr_bias_walk_rad2_s3 : gyroscope bias random-walk intensity, (rad/s)²/s.  Default 1e-8.
    acc_bias_walk_m2_s5 : accelerometer bias random-walk intensity, (m/s²)²/s.  Default 1e-6.
    zupt_std_m_s : ZUPT measurement noise σ_v, m/s.  Default 1e-2.
    zaru_std_rad_s : ZARU measurement noise, rad/s.  Default 5e-2 (a foot in stance still rolls a little).
    init_att_std_rad, init_gyr_bias_std_rad_s, init_acc_bias_std_m_s2 : initial error standard deviations
        (the thesis starts from P = 0 for the 9 states).  Defaults 0, 1e-3, 5e-2.
    heading_update : apply the heuristic heading update (see the module docstring).  Default False.
    hdr_gate_rad, hdr_straight_rad, hdr_std_rad : its gates and noise.  Defaults 0.2 rad, 10°, 0.01 rad.
    height_update : apply the flat-floor height update.  Default False.
    height_gate_m, height_std_m : its gate (a larger change starts a new floor level) and noise.
        Defaults 0.25 m, 0.001 m.
    gravity_m_s2 : gravity magnitude; None = the magnitude of the mean specific force at alignment.
    """

    n_states: int = 9
    zaru: bool = False
    gyr_noise_rad2_s: float = 1e-6
    acc_noise_m2_s3: float = 1e-4
    gyr_bias_walk_rad2_s3: float = 1e-8
    acc_bias_walk_m2_s5: float = 1e-6
    zupt_std_m_s: float = 1e-2
    zaru_std_rad_s: float = 5e-2
    init_att_std_rad: float = 0.0
    init_gyr_bias_std_rad_s: float = 1e-3
    init_acc_bias_std_m_s2: float = 5e-2
    heading_update: bool = False
    hdr_gate_rad: float = 0.2
    hdr_straight_rad: float = float(np.deg2rad(10.0))
    hdr_std_rad: float = 0.01
    height_update: bool = False
    height_gate_m: float = 0.25
    height_std_m: float = 0.001
    gravity_m_s2: float | None = None

    def __post_init__(self) -> None:
        if self.n_states not in (9, 15):
            raise ValueError(f"n_states must be 9 or 15, got {self.n_states!r}")
        if self.zaru and self.n_states != 15:
            raise ValueError("zaru=True needs n_states=15 (the gyroscope bias states)")
        for name in ("gyr_noise_rad2_s", "acc_noise_m2_s3", "gyr_bias_walk_rad2_s3", "acc_bias_walk_m2_s5",
                     "init_att_std_rad", "init_gyr_bias_std_rad_s", "init_acc_bias_std_m_s2"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0.0):
                raise ValueError(f"{name} must be a finite value >= 0, got {getattr(self, name)!r}")
        for name in ("zupt_std_m_s", "zaru_std_rad_s", "hdr_gate_rad", "hdr_straight_rad", "hdr_std_rad",
                     "height_gate_m", "height_std_m"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) > 0.0):
                raise ValueError(f"{name} must be a finite value > 0, got {getattr(self, name)!r}")
        if self.gravity_m_s2 is not None and not (9.0 < self.gravity_m_s2 < 10.5):
            raise ValueError(f"gravity_m_s2 must be None or within (9, 10.5) m/s², got {self.gravity_m_s2!r}")


@dataclass(frozen=True, eq=False)
class EkfOutput:
    """Per-sample nominal states after the updates: pos_m, vel_m_s (N, 3), c_nav_body (N, 3, 3),
    gyr_bias_rad_s, acc_bias_m_s2 (N, 3), p_diag (N, n_states) the covariance diagonal."""

    pos_m: FloatArray
    vel_m_s: FloatArray
    c_nav_body: FloatArray
    gyr_bias_rad_s: FloatArray
    acc_bias_m_s2: FloatArray
    p_diag: FloatArray


# --------------------------------------------------------------------------------------------- kernel
@njit(cache=True)
def _propagate_cov(p, ns, s, cm, dt):
    """P ← F P Fᵀ with F of the module docstring, by row then column block operations (in place)."""
    # rows: A = F P
    for j in range(ns):
        for i in range(3):
            p[3 + i, j] += dt * p[6 + i, j]
        for i in range(3):
            acc = s[i, 0] * p[0, j] + s[i, 1] * p[1, j] + s[i, 2] * p[2, j]
            if ns == 15:
                acc += cm[i, 0] * p[12, j] + cm[i, 1] * p[13, j] + cm[i, 2] * p[14, j]
            p[6 + i, j] -= acc
        if ns == 15:
            for i in range(3):
                p[i, j] -= cm[i, 0] * p[9, j] + cm[i, 1] * p[10, j] + cm[i, 2] * p[11, j]
    # columns: A Fᵀ
    for j in range(ns):
        for i in range(3):
            p[j, 3 + i] += dt * p[j, 6 + i]
        for i in range(3):
            acc = s[i, 0] * p[j, 0] + s[i, 1] * p[j, 1] + s[i, 2] * p[j, 2]
            if ns == 15:
                acc += cm[i, 0] * p[j, 12] + cm[i, 1] * p[j, 13] + cm[i, 2] * p[j, 14]
            p[j, 6 + i] -= acc
        if ns == 15:
            for i in range(3):
                p[j, i] -= cm[i, 0] * p[j, 9] + cm[i, 1] * p[j, 10] + cm[i, 2] * p[j, 11]


@njit(cache=True)
def _update3(p, ns, s0, z0, z1, z2, r_var, dx, pht, kg):
    """Update with z = δx[s0:s0+3] + n, R = r_var I (eqs. 3.35–3.38); writes δx into ``dx``."""
    for i in range(ns):
        pht[i, 0] = p[i, s0]
        pht[i, 1] = p[i, s0 + 1]
        pht[i, 2] = p[i, s0 + 2]
    a = p[s0, s0] + r_var
    b = p[s0, s0 + 1]
    c = p[s0, s0 + 2]
    d = p[s0 + 1, s0 + 1] + r_var
    e = p[s0 + 1, s0 + 2]
    f = p[s0 + 2, s0 + 2] + r_var
    c00 = d * f - e * e
    c01 = c * e - b * f
    c02 = b * e - c * d
    c11 = a * f - c * c
    c12 = b * c - a * e
    c22 = a * d - b * b
    inv_det = 1.0 / (a * c00 + b * c01 + c * c02)
    i00, i01, i02 = c00 * inv_det, c01 * inv_det, c02 * inv_det
    i11, i12, i22 = c11 * inv_det, c12 * inv_det, c22 * inv_det
    for i in range(ns):
        h0, h1, h2 = pht[i, 0], pht[i, 1], pht[i, 2]
        k0 = h0 * i00 + h1 * i01 + h2 * i02
        k1 = h0 * i01 + h1 * i11 + h2 * i12
        k2 = h0 * i02 + h1 * i12 + h2 * i22
        kg[i, 0], kg[i, 1], kg[i, 2] = k0, k1, k2
        dx[i] = k0 * z0 + k1 * z1 + k2 * z2
    for i in range(ns):
        for j in range(i, ns):
            v = p[i, j] - (kg[i, 0] * pht[j, 0] + kg[i, 1] * pht[j, 1] + kg[i, 2] * pht[j, 2])
            p[i, j] = v
            p[j, i] = v


@njit(cache=True)
def _update1(p, ns, s0, z, r_var, dx, pht):
    """Scalar update with z = δx[s0] + n, R = r_var."""
    inv = 1.0 / (p[s0, s0] + r_var)
    for i in range(ns):
        pht[i, 0] = p[i, s0]
    for i in range(ns):
        dx[i] = pht[i, 0] * inv * z
    for i in range(ns):
        for j in range(i, ns):
            v = p[i, j] - pht[i, 0] * inv * pht[j, 0]
            p[i, j] = v
            p[j, i] = v


@njit(cache=True)
def _correct(dx, ns, c, pos, vel, bg, ba, fix_att, r, tmp):
    """Closed-loop correction (3.39–3.41) with δx, then δx is consumed."""
    for i in range(3):
        pos[i] -= dx[3 + i]
        vel[i] -= dx[6 + i]
    if fix_att:
        _cayley_inplace(-dx[0], -dx[1], -dx[2], r)
        _matmul3_inplace(r, c, tmp)
        c[:, :] = tmp
    if ns == 15:
        for i in range(3):
            bg[i] -= dx[9 + i]
            ba[i] -= dx[12 + i]


@njit(cache=True)
def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@njit(cache=True)
def _ekf_kernel(acc, gyr, dt_s, stance, c_ext, use_ext, ns, zaru, c0, bg0, ba0, p0_diag,
                q_gyr, q_acc, q_bg, q_ba, r_zupt, r_zaru, gravity,
                use_hdr, hdr_gate, hdr_straight, r_hdr, use_height, height_gate, r_height,
                att_var_body, use_att_var):
    n = acc.shape[0]
    pos_out = np.empty((n, 3))
    vel_out = np.empty((n, 3))
    c_out = np.empty((n, 3, 3))
    bg_out = np.empty((n, 3))
    ba_out = np.empty((n, 3))
    pd_out = np.empty((n, ns))
    p = np.zeros((ns, ns))
    for i in range(ns):
        p[i, i] = p0_diag[i]
    c = c0.copy()
    bg = bg0.copy()
    ba = ba0.copy()
    pos = np.zeros(3)
    vel = np.zeros(3)
    r = np.empty((3, 3))
    tmp = np.empty((3, 3))
    s = np.zeros((3, 3))
    cm = np.empty((3, 3))
    dx = np.zeros(ns)
    pht = np.empty((ns, 3))
    kg = np.empty((ns, 3))
    fix_att = not use_ext
    n_stances = 0
    psi_ref = 0.0
    psi_prev = 0.0
    z_floor = 0.0
    xy_prev = np.zeros(2)
    for k in range(n):
        if use_ext:
            c[:, :] = c_ext[k]
        if k > 0:
            dt = dt_s[k]
            if not use_ext:
                _cayley_inplace((gyr[k, 0] - bg[0]) * dt, (gyr[k, 1] - bg[1]) * dt, (gyr[k, 2] - bg[2]) * dt, r)
                _matmul3_inplace(c, r, tmp)                                   # (3.23)
                c[:, :] = tmp
            f0 = acc[k, 0] - ba[0]
            f1 = acc[k, 1] - ba[1]
            f2 = acc[k, 2] - ba[2]
            fn0 = c[0, 0] * f0 + c[0, 1] * f1 + c[0, 2] * f2                  # (3.24)
            fn1 = c[1, 0] * f0 + c[1, 1] * f1 + c[1, 2] * f2
            fn2 = c[2, 0] * f0 + c[2, 1] * f1 + c[2, 2] * f2
            vel[0] += fn0 * dt                                                # (3.25)
            vel[1] += fn1 * dt
            vel[2] += (fn2 - gravity) * dt
            for i in range(3):
                pos[i] += vel[i] * dt                                         # (3.26)
            s[0, 1] = -fn2 * dt                                               # (3.32)·Δt
            s[0, 2] = fn1 * dt
            s[1, 0] = fn2 * dt
            s[1, 2] = -fn0 * dt
            s[2, 0] = -fn1 * dt
            s[2, 1] = fn0 * dt
            for i in range(3):
                for j in range(3):
                    cm[i, j] = c[i, j] * dt
            _propagate_cov(p, ns, s, cm, dt)                                  # (3.30), (3.37)
            for i in range(3):
                p[i, i] += q_gyr * dt
                p[6 + i, 6 + i] += q_acc * dt
                if ns == 15:
                    p[9 + i, 9 + i] += q_bg * dt
                    p[12 + i, 12 + i] += q_ba * dt
            if use_att_var:                                                   # clipped rates: C diag(v) Cᵀ
                v0, v1, v2 = att_var_body[k, 0], att_var_body[k, 1], att_var_body[k, 2]
                if v0 > 0.0 or v1 > 0.0 or v2 > 0.0:
                    for i in range(3):
                        for j in range(3):
                            p[i, j] += c[i, 0] * v0 * c[j, 0] + c[i, 1] * v1 * c[j, 1] + c[i, 2] * v2 * c[j, 2]
        if stance[k]:
            _update3(p, ns, 6, vel[0], vel[1], vel[2], r_zupt, dx, pht, kg)  # ZUPT (3.33–3.38)
            _correct(dx, ns, c, pos, vel, bg, ba, fix_att, r, tmp)           # (3.39–3.41)
            if zaru:
                _update3(p, ns, 9, bg[0] - gyr[k, 0], bg[1] - gyr[k, 1], bg[2] - gyr[k, 2], r_zaru, dx, pht, kg)
                _correct(dx, ns, c, pos, vel, bg, ba, fix_att, r, tmp)
            if k == n - 1 or not stance[k + 1]:                                # end of a stance
                n_stances += 1
                if use_hdr and fix_att and n_stances >= 2:
                    psi = np.arctan2(pos[1] - xy_prev[1], pos[0] - xy_prev[0])   # stride direction
                    if n_stances == 2:
                        psi_ref = psi
                    elif abs(_wrap(psi - psi_prev)) < hdr_straight:
                        quarter = np.pi / 2.0
                        m = np.floor(_wrap(psi - psi_ref) / quarter + 0.5)
                        e = _wrap(psi - (psi_ref + m * quarter))
                        if abs(e) < hdr_gate:
                            _update1(p, ns, 2, e, r_hdr, dx, pht)
                            _correct(dx, ns, c, pos, vel, bg, ba, fix_att, r, tmp)
                    psi_prev = psi
                xy_prev[0] = pos[0]
                xy_prev[1] = pos[1]
                if use_height:
                    if n_stances == 1:
                        z_floor = pos[2]
                    elif abs(pos[2] - z_floor) < height_gate:
                        _update1(p, ns, 5, pos[2] - z_floor, r_height, dx, pht)
                        _correct(dx, ns, c, pos, vel, bg, ba, fix_att, r, tmp)
                    else:
                        z_floor = pos[2]
        pos_out[k] = pos
        vel_out[k] = vel
        c_out[k] = c
        bg_out[k] = bg
        ba_out[k] = ba
        for i in range(ns):
            pd_out[k, i] = p[i, i]
    return pos_out, vel_out, c_out, bg_out, ba_out, pd_out


def _p0(params: EkfParams) -> FloatArray:
    d = np.zeros(15)
    d[0:3] = params.init_att_std_rad ** 2
    d[9:12] = params.init_gyr_bias_std_rad_s ** 2
    d[12:15] = params.init_acc_bias_std_m_s2 ** 2
    return d[: params.n_states]


def _args(acc, gyr, dt_s, stance, c0, gyr_bias0, params, c_ext, gravity_m_s2, att_var_body=None):
    acc = np.ascontiguousarray(acc, dtype=np.float64)
    gyr = np.ascontiguousarray(gyr, dtype=np.float64)
    n = len(acc)
    dt_s = np.ascontiguousarray(dt_s, dtype=np.float64)
    stance = np.ascontiguousarray(stance, dtype=np.bool_)
    if acc.shape != (n, 3) or gyr.shape != (n, 3) or dt_s.shape != (n,) or stance.shape != (n,):
        raise ValueError(f"acc, gyr must be (N, 3) and dt_s, stance (N,); got {acc.shape}, {gyr.shape}, "
                         f"{dt_s.shape}, {stance.shape}")
    use_ext = c_ext is not None
    c_ext_arr = np.ascontiguousarray(c_ext, dtype=np.float64) if use_ext else np.zeros((1, 3, 3))
    if use_ext and c_ext_arr.shape != (n, 3, 3):
        raise ValueError(f"c_ext must be (N, 3, 3), got {c_ext_arr.shape}")
    g = float(gravity_m_s2 if params.gravity_m_s2 is None else params.gravity_m_s2)
    use_att_var = att_var_body is not None
    att_var = np.ascontiguousarray(att_var_body, dtype=np.float64) if use_att_var else np.zeros((1, 3))
    if use_att_var and (att_var.shape != (n, 3) or not np.all(np.isfinite(att_var)) or np.any(att_var < 0)):
        raise ValueError(f"att_var_body must be (N, 3) finite and >= 0 (rad²), got shape {att_var.shape}")
    return (acc, gyr, dt_s, stance, c_ext_arr, use_ext, params.n_states, params.zaru,
            np.asarray(c0, dtype=np.float64), np.asarray(gyr_bias0, dtype=np.float64), np.zeros(3), _p0(params),
            params.gyr_noise_rad2_s, params.acc_noise_m2_s3, params.gyr_bias_walk_rad2_s3, params.acc_bias_walk_m2_s5,
            params.zupt_std_m_s ** 2, params.zaru_std_rad_s ** 2, g,
            params.heading_update, params.hdr_gate_rad, params.hdr_straight_rad, params.hdr_std_rad ** 2,
            params.height_update, params.height_gate_m, params.height_std_m ** 2, att_var, use_att_var)


def run_ekf(acc: ArrayLike, gyr: ArrayLike, dt_s: ArrayLike, stance: ArrayLike, c0: ArrayLike,
            gyr_bias0_rad_s: ArrayLike, params: EkfParams = EkfParams(), *, c_ext: ArrayLike | None = None,
            gravity_m_s2: float = GRAVITY_M_S2, att_var_body: ArrayLike | None = None) -> EkfOutput:
    """Run the ZUPT EKF (compiled kernel) over a walk.

    acc (N, 3) m/s², gyr (N, 3) rad/s, dt_s (N,) step ending at each sample, stance (N,) bool,
    c0 (3, 3) initial :math:`C^n_b` (alignment), gyr_bias0_rad_s (3,) initial gyroscope bias,
    c_ext (N, 3, 3) optional external attitude (9IEZ+MAD / +KF), gravity_m_s2 used when ``params.gravity_m_s2`` is None,
    att_var_body (N, 3) optional extra attitude variance, rad², added at each sample about the body axes
    (:func:`estimators.pdr.desaturation.clipped_attitude_variance`).
    """
    return EkfOutput(*_ekf_kernel(*_args(acc, gyr, dt_s, stance, c0, gyr_bias0_rad_s, params, c_ext, gravity_m_s2,
                                         att_var_body)))
