r"""Guo, Wu, Wang, Qian (2017): MARG orientation with a fast Kalman filter (a comparator; the default is chakamo).

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
which has no pole at any attitude (``measurement="triad"``, the default; :func:`measurement_9d` is the
readable version, found as the null vector of :math:`[W_a-I;\ W_m-I]`).

Equivalently, :math:`q_{am} = q_h\otimes q_a`: any accelerometer-consistent quaternion
:math:`q_a`, turned about the vertical by the heading :math:`q_h` that makes the horizontal field
point north.  The option ``measurement="decoupled"`` (deviation 2) keeps this structure but
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
same; symmetric by construction; no allocation per sample).  With the gyroscope-bias state of
deviation 12 the same factor also gives the bias rows of the gain.

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
mean of the undisturbed / disturbed trials here): 2.2° / 3.8° (6D 1.4° / 3.0°), against 5.4° / 7.4°
for BROAD's published Madgwick; the paper's filter without deviations 2, 7 and 8 scores 18.1° / 15.3°.
Today (TRIAD measurement, deviations 10 and 14): 2.13° / 3.21° (6D 1.13° / 2.63°); chosen on one half of the
trials and scored on the other (``python -m benchmarks.broad``): 2.71° / 4.08° (A→B), 1.45° / 1.82° (B→A).
They also keep a simulated knee step-up with a BMI160-like constant gyroscope bias of 1.3–2.1 °/s at
≤ 1.9° RMS (thigh 0.5–1.5°, shank 0.4–1.9°, seeds 70–75 of ``ImuSpec.random``; 35–42° without deviation 12).

Deviations from the paper (and why)
-----------------------------------
1. **Frame.** The paper's references are :math:`A^G=(0,0,1)`, :math:`M^G=(m_N,0,m_D)` in a
   north-based frame; we re-derive :math:`W_m` in ENU with :math:`M^E=(0,m_N,m_D)` (north is y).
   :math:`W_a` is unchanged.  The output is ``q_earth_sensor`` (ChakaMo convention).
2. **Decoupled heading (an option; the default until the dip reference of deviation 10).**  In the TRIAD
   solution the heading inherits the accelerometer's direction error amplified by :math:`|m_D|/m_N` (≈ 2.5
   at a 68° dip); on the raw samples, during fast translations the specific force is tens of degrees off
   the vertical and the heading is destroyed (BROAD trials 15, 30: 27°, 36°).  ``measurement="decoupled"``
   tilts the magnetometer with the predicted attitude instead, keeping magnetometer and accelerometer
   errors apart.  Its price, measured: the measured heading carries the *state's* tilt error δ as
   δ·tan(dip), an error correlated with the state that no :math:`\Sigma_\nu` models, and slow, so the bias
   state (deviation 12) learns a wrong vertical bias from it (held-out gait seed 8: heading 6.4° RMS;
   inflating :math:`\sigma^2_{\theta_z}` by :math:`\tan^2(\text{dip})\,\sigma^2_{tilt}` changes nothing, the
   predicted σ_tilt ≈ 1° being small beside :math:`\sigma_m/l_h` ≈ 20°); and from a large wrong start its
   heading, measured through a wrong tilt, can hold a false equilibrium (12 random starts of 20–175° at rest
   and 12 while turning: 3 and 2 of them stay 44–103° off after 3 s).  With the accelerometer stage of
   deviation 14 the paper's TRIAD no longer sees the raw translations and is better on everything that
   moves, so it is the default again (decoupled → TRIAD: gait seeds 0–5 / held-out 6–11 worst heading
   RMS 3.5° / 6.4° → 1.9° / 3.7°, tilt 2.7° / 4.3° → 2.3° / 3.4°; step-up with a 1.3–2.1 °/s bias, thigh 0.7–3.1° → 0.5–1.5°, shank
   0.6–2.8° → 0.4–1.9°; 700 °/s turns 0.5° / 1.1° → 0.3° / 0.7° heading RMS (median / worst, seeds 0–5);
   BROAD 9D all ten 2.10° / 3.43° → 2.13° / 3.21°, held out A→B 2.80° / 4.02° → 2.71° / 4.08°, B→A
   1.49° / 2.43° → 1.45° / 1.82°).  What had kept it from being the default, its slow heading convergence
   from a wrong start (after 2 s from 90° off: 9.7°), was the dip reference, not the measurement
   (deviation 10).
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
   (field norm and predicted dip against references tracked with ``mag_ref_tau_s``, state 20–21, which
   start from the alignment window's mean norm and dynamic dip :math:`m_D = \hat a\cdot\hat m`,
   deviation 10, and whose young dip reference gives way to a steadier field, deviation 15)
   and by :math:`\max(1, |\psi|/\text{mag\_innov\_tol})` with :math:`\psi` the heading innovation.
   The tilt bound is never below the filter's own predicted tilt uncertainty (deviation 13).
8. **Gyroscope bias at rest** (not in the paper): after ``rest_min_s`` of
   :math:`|\omega| <` ``rest_gyr_tol_rad_s`` and :math:`|\|a\|-g| <` ``rest_acc_tol_m_s2``, the raw rate
   is low-pass filtered (``bias_tau_s``) into a bias estimate (state 22–24; rest timer 25) that is
   subtracted before the prediction.  BROAD's gyroscopes carry 0.1–0.5 °/s of bias; without it the
   robust weights leave too little correction during long motions.  The same three entries are the
   bias state of deviation 12 (rest filtering moves them without changing :math:`\Sigma_{bb}`).
9. **6D variant** (``mag=None``, or a missing or gravity-parallel magnetometer sample): the
   measurement is :math:`q_a` alone, whose heading is the prediction's; its heading is unobserved:
   :math:`\Sigma_\theta = \mathrm{diag}(\sigma_a^2,\sigma_a^2,1\,\mathrm{rad}^2)`.
10. **Initial state.** The base class aligns :math:`q_0` on the first 2 s of accelerometer and
    magnetometer data (motion-compensated TRIAD, base module docstring), trusted with
    :math:`\Sigma_0 = \tfrac14\,\text{ALIGNED\_STD\_RAD}^2 I`; a start given as ``q0`` has
    :math:`\Sigma_0 = \tfrac14\sigma_0^2 I` (``init_noise_rad``).  The dip
    reference of deviation 7 starts from the data, not from the state: :math:`l_{z,ref} = m_D = \hat g\cdot
    \hat{\bar m}`, the alignment window's motion-compensated gravity and mean field (base module docstring),
    also when ``q0`` is given (:meth:`Guo._seed_from_window`; the accelerometer stage of deviation 14 too starts
    from the window's gravity then, as for every method with that stage: base class).  Both used to come from sample 0 alone: gait scenarios (seeds 0–11) with ``q0`` = truth read
    2.1–18.4° heading RMS, 22–83° with a 4 g impact on sample 0; now 0.8–3.9° and 0.6–3.4° (test
    ``test_a_heel_strike_on_sample_0_with_q0_given``).  Without a field row in the window the first field
    sample's :math:`\hat a\cdot\hat m` seeds it.  :math:`m_D` is the dynamic dip Guo et al. build their reference field
    from at every sample (5.38): the field's vertical component in *any* frame (:math:`\hat a\cdot\hat m =
    (R\hat a)\cdot(R\hat m)`), so it needs no attitude.  The dip test itself is ours (deviation 7).
    Why: the dip the test compares, :math:`l_z = e_z^T R(q^-)\hat m`, moves with the state's tilt error.
    To first order, with an earth-frame attitude error :math:`\delta` and the true field direction
    :math:`(0, m_N, m_D)`,

    .. math::  l_z = e_z^T(I + [\delta\times])\,(0, m_N, m_D)^T = m_D + m_N\,\delta_E,

    so a reference read from the prediction of a wrong start (:math:`\delta_E` large) is off by
    :math:`m_N\delta_E` and stays off for ``mag_ref_tau_s``: once the tilt has converged, the correct field
    reads as a dip disturbance and the magnetometer variance is multiplied by
    :math:`1 + (m_N\delta_{E,0}/\text{mag\_dip\_tol})^2` (the 90° start of the tests: reference +0.30 for a
    true −0.89, a factor ≈ 140 that decayed to 97 in 2 s), and the heading corrects at a crawl: the
    disturbance rejection had locked onto a wrong reference (issue 13 §1).  A single sample's
    :math:`\hat a` may carry body acceleration; the window's regression gravity does not, and an error there
    decays with ``mag_ref_tau_s`` like any other.  A *field* that is disturbed over the window is the case
    of deviation 15.
    Large initial errors then converge at the bounded rate of deviation 7: 60° / 90° / 170° about the
    tests' axis at rest 0.1° / 0.1° / 0.1° after 2 s / 2 s / 8 s (before: 2.6° / 9.7° / 5.5° with TRIAD);
    24 random starts of 20–175° about random axes, at rest or turning at up to 2 rad/s, ≤ 0.9° after 3 s
    (before: up to 27° with TRIAD, up to 136° with the decoupled heading).
11. **Missing samples**: a missing accelerometer sample skips the correction (prediction only);
    a missing gyroscope sample predicts with zero rate and does not update the bias.
12. **Gyroscope bias as a Kalman state** (not in the paper).  Why: with the robust weights of
    deviation 7 a large innovation ε is corrected at a rate growing only like √ε instead of ε, and
    the heading time constant is ≈ 20 s, so a constant bias of realistic size (BMI160: up to 3 °/s)
    that is only learned at rest (deviation 8, ≥ ``rest_min_s`` of stillness, which stepping or
    gait never gives) drifts faster than the filter corrects: 40° RMS on a simulated knee step-up
    at 1.7 °/s.  The state becomes :math:`x = (q, b)`, the rate used in (5.42) is
    :math:`\omega - b`, and to first order :math:`q^-_t = \Phi q_{t-1} + B\,\delta b` with
    :math:`B = -\tfrac{\Delta t}{2}\Xi(q^-_t)`.  The joint covariance propagates as
    :math:`\Sigma_{qb}^- = \Phi\Sigma_{qb} + B\Sigma_{bb}`,
    :math:`\Sigma_{qq}^- = \Phi\Sigma_{qq}\Phi^T + \Sigma_\xi + \Sigma_{qb}^-B^T + B(\Phi\Sigma_{qb})^T`,
    :math:`\Sigma_{bb}^- = \Sigma_{bb} + \sigma_{bw}^2\Delta t\,I` (``bias_walk_rad_s15``); the
    measurement is still :math:`q_{am} = [I_4\ 0]\,x + \nu`, so with :math:`Z = L^{-1}\Sigma_{qb}^-`
    the update adds :math:`b \mathrel{+}= w\,Z^T z`, :math:`\Sigma_{qb} = \Sigma_{qb}^- - Y^TZ`,
    :math:`\Sigma_{bb} = \Sigma_{bb}^- - Z^TZ` (the 4×4 Cholesky factor is unchanged: still one
    4-D innovation).  :math:`\Sigma_{bb,0} = \sigma_{b0}^2 I` (``bias_init_rad_s``; 0 gives back
    the filter without a bias state, bit for bit).  One more deviation from the exact Kalman
    update: the bias step is multiplied by the accelerometer's robust weight
    :math:`w = \sigma_a^2/\text{va} \le 1` (deviation 7), so that the slow bias learns from inlier
    innovations only; the covariance keeps the Kalman form.  Without :math:`w` the correlated
    specific-force errors of fast translations (BROAD 15: ‖a‖ − g is 7 m/s² RMS) walk the bias
    (with the former defaults σ_a = 0.12, bound 0.03: BROAD 9D undisturbed 4.0° without w, 2.7°
    with w, 1.9° without the bias state; hence also the new defaults σ_a = 0.2, bound 0.015).
13. **Huber bound from the predicted uncertainty.**  The tilt bound of deviation 7 is
    :math:`\max(\text{acc\_innov\_tol}, \sigma_{tilt})` with
    :math:`\sigma_{tilt}^2 = 2\,(c_1^T\Sigma_{qq}^-c_1 + c_2^T\Sigma_{qq}^-c_2)`, :math:`c_{1,2}` the
    columns :math:`i\otimes q^-, j\otimes q^-` of :math:`\Psi` (the mean variance of the two
    earth-frame tilt angles): an innovation the filter itself expects is not an outlier.  This keeps
    the convergence from a wrong start fast (deviation 10) with the tighter steady-state bound
    (0.015 rad) that the bias state needs on BROAD.

14. **Motion-compensated accelerometer** (not in the paper; ``acc_lowpass_s``, default 1.5 s,
    0 = the raw samples).  The measurement quaternion is built from the specific force low-passed in a
    quasi-inertial frame (:mod:`~estimators.orientation.acc_lowpass`, base module docstring) instead of the
    raw sample, whose direction swings 15–60° on a walking shank and whose norm-weighted mean (deviation 7)
    is 8° off the vertical there.  The stage runs inside this kernel so that its strapdown subtracts the
    bias estimate of deviation 12.  Gait scenarios of the tests (in motion from sample 0, 3–6 g heel
    strikes), worst heading RMS / tilt on seeds 0–5: 7.5° / 10.2° → 3.5° / 2.7° (held-out seeds 6–11: 6.4° /
    4.3°, not met), both with the decoupled heading of deviation 2; with the TRIAD measurement, the default
    since, 1.9° / 2.3° (held out 3.7° / 3.4°).  BROAD (10 shared trials, 9D, undisturbed / disturbed)
    2.16° / 3.85° → 2.09° / 3.43° (decoupled).  The price, measured: on pure rotation the in-motion bias
    state learns more slowly (deviation 12's test runs with the stage off), and the simulated knee step-up
    with a BMI160-like bias read 0.9–1.8° (thigh) and 0.6–2.8° (shank) instead of 0.4–1.2° and 0.5–0.7°
    (decoupled, then; TRIAD with the stage: 0.5–1.5° and 0.4–1.9°).

15. **A young dip reference gives way** (not in the paper; the rule of ChakaMo's (12)).  Why: a reference
    learnt on a disturbed start (steel beside the sensor while the window is read) is followed only with
    ``mag_ref_tau_s``, and the dip test then weights the clean field out for ≈ τ·ln(Δ/tol) ≈ 25 s: on a 12 s
    gait clip with +0.8|B| up and +0.4|B| east over the first 3 s, heading RMS 9–12 s was 31–41° (seeds 0–11).
    The kernel keeps a *candidate* (state 47: running mean of the data's dip :math:`m_D = \hat a\cdot\hat m`
    over the current run of samples within ``mag_dip_tol`` of it; 48: how long that run has held) and the
    reference's *support* (49: the time of samples whose :math:`m_D` was within ``mag_dip_tol`` of the
    reference; the window's field rows count).  While the support is below ``mag_ref_tau_s`` (a young
    reference), a sample away from the reference whose candidate has held longer than the support replaces
    it: :math:`l_{z,ref} \leftarrow` candidate, support ← the candidate's time.  The comparison uses the
    attitude-free :math:`m_D`, not :math:`l_z`, so a wrong *state* (deviation 10's case) can never move the
    reference onto itself.  The heading was confirmed against the wrong field, so the give-way also re-opens
    its variance: :math:`\Sigma^- \mathrel{+}= \tfrac14\sigma_0^2\,k_3k_3^T`, :math:`k_3 = k\otimes q^-`,
    :math:`\sigma_0` = ``init_noise_rad`` (without it the bounded correction of deviation 7 took ≈ 5 s from
    42° off: 9–12 s RMS 16–19°).  Measured, that clip, heading RMS 9–12 s: seeds 0–5 0.2–2.1°,
    held-out 6–11 0.8–4.9° (test ``test_a_dip_changing_start…``); the README's walking rows are unchanged to 0.1° but the
    floor disturbance, worst 2.8° → 2.9°; BROAD unchanged (≤ 0.01°).  No new constant: the young-reference
    limit is ``mag_ref_tau_s`` and the re-opened variance ``init_noise_rad``'s.  Not done: a reference
    confirmed for longer than ``mag_ref_tau_s`` still only follows the field with that time constant.

Why ours differs from ``ahrs.filters.FKF`` (0.4.0): it uses the one-step product (3), normalises the
measurement and then multiplies it by 0.25 (the state's norm collapses to 0.25), passes the σ's as
variances, works in NED, uses the first-order process model and writes Ξ for the other product
order (harmless only because its gyroscope noise is isotropic); it is ≈ 70 µs/sample in numpy,
this kernel ≈ 0.2 µs/sample, ≈ 0.3 through ``estimate()`` with its input validation.

State vector (``STATE_SIZE`` = 50 + the accelerometer stage's block): ``[q (4), Σqq (16, row-major),
‖m‖_ref (field units), l_z,ref (sine of the dip, negative in the north), gyroscope bias b (3, rad/s), rest
time (s), Σqb (12, 4×3 row-major), Σbb (9, 3×3 row-major), candidate m_D, its time (s), the reference's
support (s)]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.orientation import acc_lowpass
from estimators.orientation.base import (
    ALIGNED_STD_RAD,
    Alignment,
    ImuInput,
    OrientationMethod,
    check_parameter,
)
from estimators.orientation.guo_kernels import FREE_VAR_RAD2, G_M_S2, MIN_FIELD_COS, guo_batch

FloatArray = np.ndarray

STATE_SIZE = 50 + acc_lowpass.SIZE  # the filter's 50 entries, then the accelerometer stage's block


@dataclass(frozen=True)
class GuoParams:
    """Parameters of the Guo fast Kalman filter (defaults: one set for body-worn sensors, any rate).

    gyr_noise_rad_s: standard deviation of one gyroscope sample, rad/s (5.43); default 0.02.
        Only the ratios to the two next ones matter for the estimate: tilt time constant
        ≈ ``acc_noise_rad / gyr_noise_rad_s`` (10 s), heading ≈ ``mag_noise_rad / (cos(dip) ·
        gyr_noise_rad_s)`` (≈ 20 s at a 68° dip), both before the robust weights.
    acc_noise_rad: standard deviation of each component of the normalised accelerometer vector,
        ≈ rad of tilt per sample, body acceleration included (5.41); default 0.2.
    mag_noise_rad: the same for the normalised magnetometer vector, ≈ rad of heading per sample (5.41);
        default 0.15.
    init_noise_rad: standard deviation of the initial orientation, rad (Σ₀ = ¼σ₀² I); default 0.5.
    acc_norm_tol_m_s2: |‖a‖ − g| (m/s²) at which the accelerometer variance is doubled (factor
        1 + (|‖a‖−g|/tol)²); default 1.0.
    acc_innov_tol_rad: tilt innovation (rad) beyond which the accelerometer variance grows in
        proportion (Huber weight: bounded correction rate), never below the predicted tilt
        uncertainty (deviation 13); default 0.015.
    mag_norm_tol: relative deviation (-) of ‖m‖ from its tracked reference at which the magnetometer
        variance is doubled; default ``inf`` (off: it did not help on BROAD, the dip test does).
    mag_dip_tol: deviation of the field's vertical component l_z = (R(q⁻) m̂)_z (sine of the dip)
        from its tracked reference (which starts from the alignment window's ĝ·m̂, deviation 10) at which the
        magnetometer variance is doubled; default 0.1.  Also the band within which a dip confirms the
        reference or a candidate (deviation 15).
    mag_innov_tol_rad: heading innovation (rad) beyond which the magnetometer variance grows in
        proportion (Huber weight); default 0.05.
    mag_ref_tau_s: time constant, s, with which the norm and dip references follow the data, and the support
        below which a dip reference is young (deviation 15); 10.
    bias_tau_s: time constant, s, of the gyroscope bias estimate at rest; 3.0 (``inf``: no rest update).
    bias_init_rad_s: prior standard deviation of each gyroscope bias component, rad/s (Σbb₀, deviation
        12); default 0.03 (≈ 1.7 °/s; BMI160 allows ±3 °/s).  0 disables the bias state.
    bias_walk_rad_s15: bias random walk, rad/s/√s (Σbb grows by σ²Δt per sample); default 0 (a
        constant bias: the gain on the bias decays as evidence accumulates).
    rest_gyr_tol_rad_s, rest_acc_tol_m_s2, rest_min_s: rest means ‖ω‖ < 0.05 rad/s and
        |‖a‖ − g| < 0.5 m/s² for at least 1.0 s.
    acc_lowpass_s: time constant, s, of the motion-compensated accelerometer the update reads (base module
        docstring, :mod:`~estimators.orientation.acc_lowpass`; ours, not in the paper); 0 feeds the raw
        samples (the paper).  Default 1.5.
    measurement: ``"triad"`` (default: the paper's fixed point (5.38)) or ``"decoupled"`` (heading from the
        predicted tilt); see deviation 2 of the module docstring.

    Every tolerance accepts ``math.inf`` to switch its test off.
    """

    gyr_noise_rad_s: float = 0.02
    acc_noise_rad: float = 0.2
    mag_noise_rad: float = 0.15
    init_noise_rad: float = 0.5
    acc_norm_tol_m_s2: float = 1.0
    acc_innov_tol_rad: float = 0.015
    mag_norm_tol: float = math.inf
    mag_dip_tol: float = 0.1
    mag_innov_tol_rad: float = 0.05
    mag_ref_tau_s: float = 10.0
    bias_tau_s: float = 3.0
    rest_gyr_tol_rad_s: float = 0.05
    rest_acc_tol_m_s2: float = 0.5
    rest_min_s: float = 1.0
    bias_init_rad_s: float = 0.03
    bias_walk_rad_s15: float = 0.0
    measurement: str = "triad"
    acc_lowpass_s: float = 1.5

    def __post_init__(self) -> None:
        if self.measurement not in ("decoupled", "triad"):
            raise ValueError(f"measurement must be 'decoupled' or 'triad', got {self.measurement!r}")
        check_parameter("rest_min_s", self.rest_min_s, unit="s")
        check_parameter("bias_init_rad_s", self.bias_init_rad_s, unit="rad/s")
        check_parameter("bias_walk_rad_s15", self.bias_walk_rad_s15, unit="rad/s/√s")
        check_parameter("acc_lowpass_s", self.acc_lowpass_s, unit="s", hint="0 = the raw samples (the paper)")
        for name in ("gyr_noise_rad_s", "acc_noise_rad", "mag_noise_rad", "init_noise_rad", "mag_ref_tau_s"):
            check_parameter(name, getattr(self, name), low_open=True)
        for name in ("acc_norm_tol_m_s2", "acc_innov_tol_rad", "mag_norm_tol", "mag_dip_tol", "mag_innov_tol_rad",
                     "bias_tau_s", "rest_gyr_tol_rad_s", "rest_acc_tol_m_s2"):
            check_parameter(name, getattr(self, name), low_open=True, allow_inf=True, hint="math.inf disables it")


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


def _reference_step(state: FloatArray, acc, gyr, mag, acc_ok: bool, gyr_ok: bool, dt_s: float,
                    p: GuoParams) -> FloatArray:
    """Readable numpy form of one sample (same maths as ``guo_kernels.guo_step``); ``mag`` None: no field."""
    new = state.copy()
    q = state[:4]
    # joint covariance of (q, b) (deviation 12): [[Σqq, Σqb], [Σbq, Σbb]]
    sigma = np.zeros((7, 7))
    sigma[:4, :4] = state[4:20].reshape(4, 4)
    sigma[:4, 4:] = state[26:38].reshape(4, 3)
    sigma[4:, :4] = sigma[:4, 4:].T
    sigma[4:, 4:] = state[38:47].reshape(3, 3)
    if math.isfinite(p.bias_tau_s) and gyr_ok:  # gyroscope bias at rest (deviation 8)
        at_rest = (acc_ok and np.linalg.norm(gyr) < p.rest_gyr_tol_rad_s
                   and abs(np.linalg.norm(acc) - G_M_S2) < p.rest_acc_tol_m_s2)
        new[25] = new[25] + dt_s if at_rest else 0.0
        if at_rest and new[25] >= p.rest_min_s:
            new[22:25] += min(dt_s / p.bias_tau_s, 1.0) * (gyr - new[22:25])
    if gyr_ok:
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
    trans = np.eye(7)  # (q, b) transition: q⁻ = Φ q − (Δt/2) Ξ(q⁻) δb  (deviation 12)
    trans[:4, :4] = phi
    trans[:4, 4:] = -0.5 * dt_s * xi_matrix(q_pred) if gyr_ok else 0.0
    noise = np.zeros((7, 7))
    noise[:4, :4] = (dt_s / 2) ** 2 * xi @ (p.gyr_noise_rad_s**2 * np.eye(3)) @ xi.T  # (5.43)
    noise[4:, 4:] = p.bias_walk_rad_s15**2 * dt_s * np.eye(3)
    sigma7 = trans @ sigma @ trans.T + noise
    sigma_pred = sigma7[:4, :4]

    def store(q_out, cov):
        new[:4] = q_out
        new[4:20] = cov[:4, :4].ravel()
        new[26:38] = cov[:4, 4:].ravel()
        new[38:47] = cov[4:, 4:].ravel()
        return new

    if not acc_ok:
        return store(q_pred / np.linalg.norm(q_pred), sigma7)
    rot_pred = _rotation_matrix(q_pred)  # rows: east, north, up in sensor coordinates
    a = acc / np.linalg.norm(acc)
    psi = _right(q_pred)[:, 1:]  # earth-frame rotation → quaternion change, at the prediction
    tilt = np.arccos(np.clip(rot_pred[2] @ a, -1.0, 1.0))  # tilt innovation (deviation 7)
    # predicted tilt std: earth-frame rotation variance about east and north, δq = ½ Ψ δθ (deviation 13)
    tilt_sd = np.sqrt(max(2.0 * (psi[:, 0] @ sigma_pred @ psi[:, 0] + psi[:, 1] @ sigma_pred @ psi[:, 1]), 0.0))
    var_acc = (p.acc_noise_rad**2 * (1.0 + (np.linalg.norm(acc) - G_M_S2) ** 2 / p.acc_norm_tol_m_s2**2)
               * max(1.0, tilt / max(p.acc_innov_tol_rad, tilt_sd)))
    # accelerometer-consistent quaternion nearest to the prediction (5.37)
    q_acc = 0.5 * (w_matrix(np.array([0.0, 0.0, 1.0]), a) + np.eye(4)) @ q_pred
    if np.linalg.norm(q_acc) < 1e-9:
        return store(q_pred, sigma7)
    q_acc /= np.linalg.norm(q_acc)
    q_meas = q_acc
    sigma_nu = 0.25 * psi @ np.diag([var_acc, var_acc, FREE_VAR_RAD2]) @ psi.T  # 6D: heading free
    if mag is not None:
        m_unit = mag / np.linalg.norm(mag)
        l_earth = rot_pred @ m_unit  # field direction in earth by the prediction
        l_h = np.hypot(l_earth[0], l_earth[1])
        paper = p.measurement == "triad"
        if (np.linalg.norm(np.cross(m_unit, a)) if paper else l_h) > MIN_FIELD_COS:
            m_norm = np.linalg.norm(mag)
            m_d = a @ m_unit  # the dynamic dip m_D = â·m̂ of (5.38): needs no attitude
            if new[20] <= 0.0:  # no field in the alignment window: the first field sample (deviation 10)
                new[20], new[21] = m_norm, m_d
            # deviation 15: a young reference gives way to a data dip that has held longer
            near = (lambda x: x * x / p.mag_dip_tol**2 < 1.0) if math.isfinite(p.mag_dip_tol) else (lambda x: True)
            if new[48] > 0.0 and near(m_d - new[47]):
                new[48] += dt_s
                new[47] += max(min(dt_s / p.mag_ref_tau_s, 1.0), dt_s / new[48]) * (m_d - new[47])
            else:
                new[47], new[48] = m_d, dt_s
            if near(m_d - new[21]):
                new[49] += dt_s
            elif new[49] < p.mag_ref_tau_s and new[48] > new[49]:
                new[21], new[49] = new[47], new[48]
                k3 = psi[:, 2]  # the heading was confirmed against a wrong field: re-open its variance
                sigma7[:4, :4] += 0.25 * p.init_noise_rad**2 * np.outer(k3, k3)
                sigma_pred = sigma7[:4, :4]
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
    sigma_nu = sigma_nu + 0.25 * FREE_VAR_RAD2 * np.outer(q_pred, q_pred)  # deviation 5: norm direction
    # H = [I₄ 0]: K = Σ⁻Hᵀ(HΣ⁻Hᵀ + Σν)⁻¹ (7×4), the bias rows included (deviation 12)
    gain = np.linalg.solve(sigma_pred + sigma_nu, sigma7[:4, :]).T
    x_new = gain @ (q_meas - q_pred)
    q_new = q_pred + x_new[:4]
    new[22:25] += p.acc_noise_rad**2 / var_acc * x_new[4:]  # robust weight of the bias step
    sigma_new = sigma7 - gain @ sigma7[:4, :]
    return store(q_new / np.linalg.norm(q_new), 0.5 * (sigma_new + sigma_new.T))


def _seed_field_references(state: FloatArray, alignment: Alignment, dt_s: float) -> None:
    """Norm and dip references (state 20, 21) from the window's mean field and gravity (deviation 10)."""
    if alignment.mag_mean is None:
        return  # 6D, or no field sample: the first field sample seeds them in the kernel
    g = alignment.acc_mean / np.linalg.norm(alignment.acc_mean)
    m = alignment.mag_mean / np.linalg.norm(alignment.mag_mean)
    if np.linalg.norm(np.cross(m, g)) > MIN_FIELD_COS:
        state[20], state[21] = alignment.mag_norm_mean, float(g @ m)
        state[49] = alignment.n_mag * dt_s  # the window's field rows are its support (deviation 15)


# ====================================================================== method class
class Guo(OrientationMethod):
    """Guo et al. (2017) fast Kalman filter; 9D with a magnetometer, 6D without."""

    name = "guo"
    params_type = GuoParams
    state_size = STATE_SIZE
    uses_acc_lowpass = True
    lowpass_in_kernel = True
    seeds_from_window = True

    def _state_from_quaternion(self, q: FloatArray, data: ImuInput) -> FloatArray:
        state = np.zeros(STATE_SIZE)
        state[:4] = q
        state[4:20] = (0.25 * self.params.init_noise_rad**2 * np.eye(4)).ravel()
        state[38:47] = (self.params.bias_init_rad_s**2 * np.eye(3)).ravel()  # Σbb₀; Σqb₀ = 0
        # 20, 21: field norm and m_D references; ≤ 0 means "take the first valid sample"
        return state

    def _state_from_alignment(self, alignment: Alignment, data: ImuInput) -> FloatArray:
        """An aligned start is trusted (base module docstring): Σ₀ from ``ALIGNED_STD_RAD``, not ``init_noise_rad``."""
        state = self._state_from_quaternion(alignment.q, data)
        std = min(self.params.init_noise_rad, ALIGNED_STD_RAD)
        state[4:20] = (0.25 * std**2 * np.eye(4)).ravel()
        return state

    def _seed_from_window(self, state: FloatArray, alignment: Alignment, data: ImuInput) -> None:
        """The dip and norm references (deviation 10) need no attitude, only the window's gravity and field, so a
        start given as ``q0`` seeds them from the window too (from sample 0 alone a heel strike there misled them)."""
        _seed_field_references(state, alignment, data.dt_s)

    def _kernel_args(self, data: ImuInput) -> tuple:
        p = self.params
        gyr_ok = ~data.flags.gyr_missing
        return (data.acc, data.gyr, data.mag_array, data.acc_ok, gyr_ok, data.mag_ok, data.dt_s,
                p.gyr_noise_rad_s**2, p.acc_noise_rad**2, p.mag_noise_rad**2,
                p.acc_norm_tol_m_s2**-2, p.acc_innov_tol_rad, p.mag_norm_tol**-2, p.mag_dip_tol**-2,
                p.mag_innov_tol_rad, min(data.dt_s / p.mag_ref_tau_s, 1.0),
                min(data.dt_s / p.bias_tau_s, 1.0), p.rest_gyr_tol_rad_s, p.rest_acc_tol_m_s2, p.rest_min_s,
                p.measurement == "triad", p.bias_walk_rad_s15**2, p.mag_ref_tau_s, p.init_noise_rad**2)

    def _lowpass_args(self, data: ImuInput) -> tuple[FloatArray, int]:
        """Coefficients and state offset of the accelerometer stage (offset −1: off)."""
        if not self._lowpass_on:
            return np.zeros(5), -1
        return self._lowpass_coefficients(data.fs_hz), STATE_SIZE - acc_lowpass.SIZE

    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        return guo_batch(*self._kernel_args(data), np.asarray(state0, dtype=np.float64), *self._lowpass_args(data))

    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        state = np.array(state0, dtype=np.float64)
        out = np.empty((data.n, 4))
        coeffs, offset = self._lowpass_args(data)
        for k in range(data.n):
            mag = data.mag[k] if data.mag_ok[k] else None
            acc, gyr_ok = data.acc[k], not data.flags.gyr_missing[k]
            if offset >= 0:  # the accelerometer stage, its strapdown on the rate minus the bias before the sample
                rate = data.gyr[k] - state[22:25] if gyr_ok else np.zeros(3)
                acc, state[offset:] = acc_lowpass.reference_step(state[offset:], acc, rate, bool(data.acc_ok[k]),
                                                                 data.dt_s, coeffs)
            state = _reference_step(state, acc, data.gyr[k], mag, bool(data.acc_ok[k]), gyr_ok, data.dt_s,
                                    self.params)
            out[k] = state[:4]
        return out, state


__all__ = ["Guo", "GuoParams", "jacobian", "measurement_9d", "w_matrix"]
