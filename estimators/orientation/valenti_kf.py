r"""Valenti, Dryanovski, Xiao (2016): linear Kalman filter on the quaternion with AQUA measurements.

R. G. Valenti, I. Dryanovski, J. Xiao, "A linear Kalman filter for MARG orientation estimation using
the algebraic quaternion algorithm", IEEE Trans. Instrum. Meas. 65(2), 467–481, 2016; the algebraic
quaternion (AQUA) comes from their 2015 paper "Keeping a good attitude", Sensors 15(8).  The source
thesis summarises both in seed 004 §5.3.2 (eqs. 5.10–5.13) and §5.4.1 (eqs. 5.25–5.35); equation
numbers below are the thesis' unless marked otherwise.  Written from the papers (no public Python
implementation exists); the deviations are listed at the end.

State and process model (eqs. 5.33–5.34)
----------------------------------------
The state is the quaternion :math:`x = q_{ES}` (ChakaMo's ``q_earth_sensor``, ENU) with its 4×4 error
covariance :math:`P`.  Rigid-body kinematics :math:`\dot q = \tfrac12 q \otimes (0, \omega)`, integrated to
first order over :math:`\Delta t = 1/f_s`:

.. math::
    x^-_{k+1} = \Phi_k x_k,\qquad \Phi_k = I_4 + \tfrac{\Delta t}{2}\,\Omega(\omega_k),\qquad
    \Omega(\omega) = \begin{bmatrix} 0 & -\omega_x & -\omega_y & -\omega_z\\ \omega_x & 0 & \omega_z & -\omega_y\\
                     \omega_y & -\omega_z & 0 & \omega_x\\ \omega_z & \omega_y & -\omega_x & 0\end{bmatrix}

(:math:`\Omega(\omega)\,q = q \otimes (0, \omega)`; seed eq. 5.42 prints the same matrix).  Gyroscope white
noise :math:`v_g` enters as :math:`w_k = -\tfrac{\Delta t}{2}\,\Xi(x_k)\,v_g` with
:math:`\Xi(q)\,n = q \otimes (0, n)`, so (eq. 5.34)

.. math:: Q_k = \left(\tfrac{\Delta t}{2}\right)^2 \Xi(x_k)\,\Sigma_g\,\Xi(x_k)^T
              = \left(\tfrac{\Delta t}{2}\right)^2 \sigma_g^2\,(I_4 - x_k x_k^T),\qquad
          P^-_{k+1} = \Phi_k P_k \Phi_k^T + Q_k ,

the right-hand form because the gyroscope noise is isotropic here and :math:`[x\ \Xi(x)]` is orthogonal.
(The thesis prints :math:`Q_k = -(\Delta t/2)^2 \ldots` with a stray minus sign.)

Measurement: the algebraic quaternion (AQUA, eqs. 5.10–5.13, 5.25)
-------------------------------------------------------------------
In the papers the quaternion :math:`{}^L_G q` satisfies :math:`R^T({}^L_G q)\,{}^L a = {}^G g`; with
Hamilton products this is :math:`a = q \otimes (0,0,1) \otimes q^*`, i.e. :math:`{}^L_G q = q_{SG}` maps the
global frame *to the sensor* (checked numerically in the tests).  With unit :math:`a` and :math:`m`:

* tilt (eq. 5.11), two branches to avoid the singularity at :math:`a_z = -1`:

  .. math:: q_{acc} = \begin{cases}
      \left(\sqrt{\tfrac{a_z+1}{2}},\ -\tfrac{a_y}{\sqrt{2(a_z+1)}},\ \tfrac{a_x}{\sqrt{2(a_z+1)}},\ 0\right) & a_z \ge 0\\[4pt]
      \left(-\tfrac{a_y}{\sqrt{2(1-a_z)}},\ \sqrt{\tfrac{1-a_z}{2}},\ 0,\ \tfrac{a_x}{\sqrt{2(1-a_z)}}\right) & a_z < 0
      \end{cases}

  maps an intermediate frame :math:`I` (z up, heading arbitrary) to the sensor;
* the field in :math:`I`: :math:`l = q_{acc}^* \otimes m \otimes q_{acc}` (eq. 5.12),
  :math:`\Gamma = l_x^2 + l_y^2`;
* heading (eq. 5.13) rotates :math:`I` about z so that the horizontal field points to the global
  reference axis.  The papers' global frame is NWU (reference axis +x, the :math:`zx^+` half-plane);
  ChakaMo's is ENU (reference axis +y, north).  Rotating :math:`l` by :math:`-90°` about z,
  :math:`l' = (l_y, -l_x, l_z)`, turns the ENU problem into the paper's, so eq. 5.13 is used with
  :math:`l'`:

  .. math:: q_{mag} = \begin{cases}
      \left(\sqrt{\tfrac{\Gamma + l'_x\sqrt\Gamma}{2\Gamma}},\ 0,\ 0,\ \tfrac{l'_y}{\sqrt{2(\Gamma + l'_x\sqrt\Gamma)}}\right) & l'_x \ge 0\\[4pt]
      \left(\tfrac{l'_y}{\sqrt{2(\Gamma - l'_x\sqrt\Gamma)}},\ 0,\ 0,\ \sqrt{\tfrac{\Gamma - l'_x\sqrt\Gamma}{2\Gamma}}\right) & l'_x < 0
      \end{cases}

  (the thesis prints :math:`\sqrt{l_y}` in the second branch; :math:`l_y` is right, as the tests
  check).  Then :math:`q_{mag} = (\cos\tfrac\psi2, 0, 0, \sin\tfrac\psi2)` with
  :math:`\psi = \operatorname{atan2}(l'_y, l'_x)`;
* :math:`{}^L_G q = q_{acc} \otimes q_{mag}` (eq. 5.25) is :math:`q_{S,ENU}`, and the measurement of our
  state is its conjugate, :math:`z = (q_{acc} \otimes q_{mag})^*`.  Deriving AQUA directly in ENU this way
  is the same as computing it in NWU and using :math:`q_{ENU,S} = q_z(90°) \otimes q_{NWU,S}`.

The two :math:`q_{acc}` branches differ by a rotation about the intermediate z axis which
:math:`q_{mag}` undoes, so :math:`z` is continuous across :math:`a_z = 0` *up to its sign*.  The double
cover is handled as in the paper: :math:`z \leftarrow -z` when :math:`z \cdot x^- < 0`, so the linear
update always blends two quaternions of the same hemisphere.

Measurement noise (eqs. 5.26–5.32)
----------------------------------
:math:`R = J\,\Sigma_u\,J^T` with :math:`u = (a, m)` and
:math:`\Sigma_u = \operatorname{diag}(\sigma_a^2/\lVert a\rVert^2\, I_3,\ \sigma_m^2/\lVert m\rVert^2\, I_3)`
(eqs. 5.27–5.29), :math:`J` by the chain rule through :math:`f_2 = (a, l)` and :math:`f_1 = (q_{acc}, q_{mag})`
(eqs. 5.31–5.32), written here in closed form:

.. math::
    \frac{\partial p}{\partial a} = R_\otimes(q_{mag})\,D + h\,\frac{\partial\psi}{\partial a},\qquad
    \frac{\partial p}{\partial m} = h\,(R(q_{acc})\,d)^T,\qquad
    h = \tfrac12\,p \otimes (0,0,0,1),\qquad d = \frac{(-l_y,\ l_x,\ 0)}{\Gamma},

with :math:`p = q_{acc} \otimes q_{mag}`, :math:`R_\otimes(q)\,r = r \otimes q`, :math:`D = \partial q_{acc}/\partial a`
(4×3, from the branch formulas), :math:`\partial\psi/\partial l = d` and
:math:`\partial\psi/\partial a_j = d \cdot 2\operatorname{Vec}(q_{acc}^* \otimes m \otimes D_{:,j})`.
Since :math:`\lVert R(q_{acc}) d\rVert^2 = 1/\Gamma`, the magnetometer term is
:math:`(\sigma_m^2/\lVert m\rVert^2)\,h h^T/\Gamma`: the heading-angle variance is :math:`\sigma_m^2/B_h^2`.

Kalman update (eqs. 5.22–5.24 with :math:`H = I_4`)
---------------------------------------------------
:math:`S = P^- + R`, :math:`K = P^- S^{-1}`, :math:`x = x^- + K(z - x^-)`, :math:`P = (I - K)P^-`, then
:math:`x \leftarrow x/\lVert x\rVert`.  ``S`` is factorised by Cholesky; ``P`` is kept exactly symmetric
(upper triangle computed and mirrored).  Gross outliers are down-weighted by an innovation gate
(deviation 5 below).

6D variant and missing samples
------------------------------
Without a magnetometer (or when its sample is missing, or the horizontal part of the unit field in
the intermediate frame is below 0.1 %, :math:`\Gamma < 10^{-6}`) the heading of the measurement is
taken from the prediction: a *virtual field*
:math:`m_v = R(x^-)^T e_{north}` (the earth's north axis in sensor coordinates, as predicted) replaces
:math:`m` in AQUA.  Then :math:`z` has the measured tilt and the predicted heading: a tilt error
:math:`\delta\theta` about any horizontal earth axis leaves the projection of :math:`m_v` on north, so the
innovation has no heading component to first order.  Its noise is a fixed, weak heading
standard deviation of 2 rad (``VIRTUAL_HEADING_STD_RAD``), which keeps :math:`S` well conditioned.
Being (weakly) informative, it makes the 6D heading variance settle near :math:`\sqrt{Q R}` instead of
growing without bound; the estimate is unaffected because the heading innovation is zero.
(Only if the measured "up" lies exactly along the predicted north, a 90° tilt error, is the virtual
field vertical too; that sample is not corrected.)
A missing accelerometer sample skips the update (AQUA needs gravity); a missing gyroscope sample was
zeroed by :func:`~estimators.orientation.base.validate_imu` (the prediction holds).

Parameters: noise densities, rate independent
---------------------------------------------
Each parameter is a white-noise density (unit/√Hz); per-sample variances are
:math:`\sigma^2 = N^2 f_s` (the discrete equivalent of continuous white noise, as in Kalibr).  Then
:math:`Q \propto N_g^2 \Delta t` and :math:`R \propto N_a^2 f_s`, and the steady-state correction time constants

.. math:: \tau_{tilt} \approx \frac{N_a}{g\,N_g},\qquad \tau_{heading} \approx \frac{n_m}{\cos(\mathrm{dip})\,N_g}

do not depend on the sampling rate.  The defaults (:math:`N_g = 0.003` rad/s/√Hz,
:math:`N_a = 0.045` m/s²/√Hz, :math:`n_m = 0.0067`/√Hz) give :math:`\tau_{tilt} \approx 1.5` s and, at a
63° dip, :math:`\tau_{heading} \approx 5` s: tuning values for body-worn sensors that lump
linear acceleration, gyroscope bias and magnetic disturbances into the noise, not datasheet values
(a MetaMotionR's BMI160 gyroscope has about 1.2e-4 rad/s/√Hz).  The magnetometer noise :math:`n_m` is a
fraction of the field norm (the field is used as a unit vector), so the magnetometer may be in any unit
(µT, gauss, normalised): the paper's :math:`\Sigma_m = N_m^2 I` on the raw field is replaced by
:math:`n_m^2 I` on the normalised one (before, 0.3 µT/√Hz on the raw field made the heading gain depend on
the unit: 10° RMS heading error on a gait clip in µT, 39° in nT).

Motion-compensated accelerometer (ours, not in the paper)
---------------------------------------------------------
The update above reads, in place of the raw accelerometer sample, the specific force low-passed in a
quasi-inertial frame (``acc_lowpass_s``, default 1.5 s; :mod:`~estimators.orientation.acc_lowpass`, base
module docstring); ``acc_lowpass_s=0`` is the published filter, as the ``ahrs`` comparison runs it.  On the
gait scenarios of the tests (clips in motion from the first sample, 3–6 g heel strikes) the worst heading RMS
/ tilt on seeds 0–5 went from 7.5° / 6.8° to 3.2° / 3.0°; on the 10 shared BROAD trials (9D, undisturbed / disturbed
total RMSE) from 5.27° / 9.46° to 1.91° / 6.80°.

Deviations from the paper (and why)
-----------------------------------
1. Frames: ENU instead of NWU and :math:`q_{ES}` instead of :math:`q_{SG}` as the state (project
   conventions); the process model and AQUA were re-derived for it as above.
2. :math:`\Sigma_{acc}` of the *normalised* accelerometer is projected on its tangent plane,
   :math:`\tfrac{\sigma_a^2}{\lVert a\rVert^2}(I - \hat a\hat a^T)` (the exact first-order covariance of a
   normalised vector), instead of eq. 5.28's :math:`\tfrac{\sigma_a^2}{\lVert a\rVert^2} I_3`.  With the
   un-projected form the closed formulas are differentiated off the unit sphere and the radial component
   leaks into the tilt with a sign that differs between the two :math:`q_{acc}` branches, so :math:`R` would
   jump at :math:`a_z = 0`.  The unit-norm direction of the 4-D state, which no normalised measurement can
   perturb, instead gets the tilt variance, :math:`R \mathrel{+}= \tfrac{\sigma_a^2}{4\lVert a\rVert^2} z z^T`,
   so that :math:`S` stays invertible (the innovation along :math:`z` is second order anyway).
3. The predicted state is normalised before the update (the linear update blends unit quaternions).
4. The 6D variant and the handling of missing samples are ChakaMo's (the paper is MARG only).
5. Innovation gate (``innovation_gate`` :math:`g`; 0 restores the paper's update).  AQUA takes the
   heading in the *accelerometer's* tilt frame, so with a steep field (dip ≈ 65° in Europe) a tilt
   error :math:`\delta` from linear acceleration becomes a heading error of about
   :math:`\delta\tan(\text{dip})`, and in fast motion the measurement can be off by more than 90°.
   Eq. 5.32 linearises :math:`R` at the measured point and cannot describe such errors; the linear
   update then pulls the state a fixed fraction of the way to a wrong quaternion every sample.  On the
   10 BROAD trials in ``../shared/data`` (quick metric: heading offset and IMU-to-marker rotation
   fitted, total RMSE) the plain update gives 0.9–59° (mean 22°; 26° and 54° on the fast trials).
   Hence: with the normalised innovation squared :math:`d^2 = \nu^T S^{-1}\nu`,
   :math:`\nu = z - x^-`, and :math:`g' = g \cdot 100\,\text{Hz}/f_s`, when :math:`d^2 > g'` the update
   uses :math:`R\,d^2/g'` (the measurement is down-weighted until it is just consistent; for gross
   outliers the correction shrinks like :math:`1/\lVert\nu\rVert`).  :math:`S` is dominated by
   :math:`R \propto f_s`, so the same physical error gives :math:`d^2 \propto 1/f_s`; the factor keeps the
   gate rate independent (``GATE_REFERENCE_HZ``).  With the default :math:`g = 3` the same BROAD
   trials give 0.9–7.1° (mean 3.8°; Madgwick with β = 0.1 gives mean 4.1° on the same metric).  The
   price: a real large error with an already converged :math:`P` is corrected slowly.  At rest at
   100 Hz with the defaults, an error reaches < 2° after ≈ 13 s (9D) / 4.6 s (6D tilt) from 30° and
   ≈ 37 s / 21 s from 90° (plain update: 9.4 / 1.8 s and 15 / 3.3 s).  A wrong *start* is not
   affected, because :math:`P_0` is large.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators import quaternion as quat
from estimators.orientation.base import ALIGNED_STD_RAD, Alignment, FloatArray, ImuInput, OrientationMethod, check_parameter
from estimators.orientation import acc_lowpass
from estimators.orientation.valenti_kf_kernels import GAMMA_MIN, VIRTUAL_HEADING_STD_RAD, valenti_kf_batch

STATE_SIZE = 20 + acc_lowpass.SIZE
"""State layout: ``0:4`` q_earth_sensor; ``4:20`` the covariance P (4×4, row-major); then the accelerometer
stage's block (``acc_lowpass.SIZE``)."""

GATE_REFERENCE_HZ = 100.0
"""Rate at which ``innovation_gate`` is the plain χ² threshold (see the module docstring)."""

_NORTH_ENU = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class ValentiKFParams:
    """Parameters of :class:`ValentiKF` (noise densities, initial error, gate; see the module docstring).

    gyr_noise_rad_s_sqrt_hz
        Gyroscope white-noise density :math:`N_g` (rad/s/√Hz) driving the process noise (eq. 5.34),
        > 0.  Default 0.003.
    acc_noise_m_s2_sqrt_hz
        Accelerometer noise density :math:`N_a` (m/s²/√Hz) of eq. 5.28, > 0; lumps linear
        acceleration in.  Default 0.045 (tilt time constant ≈ :math:`N_a/(g N_g)` = 1.5 s).
    mag_noise_rel_sqrt_hz
        Magnetometer noise density :math:`n_m` of eq. 5.29 as a fraction of the field norm (1/√Hz: the
        noise of the unit field vector, so any field unit works), > 0; lumps magnetic disturbances in.
        Default 0.0067 (0.3 µT/√Hz in a 44.7 µT field; heading time constant ≈ :math:`n_m/(\\cos(dip) N_g)`
        = 5 s at a 63° dip).
    initial_std_rad
        Standard deviation (rad) of the initial orientation error; :math:`P_0 = (\\sigma_0/2)^2 I_4`.
        > 0.  Default 0.5 (the first corrections then nearly replace a wrong start by the measurement).
    innovation_gate
        Threshold :math:`g` on the normalised innovation squared at 100 Hz (dimensionless, ≥ 0); above
        it :math:`R` is inflated (deviation 5 in the module docstring).  0 gives the paper's plain
        update.  Default 3.
    acc_lowpass_s
        Time constant (s, ≥ 0) of the motion-compensated accelerometer the update reads (base module
        docstring; ours, not in the paper); 0 feeds the raw samples (the paper).  Default 1.5.
    """

    gyr_noise_rad_s_sqrt_hz: float = 0.003
    acc_noise_m_s2_sqrt_hz: float = 0.045
    mag_noise_rel_sqrt_hz: float = 0.0067
    initial_std_rad: float = 0.5
    innovation_gate: float = 3.0
    acc_lowpass_s: float = 1.5

    def __post_init__(self) -> None:
        check_parameter("acc_lowpass_s", self.acc_lowpass_s, unit="s", hint="0 = the raw samples (the paper)")
        check_parameter("innovation_gate", self.innovation_gate,
                        hint="0 = the paper's plain update; typically 1–20")
        for name, unit, typical in (
            ("gyr_noise_rad_s_sqrt_hz", "rad/s/√Hz", "1e-4–0.01"),
            ("acc_noise_m_s2_sqrt_hz", "m/s²/√Hz", "0.002–0.5"),
            ("mag_noise_rel_sqrt_hz", "1/√Hz (fraction of the field norm)", "0.001–0.05"),
            ("initial_std_rad", "rad", "0.01–3"),
        ):
            check_parameter(name, getattr(self, name), unit=unit, low_open=True, hint=f"typically {typical}")


# ------------------------------------------------------------------------------------ reference
def omega_matrix(gyr: FloatArray) -> FloatArray:
    """Ω(ω) of eq. 5.33 (4×4): ``Ω(ω) @ q == q ⊗ (0, ω)``."""
    wx, wy, wz = gyr
    return np.array([[0.0, -wx, -wy, -wz], [wx, 0.0, wz, -wy], [wy, -wz, 0.0, wx], [wz, wy, -wx, 0.0]])


def _right_matrix(q: FloatArray) -> FloatArray:
    """``R⊗(q)`` with ``R⊗(q) @ r == r ⊗ q``."""
    return np.stack([quat.multiply(e, q) for e in np.eye(4)], axis=1)


def acc_quaternion(a: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Eq. 5.11 for a unit ``a``: ``q_acc`` (intermediate → sensor) and ``D = ∂q_acc/∂a`` (4×3)."""
    ax, ay, az = a
    if az >= 0.0:
        s = np.sqrt(2.0 * (az + 1.0))
        q = np.array([s / 2.0, -ay / s, ax / s, 0.0])
        d = np.array([[0.0, 0.0, 1.0 / (2.0 * s)], [0.0, -1.0 / s, ay / s**3], [1.0 / s, 0.0, -ax / s**3],
                      [0.0, 0.0, 0.0]])
    else:
        t = np.sqrt(2.0 * (1.0 - az))
        q = np.array([-ay / t, t / 2.0, 0.0, ax / t])
        d = np.array([[0.0, -1.0 / t, -ay / t**3], [0.0, 0.0, -1.0 / (2.0 * t)], [0.0, 0.0, 0.0],
                      [1.0 / t, 0.0, ax / t**3]])
    return q, d


def mag_quaternion(l: FloatArray) -> FloatArray:
    """Eq. 5.13 in ENU: heading quaternion from the field ``l`` in the intermediate frame, ``l' = (l_y, -l_x)``."""
    lpx, lpy = l[1], -l[0]
    gamma = lpx**2 + lpy**2
    if lpx >= 0.0:
        b = gamma + lpx * np.sqrt(gamma)
        return np.array([np.sqrt(b / (2.0 * gamma)), 0.0, 0.0, lpy / np.sqrt(2.0 * b)])
    b = gamma - lpx * np.sqrt(gamma)
    return np.array([lpy / np.sqrt(2.0 * b), 0.0, 0.0, np.sqrt(b / (2.0 * gamma))])


def aqua_reference(a: FloatArray, m: FloatArray) -> tuple[FloatArray | None, FloatArray | None,
                                                          FloatArray | None, float]:
    """AQUA for unit ``a``, ``m`` in ENU: ``z = (q_acc ⊗ q_mag)*`` (q_earth_sensor), ``∂z/∂a``, ``∂z/∂m``, Γ.

    ``z`` and the Jacobians are ``None`` when Γ < 1e-6 (the field is vertical in the intermediate frame).

    The Jacobians are the full chain rule of eq. 5.32 (``∂z/∂a`` not yet projected on the tangent plane).
    """
    conj = np.diag([1.0, -1.0, -1.0, -1.0])
    q_acc, d = acc_quaternion(a)
    l = quat.rotate(quat.conjugate(q_acc), m)                       # eq. 5.12
    gamma = l[0] ** 2 + l[1] ** 2
    if gamma < GAMMA_MIN:  # field (nearly) vertical: no heading
        return None, None, None, float(gamma)
    q_mag = mag_quaternion(l)                                       # eq. 5.13
    p = quat.multiply(q_acc, q_mag)                                 # eq. 5.25
    dp_dpsi = 0.5 * quat.multiply(p, [0.0, 0.0, 0.0, 1.0])
    dpsi_dl = np.array([-l[1], l[0], 0.0]) / gamma
    # ∂l/∂q_acc (3×4): 2 Vec(q_acc* ⊗ m ⊗ e_i)
    qm_ = quat.multiply(quat.conjugate(q_acc), np.concatenate(([0.0], m)))
    dl_dq = np.stack([2.0 * quat.multiply(qm_, e)[1:] for e in np.eye(4)], axis=1)
    dp_da = _right_matrix(q_mag) @ d + np.outer(dp_dpsi, dpsi_dl @ dl_dq @ d)
    dp_dm = np.outer(dp_dpsi, dpsi_dl @ quat.to_matrix(q_acc).T)  # ∂l/∂m = R(q_acc)ᵀ
    return conj @ p, conj @ dp_da, conj @ dp_dm, float(gamma)


def _reference_step(x: FloatArray, p_cov: FloatArray, gyr: FloatArray, acc: FloatArray | None,
                    mag: FloatArray | None, dt_s: float, gyr_var: float, acc_var: float,
                    mag_var: float, gate: float) -> tuple[FloatArray, FloatArray]:
    """Readable numpy form of one sample (same maths as the kernel)."""
    phi = np.eye(4) + 0.5 * dt_s * omega_matrix(gyr)                        # eq. 5.33
    q_noise = (0.5 * dt_s) ** 2 * gyr_var * (np.eye(4) - np.outer(x, x))    # eq. 5.34
    p_pred = phi @ p_cov @ phi.T + q_noise
    p_pred = 0.5 * (p_pred + p_pred.T)
    x_pred = phi @ x
    x_pred /= np.linalg.norm(x_pred)
    if acc is None:
        return x_pred, p_pred
    a = acc / np.linalg.norm(acc)
    sa = acc_var / (acc @ acc)                                              # eq. 5.28
    z = None
    if mag is not None:
        z, jac_a, jac_m, gamma = aqua_reference(a, mag / np.linalg.norm(mag))
        sm = mag_var                                      # eq. 5.29 on the unit field (module docstring)
    if z is None:  # 6D: heading of the prediction through the virtual field
        m_virtual = quat.rotate(quat.conjugate(x_pred), _NORTH_ENU)
        z, jac_a, jac_m, gamma = aqua_reference(a, m_virtual)
        sm = VIRTUAL_HEADING_STD_RAD**2
        if z is None:  # measured "up" 90° from the predicted one, along predicted north
            return x_pred, p_pred
    if z @ x_pred < 0.0:                                                    # double cover
        z = -z
    tangent = np.eye(3) - np.outer(a, a)
    r_meas = sa * jac_a @ tangent @ jac_a.T + sm * jac_m @ jac_m.T + 0.25 * sa * np.outer(z, z)
    innovation = z - x_pred
    d2 = innovation @ np.linalg.solve(p_pred + r_meas, innovation)
    if gate > 0.0 and d2 > gate:                                            # innovation gate
        r_meas = r_meas * (d2 / gate)
    gain = np.linalg.solve(p_pred + r_meas, p_pred).T                       # eq. 5.22, H = I
    x_new = x_pred + gain @ innovation                                      # eq. 5.23
    p_new = (np.eye(4) - gain) @ p_pred                                     # eq. 5.24
    return x_new / np.linalg.norm(x_new), 0.5 * (p_new + p_new.T)


class ValentiKF(OrientationMethod):
    """Valenti et al. (2016) linear Kalman filter with AQUA measurements (6D and 9D).

    State ``(20,)``: ``0:4`` q_earth_sensor, ``4:20`` covariance P (4×4 row-major).
    """

    name = "valenti_kf"
    params_type = ValentiKFParams
    state_size = STATE_SIZE
    uses_acc_lowpass = True

    def _variances(self, fs_hz: float) -> tuple[float, float, float]:
        p = self.params
        return (float(p.gyr_noise_rad_s_sqrt_hz) ** 2 * fs_hz, float(p.acc_noise_m_s2_sqrt_hz) ** 2 * fs_hz,
                float(p.mag_noise_rel_sqrt_hz) ** 2 * fs_hz)

    def _gate(self, fs_hz: float) -> float:
        """The kernel's threshold on the per-sample d²: ``innovation_gate · f_ref / f_s``."""
        return float(self.params.innovation_gate) * GATE_REFERENCE_HZ / fs_hz

    def _state_from_quaternion(self, q: FloatArray, data: ImuInput) -> FloatArray:
        state = np.zeros(STATE_SIZE)
        state[:4] = q
        state[4:20] = ((0.5 * float(self.params.initial_std_rad)) ** 2 * np.eye(4)).ravel()
        return state

    def _state_from_alignment(self, alignment: Alignment, data: ImuInput) -> FloatArray:
        """An aligned start is trusted (base module docstring): P₀ from ``ALIGNED_STD_RAD``, not ``initial_std_rad``."""
        state = self._state_from_quaternion(alignment.q, data)
        std = min(float(self.params.initial_std_rad), ALIGNED_STD_RAD)
        state[4:20] = ((0.5 * std) ** 2 * np.eye(4)).ravel()
        return state

    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        state0 = np.asarray(state0, dtype=np.float64)
        return valenti_kf_batch(data.acc, data.gyr, data.mag_array, data.acc_ok, data.mag_ok, data.dt_s,
                                *self._variances(data.fs_hz), self._gate(data.fs_hz), state0)

    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        gyr_var, acc_var, mag_var = self._variances(data.fs_hz)
        gate = self._gate(data.fs_hz)
        x = np.array(state0[:4], dtype=np.float64)
        p_cov = np.array(state0[4:20], dtype=np.float64).reshape(4, 4)
        out = np.empty((data.n, 4))
        for k in range(data.n):
            acc = data.acc[k] if data.acc_ok[k] else None
            mag = data.mag[k] if data.mag_ok[k] else None
            x, p_cov = _reference_step(x, p_cov, data.gyr[k], acc, mag, data.dt_s, gyr_var, acc_var, mag_var,
                                       gate)
            out[k] = x
        state = np.array(state0, dtype=np.float64)
        state[:20] = np.concatenate([x, p_cov.ravel()])
        return out, state
