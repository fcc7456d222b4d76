r"""Self-aligning joint axis and joint position of a hinge joint (Seel, Raisch, Schauer 2014).

Two IMUs, ``a`` (e.g. thigh) and ``b`` (shank), on the two segments of a hinge joint, placed and
oriented arbitrarily.  From their gyroscopes and accelerometers alone we estimate the joint axis
:math:`j_a, j_b` (unit vectors, each in its own sensor frame), the joint centre :math:`o_a, o_b`
(m, in each sensor frame) and the joint angle.  Equations are those of seed 000 §2.4.2.

Joint axis (eqs. 68–69)
-----------------------
A hinge constrains the relative rotation to the axis, so the angular-rate components *perpendicular*
to the axis have the same magnitude in both sensors: :math:`\|g_a\times j_a\| = \|g_b\times j_b\|`.
With :math:`j = [\cos\phi\cos\theta,\ \cos\phi\sin\theta,\ \sin\phi]` (eq. 69) we minimise
:math:`\Psi = \sum_t e(t)^2`, :math:`e = \|g_a\times j_a\| - \|g_b\times j_b\|` (eq. 68) over
:math:`(\phi_a,\theta_a,\phi_b,\theta_b)` with a Gauss–Newton type solver (Levenberg–Marquardt,
``scipy.optimize.least_squares``) and the analytic Jacobian
:math:`\partial\|g\times j\|/\partial j = -(g\cdot j)\,g/\|g\times j\|` (unit :math:`j`), started from
the principal rate direction of each sensor and a few other directions (the lowest cost wins).

Joint position (eqs. 70–72) and the sign of Γ
---------------------------------------------
Let the sensor be at :math:`p_s` with orientation :math:`R` and the joint centre at
:math:`p_j = p_s + R\,o` (:math:`o` in sensor coordinates, pointing *from the sensor to the joint*).
Rigid-body kinematics give :math:`\ddot p_j = \ddot p_s + R(\dot\omega\times o + \omega\times(\omega\times o))`,
so the specific force of the joint centre expressed in the sensor frame is

.. math:: R^T(\ddot p_j + g_{up}) = a_s + \Gamma_\omega(o),\qquad
          \Gamma_\omega(o) = \omega\times(\omega\times o) + \dot\omega\times o \quad\text{(eq. 71)}.

The joint centre is one physical point, so its specific force has one norm seen from either sensor:

.. math:: e_{origin}(t) = \|a_a + \Gamma_{g_a}(o_a)\| - \|a_b + \Gamma_{g_b}(o_b)\|.

Eq. 70 as transcribed in seed 000 has ":math:`a - \Gamma(o)`": that is the same residual for
:math:`o` pointing from the joint to the sensor (:math:`\Gamma` is linear in :math:`o`).  We keep the
physical convention above (sensor → joint), so the returned ``o_a, o_b`` are the joint centre's
coordinates in each sensor frame; the accelerations of eq. 74 then use :math:`a + \Gamma(o)`.
:math:`\Gamma` is linear, :math:`\Gamma_\omega(o) = ([\omega]_\times^2 + [\dot\omega]_\times)\,o = M o`, so the
Jacobian is :math:`\partial\|a+Mo\|/\partial o = M^T(a+Mo)/\|a+Mo\|`.  :math:`\dot\omega` is a
Savitzky–Golay derivative of the gyroscope (window 7 samples at 100 Hz, scaled with the rate).

Any point on the axis satisfies the constraint, so the solution is a line
:math:`(o_a + s j_a, o_b + s j_b)`; eq. 72 picks the point closest to both sensors,
:math:`o_i = \hat o_i - j_i(\hat o_a\cdot j_a + \hat o_b\cdot j_b)/2`.

Signs of the axes
-----------------
:math:`e` is unchanged by :math:`j\to -j`.  The *overall* sign is a convention (flipping both flips the
angle): we make the largest-magnitude component of :math:`j_a` positive.  The *relative* sign matters:
:math:`j_a, j_b` must be the same physical direction.  The parts of the angular rate and of the
joint-centre specific force perpendicular to the axis are one physical vector seen from both sensors,
and seen from ``b`` they are turned by the joint angle :math:`\alpha` (eq. 73) relative to ``a``:
:math:`\varphi_b - \varphi_a - \alpha_{gyr}` must be constant (notation below).  We keep the sign of
:math:`j_b` for which these differences are most concentrated (largest weighted circular resultant
length, weights :math:`\|v_{a\perp}\|\|v_{b\perp}\|`).

Joint angle (eqs. 73, 74, 77)
-----------------------------
With :math:`\alpha` the rotation of segment ``a`` relative to ``b`` about the axis (the seed's knee
angle :math:`\theta_T-\theta_S` for ``a`` = thigh, ``b`` = shank):

* gyroscopes (eq. 73): :math:`\alpha_{gyr}(t) = \int (g_a\cdot j_a - g_b\cdot j_b)\,dt`;
* accelerometers (eq. 74, signed): the joint-centre specific force :math:`\tilde a_i = a_i + \Gamma_i(o_i)`
  projected on the plane normal to :math:`j_i` with bases :math:`x_i = j_i\times c/\|\cdot\|`,
  :math:`y_i = j_i\times x_i` (one vector :math:`c` for both sensors, the one least parallel to both axes,
  as Seel et al.), :math:`\varphi_i = \operatorname{atan2}(\tilde a_i\cdot y_i, \tilde a_i\cdot x_i)`,
  :math:`\alpha_{acc} = \varphi_b - \varphi_a` (segment ``b`` is turned by :math:`-\alpha` about :math:`j`
  relative to ``a``, so a vector fixed in ``a`` appears turned by :math:`+\alpha` in ``b``; the seed's
  arccos (eq. 74) is the absolute value of this difference);
* fusion (eq. 77): the single-axis FKC (:mod:`estimators.markov.fkc`).

The zero of :math:`\alpha_{acc}` depends on the arbitrary bases, so both angles are referred to the
pose at the start of the record: :math:`\alpha_{acc}` is shifted by the circular mean of
:math:`\alpha_{acc}-\alpha_{gyr}` over the first second (where :math:`\alpha_{gyr}` has not drifted).
Pass ``offset_rad`` to use another zero (e.g. from a static posture with a known angle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from estimators.signal import savgol_derivative

from estimators.markov.fkc import FkcParams, fkc

FloatArray = NDArray[np.float64]

__all__ = ["JointAxisResult", "estimate", "estimate_axis", "estimate_position", "joint_angle", "spherical",
           "position_residual", "angular_acceleration"]


@dataclass
class JointAxisResult:
    """j_a, j_b : (3,) unit joint axes in sensor a / b coordinates (same physical direction).
    o_a, o_b : (3,) joint centre in sensor a / b coordinates, m (shifted along the axis, eq. 72).
    axis_rms_rad_s : RMS of the axis residual (eq. 68).  position_rms_m_s2 : RMS of eq. 70."""

    j_a: FloatArray
    j_b: FloatArray
    o_a: FloatArray
    o_b: FloatArray
    axis_rms_rad_s: float
    position_rms_m_s2: float


def spherical(phi: float, theta: float) -> FloatArray:
    """Eq. 69: unit vector from the elevation ``phi`` and azimuth ``theta`` (rad)."""
    return np.array([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])


def _to_spherical(j: FloatArray) -> tuple[float, float]:
    j = j / np.linalg.norm(j)
    return float(np.arcsin(np.clip(j[2], -1, 1))), float(np.arctan2(j[1], j[0]))


def _norm_cross(g: FloatArray, j: FloatArray) -> tuple[FloatArray, FloatArray]:
    gj = g @ j
    nc = np.sqrt(np.maximum(np.einsum("ij,ij->i", g, g) - gj**2, 1e-12))
    return nc, gj



def _axis_fun(p, ga, gb, w=0.0):
    ja, jb = spherical(p[0], p[1]), spherical(p[2], p[3])
    na, _ = _norm_cross(ga, ja)
    nb, _ = _norm_cross(gb, jb)
    if w > 0.0:
        return np.concatenate([na - nb, w * na, w * nb])
    return na - nb


def _axis_jac(p, ga, gb, w=0.0):
    out = np.empty((len(ga), 4))
    for s, (phi, th, g) in enumerate(((p[0], p[1], ga), (p[2], p[3], gb))):
        j = spherical(phi, th)
        nc, gj = _norm_cross(g, j)
        d = -(gj / nc)[:, None] * g                                   # d‖g×j‖/dj
        dphi = np.array([-np.sin(phi) * np.cos(th), -np.sin(phi) * np.sin(th), np.cos(phi)])
        dth = np.array([-np.cos(phi) * np.sin(th), np.cos(phi) * np.cos(th), 0.0])
        sign = 1.0 if s == 0 else -1.0
        out[:, 2 * s] = sign * (d @ dphi)
        out[:, 2 * s + 1] = sign * (d @ dth)
    if w > 0.0:
        n = len(ga)
        extra = np.zeros((2 * n, 4))
        extra[:n, :2] = w * out[:, :2]
        extra[n:, 2:] = -w * out[:, 2:]
        return np.vstack([out, extra])
    return out


def estimate_axis(gyr_a: ArrayLike, gyr_b: ArrayLike, *,
                  principal_weight: float = 0.0) -> tuple[FloatArray, FloatArray, float]:
    r"""Joint axes (eqs. 68–69) up to sign: ``(j_a, j_b, rms residual rad/s)`` (the residual of eq. 68 alone).

    principal_weight : :math:`w \ge 0` adds :math:`w^2\sum_t(\|g_a\times j_a\|^2 + \|g_b\times j_b\|^2)` to
        :math:`\Psi` (eq. 68), a small pull of each axis towards its sensor's principal rotation axis.  When both
        segments turn about one axis at proportional rates (sagittal tasks such as the step-up, where the shank
        turns at about −2/3 of the thigh's rate) eq. 68 is satisfied along a whole family
        :math:`|g_a|\sin\theta_a = |g_b|\sin\theta_b` and the unregularised minimum lands anywhere on it (shank
        axis up to ~25° off on simulated step-ups); the pull picks the family member nearest to the segments' own
        rotation axes.  It is a prior, not free: on a well-posed 3D hinge motion (the whole limb turning about
        other axes too) it biases the axes towards the principal ones (~9° at w = 1 on the simulated exoskeleton
        hinge), so use it for sagittal-plane tasks only.  Default 0: Seel's problem exactly."""
    from scipy.optimize import least_squares  # imported on use: ~1 s at a cold start

    ga = np.asarray(gyr_a, dtype=np.float64)
    gb = np.asarray(gyr_b, dtype=np.float64)
    starts = []
    pa = np.linalg.eigh(ga.T @ ga)[1][:, -1]
    pb = np.linalg.eigh(gb.T @ gb)[1][:, -1]
    starts.append((pa, pb))
    for d in (np.array([1.0, 0.3, 0.2]), np.array([0.2, 1.0, 0.3]), np.array([0.3, 0.2, 1.0])):
        starts.append((d, d))
    best = None
    for ja0, jb0 in starts:
        p0 = np.array([*_to_spherical(ja0), *_to_spherical(jb0)])
        sol = least_squares(_axis_fun, p0, jac=_axis_jac, args=(ga, gb, float(principal_weight)), method="lm",
                            xtol=1e-10, ftol=1e-10)
        if best is None or sol.cost < best.cost:
            best = sol
    ja, jb = spherical(best.x[0], best.x[1]), spherical(best.x[2], best.x[3])
    return ja, jb, float(np.sqrt(np.mean(_axis_fun(best.x, ga, gb) ** 2)))


def angular_acceleration(gyr: ArrayLike, fs_hz: float) -> FloatArray:
    """Savitzky–Golay derivative of the rate (N, 3) → rad/s² (window ≈ 70 ms, at least 5 samples)."""
    g = np.asarray(gyr, dtype=np.float64)
    win = max(5, int(round(0.07 * fs_hz)) | 1)
    if len(g) < win:
        return np.gradient(g, 1.0 / fs_hz, axis=0)
    return savgol_derivative(g, win, 2, delta=1.0 / fs_hz, axis=0)


def _gamma_matrices(gyr: FloatArray, dgyr: FloatArray) -> FloatArray:
    """M(t) with Γ(o) = M o = ω×(ω×o) + ω̇×o (eq. 71), shape (N, 3, 3)."""
    wx, wy, wz = gyr.T
    ax, ay, az = dgyr.T
    m = np.empty((len(gyr), 3, 3))
    m[:, 0, 0] = -(wy**2 + wz**2)
    m[:, 0, 1] = wx * wy - az
    m[:, 0, 2] = wx * wz + ay
    m[:, 1, 0] = wx * wy + az
    m[:, 1, 1] = -(wx**2 + wz**2)
    m[:, 1, 2] = wy * wz - ax
    m[:, 2, 0] = wx * wz - ay
    m[:, 2, 1] = wy * wz + ax
    m[:, 2, 2] = -(wx**2 + wy**2)
    return m


def position_residual(acc_a, gyr_a, dgyr_a, acc_b, gyr_b, dgyr_b, o_a, o_b) -> FloatArray:
    """Eq. 70 with the physical sign: ``‖a_a + Γ_a(o_a)‖ − ‖a_b + Γ_b(o_b)‖`` (m/s²)."""
    ma, mb = _gamma_matrices(gyr_a, dgyr_a), _gamma_matrices(gyr_b, dgyr_b)
    return (np.linalg.norm(acc_a + ma @ o_a, axis=1) - np.linalg.norm(acc_b + mb @ o_b, axis=1))


def _gammas(gyr_a: FloatArray, gyr_b: FloatArray, fs_hz: float) -> tuple[FloatArray, FloatArray]:
    """Γ matrices (eq. 71) of both sensors; computed once per call of :func:`estimate`/:func:`joint_angle`."""
    return (_gamma_matrices(gyr_a, angular_acceleration(gyr_a, fs_hz)),
            _gamma_matrices(gyr_b, angular_acceleration(gyr_b, fs_hz)))


def _solve_position(aa: FloatArray, ma: FloatArray, ab: FloatArray,
                    mb: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    from scipy.optimize import least_squares  # imported on use: ~1 s at a cold start

    def fun(p):
        return np.linalg.norm(aa + ma @ p[:3], axis=1) - np.linalg.norm(ab + mb @ p[3:], axis=1)

    def jac(p):
        va = aa + ma @ p[:3]
        vb = ab + mb @ p[3:]
        ua = va / np.linalg.norm(va, axis=1, keepdims=True)
        ub = vb / np.linalg.norm(vb, axis=1, keepdims=True)
        return np.hstack([np.einsum("nij,ni->nj", ma, ua), -np.einsum("nij,ni->nj", mb, ub)])

    sol = least_squares(fun, np.full(6, 0.01), jac=jac, method="lm", xtol=1e-12, ftol=1e-12)
    return sol.x[:3].copy(), sol.x[3:].copy(), float(np.sqrt(2.0 * sol.cost / len(aa)))


def estimate_position(acc_a, gyr_a, acc_b, gyr_b, *, fs_hz: float) -> tuple[FloatArray, FloatArray, float]:
    """Joint centre (eqs. 70–71) before the shift of eq. 72: ``(o_a, o_b, rms m/s²)``."""
    aa, ab = np.asarray(acc_a, float), np.asarray(acc_b, float)
    ma, mb = _gammas(np.asarray(gyr_a, float), np.asarray(gyr_b, float), fs_hz)
    return _solve_position(aa, ma, ab, mb)


def _common_c(j_a: FloatArray, j_b: FloatArray) -> FloatArray:
    eye = np.eye(3)
    return eye[int(np.argmin(np.abs(eye @ j_a) + np.abs(eye @ j_b)))]


def _perp_norm(v: FloatArray, j: FloatArray) -> FloatArray:
    return np.linalg.norm(v - np.outer(v @ j, j), axis=1)


def _phi(acc_tilde: FloatArray, j: FloatArray, c: FloatArray) -> FloatArray:
    x = np.cross(j, c)
    x /= np.linalg.norm(x)
    y = np.cross(j, x)
    return np.arctan2(acc_tilde @ y, acc_tilde @ x)


def _raw_angles(acc_a, gyr_a, ma, acc_b, gyr_b, mb, fs_hz, j_a, j_b, o_a, o_b):
    ta = acc_a + ma @ o_a
    tb = acc_b + mb @ o_b
    c = _common_c(j_a, j_b)
    alpha_acc = np.unwrap(_phi(tb, j_b, c) - _phi(ta, j_a, c))
    rate = gyr_a @ j_a - gyr_b @ j_b                                   # integrand of eq. 73
    alpha_gyr = np.cumsum(rate) / fs_hz
    return alpha_gyr, alpha_acc, rate


def _checked(acc_a, gyr_a, acc_b, gyr_b, fs_hz) -> list[FloatArray]:
    arrays = [np.asarray(v, dtype=np.float64) for v in (acc_a, gyr_a, acc_b, gyr_b)]
    n = len(arrays[0])
    for name, v in zip(("acc_a", "gyr_a", "acc_b", "gyr_b"), arrays):
        if v.shape != (n, 3):
            raise ValueError(f"{name} must have shape (N, 3) like acc_a ({n}, 3), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} contains NaN or infinite values; remove or fill the gaps first")
    if not (np.isfinite(fs_hz) and fs_hz > 0):
        raise ValueError(f"fs_hz must be a positive number, got {fs_hz!r}")
    return arrays


def estimate(acc_a: ArrayLike, gyr_a: ArrayLike, acc_b: ArrayLike, gyr_b: ArrayLike, *,
             fs_hz: float, principal_weight: float = 0.0) -> JointAxisResult:
    """Joint axes and joint centre of a hinge joint from two IMUs (all arrays (N, 3), m/s² and rad/s).

    Returns :class:`JointAxisResult` (``j_a``, ``j_b`` unit vectors in each sensor's frame with a
    consistent relative sign, ``o_a``, ``o_b`` the joint centre in each sensor frame, m, after eq. 72).
    The data must contain rotation about more than the joint axis alone (e.g. the whole limb moving).
    ``principal_weight`` : see :func:`estimate_axis` (0: Seel's problem exactly).
    """
    aa, ga, ab, gb = _checked(acc_a, gyr_a, acc_b, gyr_b, fs_hz)
    return _estimate(aa, ga, ab, gb, fs_hz, *_gammas(ga, gb, fs_hz), principal_weight=principal_weight)


def _estimate(aa, ga, ab, gb, fs_hz, ma, mb, principal_weight: float = 0.0) -> JointAxisResult:
    if len(aa) < 50:
        raise ValueError(f"need at least 50 samples of motion to estimate a joint axis, got {len(aa)}")
    j_a, j_b, rms_axis = estimate_axis(ga, gb, principal_weight=principal_weight)
    if j_a[int(np.argmax(np.abs(j_a)))] < 0:
        j_a = -j_a
    o_a_hat, o_b_hat, rms_pos = _solve_position(aa, ma, ab, mb)
    # relative sign: perpendicular rates and joint-centre forces seen from b must be those seen from a
    # turned by the gyroscope joint angle (eq. 73); the wrong sign of j_b breaks this
    ta = aa + ma @ o_a_hat
    tb = ab + mb @ o_b_hat
    best = None
    for s in (1.0, -1.0):
        jb = s * j_b
        c = _common_c(j_a, jb)
        alpha = np.cumsum(ga @ j_a - gb @ jb) / fs_hz
        score = 0.0
        for va, vb in ((ga, gb), (ta, tb)):
            w = _perp_norm(va, j_a) * _perp_norm(vb, jb)
            d = _phi(vb, jb, c) - _phi(va, j_a, c) - alpha
            score += abs(np.sum(w * np.exp(1j * d))) / max(np.sum(w), 1e-12)
        if best is None or score > best[0]:
            best = (score, jb)
    j_b = best[1]
    shift = 0.5 * (o_a_hat @ j_a + o_b_hat @ j_b)                      # eq. 72
    return JointAxisResult(j_a, j_b, o_a_hat - j_a * shift, o_b_hat - j_b * shift, rms_axis, rms_pos)


def joint_angle(acc_a: ArrayLike, gyr_a: ArrayLike, acc_b: ArrayLike, gyr_b: ArrayLike, *, fs_hz: float,
                axes: JointAxisResult | None = None, params: FkcParams | None = None,
                offset_rad: float | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Joint angle of ``a`` relative to ``b`` about the axis (rad): ``(fused, gyroscope, accelerometer)``.

    Eq. 73 (gyroscopes), eq. 74 (accelerometers, signed) and their FKC fusion (eq. 77).  The angles
    are zero at the start pose unless ``offset_rad`` (the accelerometer angle's offset) is given.
    """
    aa, ga, ab, gb = _checked(acc_a, gyr_a, acc_b, gyr_b, fs_hz)
    ma, mb = _gammas(ga, gb, fs_hz)
    axes = _estimate(aa, ga, ab, gb, fs_hz, ma, mb) if axes is None else axes
    alpha_gyr, alpha_acc, rate = _raw_angles(aa, ga, ma, ab, gb, mb, fs_hz, axes.j_a, axes.j_b, axes.o_a, axes.o_b)
    if offset_rad is None:
        n0 = max(1, min(len(rate), int(round(fs_hz))))
        d = alpha_acc[:n0] - alpha_gyr[:n0]
        offset_rad = float(np.angle(np.mean(np.exp(1j * d))))
    alpha_acc = alpha_acc - offset_rad
    alpha_acc = alpha_acc - 2 * np.pi * np.round((alpha_acc - alpha_gyr) / (2 * np.pi))
    fused = fkc(rate, alpha_acc, fs_hz=fs_hz, params=params, theta0_rad=0.0).theta_rad
    return fused, alpha_gyr, alpha_acc
