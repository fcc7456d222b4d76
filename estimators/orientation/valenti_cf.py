r"""Valenti, Dryanovski, Xiao (2015): complementary filter with delta quaternions (6D and 9D).

R. G. Valenti, I. Dryanovski, J. Xiao, "Keeping a good attitude: a quaternion-based orientation
filter for IMUs and MARGs", Sensors 15(8):19302–19330, 2015.  Equation numbers are the paper's
(the same as in ``ahrs.filters.aqua``); the source thesis describes the filter in seed 004 §5.3.2
(eqs. 5.11–5.17).

Frames and quaternion
---------------------
The paper estimates :math:`{}^L_G q`, the global frame relative to the local (sensor) frame, i.e. the
*conjugate* of ChakaMo's ``q_earth_sensor``; its global frame is NWU (x magnetic north, z up).  Every
formula below is rewritten for ``q = q_earth_sensor`` in ENU (x east, y north, z up).  Conjugating
the paper's update :math:`{}^L_G q = {}^L_G q_\omega \otimes \Delta q_{acc} \otimes \Delta q_{mag}`
(eq. 59) gives the corrections as *earth-frame* rotations applied on the left,

.. math:: q_k = \widehat{\Delta q}_{mag} \otimes \widehat{\Delta q}_{acc} \otimes q_\omega ,

and each delta quaternion below is the conjugate of the paper's (same scalar part, so the
LERP/SLERP switch is unchanged).

1. Prediction (eqs. 38–42)
--------------------------
:math:`q_\omega = \operatorname{normalise}\big(q_{k-1} + \tfrac12 q_{k-1} \otimes (0, \omega_k - b)\,\Delta t\big)`,
with ``b`` the gyroscope bias held in the state (zero unless estimated, see 5).  A missing gyroscope
row holds the orientation (zero rate) and leaves the bias untouched.

2. Accelerometer correction (eqs. 44–53)
----------------------------------------
The normalised specific force is rotated into the earth frame with the prediction, the *predicted
gravity* :math:`g_p = R(q_\omega)\,\hat a` (eq. 44); the delta quaternion is the shortest rotation taking
:math:`g_p` to :math:`(0, 0, 1)` (eq. 47, conjugated):

.. math:: \Delta q_{acc} = \Big(\sqrt{\tfrac{g_z+1}{2}},\ \tfrac{g_y}{\sqrt{2(g_z+1)}},\ -\tfrac{g_x}{\sqrt{2(g_z+1)}},\ 0\Big).

It only tilts (no rotation about the vertical), so the heading of the prediction is untouched.  The
paper uses this single branch because :math:`g_z` stays near 1; it is singular only for
:math:`g_z = -1` (estimate upside down), where we take the half turn about x.  (The two-branch form
choosing by :math:`a_z \ge 0`, the thesis' eq. 5.11, is the paper's *algebraic* quaternion from one
accelerometer sample (eq. 25), used by the Kalman variant, not by this filter.)

3. Interpolation towards the identity (eqs. 48–52)
--------------------------------------------------
With gain :math:`\alpha \in [0, 1]` and :math:`\Omega = \arccos \Delta q_0`: LERP when
:math:`\Delta q_0 > \epsilon` (eq. 50, then normalised, eq. 51),
:math:`\overline{\Delta q} = (1-\alpha) q_I + \alpha \Delta q`; otherwise SLERP (eq. 52),
:math:`\widehat{\Delta q} = \frac{\sin((1-\alpha)\Omega)}{\sin\Omega} q_I + \frac{\sin(\alpha\Omega)}{\sin\Omega}\Delta q`.
:math:`\epsilon = 0.9` (``lerp_threshold``) switches to SLERP for corrections larger than ≈ 52°.

4. Magnetometer correction (eqs. 54–58), ENU
--------------------------------------------
The field is rotated into the earth frame with the accelerometer-corrected estimate,
:math:`l = R(q')\,\hat m` (eq. 54), :math:`\Gamma = l_x^2 + l_y^2` (eq. 28).  The paper rotates
:math:`l` about z onto the +x half-plane (its north); in ENU north is +y.  Writing
:math:`\theta = \operatorname{atan2}(l_y, l_x)`, the heading correction is
:math:`\varphi = \pi/2 - \theta`, so :math:`\cos\varphi = l_y/\sqrt\Gamma`,
:math:`\sin\varphi = l_x/\sqrt\Gamma`, and by the half-angle formulas

.. math::
    \Delta q_{mag} = \begin{cases}
      \Big(\frac{\sqrt{\Gamma + l_y\sqrt\Gamma}}{\sqrt{2\Gamma}},\ 0,\ 0,\ \frac{l_x}{\sqrt2\sqrt{\Gamma + l_y\sqrt\Gamma}}\Big), & l_y \ge 0 \\[4pt]
      \Big(\frac{|l_x|}{\sqrt2\sqrt{\Gamma - l_y\sqrt\Gamma}},\ 0,\ 0,\ \operatorname{sgn}(l_x)\frac{\sqrt{\Gamma - l_y\sqrt\Gamma}}{\sqrt{2\Gamma}}\Big), & l_y < 0
    \end{cases}

i.e. the paper's eq. (58) with :math:`(l_x, l_y)_{NWU} = (l_y, -l_x)_{ENU}`, conjugated.  The second
branch (the paper's :math:`l_x < 0` case, eq. 35) avoids the singularity when the field points south;
its sign is chosen so that :math:`\Delta q_0 \ge 0` (the same rotation; otherwise the SLERP towards
the identity would turn the long way round).  It is interpolated like step 3 with gain
:math:`\beta`; it only turns about the vertical, so magnetic disturbances cannot tilt the estimate.
A missing accelerometer sample skips step 2 only (the heading correction works on any tilt).

5. Adaptive gain and gyroscope bias
-----------------------------------
* Magnitude error :math:`e_m = \big|\,\lVert a\rVert - g\,\big| / g` (eq. 60) and
  :math:`\alpha = \bar\alpha f(e_m)` (eq. 61), with :math:`f = 1` for :math:`e_m \le t_1`, linear down to
  :math:`0` at :math:`t_2`, and 0 beyond (:math:`t_1 = 0.1`, :math:`t_2 = 0.2`, fractions of g).
  (The paper writes the ramp as :math:`(t_2 - e_m)/t_1`, the same thing for :math:`t_2 = 2t_1`; we use
  :math:`(t_2 - e_m)/(t_2 - t_1)`, continuous for any thresholds.)
* Optional bias estimation at rest: the sensor is *steady* when
  :math:`|\lVert a\rVert - g| < 0.1` m/s², :math:`|\omega_i - \omega_{i,k-1}| < 0.01` rad/s and
  :math:`|\omega_i - b_i| < 0.2` rad/s on every axis (the thresholds of the authors' reference implementation, ROS ``imu_complementary_filter``); then
  :math:`b \leftarrow b + \alpha_b(\omega - b)` before the prediction.

Rate-independent gains
----------------------
The paper's :math:`\bar\alpha`, :math:`\beta` and :math:`\alpha_b` are fractions *per sample*: a
correction removes the fraction α of the remaining error at each sample (exactly for SLERP, to first
order for LERP), so the error decays as :math:`(1-\alpha)^k = e^{-t/\tau}`.  ChakaMo takes the time
constants :math:`\tau` (s) and converts them at the actual rate,

.. math:: \alpha = 1 - e^{-\Delta t/\tau},\qquad \tau = -\Delta t / \ln(1 - \alpha),

(first-order low pass of cut-off :math:`1/(2\pi\tau)` Hz on the correction).  The paper's gains,
:math:`\tau = -0.01/\ln 0.99 \approx 0.995` s (``TAU_DEFAULT_S``; ChakaMo's default for the tilt), give exactly :math:`\alpha = \beta = \alpha_b = 0.01` at
100 Hz, the values of the authors' implementation and of ``ahrs`` (``ValentiCFParams.from_per_sample``
converts published per-sample gains).  The source thesis (seed 004 §7.4) used
:math:`G_{acc} = 0.01`, :math:`G_{mag} = 0.001` at 100 Hz and thresholds 0.05 / 0.15:
``ValentiCFParams.from_per_sample(0.01, 0.001, 100.0, acc_error_low=0.05, acc_error_high=0.15)``.
On the 10 BROAD trials in ``../shared/data/broad`` (9D, mean total RMSE) the defaults score 21.4°
(fast-translation and magnet trials dominate), the thesis configuration 11.4°, and slower corrections
do better still (τ_acc = 5 s, τ_mag = 10 s: 8.0°; Madgwick β = 0.1: 6.0°): tuning belongs to the benchmarks.

Motion-compensated accelerometer (ours, not in the paper)
---------------------------------------------------------
The update above reads, in place of the raw accelerometer sample, the specific force low-passed in a
quasi-inertial frame (``acc_lowpass_s``, default 1.5 s; :mod:`~estimators.orientation.acc_lowpass`, base
module docstring); ``acc_lowpass_s=0`` is the published filter, as the ``ahrs`` comparison runs it.  On the
gait scenarios of the tests (clips in motion from the first sample, 3–6 g heel strikes) the worst heading RMS
/ tilt on seeds 0–5 went from 9.7° / 11.6° to 4.7° / 3.0°; on the 10 shared BROAD trials (9D, undisturbed / disturbed
total RMSE) from 7.36° / 8.54° to 1.97° / 6.71°.

Warm-up (initial convergence)
-----------------------------
With τ ≈ 1 s a 20° initial error still leaves 2.7° after 2 s (and 20° of heading with the thesis'
τ_mag ≈ 10 s would take half a minute).  During the first ``warmup_s`` (1 s) of a state both corrections
use the faster of their own time constant and ``tau_warmup_s`` (0.1 s); the adaptive gain still
applies.  The elapsed time is the last state entry, so online blocks equal one batch.  ``warmup_s=0``
is the published filter (the ``ahrs`` comparison uses it); on BROAD it changes nothing measurable.

Compared with ``ahrs.filters.AQUA`` (0.4.0)
-------------------------------------------
With the warm-up and the adaptive gain off, no bias estimation, the field in the northern half-plane
and non-zero gyro samples, this filter equals ``AQUA.updateIMU``/``updateMARG`` after the frame change
:math:`q_{ENU,s} = q_z(90°) \otimes ({}^L_G q_{AQUA})^*` (tested to 1e-9).  Differences, all deliberate:
``AQUA`` returns the previous quaternion unchanged when the gyroscope reads exactly zero (skipping
the correction); its adaptive mode replaces the user's α by ``adaptive_gain(acc)`` with
:math:`\bar\alpha = 0.1` and stores it, so α is lost for later samples; it uses only the
:math:`l_x \ge 0` branch of eq. (58) (singular when the field points south); it skips the heading
correction when the accelerometer sample is invalid; and it has no bias estimation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators import quaternion as quat
from estimators.orientation.base import (
    Alignment, FloatArray, ImuInput, OrientationMethod, check_flag, check_parameter,
)
from estimators.orientation import acc_lowpass
from estimators.orientation.valenti_cf_kernels import valenti_cf_batch

#: time constant giving exactly the per-sample gain 0.01 at 100 Hz (the authors' default gains)
TAU_DEFAULT_S = -0.01 / math.log1p(-0.01)
#: ChakaMo's defaults for body-worn sensors.  On the raw accelerometer slow corrections were needed to reject
#: linear acceleration (10 shared BROAD trials, 9D total RMSE, undisturbed / disturbed: τ 1 s / 1 s, the paper,
#: 15.1° / 27.7°; 5 s / 10 s 7.4° / 8.5°), but then a 0.7 °/s gyroscope bias costs τ × bias (gait scenarios of the
#: tests: heading 9.7°).  On the motion-compensated accelerometer (``acc_lowpass_s``) the paper's own tilt gain
#: (τ_acc = TAU_DEFAULT_S ≈ 1 s) is best; τ_mag 8 s keeps the walking heading within 5° (seeds 0–5: 4.9° at
#: 8 s, 5.5° at 10 s, measured with a one-stage low-pass of 1 s; BROAD then 2.1° / 6.6° at 8 s, 2.4° / 5.5° at
#: 10 s, 1.9° / 7.9° at 5 s: the magnet trial 32).  As shipped (acc_lowpass_s 1.5 s): walking 4.7°, BROAD
#: 1.97° / 6.71°.
#: ``from_per_sample`` gives the paper's gains.
TAU_ACC_S = TAU_DEFAULT_S
TAU_MAG_S = 8.0
#: q (4), gyroscope bias b (3) rad/s, previous gyroscope sample (3) rad/s, elapsed time (1) s, then the
#: accelerometer stage's block (``acc_lowpass.SIZE``)
STATE_SIZE = 11 + acc_lowpass.SIZE


def per_sample_gain(tau_s: float, dt_s: float) -> float:
    """The paper's per-sample gain for time constant ``tau_s`` at step ``dt_s``: ``1 - exp(-dt/tau)``."""
    return -math.expm1(-dt_s / tau_s)


@dataclass(frozen=True)
class ValentiCFParams:
    """Parameters of :class:`ValentiCF` (rate-independent; see the module docstring).

    tau_acc_s
        Time constant (s, > 0) of the accelerometer (tilt) correction; α = 1 − exp(−Δt/τ).
        Default 5 s (the paper's α = 0.01 at 100 Hz is τ ≈ 0.995 s; see ``TAU_ACC_S`` for why).
    tau_mag_s
        Time constant (s, > 0) of the magnetometer (heading) correction, β likewise.  Default 10 s.
    lerp_threshold
        ε in [0, 1): LERP when the delta quaternion's scalar part exceeds ε, else SLERP.  Default 0.9.
    adaptive_gain
        Scale α by f(e_m) from the accelerometer magnitude error (eqs. 60–61).  Default True.
    acc_error_low, acc_error_high
        Thresholds t₁ < t₂ of e_m = | |a| − g | / g (fractions of g).  Defaults 0.1 and 0.2.
    gravity_m_s2
        Local gravity g (m/s²) for e_m and the rest test.  Default 9.81.
    estimate_bias
        Estimate the gyroscope bias while the sensor is steady (bias in ``state[4:7]``).  Default False.
    tau_bias_s
        Time constant (s, > 0) of the bias low-pass; α_b = 1 − exp(−Δt/τ).  Default ≈ 0.995 s.
    rest_gyr_rad_s, rest_gyr_change_rad_s, rest_acc_m_s2
        Steady-state thresholds: |ω − b| per axis (0.2 rad/s), |ω_k − ω_{k−1}| per axis (0.01 rad/s),
        | |a| − g | (0.1 m/s²).
    warmup_s
        Length (s, ≥ 0) of the initial convergence phase counted from the start of the state; 0 disables
        it (the published filter).  Default 1.5.
    tau_warmup_s
        Time constant (s, > 0) of both corrections during the warm-up (the faster of this and the
        normal one is used).  Default 0.1 s.
    acc_lowpass_s
        Time constant (s, ≥ 0) of the motion-compensated accelerometer the update reads (base module
        docstring; ours, not in the paper); 0 feeds the raw samples (the published filter).  Default 1.5.
    """

    tau_acc_s: float = TAU_ACC_S
    tau_mag_s: float = TAU_MAG_S
    lerp_threshold: float = 0.9
    adaptive_gain: bool = True
    acc_error_low: float = 0.1
    acc_error_high: float = 0.2
    gravity_m_s2: float = 9.81
    estimate_bias: bool = False
    tau_bias_s: float = TAU_DEFAULT_S
    rest_gyr_rad_s: float = 0.2
    rest_gyr_change_rad_s: float = 0.01
    rest_acc_m_s2: float = 0.1
    warmup_s: float = 1.0
    tau_warmup_s: float = 0.1
    acc_lowpass_s: float = 1.5

    def __post_init__(self) -> None:
        check_parameter("warmup_s", self.warmup_s, low=0.0, unit="s")
        check_parameter("acc_lowpass_s", self.acc_lowpass_s, unit="s", hint="0 = the raw samples (the paper)")
        for name in ("tau_acc_s", "tau_mag_s", "tau_bias_s", "tau_warmup_s"):
            check_parameter(name, getattr(self, name), low=0.0, low_open=True, unit="s")
        check_parameter("lerp_threshold", self.lerp_threshold, low=0.0, high=1.0)
        if self.lerp_threshold >= 1.0:
            raise ValueError(f"lerp_threshold must be in [0, 1) (1 would never interpolate), got {self.lerp_threshold!r}")
        for name in ("adaptive_gain", "estimate_bias"):
            check_flag(name, getattr(self, name))
        check_parameter("acc_error_low", self.acc_error_low, low=0.0, high=1.0)
        check_parameter("acc_error_high", self.acc_error_high, low=0.0)
        if not self.acc_error_high > self.acc_error_low:
            raise ValueError(
                f"acc_error_high ({self.acc_error_high!r}) must be greater than acc_error_low ({self.acc_error_low!r})"
            )
        check_parameter("gravity_m_s2", self.gravity_m_s2, low=0.0, low_open=True, unit="m/s²")
        for name in ("rest_gyr_rad_s", "rest_gyr_change_rad_s"):
            check_parameter(name, getattr(self, name), low=0.0, low_open=True, unit="rad/s")
        check_parameter("rest_acc_m_s2", self.rest_acc_m_s2, low=0.0, low_open=True, unit="m/s²")

    @classmethod
    def from_per_sample(cls, alpha: float, beta: float, fs_hz: float, **others) -> ValentiCFParams:
        """Parameters from the paper's per-sample gains α, β (in (0, 1)) published for rate ``fs_hz``."""
        for name, gain in (("alpha", alpha), ("beta", beta)):
            if not 0.0 < gain < 1.0:
                raise ValueError(f"{name} must be in (0, 1), got {gain!r}")
        if not (math.isfinite(fs_hz) and fs_hz > 0):
            raise ValueError(f"fs_hz must be finite and > 0 Hz, got {fs_hz!r}")
        dt = 1.0 / fs_hz
        return cls(tau_acc_s=-dt / math.log1p(-alpha), tau_mag_s=-dt / math.log1p(-beta), **others)


# ------------------------------------------------------------------------------------ reference
def _interpolate_to_identity(delta: FloatArray, gain: float, eps: float) -> FloatArray:
    """Eqs. (50)–(52) in numpy."""
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    if delta[0] > eps:
        out = (1.0 - gain) * identity + gain * delta
    else:
        omega = np.arccos(delta[0])
        out = (np.sin((1.0 - gain) * omega) * identity + np.sin(gain * omega) * delta) / np.sin(omega)
    return out / np.linalg.norm(out)


def _delta_acc(g_p: FloatArray) -> FloatArray:
    """Eq. (47) conjugated: the shortest rotation taking the predicted gravity ``g_p`` to (0, 0, 1)."""
    gx, gy, gz = g_p
    gz = min(gz, 1.0)
    if gz + 1.0 <= 1e-12:
        return np.array([0.0, 1.0, 0.0, 0.0])
    r = np.sqrt(2.0 * (gz + 1.0))
    return np.array([r / 2.0, gy / r, -gx / r, 0.0])


def _delta_mag(l_earth: FloatArray) -> FloatArray | None:
    """Eq. (58) for ENU: the rotation about z taking the horizontal field onto +y (north), w >= 0."""
    lx, ly = l_earth[0], l_earth[1]
    gam = lx * lx + ly * ly
    if gam <= 1e-300:
        return None
    if ly >= 0.0:
        s = np.sqrt(gam + ly * np.sqrt(gam))
        return np.array([s / np.sqrt(2.0 * gam), 0.0, 0.0, lx / (np.sqrt(2.0) * s)])
    s = np.sqrt(gam - ly * np.sqrt(gam))  # the field points south: the other half-angle formula
    sign = 1.0 if lx >= 0.0 else -1.0
    return np.array([abs(lx) / (np.sqrt(2.0) * s), 0.0, 0.0, sign * s / np.sqrt(2.0 * gam)])


class ValentiCF(OrientationMethod):
    """Valenti's complementary filter (6D and 9D).

    State ``(11,)``: ``q_earth_sensor`` (4), gyroscope bias ``b`` in rad/s (3; stays at its initial
    value, zero, unless ``estimate_bias``), previous gyroscope sample in rad/s (3; for the rest test),
    time elapsed since the state was created in s (1; stops counting at ``warmup_s``).
    """

    name = "valenti_cf"
    params_type = ValentiCFParams
    state_size = STATE_SIZE
    uses_acc_lowpass = True

    def _state_from_alignment(self, alignment: Alignment, data: ImuInput) -> FloatArray:
        """An aligned start is trusted (base module docstring): the warm-up is for a start given as ``q0``."""
        state = self._state_from_quaternion(alignment.q, data)
        state[10] = self.params.warmup_s
        return state

    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        p = self.params
        state0 = np.asarray(state0, dtype=np.float64)
        return valenti_cf_batch(
            data.acc, data.gyr, data.mag_array, data.acc_ok, data.mag_ok, data.dt_s,
            float(p.tau_acc_s), float(p.tau_mag_s), float(p.lerp_threshold), bool(p.adaptive_gain),
            float(p.acc_error_low), float(p.acc_error_high), float(p.gravity_m_s2), bool(p.estimate_bias),
            float(p.tau_bias_s), float(p.rest_gyr_rad_s), float(p.rest_gyr_change_rad_s), float(p.rest_acc_m_s2),
            float(p.warmup_s), float(p.tau_warmup_s), ~data.flags.gyr_missing, state0,
        )

    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        p = self.params
        dt = data.dt_s
        alpha_b = per_sample_gain(p.tau_bias_s, dt)
        q = np.array(state0[:4], dtype=np.float64)
        bias = np.array(state0[4:7], dtype=np.float64)
        gyr_prev = np.array(state0[7:10], dtype=np.float64)
        elapsed = float(state0[10])
        out = np.empty((data.n, 4))
        for k in range(data.n):
            # warm-up: the faster of the normal and the warm-up time constants
            warm = elapsed < p.warmup_s
            alpha_bar = per_sample_gain(min(p.tau_acc_s, p.tau_warmup_s) if warm else p.tau_acc_s, dt)
            beta = per_sample_gain(min(p.tau_mag_s, p.tau_warmup_s) if warm else p.tau_mag_s, dt)
            elapsed = min(elapsed + dt, p.warmup_s)
            gyr = data.gyr[k]
            acc = data.acc[k] if data.acc_ok[k] else None
            a_norm = np.linalg.norm(acc) if acc is not None else 0.0
            if not data.flags.gyr_missing[k]:
                if p.estimate_bias and acc is not None:
                    steady = (abs(a_norm - p.gravity_m_s2) < p.rest_acc_m_s2
                              and np.all(np.abs(gyr - gyr_prev) < p.rest_gyr_change_rad_s)
                              and np.all(np.abs(gyr - bias) < p.rest_gyr_rad_s))
                    if steady:
                        bias = bias + alpha_b * (gyr - bias)
                gyr_prev = gyr.copy()
                # prediction
                q = q + 0.5 * quat.multiply(q, np.concatenate(([0.0], gyr - bias))) * dt
                q = q / np.linalg.norm(q)
            if acc is not None:
                alpha = alpha_bar
                if p.adaptive_gain:
                    e_m = abs(a_norm - p.gravity_m_s2) / p.gravity_m_s2           # eq. (60)
                    factor = np.clip((p.acc_error_high - e_m) / (p.acc_error_high - p.acc_error_low), 0.0, 1.0)
                    alpha = alpha_bar * factor                                      # eq. (61)
                if alpha > 0.0:
                    g_p = quat.rotate(q, acc / a_norm)                              # eq. (44)
                    d_acc = _interpolate_to_identity(_delta_acc(g_p), alpha, p.lerp_threshold)
                    q = quat.multiply(d_acc, q)                                     # eq. (53)
            if data.mag_ok[k] and beta > 0.0:
                l_earth = quat.rotate(q, data.mag[k])                               # eq. (54)
                d_mag = _delta_mag(l_earth)
                if d_mag is not None:
                    d_mag = _interpolate_to_identity(d_mag, beta, p.lerp_threshold)
                    q = quat.multiply(d_mag, q)                                     # eq. (59)
            q = q / np.linalg.norm(q)
            out[k] = q
        state = np.array(state0, dtype=np.float64)
        state[:11] = np.concatenate([q, bias, gyr_prev, [elapsed]])
        return out, state
