r"""Motion-compensated accelerometer for the published filters (ours, after VQF §3.2).

Why
---
Guo, Madgwick and both Valenti filters correct their inclination towards the *normalised* specific force of
each sample, :math:`\hat a_k = a_k/\lVert a_k\rVert`.  On a limb that swings (a shank 0.25 m below the knee)
the linear acceleration reaches ±40 % of g and turns the instantaneous direction by 15–60°.  A filter is a
weighted mean of these directions, and the mean of *unit* vectors is biased whenever the norm of the sample
correlates with its direction (it does: tangential and centripetal accelerations follow the swing phase).
Gating by the norm makes it worse, because the samples that pass sit at particular phases.  Measured on the
gait scenarios of the tests (true orientation, 10 s, seeds 0–5): the mean unit direction is 3.5° off the
vertical, the norm-gated means of Valenti's adaptive gain and Guo's weight 6.8° and 8.2°.  The mean of the
raw vectors, rotated into an inertial frame, is 0.0–0.8° off: the limb's velocity is bounded, so its
acceleration averages out.

What
----
The same idea as the motion-compensated initial alignment (base module docstring), run causally for the
whole recording, as VQF does for its own inclination (Laidig & Seel 2023, §3.2):

1. *Strapdown* of the raw gyroscope from the start of the state:
   :math:`q_{IS,k} = q_{IS,k-1} \otimes \exp(\omega_k\,\Delta t)` (``I``: a quasi-inertial frame, drifting only
   with the gyroscope's error; missing gyroscope rows are zeros: held).
2. *Low-pass in* ``I`` without lag on a drift: :math:`a_{I,k} = R(q_{IS,k})\,a_k` passes the second-order
   Butterworth low-pass :math:`H` of ChakaMo's filter (cut-off :math:`f_c = \sqrt2/(2\pi\tau)`, bilinear
   transform; ``τ`` = the method's ``acc_lowpass_s``) twice, and the output is
   :math:`\bar a_I = 2\,H a_I - H(H a_I)`, i.e. :math:`1 - (1-H)^2` (Brown's double exponential smoothing
   with Butterworth stages).  Gravity is constant in an ideal ``I``, but the real ``I`` turns at the
   gyroscope bias :math:`b`, so gravity there is a slow ramp.  :math:`H` alone follows a ramp with its DC
   group delay τ (an error of :math:`\tau\,|b_h|`: 1.7° at τ = 1 s and 1.7 °/s, which the bias state of
   Guo's filter then learns as a wrong bias: a simulated knee step-up with a BMI160-like bias read 2.4–6.4°
   instead of 0.4–1.2°); the error of :math:`1-(1-H)^2` is :math:`(1-H)^2 = O(s^2)`, zero on a ramp.  Above
   :math:`f_c` it still falls with the square of the frequency (gain ≈ :math:`2H`), so the limb's
   acceleration is averaged out.
3. *Back to the sensor*: :math:`\tilde a_k = R(q_{IS,k})^T\,\bar a_{I,k}` replaces :math:`a_k` as the
   accelerometer sample of the published update (and of its norm gates and rest tests, which then see a
   quiet signal).  Missing accelerometer rows stay missing (the filter state is held).

Both stages start at their steady state: from the initial alignment, at the alignment window's gravity
estimate (the velocity regression of the base module docstring) in the frame before sample 0, where
:math:`q_{IS} = 1`, followed by one impulse that sets the limb's start velocity (:func:`initial_block`); from
a ``q0`` (or online without alignment) at the first valid sample.  ``acc_lowpass_s = 0`` switches the stage
off (the published filter).

State block (``SIZE`` = 17, appended to the method's own state): ``q_IS`` (4), the DF2T states of the first
stage ``z1 (3), z2 (3)`` and of the second ``z1 (3), z2 (3)``, and 1 once they hold a value (0: the next valid
sample sets their steady state).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from estimators import quaternion as quat
from estimators.orientation.quat_kernels import qmul, qrot
from estimators.signal import butter_lowpass

FloatArray = np.ndarray

SIZE = 17
_READY = 16


def coefficients(tau_s: float, fs_hz: float) -> FloatArray:
    """``[b0, b1, b2, a1, a2]`` of the low-pass with :math:`f_c = \\sqrt2/(2\\pi\\tau)` (capped at 0.45 fs)."""
    fc_hz = min(math.sqrt(2.0) / (2.0 * math.pi * tau_s), 0.45 * fs_hz)
    b, a = butter_lowpass(fc_hz, fs_hz)
    return np.array([b[0], b[1], b[2], a[1], a[2]])


def _steady(x: FloatArray, coeffs: FloatArray) -> tuple[FloatArray, FloatArray]:
    """DF2T state of a stage that has seen the constant input ``x`` forever (DC gain 1)."""
    b0, _, b2, _, a2 = coeffs
    return (1.0 - b0) * x, (b2 - a2) * x


def _stage(x: FloatArray, z1: FloatArray, z2: FloatArray, coeffs: FloatArray):
    """One DF2T step of a stage: ``(y, z1, z2)``."""
    b0, b1, b2, a1, a2 = coeffs
    y = b0 * x + z1
    return y, b1 * x - a1 * y + z2, b2 * x - a2 * y


def initial_block(gravity_s: FloatArray | None, coeffs: FloatArray, velocity_m_s: FloatArray | None = None,
                  dt_s: float = 0.0) -> FloatArray:
    r"""A fresh state block: ``q_IS = 1`` and both stages at their steady state on ``gravity_s`` (or empty).

    With ``velocity_m_s`` (the start velocity :math:`u_0` relative to the window mean, from
    :func:`~estimators.orientation.base.velocity_regression`), the stages are then stepped once on
    :math:`g + u_0/\\Delta t`: their past is a limb at its mean velocity brought to :math:`u_0` just before
    sample 0.  Without that impulse, a clip that starts mid-swing shows the low-pass a velocity step of
    :math:`-u_0` when the swing returns to its mean, a transient of ≈ :math:`u_0/\\tau` (gait scenarios of
    the tests, one stage, τ = 1 s: 4.6–6.8° in the first 2 s; 2.1–3.3° with the impulse).
    """
    block = np.zeros(SIZE)
    block[0] = 1.0
    if gravity_s is not None:
        g = np.asarray(gravity_s, dtype=np.float64)
        z1, z2 = _steady(g, coeffs)
        w1, w2 = _steady(g, coeffs)
        if velocity_m_s is not None and dt_s > 0.0:
            y, z1, z2 = _stage(g + np.asarray(velocity_m_s) / dt_s, z1, z2, coeffs)
            _, w1, w2 = _stage(y, w1, w2, coeffs)
        block[4:7], block[7:10], block[10:13], block[13:16] = z1, z2, w1, w2
        block[_READY] = 1.0
    return block


@njit(cache=True)
def lowpass_step(s, i0, ax, ay, az, rx, ry, rz, acc_ok, dt_s, c):
    """One sample on the block ``s[i0:i0 + SIZE]`` (in place) with the rate ``r`` (rad/s); returns the filtered
    specific force (three floats, zeros when ``acc_ok`` is false: the row stays missing)."""
    b0, b1, b2, a1, a2 = c[0], c[1], c[2], c[3], c[4]
    # step 1: q_IS ⊗ exp(ω dt)
    gx, gy, gz = rx * dt_s, ry * dt_s, rz * dt_s
    ang = math.sqrt(gx * gx + gy * gy + gz * gz)
    sh = 0.5 - ang * ang / 48.0 if ang < 1e-4 else math.sin(0.5 * ang) / ang  # as quaternion.exp
    w, x, y, z = qmul(s[i0], s[i0 + 1], s[i0 + 2], s[i0 + 3], math.cos(0.5 * ang), gx * sh, gy * sh, gz * sh)
    nq = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / nq, x / nq, y / nq, z / nq
    s[i0], s[i0 + 1], s[i0 + 2], s[i0 + 3] = w, x, y, z
    if not acc_ok:
        return 0.0, 0.0, 0.0
    # step 2: into I, two Butterworth stages (DF2T per axis), 2 H − H²
    ai = qrot(w, x, y, z, ax, ay, az)
    ybar = [0.0, 0.0, 0.0]
    for j in range(3):
        xj = ai[j]
        if s[i0 + _READY] == 0.0:
            s[i0 + 4 + j] = (1.0 - b0) * xj
            s[i0 + 7 + j] = (b2 - a2) * xj
            s[i0 + 10 + j] = (1.0 - b0) * xj
            s[i0 + 13 + j] = (b2 - a2) * xj
        y1 = b0 * xj + s[i0 + 4 + j]
        s[i0 + 4 + j] = b1 * xj - a1 * y1 + s[i0 + 7 + j]
        s[i0 + 7 + j] = b2 * xj - a2 * y1
        y2 = b0 * y1 + s[i0 + 10 + j]
        s[i0 + 10 + j] = b1 * y1 - a1 * y2 + s[i0 + 13 + j]
        s[i0 + 13 + j] = b2 * y1 - a2 * y2
        ybar[j] = 2.0 * y1 - y2
    s[i0 + _READY] = 1.0
    # step 3: back to the sensor frame
    return qrot(w, -x, -y, -z, ybar[0], ybar[1], ybar[2])


@njit(cache=True)
def lowpass_batch(acc, gyr, acc_ok, dt_s, coeffs, block0):
    """The stage over ``(N, 3)`` rows (module docstring): returns ``(acc_filtered (N, 3), block (SIZE,))``."""
    n = acc.shape[0]
    out = np.zeros((n, 3))
    s = block0.copy()
    for k in range(n):
        out[k, 0], out[k, 1], out[k, 2] = lowpass_step(s, 0, acc[k, 0], acc[k, 1], acc[k, 2], gyr[k, 0], gyr[k, 1],
                                                       gyr[k, 2], acc_ok[k], dt_s, coeffs)
    return out, s


def reference_step(block: FloatArray, acc: FloatArray, rate: FloatArray, acc_ok: bool, dt_s: float,
                   coeffs: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Readable numpy form of one sample: ``(filtered specific force (3,), new block)``."""
    q_is = quat.normalize(quat.multiply(block[:4], quat.exp(rate * dt_s)))   # step 1
    new = np.array(block, dtype=np.float64)
    new[:4] = q_is
    if not acc_ok:
        return np.zeros(3), new
    a_i = quat.rotate(q_is, acc)                                             # step 2
    if not new[_READY]:  # steady state on the first sample
        (new[4:7], new[7:10]), (new[10:13], new[13:16]) = _steady(a_i, coeffs), _steady(a_i, coeffs)
    y1, new[4:7], new[7:10] = _stage(a_i, new[4:7], new[7:10], coeffs)
    y2, new[10:13], new[13:16] = _stage(y1, new[10:13], new[13:16], coeffs)
    new[_READY] = 1.0
    return quat.rotate(quat.conjugate(q_is), 2.0 * y1 - y2), new             # step 3


def lowpass_reference(acc: FloatArray, gyr: FloatArray, acc_ok: FloatArray, dt_s: float, coeffs: FloatArray,
                      block0: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Readable numpy twin of :func:`lowpass_batch` (same numbers to rounding)."""
    block = np.array(block0, dtype=np.float64)
    out = np.zeros((acc.shape[0], 3))
    for k in range(acc.shape[0]):
        out[k], block = reference_step(block, acc[k], gyr[k], bool(acc_ok[k]), dt_s, coeffs)
    return out, block
