r"""Guo, Wu, Wang, Qian (2017): MARG orientation with a fast Kalman filter (ChakaMo's clinical default).

S. Guo, J. Wu, Z. Wang, J. Qian, "Novel MARG-sensor orientation estimation algorithm using fast
Kalman filter", *Journal of Sensors* 2017, 8542153.  Equation numbers (5.xx) are those of the
source thesis (seed 004, §5.4.2), which restates the paper.

The filter is a linear Kalman filter whose state *is* the quaternion :math:`q = q_{earth\,sensor}`
(4 entries, covariance :math:`\Sigma_q` 4×4).  The gyroscope drives the process model; the
accelerometer and magnetometer are turned into a *measurement quaternion* in closed form.

Measurement model (5.36–5.41)
-----------------------------
With the normalised specific force :math:`\hat a` and field :math:`\hat m` in sensor coordinates,
the model is :math:`\hat a = C A^E`, :math:`\hat m = C M^E` (5.36), :math:`C = R(q)^T`.  Written with
quaternions, :math:`q\otimes\hat a = A^E\otimes q` is *linear* in :math:`q`:
:math:`q = W_a q` with :math:`W_a = -L(A^E)\,R(\hat a)` (``L``/``R``: the left/right Hamilton product
matrices, :func:`w_matrix`).  :math:`W_a` is symmetric and orthogonal with eigenvalues ±1 (twice
each), so :math:`\tfrac12(W_a+I)` is the projector onto the 2-D set of quaternions consistent with
the accelerometer (5.37); likewise :math:`\tfrac12(W_m+I)` for the magnetometer.  With
:math:`A^E = (0,0,1)` (ENU, z up)

.. math::
    W_a = \begin{bmatrix} a_z & a_y & -a_x & 0\\ a_y & -a_z & 0 & a_x\\
          -a_x & 0 & -a_z & a_y\\ 0 & a_x & a_y & a_z \end{bmatrix},\qquad
    W_m = m_N W_{(0,1,0)}(\hat m) + m_D W_{(0,0,1)}(\hat m),

where :math:`W_{(0,1,0)}(\hat m) = \begin{bmatrix} m_y & -m_z & 0 & m_x\\ -m_z & -m_y & m_x & 0\\
0 & m_x & m_y & m_z\\ m_x & 0 & m_z & -m_y\end{bmatrix}` and :math:`W_{(0,0,1)}(\hat m)` is
:math:`W_a` with :math:`\hat m` in place of :math:`\hat a`.  The reference field
:math:`M^E = (0, m_N, m_D)` is built from the data, :math:`m_D = \hat a\cdot\hat m`,
:math:`m_N = \sqrt{1-m_D^2}` (the paper's dynamic dip), so both equations hold exactly for one
rotation.  The paper's measurement quaternion is the fixed point of
:math:`q = \tfrac14(W_a+I)(W_m+I)\,q` (5.38), the intersection of the two +1 eigenspaces.  In
closed form it is the rotation whose matrix has the rows east :math:`= \hat m\times\hat a/m_N`,
north :math:`=\hat a\times\text{east}`, up :math:`=\hat a` (TRIAD), converted by Shepperd's method,
which has no pole at any attitude (``measurement="triad"``; :func:`measurement_9d` is the readable
version, found as the null vector of :math:`[W_a-I;\ W_m-I]`).

Equivalently, :math:`q_{am} = q_h\otimes q_a`: any accelerometer-consistent quaternion
:math:`q_a`, turned about the vertical by the heading :math:`q_h` that makes the horizontal field
point north.  ChakaMo's default (``measurement="decoupled"``, deviation 2) keeps this structure but
takes :math:`q_a = \tfrac12(W_a+I)q^-_t/\|\cdot\|` (5.37 applied to the prediction: the
accelerometer-consistent quaternion nearest to it) and computes the heading with the *predicted*
tilt: with :math:`l = R(q^-_t)\hat m`, :math:`q_h \propto (l_h + l_y, 0, 0, l_x)`,
:math:`l_h = \sqrt{l_x^2+l_y^2}`.  The measurement's sign is chosen so that
:math:`q_{am}\cdot q^-_t \ge 0` (it must agree with the prediction for the linear update).

Noise of the measurement quaternion, :math:`\Sigma_\nu = J\,\Sigma_{acc,mag}J^T` (5.39–5.41), with
:math:`\Sigma_{acc,mag} = \mathrm{diag}(\sigma_a^2 I_3, \sigma_m^2 I_3)` (5.41).  For the TRIAD
solution a perturbation :math:`\delta\hat a, \delta\hat m` rotates the result by the earth-frame
angle :math:`\delta\theta = (d_y,\ -d_x,\ (n_x - m_D d_x)/m_N)`, :math:`d = R\,\delta\hat a`,
:math:`n = R\,\delta\hat m`, and :math:`\delta q = \tfrac12(0,\delta\theta)\otimes q`.  The chain rule
(5.40) gives :math:`J = \tfrac12\Psi(q)\,\partial\theta/\partial(\hat a,\hat m)` with
:math:`\Psi(q) = [i\otimes q,\ j\otimes q,\ k\otimes q]` (:func:`jacobian`), hence
:math:`\Sigma_\nu = \tfrac14\Psi\,\Sigma_\theta\Psi^T` with

.. math::
    \Sigma_\theta^{triad} = \begin{bmatrix}\sigma_a^2 & 0 & 0\\ 0 & \sigma_a^2 & m_D\sigma_a^2/m_N\\
    0 & m_D\sigma_a^2/m_N & (\sigma_m^2 + m_D^2\sigma_a^2)/m_N^2\end{bmatrix},\qquad
    \Sigma_\theta^{decoupled} = \mathrm{diag}(\sigma_a^2,\ \sigma_a^2,\ \sigma_m^2/l_h^2).

Process model (5.42–5.44)
-------------------------
:math:`q^-_t = \Phi_t q_{t-1}`, :math:`\Phi_t = \cos(\tfrac{|\omega|\Delta t}{2}) I +
\tfrac{\sin(|\omega|\Delta t/2)}{|\omega|}[\Omega\times]`: the exact zero-order-hold solution,
whose first-order truncation is the paper's :math:`I + \tfrac{\Delta t}{2}[\Omega\times]` (5.42).
Process noise :math:`\Sigma_\xi = (\tfrac{\Delta t}{2})^2\,\Xi\,\Sigma_{gyr}\Xi^T` (5.43) with
:math:`\Xi = [q\otimes i,\ q\otimes j,\ q\otimes k]` of :math:`q_{t-1}` (5.44 written for our Hamilton
convention; the thesis' printed Ξ has sign slips; :math:`\Xi\Xi^T = I - qq^T` for a unit :math:`q`).

Kalman update
-------------
:math:`\Sigma^-_t = \Phi\Sigma_{t-1}\Phi^T + \Sigma_\xi`, :math:`G_t = \Sigma^-_t(\Sigma^-_t+\Sigma_\nu)^{-1}`,
:math:`q_t = q^-_t + G_t(q_{am} - q^-_t)`, :math:`\Sigma_t = (I - G_t)\Sigma^-_t`, then
:math:`q_t \leftarrow q_t/\|q_t\|`.  The kernel evaluates the gain with a hand-written Cholesky
factor :math:`LL^T = \Sigma^- + \Sigma_\nu`: :math:`Y = L^{-1}\Sigma^-`,
:math:`q_t = q^-_t + Y^T L^{-1}(q_{am}-q^-_t)`, :math:`\Sigma_t = \Sigma^- - Y^TY` (algebraically the
same; symmetric by construction; no allocation per sample).

Parameters and rate
-------------------
:math:`\sigma_{gyr}` is the standard deviation of one gyroscope sample (rad/s) as in (5.43);
:math:`\sigma_a`, :math:`\sigma_m` are standard deviations of the *normalised* accelerometer and
magnetometer vectors (per axis, i.e. small-angle radians of direction error, body acceleration and
soft disturbances included).  In steady state the tilt time constant is
:math:`\approx\sigma_a/\sigma_{gyr}` s and the heading one :math:`\approx\sigma_m/(l_h\sigma_{gyr})` s,
independent of the sampling rate: one parameter set serves 100 Hz and 286 Hz alike (BROAD
decimated to 95 Hz scores as at 286 Hz).  The thesis ran :math:`\sigma_{acc}=0.001, \sigma_{gyr}=0.3,
\sigma_{mag}=0.4` (seed 004 §7.4, in an implementation that used them as variances).  Our defaults
(:class:`GuoParams`) were chosen once for all trials of BROAD (Laidig et al. 2021, 9D total RMSE,
mean of the undisturbed / disturbed trials here): 1.9° / 3.9°, against 5.4° / 7.4° for BROAD's
published Madgwick; the paper's filter without deviations 2, 7 and 8 scores 18.1° / 15.3°.

Deviations from the paper (and why)
-----------------------------------
1. **Frame.** The paper's references are :math:`A^G=(0,0,1)`, :math:`M^G=(m_N,0,m_D)` in a
   north-based frame; we re-derive :math:`W_m` in ENU with :math:`M^E=(0,m_N,m_D)` (north is y).
   :math:`W_a` is unchanged.  The output is ``q_earth_sensor`` (ChakaMo convention).
2. **Decoupled heading (default).** In the TRIAD solution the heading inherits the accelerometer's
   direction error amplified by :math:`|m_D|/m_N` (≈ 2.5 at a 68° dip); during fast translations
   the specific force is tens of degrees off the vertical and the heading is destroyed (BROAD
   trials 15, 30: 27°, 36°).  Tilting the magnetometer with the predicted attitude instead keeps
   magnetometer and accelerometer errors apart.  ``measurement="triad"`` restores the paper.
3. **Fixed point, not one product.** The paper's symbolic expression applies
   :math:`\tfrac14(W_a+I)(W_m+I)` once to :math:`q_{t-1}`; one application is a contraction towards
   the solution, not the solution, so that "measurement" keeps part of the previous state.
4. **Linearisation point.** :math:`J` is differentiated with respect to the *direction* of the
   vectors (radial changes of a normalised vector change nothing, checked against finite
   differences) and :math:`\Psi` is evaluated at :math:`q^-_t`, not at :math:`q_{am}`: equal to
   first order, but with large innovations the prediction is where the update is linearised.
5. **Norm direction.** :math:`\Sigma_\nu` and :math:`\Sigma_\xi` are singular along :math:`q` (they
   only describe rotations); a free variance (:math:`\tfrac14\cdot 1\,\mathrm{rad}^2` along
   :math:`q^-_t`) is added to :math:`\Sigma_\nu` so that :math:`\Sigma^-+\Sigma_\nu` stays positive
   definite and the measurement says nothing about the norm, which normalisation restores.  (A
   small variance there let the chord :math:`q_{am}-q^-_t` of a large innovation pull hard.)
6. **Exact process model** instead of the first-order :math:`\Phi` (see above).
7. **Robust weights** (not in the paper; each can be switched off with ``math.inf``): the
   accelerometer variance is multiplied by :math:`1 + ((\|a\|-g)/\text{acc\_norm\_tol})^2` and by
   :math:`\max(1, \varepsilon_{tilt}/\text{acc\_innov\_tol})` (a Huber weight: large tilt innovations
   :math:`\varepsilon_{tilt} = \angle(R(q^-)\hat a, e_z)` correct at a bounded rate instead of
   dragging the estimate); the magnetometer variance by
   :math:`1 + (\Delta\|m\|/\|m\|_{ref}/\text{mag\_norm\_tol})^2 + (\Delta l_z/\text{mag\_dip\_tol})^2`
   (field norm and predicted dip against references tracked with ``mag_ref_tau_s``, state 20–21)
   and by :math:`\max(1, |\psi|/\text{mag\_innov\_tol})` with :math:`\psi` the heading innovation.
8. **Gyroscope bias at rest** (not in the paper): after ``rest_min_s`` of
   :math:`|\omega| <` ``rest_gyr_tol_rad_s`` and :math:`|\|a\|-g| <` ``rest_acc_tol_m_s2``, the raw rate
   is low-pass filtered (``bias_tau_s``) into a bias estimate (state 22–24; rest timer 25) that is
   subtracted before the prediction.  BROAD's gyroscopes carry 0.1–0.5 °/s of bias; without it the
   robust weights leave too little correction during long motions.
9. **6D variant** (``mag=None``, or a missing or gravity-parallel magnetometer sample): the
   measurement is :math:`q_a` alone, whose heading is the prediction's; its heading is unobserved:
   :math:`\Sigma_\theta = \mathrm{diag}(\sigma_a^2,\sigma_a^2,1\,\mathrm{rad}^2)`.
10. **Initial state.** The base class aligns :math:`q_0` on the first 0.1 s of accelerometer and
    magnetometer data (TRIAD); :math:`\Sigma_0 = \tfrac14\sigma_0^2 I` (``init_noise_rad``).  Large
    initial errors converge at the bounded rate of deviation 7 (90°: < 2° in 2 s; 170°: in 8 s).
11. **Missing samples**: a missing accelerometer sample skips the correction (prediction only);
    a missing gyroscope sample predicts with zero rate and does not update the bias.

Why ours differs from ``ahrs.filters.FKF`` (0.4.0): it uses the one-step product (3), normalises the
measurement and then multiplies it by 0.25 (the state's norm collapses to 0.25), passes the σ's as
variances, works in NED, uses the first-order process model and writes Ξ for the other product
order (harmless only because its gyroscope noise is isotropic); it is ≈ 70 µs/sample in numpy,
this kernel ≈ 0.2 µs/sample.

State vector (``STATE_SIZE`` = 26): ``[q (4), Σ (16, row-major), ‖m‖_ref (field units),
l_z,ref (sine of the dip, negative in the north), gyroscope bias (3, rad/s), rest time (s)]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from estimators.orientation.base import ImuInput, OrientationMethod, check_parameter

FloatArray = np.ndarray

G_M_S2 = 9.81
_FREE_VAR_RAD2 = 1.0           # variance of unobserved directions (6D heading, quaternion norm)
_MIN_FIELD_COS = 1e-3          # |m × a| below this: field parallel to gravity, heading undefined
STATE_SIZE = 26


@dataclass(frozen=True)
class GuoParams:
    """Parameters of the Guo fast Kalman filter (defaults: one set for body-worn sensors, any rate).

    gyr_noise_rad_s: standard deviation of one gyroscope sample, rad/s (5.43); default 0.02.
        Only the ratios to the two next ones matter for the estimate: tilt time constant
        ≈ ``acc_noise_rad / gyr_noise_rad_s`` (6 s), heading ≈ ``mag_noise_rad / (cos(dip) ·
        gyr_noise_rad_s)`` (≈ 20 s at a 68° dip), both before the robust weights.
    acc_noise_rad: standard deviation of each component of the normalised accelerometer vector,
        ≈ rad of tilt per sample, body acceleration included (5.41); default 0.12.
    mag_noise_rad: the same for the normalised magnetometer vector (5.41); default 0.15.
    init_noise_rad: standard deviation of the initial orientation, rad (Σ₀ = ¼σ₀² I); default 0.5.
    acc_norm_tol_m_s2: |‖a‖ − g| (m/s²) at which the accelerometer variance is doubled (factor
        1 + (|‖a‖−g|/tol)²); default 1.0.
    acc_innov_tol_rad: tilt innovation (rad) beyond which the accelerometer variance grows in
        proportion (Huber weight: bounded correction rate); default 0.03.
    mag_norm_tol: relative deviation of ‖m‖ from its tracked reference at which the magnetometer
        variance is doubled; default ``inf`` (off: it did not help on BROAD, the dip test does).
    mag_dip_tol: deviation of the field's vertical component l_z = (R(q⁻) m̂)_z (sine of the dip)
        from its tracked reference at which the magnetometer variance is doubled; default 0.1.
    mag_innov_tol_rad: heading innovation (rad) beyond which the magnetometer variance grows in
        proportion (Huber weight); default 0.05.
    mag_ref_tau_s: time constant, s, with which the norm and dip references follow the data; 10.
    bias_tau_s: time constant, s, of the gyroscope bias estimate at rest; 3.0 (``inf``: no bias).
    rest_gyr_tol_rad_s, rest_acc_tol_m_s2, rest_min_s: rest means ‖ω‖ < 0.05 rad/s and
        |‖a‖ − g| < 0.5 m/s² for at least 1.0 s.
    measurement: ``"decoupled"`` (default; heading from the predicted tilt) or ``"triad"`` (the
        paper's fixed point); see deviation 2 of the module docstring.

    Every tolerance accepts ``math.inf`` to switch its test off.
    """

    gyr_noise_rad_s: float = 0.02
    acc_noise_rad: float = 0.12
    mag_noise_rad: float = 0.15
    init_noise_rad: float = 0.5
    acc_norm_tol_m_s2: float = 1.0
    acc_innov_tol_rad: float = 0.03
    mag_norm_tol: float = math.inf
    mag_dip_tol: float = 0.1
    mag_innov_tol_rad: float = 0.05
    mag_ref_tau_s: float = 10.0
    bias_tau_s: float = 3.0
    rest_gyr_tol_rad_s: float = 0.05
    rest_acc_tol_m_s2: float = 0.5
    rest_min_s: float = 1.0
    measurement: str = "decoupled"

    def __post_init__(self) -> None:
        if self.measurement not in ("decoupled", "triad"):
            raise ValueError(f"measurement must be 'decoupled' or 'triad', got {self.measurement!r}")
        check_parameter("rest_min_s", self.rest_min_s, unit="s")
        for name in ("gyr_noise_rad_s", "acc_noise_rad", "mag_noise_rad", "init_noise_rad", "mag_ref_tau_s"):
            check_parameter(name, getattr(self, name), low_open=True)
        for name in ("acc_norm_tol_m_s2", "acc_innov_tol_rad", "mag_norm_tol", "mag_dip_tol", "mag_innov_tol_rad",
                     "bias_tau_s", "rest_gyr_tol_rad_s", "rest_acc_tol_m_s2"):
            check_parameter(name, getattr(self, name), low_open=True, allow_inf=True, hint="math.inf disables it")


# ====================================================================== compiled kernel
@njit(cache=True)
def _guo_step(state, ax, ay, az, gx, gy, gz, mx, my, mz, acc_ok, gyr_ok, mag_ok, use_mag, dt_s,
              var_gyr, var_acc, var_mag, inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2,
              mag_innov_tol, ref_alpha, bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, w):
    """One sample in place on ``state`` (STATE_SIZE,); ``w`` is scratch (≥ 80)."""
    q0, q1, q2, q3 = state[0], state[1], state[2], state[3]
    # ---- gyroscope bias at rest (deviation 8)
    if bias_alpha > 0.0 and gyr_ok:
        gn_raw = math.sqrt(gx * gx + gy * gy + gz * gz)
        at_rest = False
        if acc_ok and gn_raw < rest_gyr:
            at_rest = abs(math.sqrt(ax * ax + ay * ay + az * az) - G_M_S2) < rest_acc
        if at_rest:
            state[25] += dt_s
            if state[25] >= rest_min_s:
                state[22] += bias_alpha * (gx - state[22])
                state[23] += bias_alpha * (gy - state[23])
                state[24] += bias_alpha * (gz - state[24])
        else:
            state[25] = 0.0
        gx -= state[22]
        gy -= state[23]
        gz -= state[24]
    # ---- prediction (5.42): q⁻ = Φ q, Φ = c I + s [Ω×]
    wn = math.sqrt(gx * gx + gy * gy + gz * gz)
    half = 0.5 * wn * dt_s
    if half > 1e-8:
        c = math.cos(half)
        s = math.sin(half) / wn
    else:
        c = 1.0 - 0.5 * half * half
        s = 0.5 * dt_s
    d1 = s * gx
    d2 = s * gy
    d3 = s * gz
    F = w[0:16]
    F[0] = c; F[1] = -d1; F[2] = -d2; F[3] = -d3
    F[4] = d1; F[5] = c; F[6] = d3; F[7] = -d2
    F[8] = d2; F[9] = -d3; F[10] = c; F[11] = d1
    F[12] = d3; F[13] = d2; F[14] = -d1; F[15] = c
    p0 = c * q0 - d1 * q1 - d2 * q2 - d3 * q3
    p1 = d1 * q0 + c * q1 + d3 * q2 - d2 * q3
    p2 = d2 * q0 - d3 * q1 + c * q2 + d1 * q3
    p3 = d3 * q0 + d2 * q1 - d1 * q2 + c * q3
    # ---- Σ⁻ = Φ Σ Φᵀ + (Δt/2)² σg² (I − q qᵀ)   (5.43, 5.44)
    A = w[16:32]  # Φ Σ
    for i in range(4):
        for j in range(4):
            v = 0.0
            for k in range(4):
                v += F[4 * i + k] * state[4 + 4 * k + j]
            A[4 * i + j] = v
    Sm = w[32:48]  # Σ⁻ (state[0:4] still holds q_{t-1})
    qn = 0.25 * dt_s * dt_s * var_gyr
    for i in range(4):
        for j in range(i, 4):
            v = 0.0
            for k in range(4):
                v += A[4 * i + k] * F[4 * j + k]
            v -= qn * state[i] * state[j]
            if i == j:
                v += qn
            Sm[4 * i + j] = v
            Sm[4 * j + i] = v
    if not acc_ok:
        for i in range(16):
            state[4 + i] = Sm[i]
        n = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
        state[0] = p0 / n; state[1] = p1 / n; state[2] = p2 / n; state[3] = p3 / n
        return
    # Ψ̄ = [q, i⊗q, j⊗q, k⊗q] at q = q⁻: earth-frame rotations → quaternion changes
    C = w[48:64]  # row i: (q_i, (i⊗q)_i, (j⊗q)_i, (k⊗q)_i)
    C[0] = p0; C[1] = -p1; C[2] = -p2; C[3] = -p3
    C[4] = p1; C[5] = p0; C[6] = p3; C[7] = -p2
    C[8] = p2; C[9] = -p3; C[10] = p0; C[11] = p1
    C[12] = p3; C[13] = p2; C[14] = -p1; C[15] = p0
    # ---- measurement quaternion (5.36–5.38)
    an = math.sqrt(ax * ax + ay * ay + az * az)
    ux = ax / an; uy = ay / an; uz = az / an
    # rows of R(q⁻) (earth axes in sensor coordinates) for the robust weights (deviation 7)
    r00 = 1.0 - 2.0 * (p2 * p2 + p3 * p3); r01 = 2.0 * (p1 * p2 - p0 * p3); r02 = 2.0 * (p1 * p3 + p0 * p2)
    r10 = 2.0 * (p1 * p2 + p0 * p3); r11 = 1.0 - 2.0 * (p1 * p1 + p3 * p3); r12 = 2.0 * (p2 * p3 - p0 * p1)
    r20 = 2.0 * (p1 * p3 - p0 * p2); r21 = 2.0 * (p2 * p3 + p0 * p1); r22 = 1.0 - 2.0 * (p1 * p1 + p2 * p2)
    dg = an - G_M_S2
    tilt = math.acos(min(max(r20 * ux + r21 * uy + r22 * uz, -1.0), 1.0))
    va = var_acc * (1.0 + dg * dg * inv_acc_tol2) * max(1.0, tilt / acc_innov_tol)
    # ½(W_a + I) q⁻  (5.37): the accelerometer-consistent quaternion nearest to the prediction
    a0 = 0.5 * (p0 + uz * p0 + uy * p1 - ux * p2)
    a1 = 0.5 * (p1 + uy * p0 - uz * p1 + ux * p3)
    a2 = 0.5 * (p2 - ux * p0 - uz * p2 + uy * p3)
    a3 = 0.5 * (p3 + ux * p1 + uy * p2 + uz * p3)
    nrm = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
    if nrm < 1e-9:  # prediction exactly upside down: no nearest point, skip the correction
        for i in range(16):
            state[4 + i] = Sm[i]
        state[0] = p0; state[1] = p1; state[2] = p2; state[3] = p3
        return
    a0 /= nrm; a1 /= nrm; a2 /= nrm; a3 /= nrm
    m0 = a0; m1 = a1; m2 = a2; m3 = a3
    txx = va; tyy = va; tyz = 0.0; tzz = _FREE_VAR_RAD2
    if use_mag and mag_ok:
        mn = math.sqrt(mx * mx + my * my + mz * mz)
        vx = mx / mn; vy = my / mn; vz = mz / mn
        # field direction in earth coordinates by the prediction
        lx = r00 * vx + r01 * vy + r02 * vz
        ly = r10 * vx + r11 * vy + r12 * vz
        lz = r20 * vx + r21 * vy + r22 * vz
        ex = vy * uz - vz * uy
        ey = vz * ux - vx * uz
        ez = vx * uy - vy * ux
        mN = math.sqrt(ex * ex + ey * ey + ez * ez)
        lh = math.sqrt(lx * lx + ly * ly)
        if (mN if paper_triad else lh) > _MIN_FIELD_COS:
            # disturbance: field norm and dip against tracked references, heading innovation
            if state[20] <= 0.0:
                state[20] = mn
                state[21] = lz
            rel = (mn - state[20]) / state[20]
            ddip = lz - state[21]
            head = abs(math.atan2(lx, ly))
            vm = (var_mag * (1.0 + rel * rel * inv_norm_tol2 + ddip * ddip * inv_dip_tol2)
                  * max(1.0, head / mag_innov_tol))
            state[20] += ref_alpha * (mn - state[20])
            state[21] += ref_alpha * (lz - state[21])
            if paper_triad:
                # fixed point of ¼(W_a+I)(W_m+I): rows of R_earth_sensor are east, north, up (Shepperd)
                mD = ux * vx + uy * vy + uz * vz
                ex /= mN; ey /= mN; ez /= mN
                nx = uy * ez - uz * ey
                ny = uz * ex - ux * ez
                nz = ux * ey - uy * ex
                tr = ex + ny + uz
                if tr >= ex and tr >= ny and tr >= uz:
                    r = 2.0 * math.sqrt(1.0 + tr)
                    m0 = 0.25 * r; m1 = (uy - nz) / r; m2 = (ez - ux) / r; m3 = (nx - ey) / r
                elif ex >= ny and ex >= uz:
                    r = 2.0 * math.sqrt(max(1.0 + ex - ny - uz, 0.0))
                    m0 = (uy - nz) / r; m1 = 0.25 * r; m2 = (ey + nx) / r; m3 = (ez + ux) / r
                elif ny >= uz:
                    r = 2.0 * math.sqrt(max(1.0 - ex + ny - uz, 0.0))
                    m0 = (ez - ux) / r; m1 = (ey + nx) / r; m2 = 0.25 * r; m3 = (nz + uy) / r
                else:
                    r = 2.0 * math.sqrt(max(1.0 - ex - ny + uz, 0.0))
                    m0 = (nx - ey) / r; m1 = (ez + ux) / r; m2 = (nz + uy) / r; m3 = 0.25 * r
                tyz = mD * va / mN
                tzz = (vm + mD * mD * va) / (mN * mN)
            else:
                # heading about the vertical that turns the predicted horizontal field north:
                # q_h ∝ (l_h + l_y, 0, 0, l_x); q_am = q_h ⊗ q_a  (deviation 2)
                h0 = lh + ly
                h3 = lx
                hn = math.sqrt(h0 * h0 + h3 * h3)
                if hn < 1e-12:
                    h0 = 0.0; h3 = 1.0
                else:
                    h0 /= hn; h3 /= hn
                m0 = h0 * a0 - h3 * a3
                m1 = h0 * a1 - h3 * a2
                m2 = h0 * a2 + h3 * a1
                m3 = h0 * a3 + h3 * a0
                tzz = vm / (lh * lh)
    if m0 * p0 + m1 * p1 + m2 * p2 + m3 * p3 < 0.0:
        m0 = -m0; m1 = -m1; m2 = -m2; m3 = -m3
    # ---- Σν = ¼ Ψ̄ diag(free, Σθ) Ψ̄ᵀ  (5.39–5.41)
    S = w[64:80]
    for i in range(4):
        b1 = C[4 * i + 1] * txx
        b2 = C[4 * i + 2] * tyy + C[4 * i + 3] * tyz
        b3 = C[4 * i + 2] * tyz + C[4 * i + 3] * tzz
        b0 = C[4 * i] * _FREE_VAR_RAD2
        for j in range(i, 4):
            v = Sm[4 * i + j] + 0.25 * (b0 * C[4 * j] + b1 * C[4 * j + 1] + b2 * C[4 * j + 2]
                                         + b3 * C[4 * j + 3])
            S[4 * i + j] = v
    # ---- Cholesky S = L Lᵀ (lower, stored in S's lower triangle by rows)
    for i in range(4):
        for j in range(i + 1):
            v = S[4 * j + i]  # upper entry (j, i) == (i, j)
            for k in range(j):
                v -= S[4 * i + k] * S[4 * j + k]
            if i == j:
                S[4 * i + i] = math.sqrt(v)
            else:
                S[4 * i + j] = v / S[4 * j + j]
    # ---- Y = L⁻¹ Σ⁻ (into A), z = L⁻¹ (q_am − q⁻)
    r0 = m0 - p0; r1 = m1 - p1; r2 = m2 - p2; r3 = m3 - p3
    z = w[0:4]  # F is no longer needed
    for i in range(4):
        ri = r0 if i == 0 else (r1 if i == 1 else (r2 if i == 2 else r3))
        for k in range(i):
            ri -= S[4 * i + k] * z[k]
        z[i] = ri / S[4 * i + i]
        for j in range(4):
            v = Sm[4 * i + j]
            for k in range(i):
                v -= S[4 * i + k] * A[4 * k + j]
            A[4 * i + j] = v / S[4 * i + i]
    # ---- q = q⁻ + Yᵀ z ; Σ = Σ⁻ − YᵀY ; normalise
    for j in range(4):
        v = 0.0
        for k in range(4):
            v += A[4 * k + j] * z[k]
        w[4 + j] = v
    p0 += w[4]; p1 += w[5]; p2 += w[6]; p3 += w[7]
    for i in range(4):
        for j in range(i, 4):
            v = Sm[4 * i + j]
            for k in range(4):
                v -= A[4 * k + i] * A[4 * k + j]
            state[4 + 4 * i + j] = v
            state[4 + 4 * j + i] = v
    n = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
    state[0] = p0 / n; state[1] = p1 / n; state[2] = p2 / n; state[3] = p3 / n


@njit(cache=True)
def _guo_batch(acc, gyr, mag, acc_ok, gyr_ok, mag_ok, use_mag, dt_s, var_gyr, var_acc, var_mag,
               inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2, mag_innov_tol, ref_alpha,
               bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, state0):
    n = acc.shape[0]
    state = state0.copy()
    out = np.empty((n, 4))
    work = np.empty(80)
    for k in range(n):
        if use_mag:
            mx = mag[k, 0]; my = mag[k, 1]; mz = mag[k, 2]
        else:
            mx = 0.0; my = 0.0; mz = 0.0
        _guo_step(state, acc[k, 0], acc[k, 1], acc[k, 2], gyr[k, 0], gyr[k, 1], gyr[k, 2], mx, my, mz,
                  acc_ok[k], gyr_ok[k], mag_ok[k], use_mag, dt_s, var_gyr, var_acc, var_mag,
                  inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2, mag_innov_tol, ref_alpha,
                  bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, work)
        out[k, 0] = state[0]; out[k, 1] = state[1]; out[k, 2] = state[2]; out[k, 3] = state[3]
    return out, state


# ====================================================================== readable reference
def _left(p: FloatArray) -> FloatArray:
    """L(p): p ⊗ q = L(p) q."""
    w, x, y, z = p
    return np.array([[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]])


def _right(p: FloatArray) -> FloatArray:
    """R(p): q ⊗ p = R(p) q."""
    w, x, y, z = p
    return np.array([[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]])


def _pure(v: FloatArray) -> FloatArray:
    return np.concatenate([[0.0], v])


def w_matrix(reference: FloatArray, measured: FloatArray) -> FloatArray:
    """:math:`W = -L(r)R(v)`: ``q = W q`` ⇔ ``rotate(q, v) == r`` for unit ``r``, ``v`` (5.37)."""
    return -_left(_pure(reference)) @ _right(_pure(measured))


def omega_matrix(gyr: FloatArray) -> FloatArray:
    """[Ω×] of (5.42): ``q ⊗ (0, ω) = [Ω×] q``."""
    return _right(_pure(gyr))


def xi_matrix(q: FloatArray) -> FloatArray:
    """Ξ of (5.44) in our convention: columns ``q⊗i, q⊗j, q⊗k`` (``q ⊗ (0, ω) = Ξ ω``)."""
    return _left(q)[:, 1:]


def measurement_9d(acc: FloatArray, mag: FloatArray) -> tuple[FloatArray, FloatArray, float, float]:
    """Fixed point of ¼(W_a+I)(W_m+I) (5.38) and its earth-frame Jacobian w.r.t. (â, m̂) (5.40).

    Returns ``(q_am, dθ/d(â, m̂) (3×6), m_D, m_N)``; the sign of ``q_am`` is arbitrary here.  The
    quaternion Jacobian is ``J = jacobian(q, dθ)`` (at ``q_am`` for the paper, at ``q⁻`` in the filter).
    """
    a = acc / np.linalg.norm(acc)
    m = mag / np.linalg.norm(mag)
    m_d = float(a @ m)
    m_n = float(np.linalg.norm(np.cross(m, a)))
    w_a = w_matrix(np.array([0.0, 0.0, 1.0]), a)
    w_m = w_matrix(np.array([0.0, m_n, m_d]), m)
    # the common +1 eigenvector: null space of [W_a − I; W_m − I]
    _, _, vt = np.linalg.svd(np.vstack([w_a - np.eye(4), w_m - np.eye(4)]))
    q = vt[-1]
    rot = _rotation_matrix(q)
    dtheta = np.zeros((3, 6))  # earth-frame rotation per unit change of (â, m̂)
    dtheta[0, :3] = rot[1]
    dtheta[1, :3] = -rot[0]
    dtheta[2, :3] = -m_d / m_n * rot[0]
    dtheta[2, 3:] = rot[0] / m_n
    return q, dtheta, m_d, m_n


def jacobian(q: FloatArray, dtheta: FloatArray) -> FloatArray:
    """J = ½ [i⊗q, j⊗q, k⊗q] dθ: an earth-frame rotation dθ moves ``q`` by ½(0, dθ) ⊗ q."""
    return 0.5 * _right(q)[:, 1:] @ dtheta


def _rotation_matrix(q: FloatArray) -> FloatArray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _reference_step(state: FloatArray, acc, gyr, mag, acc_ok: bool, gyr_ok: bool, mag_ok: bool, dt_s: float,
                    p: GuoParams) -> FloatArray:
    new = state.copy()
    q = state[:4]
    sigma = state[4:20].reshape(4, 4)
    if math.isfinite(p.bias_tau_s) and gyr_ok:  # gyroscope bias at rest (deviation 8)
        at_rest = (acc_ok and np.linalg.norm(gyr) < p.rest_gyr_tol_rad_s
                   and abs(np.linalg.norm(acc) - G_M_S2) < p.rest_acc_tol_m_s2)
        new[25] = new[25] + dt_s if at_rest else 0.0
        if at_rest and new[25] >= p.rest_min_s:
            new[22:25] += min(dt_s / p.bias_tau_s, 1.0) * (gyr - new[22:25])
        gyr = gyr - new[22:25]
    # prediction (5.42) with the exact exponential of [Ω×]
    wn = np.linalg.norm(gyr)
    half = 0.5 * wn * dt_s
    if half > 1e-8:
        phi = np.cos(half) * np.eye(4) + np.sin(half) / wn * omega_matrix(gyr)
    else:
        phi = (1.0 - 0.5 * half**2) * np.eye(4) + 0.5 * dt_s * omega_matrix(gyr)
    q_pred = phi @ q
    xi = xi_matrix(q)
    sigma_xi = (dt_s / 2) ** 2 * xi @ (p.gyr_noise_rad_s**2 * np.eye(3)) @ xi.T  # (5.43)
    sigma_pred = phi @ sigma @ phi.T + sigma_xi
    if not acc_ok:
        new[:4] = q_pred / np.linalg.norm(q_pred)
        new[4:20] = sigma_pred.ravel()
        return new
    rot_pred = _rotation_matrix(q_pred)  # rows: east, north, up in sensor coordinates
    a = acc / np.linalg.norm(acc)
    psi = _right(q_pred)[:, 1:]  # earth-frame rotation → quaternion change, at the prediction
    tilt = np.arccos(np.clip(rot_pred[2] @ a, -1.0, 1.0))  # tilt innovation (deviation 7)
    var_acc = (p.acc_noise_rad**2 * (1.0 + (np.linalg.norm(acc) - G_M_S2) ** 2 / p.acc_norm_tol_m_s2**2)
               * max(1.0, tilt / p.acc_innov_tol_rad))
    # accelerometer-consistent quaternion nearest to the prediction (5.37)
    q_acc = 0.5 * (w_matrix(np.array([0.0, 0.0, 1.0]), a) + np.eye(4)) @ q_pred
    if np.linalg.norm(q_acc) < 1e-9:
        new[:4] = q_pred
        new[4:20] = sigma_pred.ravel()
        return new
    q_acc /= np.linalg.norm(q_acc)
    q_meas = q_acc
    sigma_nu = 0.25 * psi @ np.diag([var_acc, var_acc, _FREE_VAR_RAD2]) @ psi.T  # 6D: heading free
    if mag is not None and mag_ok:
        m_unit = mag / np.linalg.norm(mag)
        l_earth = rot_pred @ m_unit  # field direction in earth by the prediction
        l_h = np.hypot(l_earth[0], l_earth[1])
        paper = p.measurement == "triad"
        if (np.linalg.norm(np.cross(m_unit, a)) if paper else l_h) > _MIN_FIELD_COS:
            m_norm = np.linalg.norm(mag)
            if new[20] <= 0.0:
                new[20], new[21] = m_norm, l_earth[2]
            rel = (m_norm - new[20]) / new[20]
            heading = np.arctan2(l_earth[0], l_earth[1])  # heading innovation
            var_mag = (p.mag_noise_rad**2
                       * (1.0 + (rel / p.mag_norm_tol) ** 2 + ((l_earth[2] - new[21]) / p.mag_dip_tol) ** 2)
                       * max(1.0, abs(heading) / p.mag_innov_tol_rad))
            alpha = min(dt_s / p.mag_ref_tau_s, 1.0)
            new[20] += alpha * (m_norm - new[20])
            new[21] += alpha * (l_earth[2] - new[21])
            if paper:
                q_meas, dtheta, _, _ = measurement_9d(acc, mag)
                jac = jacobian(q_pred, dtheta)  # deviation 4: linearised at the prediction
                sigma_nu = jac @ np.diag([var_acc] * 3 + [var_mag] * 3) @ jac.T  # (5.39), (5.41)
            else:
                q_head = np.array([np.cos(heading / 2), 0.0, 0.0, np.sin(heading / 2)])
                q_meas = _left(q_head) @ q_acc  # q_head ⊗ q_acc
                sigma_nu = 0.25 * psi @ np.diag([var_acc, var_acc, var_mag / l_h**2]) @ psi.T
    if q_meas @ q_pred < 0.0:
        q_meas = -q_meas
    sigma_nu = sigma_nu + 0.25 * _FREE_VAR_RAD2 * np.outer(q_pred, q_pred)  # deviation 5: norm direction
    gain = np.linalg.solve(sigma_pred + sigma_nu, sigma_pred).T  # Σ⁻(Σ⁻+Σν)⁻¹, both symmetric
    q_new = q_pred + gain @ (q_meas - q_pred)
    sigma_new = (np.eye(4) - gain) @ sigma_pred
    new[:4] = q_new / np.linalg.norm(q_new)
    new[4:20] = (0.5 * (sigma_new + sigma_new.T)).ravel()
    return new


# ====================================================================== method class
class Guo(OrientationMethod):
    """Guo et al. (2017) fast Kalman filter; 9D with a magnetometer, 6D without."""

    name = "guo"
    params_type = GuoParams
    supports_6d = True
    supports_9d = True

    def _state_from_quaternion(self, q: FloatArray, data: ImuInput) -> FloatArray:
        state = np.zeros(STATE_SIZE)
        state[:4] = q
        state[4:20] = (0.25 * self.params.init_noise_rad**2 * np.eye(4)).ravel()
        # 20, 21: field norm and m_D references; ≤ 0 means "take the first valid sample"
        return state

    def _kernel_args(self, data: ImuInput) -> tuple:
        p = self.params
        use_mag = data.mag is not None
        mag = data.mag if use_mag else data.acc
        gyr_ok = ~data.flags.gyr_missing
        return (data.acc, data.gyr, mag, data.acc_ok, gyr_ok, data.mag_ok, use_mag, data.dt_s,
                p.gyr_noise_rad_s**2, p.acc_noise_rad**2, p.mag_noise_rad**2,
                p.acc_norm_tol_m_s2**-2, p.acc_innov_tol_rad, p.mag_norm_tol**-2, p.mag_dip_tol**-2,
                p.mag_innov_tol_rad, min(data.dt_s / p.mag_ref_tau_s, 1.0),
                min(data.dt_s / p.bias_tau_s, 1.0), p.rest_gyr_tol_rad_s, p.rest_acc_tol_m_s2, p.rest_min_s,
                p.measurement == "triad")

    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        return _guo_batch(*self._kernel_args(data), np.asarray(state0, dtype=np.float64))

    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        state = np.array(state0, dtype=np.float64)
        out = np.empty((data.n, 4))
        for k in range(data.n):
            mag = None if data.mag is None else data.mag[k]
            state = _reference_step(state, data.acc[k], data.gyr[k], mag, bool(data.acc_ok[k]),
                                    not data.flags.gyr_missing[k], bool(data.mag_ok[k]), data.dt_s, self.params)
            out[k] = state[:4]
        return out, state


__all__ = ["Guo", "GuoParams", "jacobian", "measurement_9d", "w_matrix"]
