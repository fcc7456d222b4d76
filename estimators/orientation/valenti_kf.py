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
standard deviation of 2 rad (``_VIRTUAL_HEADING_STD_RAD``), which keeps :math:`S` well conditioned.
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

.. math:: \tau_{tilt} \approx \frac{N_a}{g\,N_g},\qquad \tau_{heading} \approx \frac{N_m}{B_h\,N_g}

do not depend on the sampling rate.  The defaults (:math:`N_g = 0.003` rad/s/√Hz,
:math:`N_a = 0.045` m/s²/√Hz, :math:`N_m = 0.3` µT/√Hz) give :math:`\tau_{tilt} \approx 1.5` s and, for a
20 µT horizontal field, :math:`\tau_{heading} \approx 5` s: tuning values for body-worn sensors that lump
linear acceleration, gyroscope bias and magnetic disturbances into the noise, not datasheet values
(a MetaMotionR's BMI160 gyroscope has about 1.2e-4 rad/s/√Hz).  The magnetometer must be in µT.

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

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from estimators import quaternion as quat
from estimators.orientation.base import FloatArray, ImuInput, OrientationMethod, check_parameter

STATE_SIZE = 20
"""State layout: ``0:4`` q_earth_sensor; ``4:20`` the covariance P (4×4, row-major)."""

GATE_REFERENCE_HZ = 100.0
"""Rate at which ``innovation_gate`` is the plain χ² threshold (see the module docstring)."""

_VIRTUAL_HEADING_STD_RAD = 2.0
_GAMMA_MIN = 1e-6
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
    mag_noise_ut_sqrt_hz
        Magnetometer noise density :math:`N_m` (µT/√Hz) of eq. 5.29, > 0; lumps magnetic disturbances
        in.  Default 0.3 (heading time constant ≈ :math:`N_m/(B_h N_g)` = 5 s for :math:`B_h` = 20 µT).
    initial_std_rad
        Standard deviation (rad) of the initial orientation error; :math:`P_0 = (\\sigma_0/2)^2 I_4`.
        > 0.  Default 0.5 (the first corrections then nearly replace a wrong start by the measurement).
    innovation_gate
        Threshold :math:`g` on the normalised innovation squared at 100 Hz (dimensionless, ≥ 0); above
        it :math:`R` is inflated (deviation 5 in the module docstring).  0 gives the paper's plain
        update.  Default 3.
    """

    gyr_noise_rad_s_sqrt_hz: float = 0.003
    acc_noise_m_s2_sqrt_hz: float = 0.045
    mag_noise_ut_sqrt_hz: float = 0.3
    initial_std_rad: float = 0.5
    innovation_gate: float = 3.0

    def __post_init__(self) -> None:
        check_parameter("innovation_gate", self.innovation_gate,
                        hint="0 = the paper's plain update; typically 1–20")
        for name, unit, typical in (
            ("gyr_noise_rad_s_sqrt_hz", "rad/s/√Hz", "1e-4–0.01"),
            ("acc_noise_m_s2_sqrt_hz", "m/s²/√Hz", "0.002–0.5"),
            ("mag_noise_ut_sqrt_hz", "µT/√Hz", "0.05–2"),
            ("initial_std_rad", "rad", "0.01–3"),
        ):
            check_parameter(name, getattr(self, name), unit=unit, low_open=True, hint=f"typically {typical}")


# --------------------------------------------------------------------------------------- kernel
@njit(cache=True)
def _predict(st, gx, gy, gz, dt_s, gyr_var, xm, pm, phi, tmp):
    """Eqs. 5.33–5.34: ``xm = normalise(Φ x)``, ``pm = Φ P Φᵀ + Q`` (upper triangle mirrored)."""
    h = 0.5 * dt_s
    hx = h * gx
    hy = h * gy
    hz = h * gz
    phi[0] = 1.0
    phi[1] = -hx
    phi[2] = -hy
    phi[3] = -hz
    phi[4] = hx
    phi[5] = 1.0
    phi[6] = hz
    phi[7] = -hy
    phi[8] = hy
    phi[9] = -hz
    phi[10] = 1.0
    phi[11] = hx
    phi[12] = hz
    phi[13] = hy
    phi[14] = -hx
    phi[15] = 1.0
    # tmp = Φ P
    for i in range(4):
        for j in range(4):
            tmp[4 * i + j] = (phi[4 * i] * st[4 + j] + phi[4 * i + 1] * st[8 + j]
                              + phi[4 * i + 2] * st[12 + j] + phi[4 * i + 3] * st[16 + j])
    c = h * h * gyr_var
    for i in range(4):
        for j in range(i, 4):
            v = (tmp[4 * i] * phi[4 * j] + tmp[4 * i + 1] * phi[4 * j + 1]
                 + tmp[4 * i + 2] * phi[4 * j + 2] + tmp[4 * i + 3] * phi[4 * j + 3])
            v -= c * st[i] * st[j]
            if i == j:
                v += c
            pm[4 * i + j] = v
            pm[4 * j + i] = v
    n2 = 0.0
    for i in range(4):
        v = phi[4 * i] * st[0] + phi[4 * i + 1] * st[1] + phi[4 * i + 2] * st[2] + phi[4 * i + 3] * st[3]
        xm[i] = v
        n2 += v * v
    inv = 1.0 / math.sqrt(n2)
    for i in range(4):
        xm[i] *= inv


@njit(cache=True)
def _aqua(ax, ay, az, mx, my, mz, virtual, xm, z, jt):
    """AQUA measurement ``z`` (q_earth_sensor, sign matched to ``xm``) and its tangent Jacobians.

    ``a`` and ``m`` are unit vectors; ``virtual`` replaces ``m`` by the predicted north axis.
    Fills ``jt`` (4×3 row-major, ∂z/∂a projected on the tangent plane of a) and returns
    ``(gamma, h0, h1, h2, h3)`` with ``h`` = ∂z/∂ψ; ``gamma < 0`` when the field is unusable.
    """
    # eq. 5.11: q_acc (intermediate → sensor) and D = ∂q_acc/∂a, columns (ax, ay, az)
    if az >= 0.0:
        s = math.sqrt(2.0 * (az + 1.0))
        w = 0.5 * s
        x = -ay / s
        y = ax / s
        zz = 0.0
        s3 = s * s * s
        d00 = 0.0
        d01 = 0.0
        d02 = 0.5 / s
        d10 = 0.0
        d11 = -1.0 / s
        d12 = ay / s3
        d20 = 1.0 / s
        d21 = 0.0
        d22 = -ax / s3
        d30 = 0.0
        d31 = 0.0
        d32 = 0.0
    else:
        t = math.sqrt(2.0 * (1.0 - az))
        w = -ay / t
        x = 0.5 * t
        y = 0.0
        zz = ax / t
        t3 = t * t * t
        d00 = 0.0
        d01 = -1.0 / t
        d02 = -ay / t3
        d10 = 0.0
        d11 = 0.0
        d12 = -0.5 / t
        d20 = 0.0
        d21 = 0.0
        d22 = 0.0
        d30 = 1.0 / t
        d31 = 0.0
        d32 = ax / t3
    if virtual:
        # predicted north axis in sensor coordinates: second row of R(xm)
        qw = xm[0]
        qx = xm[1]
        qy = xm[2]
        qz = xm[3]
        mx = 2.0 * (qx * qy + qw * qz)
        my = 1.0 - 2.0 * (qx * qx + qz * qz)
        mz = 2.0 * (qy * qz - qw * qx)
    # u = q_acc* ⊗ (0, m);  l = Vec(u ⊗ q_acc)  (eq. 5.12)
    u0 = x * mx + y * my + zz * mz
    u1 = w * mx - (y * mz - zz * my)
    u2 = w * my - (zz * mx - x * mz)
    u3 = w * mz - (x * my - y * mx)
    lx = u0 * x + w * u1 + (u2 * zz - u3 * y)
    ly = u0 * y + w * u2 + (u3 * x - u1 * zz)
    gamma = lx * lx + ly * ly
    if gamma < _GAMMA_MIN:
        return -1.0, 0.0, 0.0, 0.0, 0.0
    # eq. 5.13 with l' = (ly, -lx): ENU north on +y
    g = math.sqrt(gamma)
    if ly >= 0.0:
        b = gamma + ly * g
        c = math.sqrt(b / (2.0 * gamma))
        sn = -lx / math.sqrt(2.0 * b)
    else:
        b = gamma - ly * g
        sn = math.sqrt(b / (2.0 * gamma))
        c = -lx / math.sqrt(2.0 * b)
    # p = q_acc ⊗ q_mag (eq. 5.25)
    p0 = c * w - sn * zz
    p1 = c * x + sn * y
    p2 = c * y - sn * x
    p3 = c * zz + sn * w
    # h = ½ p ⊗ k = ∂p/∂ψ;  d = ∂ψ/∂l
    h0 = -0.5 * p3
    h1 = 0.5 * p2
    h2 = -0.5 * p1
    h3 = 0.5 * p0
    dx = -ly / gamma
    dy = lx / gamma
    # columns of ∂p/∂a: R⊗(q_mag) D_j + h ∂ψ/∂a_j,  ∂ψ/∂a_j = d · 2 Vec(u ⊗ D_j)
    for j in range(3):
        if j == 0:
            e0 = d00
            e1 = d10
            e2 = d20
            e3 = d30
        elif j == 1:
            e0 = d01
            e1 = d11
            e2 = d21
            e3 = d31
        else:
            e0 = d02
            e1 = d12
            e2 = d22
            e3 = d32
        vx = u0 * e1 + e0 * u1 + (u2 * e3 - u3 * e2)
        vy = u0 * e2 + e0 * u2 + (u3 * e1 - u1 * e3)
        dpsi = 2.0 * (dx * vx + dy * vy)
        jt[j] = c * e0 - sn * e3 + h0 * dpsi
        jt[3 + j] = c * e1 + sn * e2 + h1 * dpsi
        jt[6 + j] = c * e2 - sn * e1 + h2 * dpsi
        jt[9 + j] = c * e3 + sn * e0 + h3 * dpsi
    # project on the tangent plane of a, and conjugate: z = p*, rows 1..3 change sign
    for i in range(4):
        r = jt[3 * i] * ax + jt[3 * i + 1] * ay + jt[3 * i + 2] * az
        sg = 1.0 if i == 0 else -1.0
        jt[3 * i] = sg * (jt[3 * i] - r * ax)
        jt[3 * i + 1] = sg * (jt[3 * i + 1] - r * ay)
        jt[3 * i + 2] = sg * (jt[3 * i + 2] - r * az)
    z[0] = p0
    z[1] = -p1
    z[2] = -p2
    z[3] = -p3
    # double cover: same hemisphere as the prediction
    if z[0] * xm[0] + z[1] * xm[1] + z[2] * xm[2] + z[3] * xm[3] < 0.0:
        for i in range(4):
            z[i] = -z[i]
    return gamma, h0, -h1, -h2, -h3


@njit(cache=True)
def _factor_solve(s, v, xm, pm, z, r, r_scale):
    """Cholesky of S = P⁻ + r_scale·R into ``s`` (lower); ``v`` = S⁻¹[z − x⁻ | P⁻] (5 columns of 4)."""
    for i in range(16):
        s[i] = pm[i] + r_scale * r[i]
    for j in range(4):
        t = s[5 * j]
        for k in range(j):
            t -= s[4 * j + k] * s[4 * j + k]
        ljj = math.sqrt(t)
        s[5 * j] = ljj
        for i in range(j + 1, 4):
            t = s[4 * i + j]
            for k in range(j):
                t -= s[4 * i + k] * s[4 * j + k]
            s[4 * i + j] = t / ljj
    for col in range(5):
        for i in range(4):
            b = z[i] - xm[i] if col == 0 else pm[4 * i + col - 1]
            for k in range(i):
                b -= s[4 * i + k] * v[4 * col + k]
            v[4 * col + i] = b / s[5 * i]
        for i in range(3, -1, -1):
            b = v[4 * col + i]
            for k in range(i + 1, 4):
                b -= s[4 * k + i] * v[4 * col + k]
            v[4 * col + i] = b / s[5 * i]


@njit(cache=True)
def _update(st, xm, pm, z, r, s, v, gate):
    """Eqs. 5.22–5.24 with H = I: S = P⁻ + R (Cholesky), x = x⁻ + P⁻S⁻¹(z − x⁻), P = P⁻ − P⁻S⁻¹P⁻.

    Innovation gate (deviation 5): when ``d² = νᵀS⁻¹ν > gate > 0``, R is scaled by ``d²/gate``.
    """
    _factor_solve(s, v, xm, pm, z, r, 1.0)
    if gate > 0.0:
        d2 = 0.0
        for i in range(4):
            d2 += (z[i] - xm[i]) * v[i]
        if d2 > gate:
            _factor_solve(s, v, xm, pm, z, r, d2 / gate)
    n2 = 0.0
    for i in range(4):
        val = xm[i] + pm[4 * i] * v[0] + pm[4 * i + 1] * v[1] + pm[4 * i + 2] * v[2] + pm[4 * i + 3] * v[3]
        st[i] = val
        n2 += val * val
    inv = 1.0 / math.sqrt(n2)
    for i in range(4):
        st[i] *= inv
    # P = P⁻ − P⁻ W, W = S⁻¹P⁻ (column j of W is v[4(j+1):4(j+2)])
    for i in range(4):
        for j in range(i, 4):
            val = pm[4 * i + j] - (pm[4 * i] * v[4 * (j + 1)] + pm[4 * i + 1] * v[4 * (j + 1) + 1]
                                   + pm[4 * i + 2] * v[4 * (j + 1) + 2] + pm[4 * i + 3] * v[4 * (j + 1) + 3])
            st[4 + 4 * i + j] = val
            st[4 + 4 * j + i] = val


@njit(cache=True)
def _measure(ax, ay, az, mx, my, mz, use_mag, acc_var, mag_var, xm, z, jt, r):
    """AQUA measurement ``z`` and its covariance ``r`` (4×4); False when no measurement can be formed."""
    na2 = ax * ax + ay * ay + az * az
    na = math.sqrt(na2)
    ax /= na
    ay /= na
    az /= na
    sa = acc_var / na2
    gamma = -1.0
    sm = 0.0
    h0 = 0.0
    h1 = 0.0
    h2 = 0.0
    h3 = 0.0
    if use_mag:
        nm2 = mx * mx + my * my + mz * mz
        nm = math.sqrt(nm2)
        sm = mag_var / nm2
        gamma, h0, h1, h2, h3 = _aqua(ax, ay, az, mx / nm, my / nm, mz / nm, False, xm, z, jt)
    if gamma < 0.0:
        sm = _VIRTUAL_HEADING_STD_RAD * _VIRTUAL_HEADING_STD_RAD
        gamma, h0, h1, h2, h3 = _aqua(ax, ay, az, 0.0, 0.0, 0.0, True, xm, z, jt)
        if gamma < 0.0:  # measured "up" 90° from the predicted one, along predicted north: no heading
            return False
    # R = σa² Jt Jtᵀ + σm²/Γ h hᵀ + σa²/4 z zᵀ  (eqs. 5.30, 5.32; deviation 2)
    sh = sm / gamma
    sz = 0.25 * sa
    for i in range(4):
        hi = h0 if i == 0 else (h1 if i == 1 else (h2 if i == 2 else h3))
        for j in range(i, 4):
            hj = h0 if j == 0 else (h1 if j == 1 else (h2 if j == 2 else h3))
            val = (sa * (jt[3 * i] * jt[3 * j] + jt[3 * i + 1] * jt[3 * j + 1] + jt[3 * i + 2] * jt[3 * j + 2])
                   + sh * hi * hj + sz * z[i] * z[j])
            r[4 * i + j] = val
            r[4 * j + i] = val
    return True


@njit(cache=True)
def _valenti_kf_step(st, gx, gy, gz, ax, ay, az, mx, my, mz, use_acc, use_mag,
                     dt_s, gyr_var, acc_var, mag_var, gate, work):
    """One sample in place on ``st`` (layout: :data:`STATE_SIZE`); ``work`` is scratch (104 floats)."""
    xm = work[0:4]
    pm = work[4:20]
    phi = work[20:36]
    tmp = work[36:52]
    z = work[52:56]
    jt = work[56:68]
    r = work[68:84]
    v = work[84:104]
    _predict(st, gx, gy, gz, dt_s, gyr_var, xm, pm, phi, tmp)
    if use_acc and _measure(ax, ay, az, mx, my, mz, use_mag, acc_var, mag_var, xm, z, jt, r):
        _update(st, xm, pm, z, r, tmp, v, gate)
    else:  # no accelerometer: prediction only
        for i in range(4):
            st[i] = xm[i]
        for i in range(16):
            st[4 + i] = pm[i]


@njit(cache=True)
def _valenti_kf_batch(acc, gyr, mag, acc_ok, mag_ok, use_mag, dt_s, gyr_var, acc_var, mag_var, gate, state0):
    """Run :func:`_valenti_kf_step` over ``(N, 3)`` inputs; ``mag`` is ignored when ``use_mag`` is false.

    Variances are per sample (``N² f_s``).  Returns ``q (N, 4)`` and the final state (a copy).
    """
    n = acc.shape[0]
    out = np.empty((n, 4))
    st = state0.copy()
    work = np.empty(104)
    for k in range(n):
        if use_mag:
            mx = mag[k, 0]
            my = mag[k, 1]
            mz = mag[k, 2]
            mk = mag_ok[k]
        else:
            mx = 0.0
            my = 0.0
            mz = 0.0
            mk = False
        _valenti_kf_step(st, gyr[k, 0], gyr[k, 1], gyr[k, 2], acc[k, 0], acc[k, 1], acc[k, 2],
                         mx, my, mz, acc_ok[k], mk, dt_s, gyr_var, acc_var, mag_var, gate, work)
        out[k, 0] = st[0]
        out[k, 1] = st[1]
        out[k, 2] = st[2]
        out[k, 3] = st[3]
    return out, st


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
    if gamma < _GAMMA_MIN:  # field (nearly) vertical: no heading
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
        sm = mag_var / (mag @ mag)                                          # eq. 5.29
    if z is None:  # 6D: heading of the prediction through the virtual field
        m_virtual = quat.rotate(quat.conjugate(x_pred), _NORTH_ENU)
        z, jac_a, jac_m, gamma = aqua_reference(a, m_virtual)
        sm = _VIRTUAL_HEADING_STD_RAD**2
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
    supports_6d = True
    supports_9d = True

    def _variances(self, fs_hz: float) -> tuple[float, float, float]:
        p = self.params
        return (float(p.gyr_noise_rad_s_sqrt_hz) ** 2 * fs_hz, float(p.acc_noise_m_s2_sqrt_hz) ** 2 * fs_hz,
                float(p.mag_noise_ut_sqrt_hz) ** 2 * fs_hz)

    def _gate(self, fs_hz: float) -> float:
        """The kernel's threshold on the per-sample d²: ``innovation_gate · f_ref / f_s``."""
        return float(self.params.innovation_gate) * GATE_REFERENCE_HZ / fs_hz

    def _state_from_quaternion(self, q: FloatArray, data: ImuInput) -> FloatArray:
        state = np.empty(STATE_SIZE)
        state[:4] = q
        state[4:] = ((0.5 * float(self.params.initial_std_rad)) ** 2 * np.eye(4)).ravel()
        return state

    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        state0 = np.asarray(state0, dtype=np.float64)
        if state0.shape != (STATE_SIZE,):
            raise ValueError(f"valenti_kf state must have shape ({STATE_SIZE},), got {state0.shape}")
        use_mag = data.mag is not None
        mag = data.mag if use_mag else data.acc
        return _valenti_kf_batch(data.acc, data.gyr, mag, data.acc_ok, data.mag_ok, use_mag, data.dt_s,
                                 *self._variances(data.fs_hz), self._gate(data.fs_hz), state0)

    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        gyr_var, acc_var, mag_var = self._variances(data.fs_hz)
        gate = self._gate(data.fs_hz)
        x = np.array(state0[:4], dtype=np.float64)
        p_cov = np.array(state0[4:], dtype=np.float64).reshape(4, 4)
        out = np.empty((data.n, 4))
        for k in range(data.n):
            acc = data.acc[k] if data.acc_ok[k] else None
            mag = data.mag[k] if (data.mag is not None and data.mag_ok[k]) else None
            x, p_cov = _reference_step(x, p_cov, data.gyr[k], acc, mag, data.dt_s, gyr_var, acc_var, mag_var,
                                       gate)
            out[k] = x
        state = np.concatenate([x, p_cov.ravel()])
        return out, state
