r"""Strapdown mechanisation and initial alignment for a foot-mounted IMU (seed 001 §3.7, eqs. 3.19–3.29).

Frames: body b = the sensor, navigation n = ENU earth (z up).  ``C`` is the body-to-navigation
direction cosine matrix :math:`C^n_b` (= ``to_matrix(q_earth_sensor)``), ``f`` the specific force
(m/s², +g on the up axis at rest), ``w`` the angular rate (rad/s).

Continuous equations (3.19–3.21)
--------------------------------
.. math::
    \dot C^n_b = C^n_b\,\Omega, \qquad \dot v^n = C^n_b f^b + g^n, \qquad \dot p^n = v^n,

with :math:`\Omega = [\omega^b\times]` the skew matrix of eq. (3.22) and :math:`g^n = (0, 0, -g)`.

Discrete mechanisation, step :math:`\Delta t_k` (3.23–3.27)
-----------------------------------------------------------
.. math::
    C_{k+1} &= C_k\,(2I + \Omega_{k+1}\Delta t)(2I - \Omega_{k+1}\Delta t)^{-1} &\text{(3.23)}\\
    f^n_{k+1} &= C_{k+1} f^b_{k+1} + g^n &\text{(3.24)}\\
    v_{k+1} &= v_k + f^n_{k+1}\Delta t &\text{(3.25)}\\
    p_{k+1} &= p_k + v_{k+1}\Delta t &\text{(3.26)}

(3.23) is the Padé [1/1] approximant of the exact :math:`C_k e^{\Omega\Delta t}` (3.27).  For a skew
matrix :math:`A = [a\times]` the approximant is the Cayley transform, evaluated in closed form

.. math:: (2I + A)(2I - A)^{-1} = I + \frac{4}{4 + |a|^2}\Big(A + \tfrac12 A^2\Big),

which is exactly orthogonal (no re-orthonormalisation needed) and rotates by
:math:`2\arctan(|a|/2) = |a| - |a|^3/12 + \dots` about :math:`a`.

Initial alignment (3.29)
------------------------
From the mean specific force :math:`\bar f` over the first still period, roll and pitch (yaw = 0: it is
unobservable without a magnetometer):

.. math::
    \phi = \operatorname{atan2}(\bar f_y, \bar f_z), \qquad
    \theta = \operatorname{atan2}\big(-\bar f_x, \sqrt{\bar f_y^2 + \bar f_z^2}\big), \qquad
    C_0 = R_y(\theta)\,R_x(\phi)

(the thesis writes :math:`\theta = \arcsin(f_x/g)` with the opposite sign convention of its NED frame).
The gyroscope bias is the mean rate over the same still period.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.physics import GRAVITY_M_S2

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


__all__ = ["GRAVITY_M_S2", "Alignment", "align", "cayley", "first_still_period", "strapdown", "strapdown_reference"]


@njit(cache=True)
def _cayley_inplace(ax: float, ay: float, az: float, out: np.ndarray) -> None:
    """``out`` (3, 3) = Padé/Cayley rotation (2I + A)(2I − A)⁻¹ of the rotation vector ``a`` (eq. 3.23)."""
    n2 = ax * ax + ay * ay + az * az
    c = 4.0 / (4.0 + n2)
    h = 0.5 * c
    # A + A²/2 with A = [a×]; A² = a aᵀ − |a|² I
    out[0, 0] = 1.0 + h * (ax * ax - n2)
    out[1, 1] = 1.0 + h * (ay * ay - n2)
    out[2, 2] = 1.0 + h * (az * az - n2)
    out[0, 1] = c * (-az) + h * ax * ay
    out[1, 0] = c * az + h * ax * ay
    out[0, 2] = c * ay + h * ax * az
    out[2, 0] = c * (-ay) + h * ax * az
    out[1, 2] = c * (-ax) + h * ay * az
    out[2, 1] = c * ax + h * ay * az


@njit(cache=True)
def _matmul3_inplace(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out = a @ b`` for (3, 3) arrays (``out`` must not alias ``a`` or ``b``)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


def cayley(rotvec: ArrayLike) -> FloatArray:
    """(3, 3) Padé rotation :math:`(2I + A)(2I - A)^{-1}`, :math:`A = [a\\times]` (eq. 3.23), numpy form."""
    a = np.asarray(rotvec, dtype=np.float64)
    big_a = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return (2.0 * np.eye(3) + big_a) @ np.linalg.inv(2.0 * np.eye(3) - big_a)


@njit(cache=True)
def _strapdown_kernel(acc, gyr, dt_s, c0, gyr_bias, gravity):
    n = acc.shape[0]
    pos = np.zeros((n, 3))
    vel = np.zeros((n, 3))
    c_out = np.empty((n, 3, 3))
    c = c0.copy()
    r = np.empty((3, 3))
    tmp = np.empty((3, 3))
    v = np.zeros(3)
    p = np.zeros(3)
    for k in range(n):
        if k > 0:
            dt = dt_s[k]
            _cayley_inplace((gyr[k, 0] - gyr_bias[0]) * dt, (gyr[k, 1] - gyr_bias[1]) * dt,
                            (gyr[k, 2] - gyr_bias[2]) * dt, r)
            _matmul3_inplace(c, r, tmp)
            c[:, :] = tmp
            for i in range(3):
                fn = c[i, 0] * acc[k, 0] + c[i, 1] * acc[k, 1] + c[i, 2] * acc[k, 2]
                if i == 2:
                    fn -= gravity
                v[i] += fn * dt
                p[i] += v[i] * dt
        pos[k] = p
        vel[k] = v
        c_out[k] = c
    return pos, vel, c_out


def strapdown(acc: ArrayLike, gyr: ArrayLike, dt_s: ArrayLike, c0: ArrayLike, gyr_bias_rad_s: ArrayLike = (0, 0, 0),
              gravity_m_s2: float = GRAVITY_M_S2) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Free-inertial ("naive") mechanisation, eqs. (3.23)–(3.26): ``(pos_m, vel_m_s, C)`` (N,3), (N,3), (N,3,3).

    acc (N, 3) m/s², gyr (N, 3) rad/s, dt_s (N,) step ending at each sample (``dt_s[0]`` unused),
    c0 (3, 3) initial :math:`C^n_b`; sample 0 is the initial state (p = v = 0).
    """
    a = np.ascontiguousarray(acc, dtype=np.float64)
    return _strapdown_kernel(a, np.ascontiguousarray(gyr, dtype=np.float64),
                             np.ascontiguousarray(dt_s, dtype=np.float64), np.asarray(c0, dtype=np.float64),
                             np.asarray(gyr_bias_rad_s, dtype=np.float64), float(gravity_m_s2))


def strapdown_reference(acc: ArrayLike, gyr: ArrayLike, dt_s: ArrayLike, c0: ArrayLike,
                        gyr_bias_rad_s: ArrayLike = (0, 0, 0),
                        gravity_m_s2: float = GRAVITY_M_S2) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Readable numpy version of :func:`strapdown` (matrix inverse form of eq. 3.23)."""
    acc = np.asarray(acc, dtype=np.float64)
    gyr = np.asarray(gyr, dtype=np.float64) - np.asarray(gyr_bias_rad_s, dtype=np.float64)
    dt_s = np.asarray(dt_s, dtype=np.float64)
    n = len(acc)
    c = np.asarray(c0, dtype=np.float64).copy()
    g_n = np.array([0.0, 0.0, -gravity_m_s2])
    p, v = np.zeros(3), np.zeros(3)
    pos, vel, cs = np.zeros((n, 3)), np.zeros((n, 3)), np.empty((n, 3, 3))
    for k in range(n):
        if k > 0:
            c = c @ cayley(gyr[k] * dt_s[k])          # (3.23)
            f_n = c @ acc[k] + g_n                    # (3.24)
            v = v + f_n * dt_s[k]                     # (3.25)
            p = p + v * dt_s[k]                       # (3.26)
        pos[k], vel[k], cs[k] = p, v, c
    return pos, vel, cs


class Alignment:
    """Initial state from a still period: ``c0`` (3, 3) :math:`C^n_b`, ``q0`` (4,), ``gyr_bias_rad_s`` (3,),
    ``acc_mean_m_s2`` (3,), ``gravity_m_s2`` (the measured |f|), ``pitch_rad``, ``roll_rad``, ``still`` [start, end)."""

    def __init__(self, c0: FloatArray, gyr_bias_rad_s: FloatArray, acc_mean_m_s2: FloatArray,
                 roll_rad: float, pitch_rad: float, still: tuple[int, int]) -> None:
        self.c0 = c0
        self.q0 = quat.from_matrix(c0)
        self.gyr_bias_rad_s = gyr_bias_rad_s
        self.acc_mean_m_s2 = acc_mean_m_s2
        self.gravity_m_s2 = float(np.linalg.norm(acc_mean_m_s2))
        self.roll_rad = roll_rad
        self.pitch_rad = pitch_rad
        self.still = still


def first_still_period(gyr: ArrayLike, fs_hz: float, *, threshold_rad_s: float = 0.15,
                       min_s: float = 0.5, max_s: float = 5.0) -> tuple[int, int]:
    """``[0, end)`` of the initial still period: the samples before |ω| first exceeds ``threshold_rad_s``
    (less 0.1 s of margin), capped at ``max_s``; ``ValueError`` if shorter than ``min_s``."""
    w = np.linalg.norm(np.asarray(gyr, dtype=np.float64), axis=1)
    moving = np.flatnonzero(w > threshold_rad_s)
    end = len(w) if moving.size == 0 else int(moving[0])
    end = min(end - int(round(0.1 * fs_hz)), int(round(max_s * fs_hz)))
    if end < int(round(min_s * fs_hz)):
        raise ValueError(f"the walk must start with the foot still for at least {min_s} s (found {max(end, 0) / fs_hz:.2f} s "
                         f"with |gyr| below {threshold_rad_s:g} rad/s); the initial alignment needs it")
    return 0, end


def align(acc: ArrayLike, gyr: ArrayLike, still: tuple[int, int]) -> Alignment:
    """Initial alignment, eq. (3.29): roll and pitch from the mean specific force, yaw 0, gyroscope bias
    = the mean rate over the still samples ``still = (start, end)``."""
    s0, s1 = still
    f = np.asarray(acc, dtype=np.float64)[s0:s1].mean(axis=0)
    b = np.asarray(gyr, dtype=np.float64)[s0:s1].mean(axis=0)
    roll = float(np.arctan2(f[1], f[2]))
    pitch = float(np.arctan2(-f[0], np.hypot(f[1], f[2])))
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    r_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    r_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return Alignment(r_y @ r_x, b, f, roll, pitch, (s0, s1))
