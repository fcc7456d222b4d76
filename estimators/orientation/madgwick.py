r"""Madgwick (2011): gradient-descent orientation filter for IMU (6D) and MARG (9D) sensors.

S. O. H. Madgwick, A. J. L. Harrison, R. Vaidyanathan, "Estimation of IMU and MARG orientation
using a gradient descent algorithm", IEEE ICORR 2011 (equation numbers below are the paper's);
the source thesis describes it in seed 004 §5.3.1 (eqs. 5.1–5.9).

Frames and quaternion
---------------------
The paper's :math:`{}^S_E\hat q` ("earth relative to sensor") is used as
:math:`v_E = q \otimes v_S \otimes q^*`, which is exactly ChakaMo's ``q_earth_sensor``.
The paper's earth frame has x towards magnetic north and z up (NWU: the accelerometer at rest reads
+1 on the upward axis, :math:`d_g = (0, 0, 1)`, :math:`b = (b_x, 0, b_z)`).  ChakaMo's earth frame
is ENU (x east, y north, z up); the two differ by a constant rotation about the vertical,

.. math:: q_{ENU,s} = q_z(+90°) \otimes q_{NWU,s},\qquad q_z(90°) = (\tfrac{1}{\sqrt2}, 0, 0, \tfrac{1}{\sqrt2}),

(it takes NWU north (1, 0, 0) to ENU north (0, 1, 0) and west (0, 1, 0) to (-1, 0, 0)).

The update (one sample, :math:`\Delta t = 1/f_s`)
-------------------------------------------------
* Gyroscope rate of change (eq. 12): :math:`\dot q_\omega = \tfrac12\, q \otimes (0, \omega)`.
* Objective (eqs. 25, 29, 31): the model of the normalised measurements minus the measurements,

  .. math:: f(q) = \begin{bmatrix} R(q)^T d_g - \hat a \\ R(q)^T b - \hat m \end{bmatrix},\qquad
            d_g = (0, 0, 1),\quad b = (0, b_h, b_z)\ \text{(ENU: horizontal reference on +y, north)}

  (6D: the first three rows only).
* Magnetic distortion compensation (eqs. 45–46): the measured field is rotated into the earth frame
  with the current estimate, :math:`h = q \otimes \hat m \otimes q^*`, and the reference keeps only its
  inclination: :math:`b_h = \sqrt{h_x^2 + h_y^2}`, :math:`b_z = h_z`.  A disturbed field can therefore
  only pull the heading, and no local field has to be known beforehand.
* Gradient (eq. 34, 6D) / (eq. 44, 9D): :math:`\nabla f = J^T(q) f(q)`.
* Fusion (eqs. 42–43): :math:`\dot q = \dot q_\omega - \beta\, \nabla f / \lVert \nabla f \rVert`,
  :math:`q_k = \operatorname{normalise}(q_{k-1} + \dot q\, \Delta t)`.

As in the paper (and ``ahrs``), the gradient is evaluated at the *previous* estimate against the
*current* measurements, and the normalised step always has length β however small the error.  During
rotation the gradient therefore always points along the motion (the measurements are one sample
ahead of :math:`q_{k-1}`), and the full-length step pushes the estimate until it runs about one sample
*ahead* of the truth: on noise-free data the error lies along the rotation and is ≈ |ω|Δt (0.76° mean
at 1.3 rad/s mean rate, 100 Hz) for any β ≥ 0.05, while pure gyroscope integration is exact.  This is a
property of the published filter, kept on purpose (it shrinks with the sampling period).

If the accelerometer sample is missing (``acc_ok`` false) the step is gyroscope only (the paper's
MARG objective needs both vectors, as in Madgwick's own code); a missing magnetometer sample falls
back to the 6D objective.  Unlike ``ahrs``, a gyroscope reading of exactly zero does
*not* skip the correction (``ahrs`` returns the previous quaternion unchanged in that case).

The radial part of the paper's gradient (why the formula below has a ``-2 c·f q`` term)
------------------------------------------------------------------------------------------------
The paper writes the rotation-matrix diagonal in the "unit-norm" form, e.g.
:math:`2(\tfrac12 - q_2^2 - q_3^2)` instead of the homogeneous :math:`q_1^2+q_2^2-q_3^2-q_4^2`.  The two
agree on the unit sphere, but the 4-D Jacobians differ by a radial term: with :math:`c` the model at
the paper's identity orientation (sensor axes = NWU axes), :math:`c = (0, 0, 1, b_h, 0, b_z)`,

.. math:: f_{paper}(q) = f_{hom}(q) + (1 - \lVert q\rVert^2)\, c,\qquad
          \nabla f_{paper} = J_{hom}^T f - 2 (c \cdot f)\, q .

The radial component enlarges :math:`\lVert\nabla f\rVert` and so changes the length of the
normalised tangential step; it depends on which earth frame the paper's polynomials were written in.
We keep it exactly (with :math:`c` as in the paper) so that this filter *is* Madgwick's filter
expressed in ENU: equal to the paper and to ``ahrs.filters.Madgwick`` in NWU up to the constant
:math:`q_z(90°)` (tested to 1e-6 against ``ahrs``; agreement is at rounding level, ~1e-15), and to the
C code's 6D update (its 9D update has the bug below).  Writing the ENU objective with the
"unit-norm" substitution on the ENU diagonal instead would give a slightly different filter.

The factor-of-two bug of the widely copied C code (not reproduced)
------------------------------------------------------------------
In ``MadgwickAHRS.c`` (x-io, 2011–2012, copied into many libraries and used by BROAD) the variables
``_2bx = sqrt(hx*hx + hy*hy)`` and ``_2bz = h_z`` hold :math:`b_x` and :math:`b_z`, not
:math:`2b_x` and :math:`2b_z` as their names and every formula using them assume.  The model field is
therefore :math:`R^T b / 2`: a half-length reference compared with the unit measured field, whose
residual (:math:`-\hat m/2` at the true orientation) never vanishes.  Its gradient is then dominated by a
radial component of length ≈ 0.4–1.0 (depending on the orientation) even at zero error, so the
normalised step is no longer "β in the direction of the error": its tangential part becomes ≈ β·(error
gradient)/(radial part), a proportional correction whose gain changes with the orientation.  Here
:math:`b` is used at full length, as in the paper's eq. (46), and near convergence both parts of the
gradient shrink with the error.

Gain
----
``beta_rad_s`` is the paper's :math:`\beta` (eq. 50): the magnitude of the quaternion-derivative
correction, in 1/s (rad/s of quaternion rate).  The corresponding rotation rate is up to
:math:`2\beta` rad/s, and the paper relates it to the gyroscope error as
:math:`\beta = \sqrt{3/4}\,\tilde\omega_\beta`.  It is a continuous-time gain: the same value is right at
any sampling rate.  ``ahrs`` calls it ``gain`` (defaults 0.033 IMU / 0.041 MARG, the paper's values for
a calibrated, slowly moving sensor).  BROAD's single best value over its 39 trials, 0.12, is in these
same units (their C implementation, with the bug above).  With the bug fixed, on the 10 BROAD trials in
``../shared/data/broad`` (9D, mean total RMSE; ``benchmarks/broad.py``): β = 0.041 → 6.90°,
0.07 → 6.19°, **0.1 → 6.04°**, 0.12 → 6.12°, 0.15 → 6.40°, 0.2 → 7.14° (6D: 0.041 → 6.60°, 0.1 → 6.80°).
That choice was made on the raw accelerometer, where a large β let the step pull the estimate through the
limb's accelerations.  On the motion-compensated accelerometer (below) the gradient points along the motion
almost always, and the full-length step then adds up to 2β rad/s to every rotation: flexion ROM on the
walking benchmark (``python -m benchmarks.walking``, seeds 0–5, known mounting, mean / worst ROM error) reads
3.5° / 4.6° at β = 0.1, 1.57° / 2.93° at 0.05, 1.24° / 2.45° at 0.041 (the paper's MARG value), **0.93° /
1.89° at 0.03**; BROAD 9D (undisturbed / disturbed) 2.23° / 6.35°, 1.85° / 5.25°, 1.78° / 5.07°, 1.79° / 4.88°.
The default is 0.03.

Motion-compensated accelerometer (ours, not in the paper)
---------------------------------------------------------
The update above reads, in place of the raw accelerometer sample, the specific force low-passed in a
quasi-inertial frame (``acc_lowpass_s``, default 1.5 s; :mod:`~estimators.orientation.acc_lowpass`, base
module docstring); ``acc_lowpass_s=0`` is the published filter, as the ``ahrs`` comparison runs it.  On the
gait scenarios of the tests (clips in motion from the first sample, 3–6 g heel strikes) the worst heading RMS
/ tilt on seeds 0–5 went from 5.8° / 11.0° to 4.2° / 3.4° (with β = 0.03); on the 10 shared BROAD trials (9D, undisturbed / disturbed
total RMSE) from 4.92° / 7.15° to 1.79° / 4.88° (β = 0.1 → 0.03, see *Gain*).

Warm-up (initial convergence)
-----------------------------
With a constant β the estimate turns towards the measurements at most :math:`2\beta` rad/s (11.5 °/s at
0.1, about half that with noisy data), so a wrong initial orientation takes seconds to fade.  The
source thesis (seed 004 §7.4) therefore ran β = 2 for the first 2 s and β = 0.03 afterwards.  ChakaMo
keeps that idea as a documented option on by default: during the first ``warmup_s`` (1 s) of a state,
β = max(``beta_rad_s``, ``beta_warmup_rad_s``) (1.0: a 20° error is gone in ≈ 0.2 s while the noise
jitter stays ≈ 1°).  The time since the state was created is the fifth state entry, so online blocks
and one batch agree.  ``warmup_s=0`` gives the published filter exactly (the ``ahrs`` comparison uses
it); on BROAD the warm-up changes nothing (the trials start at rest and aligned).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from estimators import quaternion as quat
from estimators.orientation import acc_lowpass
from estimators.orientation.base import Alignment, FloatArray, ImuInput, OrientationMethod, check_parameter
from estimators.orientation.quat_kernels import qrot

_TINY = 1e-300


@dataclass(frozen=True)
class MadgwickParams:
    """Parameters of :class:`Madgwick`.

    beta_rad_s
        Gain β of eq. (50), in 1/s (quaternion-derivative magnitude; up to 2β rad/s of rotation),
        ≥ 0.  0 integrates the gyroscope only.  Default 0.03 (see the module docstring).
    warmup_s
        Length (s, ≥ 0) of the initial convergence phase counted from the start of the state; 0 disables
        it (the published filter).  Default 1.5.
    beta_warmup_rad_s
        β during the warm-up, in 1/s like ``beta_rad_s`` (up to 2β rad/s of rotation; the larger of this and
        ``beta_rad_s`` is used), ≥ 0.  Default 1.0.
    acc_lowpass_s
        Time constant (s, ≥ 0) of the motion-compensated accelerometer the update reads (base module
        docstring; ours, not in the paper); 0 feeds the raw samples (the published filter).  Default 1.5.
    """

    beta_rad_s: float = 0.03
    warmup_s: float = 1.0
    beta_warmup_rad_s: float = 1.0
    acc_lowpass_s: float = 1.5

    def __post_init__(self) -> None:
        check_parameter("beta_rad_s", self.beta_rad_s, unit="rad/s", hint="typically 0.01–0.5")
        check_parameter("warmup_s", self.warmup_s, unit="s", hint="0 disables the warm-up")
        check_parameter("beta_warmup_rad_s", self.beta_warmup_rad_s, unit="rad/s", hint="typically 0.5–2")
        check_parameter("acc_lowpass_s", self.acc_lowpass_s, unit="s", hint="0 = the raw samples (the paper)")


# --------------------------------------------------------------------------------------- kernel
@njit(cache=True, fastmath=False)
def _madgwick_step(w, x, y, z, gx, gy, gz, ax, ay, az, mx, my, mz, acc_ok, mag_ok, dt_s, beta):
    """One sample; returns the normalised quaternion (w, x, y, z) as four floats."""
    # eq. (12): gyroscope rate of change, 0.5 q ⊗ (0, ω)
    dw = 0.5 * (-x * gx - y * gy - z * gz)
    dx = 0.5 * (w * gx + y * gz - z * gy)
    dy = 0.5 * (w * gy - x * gz + z * gx)
    dz = 0.5 * (w * gz + x * gy - y * gx)

    if acc_ok:
        na = math.sqrt(ax * ax + ay * ay + az * az)
        ax /= na
        ay /= na
        az /= na
        # model of gravity R^T e_z (homogeneous form) and residual
        rz0 = 2.0 * (x * z - w * y)
        rz1 = 2.0 * (y * z + w * x)
        rz2 = w * w - x * x - y * y + z * z
        fg0 = rz0 - ax
        fg1 = rz1 - ay
        fg2 = rz2 - az
        u0 = fg0
        u1 = fg1
        u2 = fg2
        v0 = 0.0
        v1 = 0.0
        v2 = 0.0
        c = fg2
        if mag_ok:
            nm = math.sqrt(mx * mx + my * my + mz * mz)
            mx /= nm
            my /= nm
            mz /= nm
            # eq. (45): h = q ⊗ m ⊗ q*  (R m, R = matrix of q)
            hx, hy, hz = qrot(w, x, y, z, mx, my, mz)
            # eq. (46) in ENU: b = (0, |h_xy|, h_z)
            bh = math.sqrt(hx * hx + hy * hy)
            bz = hz
            # model of the field R^T b = bh R^T e_y + bz R^T e_z
            ry0 = 2.0 * (x * y + w * z)
            ry1 = w * w - x * x + y * y - z * z
            ry2 = 2.0 * (y * z - w * x)
            fm0 = bh * ry0 + bz * rz0 - mx
            fm1 = bh * ry1 + bz * rz1 - my
            fm2 = bh * ry2 + bz * rz2 - mz
            u0 += bz * fm0
            u1 += bz * fm1
            u2 += bz * fm2
            v0 = bh * fm0
            v1 = bh * fm1
            v2 = bh * fm2
            c += bh * fm0 + bz * fm2
        # eqs. (34)/(44): J^T f, homogeneous Jacobian plus the paper's radial term -2 (c·f) q
        sw = 2.0 * (-y * u0 + x * u1 + w * u2 + z * v0 + w * v1 - x * v2 - c * w)
        sx = 2.0 * (z * u0 + w * u1 - x * u2 + y * v0 - x * v1 - w * v2 - c * x)
        sy = 2.0 * (-w * u0 + z * u1 - y * u2 + x * v0 + y * v1 + z * v2 - c * y)
        sz = 2.0 * (x * u0 + y * u1 + z * u2 + w * v0 - z * v1 + y * v2 - c * z)
        ns = math.sqrt(sw * sw + sx * sx + sy * sy + sz * sz)
        if ns > _TINY:
            k = beta / ns
            # eq. (43)
            dw -= k * sw
            dx -= k * sx
            dy -= k * sy
            dz -= k * sz

    # eq. (42): integrate and normalise
    w += dw * dt_s
    x += dx * dt_s
    y += dy * dt_s
    z += dz * dt_s
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return w / n, x / n, y / n, z / n


@njit(cache=True)
def _madgwick_batch(acc, gyr, mag, acc_ok, mag_ok, dt_s, beta, warmup_s, beta_warmup, state0):
    """Run :func:`_madgwick_step` over ``(N, 3)`` inputs (6D: ``mag_ok`` all false, ``mag`` zeros).

    Returns ``q (N, 4)`` (estimate after each sample) and the final state (a copy, ``(5,)``).
    """
    n = acc.shape[0]
    out = np.empty((n, 4))
    w = state0[0]
    x = state0[1]
    y = state0[2]
    z = state0[3]
    elapsed = state0[4]
    beta_fast = max(beta, beta_warmup)
    for k in range(n):
        b = beta_fast if elapsed < warmup_s else beta
        elapsed = min(elapsed + dt_s, warmup_s)
        w, x, y, z = _madgwick_step(w, x, y, z, gyr[k, 0], gyr[k, 1], gyr[k, 2],
                                    acc[k, 0], acc[k, 1], acc[k, 2], mag[k, 0], mag[k, 1], mag[k, 2],
                                    acc_ok[k], mag_ok[k], dt_s, b)
        out[k, 0] = w
        out[k, 1] = x
        out[k, 2] = y
        out[k, 3] = z
    state = state0.copy()
    state[0] = w
    state[1] = x
    state[2] = y
    state[3] = z
    state[4] = elapsed
    return out, state


# ------------------------------------------------------------------------------------ reference
def _reference_step(q: FloatArray, gyr: FloatArray, acc: FloatArray | None, mag: FloatArray | None,
                    dt_s: float, beta: float) -> FloatArray:
    """Readable numpy form of one update (same maths as the kernel, matrices written out)."""
    w, x, y, z = q
    q_dot = 0.5 * quat.multiply(q, np.concatenate(([0.0], gyr)))  # eq. (12)
    if acc is not None:
        a = acc / np.linalg.norm(acc)
        r = quat.to_matrix(q)
        model = [r[2]]                      # R^T e_z: the third row of R
        meas = [a]
        # ∂(R^T e_z)/∂(w, x, y, z), homogeneous form
        jac = [2.0 * np.array([[-y, z, -w, x], [x, w, z, y], [w, -x, -y, z]])]
        c_ref = [np.array([0.0, 0.0, 1.0])]  # the model at the paper's identity (NWU) orientation
        if mag is not None:
            m = mag / np.linalg.norm(mag)
            h = quat.rotate(q, m)                          # eq. (45)
            b_h, b_z = np.hypot(h[0], h[1]), h[2]          # eq. (46), ENU: b = (0, b_h, b_z)
            model.append(b_h * r[1] + b_z * r[2])
            meas.append(m)
            jac_ry = 2.0 * np.array([[z, y, x, w], [w, -x, y, -z], [-x, -w, z, y]])
            jac.append(b_h * jac_ry + b_z * jac[0])
            c_ref.append(np.array([b_h, 0.0, b_z]))
        f = np.concatenate(model) - np.concatenate(meas)   # eqs. (25)/(31)
        grad = np.vstack(jac).T @ f - 2.0 * (np.concatenate(c_ref) @ f) * q  # eqs. (34)/(44)
        norm = np.linalg.norm(grad)
        if norm > _TINY:
            q_dot = q_dot - beta * grad / norm             # eq. (43)
    q_new = q + q_dot * dt_s                               # eq. (42)
    return q_new / np.linalg.norm(q_new)


class Madgwick(OrientationMethod):
    """Madgwick's gradient-descent filter (6D and 9D).

    State ``(16,)``: ``q_earth_sensor`` (4), time elapsed since the state was created, s (1; it stops
    counting at ``warmup_s``), the accelerometer stage's block (``acc_lowpass.SIZE``).
    """

    name = "madgwick"
    params_type = MadgwickParams
    state_size = 5 + acc_lowpass.SIZE
    uses_acc_lowpass = True

    def _state_from_alignment(self, alignment: Alignment, data: ImuInput) -> FloatArray:
        """An aligned start is trusted (base module docstring): the warm-up is for a start given as ``q0``."""
        state = self._state_from_quaternion(alignment.q, data)
        state[4] = self.params.warmup_s
        return state

    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        state0 = np.asarray(state0, dtype=np.float64)
        p = self.params
        return _madgwick_batch(data.acc, data.gyr, data.mag_array, data.acc_ok, data.mag_ok, data.dt_s,
                               float(p.beta_rad_s), float(p.warmup_s), float(p.beta_warmup_rad_s), state0)

    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        p = self.params
        q = np.array(state0[:4], dtype=np.float64)
        elapsed = float(state0[4])
        out = np.empty((data.n, 4))
        for k in range(data.n):
            beta = max(p.beta_rad_s, p.beta_warmup_rad_s) if elapsed < p.warmup_s else p.beta_rad_s
            elapsed = min(elapsed + data.dt_s, p.warmup_s)
            acc = data.acc[k] if data.acc_ok[k] else None
            mag = data.mag[k] if (data.mag_ok[k] and acc is not None) else None
            q = _reference_step(q, data.gyr[k], acc, mag, data.dt_s, float(beta))
            out[k] = q
        state = np.array(state0, dtype=np.float64)
        state[:4], state[4] = q, elapsed
        return out, state
