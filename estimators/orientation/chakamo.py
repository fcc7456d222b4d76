r"""ChakaMo's own orientation filter: quasi-inertial acceleration filtering, bias estimation, magnetic
disturbance rejection and an offline (non-causal) smoother.

The design builds on the ideas of VQF (D. Laidig, T. Seel, "VQF: Highly accurate IMU orientation
estimation with bias estimation and magnetic disturbance rejection", Information Fusion 91:187–204,
2023; "[VQF]" below) and is an independent implementation.  Equation numbers (1)–(15) refer to this
docstring; the code that cites them: :mod:`~estimators.orientation.chakamo_kernels` (compiled causal
filter, state layout), :mod:`~estimators.orientation.chakamo_reference` (its readable numpy twin) and
:mod:`~estimators.orientation.chakamo_offline` (the offline smoother's numpy steps).

Frames
------
``S`` sensor; ``I`` quasi-inertial frame (the strapdown frame, drifting only with the gyroscope
error); ``E'`` earth frame without heading (z up); ``E`` ENU earth frame (y magnetic north).

.. math::
    q_{ES} = R_z(\delta) \otimes q_{E'I} \otimes q_{IS}                                   \tag{0}

Causal filter (one sample, ``dt = 1/fs``)
-----------------------------------------
1. *Strapdown* with the bias estimate :math:`\hat b` ([VQF] §3.1):
   :math:`q_{IS} \leftarrow q_{IS} \otimes \exp((\omega - \hat b)\,dt)`.                       (1)
2. *Acceleration in the quasi-inertial frame* ([VQF] §3.2, the key idea): the specific force is
   rotated into ``I``, :math:`a_I = q_{IS} a_S q_{IS}^*`, and low-pass filtered there by a
   second-order Butterworth filter with cut-off :math:`f_c = \sqrt2/(2\pi\tau_{acc})`         (2)
   (bilinear transform, coefficients from ``fs`` so that the filter is rate-independent).  In ``I``,
   gravity is (almost) constant while linear accelerations of a moving limb average out, so the
   filter removes them far better than a gain on the raw sample.  During the first ``tau_acc_s``
   the filter output is the running mean (filter state set to its steady state).  From the initial
   alignment (base module docstring) that mean starts as the alignment window's motion-compensated
   mean, with the weight of its rows, also from a ``q0`` (rotated into ``I`` by it): a wrong ``q0``'s
   tilt is corrected at the first sample to the window's gravity, not to sample 0's raw specific force.
3. *Inclination correction*: :math:`\hat a_{E'} = q_{E'I} \bar a_I / |\bar a_I|`;
   :math:`q_{E'I} \leftarrow c \otimes q_{E'I}` with :math:`c` the shortest rotation taking
   :math:`\hat a_{E'}` to ``z`` (axis :math:`(\hat a_y, -\hat a_x, 0)`).  The full correction is
   applied at every sample: the smoothing is done by the low-pass filter.                   (3-4)
4. *Gyroscope bias* — a 3-state Kalman filter (6 states with the scale errors (8k); the kernel always runs the 6-state
   form, whose scale block is zero without them) with random-walk model, covariance ``P``:
   :math:`P \leftarrow P + \sigma_{init}^2\,dt/T_{forget}\, I`                                  (5)
   * *at rest* (gyroscope low-pass :math:`\bar\omega` and the deviations of ω and a from their
     first-order low-passes (τ = ``rest_tau_s``) below ``rest_gyr_th_rad_s`` / ``rest_acc_th_m_s2``
     for ``rest_min_s``):                                                                      (6)
     measurement :math:`\bar\omega = b + v`, :math:`H = I`;                                     (7)
   * *in motion* ([VQF] §3.5): a bias error :math:`e = b - \hat b` turns the quasi-inertial frame
     at :math:`R_{IS} e`; the low-passed acceleration sees that drift through the same low-pass
     ``LP`` (2), and the inclination correction undoes it.  Its rotation vector per second gives two
     measurements (rows x, y) with :math:`M = R_{E'I}\,LP(R_{IS})`, :math:`v = R_{E'I}\,LP(R_{IS}\hat b_{used})`:
     :math:`y = \log(c)_{x,y}/dt = -M_{x,y}\,b + v_{x,y} + \nu`, innovation
     :math:`y - v_{x,y} + M_{x,y}\hat b`.                                                        (8)
     Filtering ``R`` and :math:`R\hat b` with the same filter as the acceleration accounts for the
     delay of the correction.  The vertical component is unobservable here (it only grows in ``P``).
   Measurement variances are noise *densities* divided by ``dt`` so that the information gathered
   per second does not depend on the rate: at rest :math:`r = \sigma_{rest}^2 \tau_{rest} / dt`
   (τ the correlation time of the low-passed rate); in motion
   :math:`r = \sigma^2 \tau_{ref}^2 / (\tau_{acc}\, dt)` with :math:`\tau_{ref}` = 3 s
   (``MOTION_NOISE_TAU_S``): a shorter acceleration time constant lets more linear acceleration
   through the low-pass, so the correction is a noisier bias measurement (at τ_acc = 3 s this is
   :math:`\sigma^2\tau_{acc}/dt`).  In motion the noise also grows with the angular rate,
   :math:`\sigma^2 = \sigma_{motion}^2 + s^2\, LP(|\omega - \hat b|^2)` (``s = bias_motion_rate_scale``:
   gyroscope scale-factor and misalignment errors look like a rate-proportional bias during fast
   rotations).  Robustness: scalar measurements are applied sequentially, innovations are clipped to
   ±``bias_clip_rad_s`` (one burst of linear acceleration cannot throw the estimate), the variances
   never grow beyond the initial one, and the estimate is clipped to ±``bias_clip_rad_s``.
   *Gyroscope scale states* (``gyr_scale_sigma`` > 0, the default; [VQF] has none): the gyroscope reads
   :math:`\omega_{meas} = (1 + \operatorname{diag} k)\,\omega + b` with a per-axis scale error ``k``, so the
   state is :math:`x = (b, k)` (6 states, full 6×6 covariance), the rate integrated in (1) is
   :math:`\omega_{meas} - \hat b_{used}` with :math:`\hat b_{used} = \hat b + \operatorname{diag}(\hat k)\,\omega_{meas}`
   (also inside ``v``), and a scale error turns ``I`` at :math:`R_{IS}\operatorname{diag}(\omega)\,e_k`, seen
   through the same low-pass, so each row of (8) gains
   :math:`y = -M_{x,y}\,b - N_{x,y}\,k + v_{x,y} + \nu`, :math:`N = R_{E'I}\,LP(R_{IS}\operatorname{diag}\omega_{meas})`,
   innovation :math:`y - v_{x,y} + M_{x,y}\hat b + N_{x,y}\hat k`.                                     (8k)
   The rest rows (7) carry zeros for ``k`` (at rest ω ≈ 0: no scale error shows).  The heading rows (12b)
   run in motion and carry zeros for ``k`` too: they treat :math:`\hat k` as known, so their known term is
   :math:`v_z = LP_1(r_z\cdot\hat b)` with :math:`\hat b` *alone*; the heading lag sees the total rate error
   :math:`(b - \hat b) + \operatorname{diag}(k - \hat k)\,\omega`, so with :math:`\hat b, \hat k` exact the
   innovation :math:`err/\tau - v_z + m_z\cdot\hat b` is then zero (the rate error the rows cannot name,
   :math:`\operatorname{diag}(k - \hat k)\,\omega`, counts as their noise).  A :math:`v_z` built from
   :math:`\hat b_{used}` (as first written) left the innovation at :math:`-LP_1(r_z\operatorname{diag}(\omega)\,\hat k)`
   with no ``k`` column to explain it, and the vertical bias took up :math:`\hat k\,\omega` (tested: a known
   scale error, the bias learnt from the heading alone, moved the bias by 0.05–0.06 °/s; now < 0.003 °/s).
   Giving the rows their scale columns :math:`-LP_1(r_z\operatorname{diag}\omega)` would be the other
   consistent choice; it lets the field teach ``k`` and is not done.
   Prior: :math:`\sigma_k` = ``gyr_scale_sigma`` per axis, 0.5 %, *the value of the project simulator's sensor
   model*: a MetaMotionR's gyroscope scale errors are drawn there with σ 0.5 % per axis
   (``estimators.simulation.spec.ImuSpec.random``, ``GyrErrors(scale_error=rng.normal(0.0, 0.005, 3))``; the
   fixed default ``GyrErrors`` reads +0.4, −0.3, +0.2 %).  It is not a grid key, but it is not blind to BROAD
   either: scans at 0.5 / 1 / 2 % had been seen before (the prototype, (8b ix)), and with :math:`\sigma_k` itself
   in the held-out grid half A chooses 2 % and A→B is lost ((8b ix), (8b xii)).  Random walk as (5),
   :math:`P_{kk} \mathrel{+}= \sigma_k^2\,dt/T_k` capped at :math:`\sigma_k^2`, with a slow :math:`T_k` =
   ``gyr_scale_forgetting_s`` = 10⁴ s (set by hand for a sensitivity that drifts with temperature: ≈ 0.12 % over
   10 min at this walk); ``k`` is clipped to ±5 % (``K_CLIP``; a prior above it is refused).  Weakly observed
   (only while the sensor turns, only through the inclination), the states absorb rate-proportional errors of
   any cause (misalignment too), so their estimates follow the prior.  Tested on the simulator with known scale
   errors (+1.2, −1.0, +0.8 %, no cross-axis error) and a prior of 1 %: the forward pass reads each within 30 %;
   the default prior (0.5 %) under-reads them (46–77 % of each) and still lowers the orientation error.
   *Tried and not kept* (an impact pause, "(8a)"): BROAD trial 24 (finger taps of 5–15 g during rotations)
   is ChakaMo's worst 6D disturbed trial; there the strapdown with the rest bias tilts 0.5–1° at some taps and
   the motion bias (8) wanders 0.03–0.05°/s off the rest bias while VQF's stays put.  Pausing (8) for
   3 τ_acc after a sample whose specific-force norm departs from the low-passed one by more than a threshold
   gained trial 24 (6D 0.92° → 0.80°) only when *every* impact paused; that form also paused the offline passes
   for most of a walk (heel strikes of 4–6.5 g, no threshold separates them from the taps) and cost
   ``benchmarks.walking`` knee RMSE 1.38° → 1.42° (6D), 1.37° → 1.41° (9D).  Pausing only after isolated
   impacts cost 1.38° → 1.41° and 1.37° → 1.40° and left trial 24 at 0.92° (its taps repeat), 6D trial 24 at
   30 / 40 / 60 m/s²: 0.91 / 0.92 / 0.90° against 0.92° without.  Held out, 6D B→A stayed 3.07° (VQF 6D 3.00°).
   Not kept: it gained nothing on BROAD, cost walking, and its only support was our own simulator.
   *Also tried, 6D, not kept* (all ten undisturbed / disturbed total RMSE; defaults 1.01/2.49°, trial 24 0.92°,
   30 5.21°).  The gap on half A's disturbed pair is (8) alone on trial 24: with ``motion_bias=False`` it reads
   0.81°, as VQF 6D (whose own motion bias changes nothing there), but trial 10 goes 0.78 → 1.08° and half B
   prefers (8) on (1.770° against 1.903°).  Trial 30 is shared: VQF 6D reads 5.19°; against the optical
   reference (10 s windows) the in-motion gyroscope error about the vertical departs from the rest bias by
   0.1–0.35°/s, which no accelerometer sees.  (i) No learning along gravity: the increment of (8) projected off
   the low-passed vertical :math:`M_z`: 1.06/2.45, trial 24 0.85°, 10 0.78 → 0.94°; half B chooses it (with
   ``bias_sigma_motion_rad_s`` 0.1°/s: 1.758° against 1.770°) and half A does not, so held out B→A becomes
   0.76/3.02° (from 0.64/3.07°; VQF 6D 0.81/3.00°): the disturbed gap halves, the undisturbed half pays more.
   (ii) VQF's vertical pseudo-measurement :math:`M_z b = 0` at 10⁴ × the motion variance: 1.01/2.50, trial 24
   0.92°.  (iii) The bias random walk at VQF's drift ((0.1°/s)² per 100 s: ``bias_forgetting_s`` 2500):
   1.07/2.56, trial 24 0.80°, 30 5.18°, but 10 1.05°, 32 2.06°; half B prefers 100 s (1.770° against 1.893° at
   400 s, 1.935° at 2500 s), so held out nothing changes.  (iv) The innovation clip taken from the noise,
   :math:`k\sqrt r` (k = 0.1–3) instead of ±``bias_clip_rad_s``: 1.00/2.49, trial 24 0.92° (its innovations
   never reach the clip: :math:`\sqrt r` ≈ 6°/s per sample).  (v) The noise from the innovations (covariance
   matching, Mehra 1972): the innovations of (8) low-passed over τ_acc have a standard deviation of 0.02–0.13°/s
   on all ten trials (trial 24 0.04–0.07°/s, the undisturbed 02–18 0.02–0.07°/s), below the model's
   :math:`\sqrt{r\,dt/2\tau_{acc}}` = 0.14°/s: the noise of (8) is nowhere under-stated and the taps do not stand
   out, so a gate taken from the covariance never acts (a factor max(1, observed / modelled) on ``r``: every trial
   unchanged).  (vi) What half A's disturbed pair does respond to is the rate-proportional noise ``s``: trials 24
   and 30 turn 1194° and 3910° net about the vertical, and the vertical gyroscope error in 5 s windows (against
   the optical reference) regresses on that rotation at −0.76 % and −0.47 % (r = −0.60, −0.70), a scale error
   that (8) reads as bias.  ``s`` 0.004–0.016 gives 24 0.80–0.83°, 30 5.16–5.17° (half A disturbed 2.98–3.00°),
   but half B prefers ``s`` = 0 (1.742° against 1.823° at 0.002), which gives half A 3.42°: the two halves
   disagree on how far (8) may be trusted during fast rotations, so no choice made on B closes the gap.
   (vii) A continuous weight of (8) by the specific force's departure from gravity, :math:`\sigma^2 \mathrel{+}=
   k_a^2\,LP_{\tau_{acc}}((|a| - |\bar a_I|)^2)` (no threshold, no pause): trial 24 is no outlier there (RMS of
   :math:`|a| - g` 3.1 m/s², against 7.0 and 16.2 on the translation trials 15 and 18), and at σ_motion 0.1°/s,
   :math:`k_a` 0.03 / 0.1 / 0.3 °/s per m/s² gives 24 0.93 / 0.87 / 0.82°, 30 5.20 / 5.19 / 5.17°, but trial 27
   (phone vibration, half B) 1.45 → 1.54 / 1.70 / 1.71° and 10 0.41 → 0.44 / 0.63 / 0.95°; in the 6D held-out grid
   (0, 0.03, 0.1, 0.3) both halves choose 0, so held out nothing changes (6D A→B 1.40/2.01, B→A 0.64/3.07).
   (viii) A gyroscope *scale* state, the cause (vi) points at: :math:`\omega_{meas} = (1 + k)\,\omega + b`, the
   scale error read by the same measurement (8) through :math:`R_{E'I}\,LP(R_{IS}\,\omega)` (a 4-state filter;
   rest (7) with :math:`H = [I, 0]`; the passes' ``k`` combined as (13)).  Checked first on trials 24 and 35 with
   their gyroscope multiplied by 1.01: the filter finds k = 0.0085 and 24 reads 0.64° (2.91° without the state),
   35 4.32° (10.49°).  Isotropic (one k), at the prior :math:`\sigma_k` 0.002 / 0.005 / 0.01 (σ_motion 0.1°/s):
   02 0.71 → 0.41 / 0.39 / 0.44°, 24 0.93 → 0.92 / 0.87 / 0.84°, 30 5.21 → 4.75 / 4.64 / 4.66°, but 35
   2.93 → 3.57 / 3.93 / 4.11° and 32 1.67 → 1.79 / 1.94 / 2.08°: half A chooses 0.005, half B 0, held out A→B
   1.40/2.44 (disturbed worse than VQF 6D's 2.26), B→A unchanged.  (ix) Per-axis scales (diag k, a 6-state
   filter with the full covariance): σ_k 0.005 / 0.01 / 0.02 (σ_motion 0.1°/s) read 02 0.38 / 0.40 / 0.41°,
   24 0.89 / 0.81 / 0.72°, 30 4.17 / 3.31 / 2.29°, 32 1.28 / 1.14 / 3.87°, 35 2.42 / 0.83 / 4.88° (halves A / B
   1.330 / 1.592, 1.147 / 1.247, 0.933 / 2.616; without 1.611 / 1.770).  At 0.01 every disturbed trial gains
   (35, whose heading drifts in motion (13a), gains most), but the estimates follow the prior (35: k ≈ +1.0, +0.7,
   −1.1 % at σ_k 0.01, ≈ +2, +1.6, −1.9 % at 0.02; the posterior σ stays at 70–95 % of the prior): weakly
   observed, the states absorb whatever rate-proportional error the trial has, and at 0.02 they overfit 32 and 35.
   Without the rate-proportional noise ``s`` (which stood for this error) it is worse everywhere (σ_k 0.01: 35
   5.55°, 30 5.67°).  Held out (grid 0 / 0.005 / 0.01 / 0.02): B→A chooses 0.01 and reads 0.54/2.06 (VQF 6D
   0.81/3.00: met), A→B chooses 0.02 and reads 1.56/3.32 (VQF 6D 1.49/2.26: both lost; today 1.40/2.01).
   9D (both halves choose 0.02): A→B 1.16/3.02 (today 1.11/2.77, offline VQF 2.26/3.18), B→A 0.98/1.20 (today
   1.06/1.12, VQF 1.26/2.73); ``benchmarks.walking`` knee RMSE at 0.01 / 0.02: 9D 1.37 / 1.38°, 6D 1.39 / 1.40°
   (today 1.37°, 1.38°).  Not kept *as a grid key*: it closes one split by breaking the other (the prototype:
   branch ``h/est9-scale-proto``, compiled kernel only, no numpy twin).  Kept with a fixed prior: (8b xii).  (x) A wider held-out grid of
   ``bias_sigma_motion_rad_s``: it reached down to 0.1°/s only, and both halves chose that edge in 6D.  Below it
   (6D, mean total RMSE of half A / B): 0.1°/s 1.611 / 1.770, 0.075 1.589 / 1.752, 0.05 1.587 / 1.734, 0.025
   1.603 / 1.720, 0.0125 1.610 / 1.717, 0.003 1.614 / 1.718, 0.0001 1.614 / 1.718 (flat below ≈ 0.02°/s, where
   the rate-proportional noise ``s`` sets the weight of (8)); at 0.0125°/s trial 24 reads 0.89°, 30 5.13°, 27 1.24°,
   10 0.53° (defaults 0.92, 5.21, 1.61, 0.78°).  With the grid 0.0125 / 0.05 / 0.2 / 0.8 / 1.6°/s (kept: the same
   choices and scores as the factor-2 grid 0.0125–1.6°/s, at the old run time) half A chooses 0.05 and half B
   0.0125: 6D A→B 1.41/1.95 (was 1.40/2.01; VQF 6D 1.49/2.26), B→A 0.68/3.01 (was 0.64/3.07; VQF 6D 0.81/3.00,
   3.009 against 2.999: *not met*, and no σ_motion meets it: 3.007 at 0.0001°/s); 9D unchanged (A 0.8, B 1.6°/s).
   The default stays 0.2°/s: the halves disagree (0.05 and 0.0125°/s in 6D, 0.8 and 1.6°/s in 9D).
   (xi) A second 6D grid key beside that σ_motion grid (each tried alone; 6D, held out B→A undisturbed /
   disturbed; today 0.68/3.01).  In every case half B takes the point that trusts (8) most, which trial 27
   (phone vibration) rewards, and half A pays: ``tau_acc_s`` 1.5 / 2 / 3 / 4.5 / 6 s: B chooses 2 s at
   0.0125°/s (27 1.24 → 0.45°), A then reads 1.91/3.03 (trial 10 0.53 → 4.25°; at 1.5 s 9.16°); with
   2.5 / 3 / 3.5 s B chooses 2.5 s, 1.02/3.02; with 3 / 3.5 s B keeps 3 s and A→B moves to 1.39/2.00.
   ``bias_motion_rate_scale`` 0 / 0.001 / 0.002 / 0.004 / 0.008: B chooses 0.001, A reads 2.07/3.25 (at 0 and
   0.0125°/s (8) diverges: 10 32°, 15 24°).  ``bias_forgetting_s`` 50 / 100 / 200 / 400 s: B chooses 50 s,
   1.18/3.10.  ``bias_sigma_rest_rad_s`` 0.01 / 0.03 / 0.1°/s: B chooses 0.01, 0.67/3.03.  Trial 24's gap
   to VQF 6D is heading only (at B's choice: inclination 0.51° as VQF's, heading 0.73° against 0.62°): over
   the 120 s of taps the smoothed bias moves 0.02–0.07°/s off the rest bias on every axis and comes back to
   it at the closing rest, while offline VQF's stays within 0.01°/s (its process noise is 25 × smaller:
   (iii)).  But trial 27's wander is of the same size and helps: its heading drifts ≈ 0.05°/s through the
   vibration, a real in-motion gyroscope error that (8) follows (6D 1.24° at 0.0125°/s against VQF 6D's
   1.71°); no grid point tells the two apart.  Trial 30 is a heading drift of ≈ 16° over 110 s of fast
   rotation, the same in ours and VQF 6D (5.13° against 5.19°), which only a scale state (viii–ix) reaches.
   A directional form of ``s`` (the scale error's drift is :math:`k\,R_{IS}\omega`, so row j of (8) gets
   :math:`s_d^2\,(R_{E'I}\,LP(R_{IS}\omega))_j^2` on top of its noise; compiled kernel only): with ``s`` kept, half A
   gains at :math:`s_d` 0.02 (1.587 → 1.548; at 0.0125°/s 24 0.85°, 30 5.06°) and half B loses (1.717 → 1.897: 27,
   32, 35), so B chooses 0 and nothing changes; in place of ``s`` (8) diverges at σ_motion 0.05°/s (10 2.8–5.9°).
   A steeper rate term, :math:`s^2 LP(|\omega|^4)` (1 rad/s units) in place of :math:`s^2 LP(|\omega|^2)`: half A
   gains (s 0.002, 0.0125°/s: 1.493, 24 0.69°, 30 5.03°; all ten 0.89/2.50), half B loses (at s 0.002 1.855 at
   best, 27 1.54–1.77°), so a form switch {|ω|², |ω|⁴} in the grid is chosen off by B; with ``s`` in the grid as
   well B chooses |ω|², s 0.001 (1.389) as above; with the |ω|⁴ form alone (s 0.001 / 0.002 / 0.004) B chooses
   0.001 at 0.05°/s and A reads 0.87/2.93 (undisturbed lost: VQF 6D 0.81; trial 10 1.14°: slow translation
   needs the noise in slow motion that trial 27 does not want).  None is kept: each closes nothing held out.
   (xii) *Kept*: the per-axis scale states of (ix) with the prior *fixed* (σ_k 0.5 %, the simulator's sensor
   model, (8k); not a grid key, so each half chooses only σ_motion) and a slow random walk (:math:`T_k` 10⁴ s;
   (ix) reused ``bias_forgetting_s`` = 100 s), as (8k), both kernels.  Held out (6D; VQF 6D A→B 1.49/2.26, B→A
   0.81/3.00): A→B 1.42/1.59 (was 1.41/1.95), B→A 0.58/2.41 (was 0.68/3.01): *met on both splits*, A choosing
   σ_motion 0.05°/s, B 0.0125°/s.  9D: A→B 1.11/2.75 (was 1.11/2.77; offline VQF 2.26/3.18), B→A 0.99/1.38 (was
   1.06/1.12; VQF 1.26/2.73): still met.  All ten: 6D 0.94/2.18 (was 1.01/2.49; trial 30 5.21 → 4.29°, 32 1.77 →
   1.46°, 35 2.95 → 2.66°, 02 0.72 → 0.36°, 15 1.32 → 1.33°), 9D 1.08/2.10 (was 1.08/2.13; 32 1.15 → 1.21°, 35
   0.98 → 0.85°).  *How blind the prior is*: the value comes from the simulator's sensor model; but BROAD scans
   at 0.5 / 1 / 2 % had been seen (ix), and with σ_k itself in the held-out grid half A chooses 2 % and A→B is
   lost, so the held-out result rests on a value fixed outside the grid, not on a procedure that finds it.
   First kept at 1 % (called a datasheet tolerance, but chosen after (ix), where 1 % was the best of the three
   on all ten trials): held out 6D A→B 1.46/1.05, B→A 0.52/2.03, 9D 1.12/2.74, 0.99/1.25 with the (12b) rows
   then absorbing k̂ω (fixed since, (8k); at 1 % with the fix 9D reads 1.11/2.74, 0.98/1.34, all ten 1.08/2.14,
   6D unchanged).  Sensitivity (6D held out, each σ_k fixed, A→B / B→A; 6D has no
   (12b)): 0.5 % as above; 1 % 1.46/1.05, 0.52/2.03 (met); 2 % 1.59/3.04, 0.74/1.94 (A→B lost: 32, 35 overfit as
   in (ix)); 3 % 1.64/3.79, 0.75/1.66 (lost).  So the goal holds for a prior of 0.5–1 % and fails at 2 % and
   above; T_k 100 s instead of 10⁴ s (at 1 %): 1.45/1.09, 0.50/1.99.  (8b)
5. *Heading* ([VQF] §3.3): :math:`m_{E'} = q_{E'I} q_{IS} m q_{IS}^* q_{E'I}^*`,
   target :math:`\delta^* = \operatorname{atan2}(m_x, m_y)` (the field's horizontal part on +y),  (9)
   :math:`\delta \leftarrow \delta + k\,\operatorname{wrap}(\delta^* - \delta)`,
   :math:`k = \max(1 - e^{-dt/\tau_{mag}}, 1/(n+1))` (running mean for the first samples; from the
   initial alignment, ``n`` starts at the window's field rows and the reference norm and dip of (11)
   are the window's).                                                                             (10)
6. *Magnetic disturbance rejection* ([VQF] §3.4): the norm :math:`|m|` and dip
   :math:`\arcsin(-m_{E',z}/|m|)` are compared with reference values learned while undisturbed
   (first-order low-pass, ``mag_ref_tau_s``).  A sample is near the reference when
   :math:`\big||m| - |m|_{ref}\big| < \text{mag\_norm\_th}\,|m|_{ref}` and
   :math:`|dip - dip_{ref}| < \text{mag\_dip\_th\_rad}`, and undisturbed when it has been near the
   reference for ``mag_min_undisturbed_s`` (hysteresis: the edges of a disturbance are not trusted);  (11)
   disturbed samples do not correct the heading (gyroscope only).  A *candidate* reference follows
   the current field while it stays within the same thresholds; after ``mag_max_rejection_s`` of
   rejection, a candidate that has held for ``mag_new_field_s`` becomes the new reference and
   the heading correction restarts (with the running-mean gain of (10)).                         (12)
   *A young reference never locks*: the reference counts its *support*, the time accepted samples
   have confirmed it (the alignment window's field rows count: see :meth:`Chakamo._state_from_alignment`).
   While the support is below ``mag_new_field_s``, a field away from the reference that has held
   longer than that support replaces it at once.  So a reference learnt next to a steel object at the
   start of a recording gives way to the clean field as soon as the clean field has lasted longer
   than the disturbed one had (tested: 3 s of disturbance at the start of a gait clip), while short
   disturbances (a stance near the floor: under 0.5 s) never displace a reference confirmed for seconds.

   *No rest and no undisturbed period* (the field wanders everywhere): samples within the thresholds
   of the current reference correct the heading; the reference moves to whichever stable field has
   held longest while young, and after ``mag_new_field_s`` of support only by the 60 s rule above.
   Between accepted samples the heading follows the gyroscope.  The heading is then only as good as
   the field the accepted samples saw: the filter does not (and cannot) tell a uniform, stable
   disturbance from the earth's field.  The offline smoother (15) then weights the samples by their
   distance from the recording's median norm and dip.

   *Optional* (``mag_bias``): a bias error also turns the heading, :math:`\dot\delta^* =
   -(R_{E'S} e)_z`, and the first-order heading filter (10) lags a ramp by :math:`\tau_{mag}` times
   its rate, so :math:`\operatorname{wrap}(\delta^* - \delta)/\tau_{mag} = -LP_1(R_{E'S})_z\, e + \nu`
   is a measurement of the vertical bias (same innovation form as (8), first-order low-passes with
   ``tau_mag_s``, noise :math:`\sigma_{mag}^2\tau_{mag}/dt`, only on accepted samples after the
   initial ramp).  *Gate*: a bias error within its prior lags the heading by at most
   :math:`3\sigma_{init}\tau_{mag}` (13.5° with the defaults); a larger :math:`|\delta^* - \delta|` is a field
   that changed within the thresholds of (11) (a recording that starts next to a magnet), not a bias, and is
   not used as one.                                                                            (12b)

Offline smoother (``offline=True``, the default: clinical analysis happens after recording)
------------------------------------------------------------------------------------------
The causal filter runs forward, and backward in time (samples reversed, gyroscope negated).
1. *Bias, two-filter smoother*: the forward estimate uses samples ``[0, k]``, the backward one
   ``[k, N)``; both are Gaussian estimates of the same random-walk bias, combined in information
   form :math:`P_s^{-1} = P_f^{-1} + P_b^{-1}`,
   :math:`\hat b_s = P_s (P_f^{-1}\hat b_f + P_b^{-1}\hat b_b)`                                (13)
   (Fraser & Potter 1969; the backward pass estimates :math:`-b`).  The scale states (8k) (the backward pass,
   gyroscope negated, estimates the same ``k``) are combined per axis by their variances,
   :math:`\hat k_s = (P_{k,b}\hat k_f + P_{k,f}\hat k_b)/(P_{k,f} + P_{k,b})`, and the strapdown below uses
   :math:`\hat b_s + \operatorname{diag}(\hat k_s)\,\omega_{meas}`; (13) itself uses the bias block of each pass's
   covariance (the bias–scale cross-covariance is left out of the combination).
   *The passes use the field for the vertical bias* (``offline_mag_bias``, default on; the causal filter's
   ``mag_bias`` stays off): the accelerometer (8) never sees the bias about the vertical, so during motion the
   strapdown heading drifts with it, and where the field is rejected the heading kernel (14) can only bridge
   from the clean ends.  BROAD trial 35 (magnet at 4 cm): the strapdown heading drifts 9.6° over 85 s of motion
   (0.11 °/s, flat at rest, the same with the motion bias (8) off: a drift seen only in motion) while the field is
   rejected for 55 s of it; (12b) measures that drift in the clean motion after the magnet, the backward pass
   carries it into the gap and (13) combines it: trial 35 1.69° → 0.98°, 32 (magnet at 1 cm) 1.66° → 1.15°.
   *Designed on half B*: the design looked at trials 32 and 35 (both in half B of the held-out split).  On half A
   it barely moves a trial (defaults, 9D total RMSE off → on: 02 0.74 → 0.75°, 10 1.55 → 1.53°, 18 0.89 → 0.90°,
   24 0.83 → 0.81°, 30 1.46 → 1.44°; mean 1.094 → 1.086°).  The held-out grid of ``benchmarks.broad`` includes
   the switch, so each tuning half chooses it: both choose it on, half A by that small margin only.
   *Known cost*: a field that turns slowly within the thresholds of (11) is partly learnt as bias (the gate
   below is a constant, not the covariance; after a rejection gap the lag model overstates the bias): the
   session pipeline's slowly turning field test keeps its guarantee only with ``offline_mag_bias=False``.
   In the causal filter (12b) hurts BROAD (9D 1.50/2.90 → 1.74/2.97 undisturbed/disturbed means, gated): there the
   heading correction (10) already follows a drift, and a field inhomogeneity read as bias turns the output at
   once.                                                                                      (13a)
2. The strapdown (1) is re-run with :math:`\hat b_s`; the acceleration in ``I`` is filtered with the
   same Butterworth filter *forward and backward* (zero phase, no delay), and :math:`q_{E'I}(k)` is
   the shortest rotation taking the filtered direction to ``z``.  Missing accelerometer rows are
   interpolated in ``I``.  At the ends the signal is extended by its mirror image (even padding over
   3 τ_acc): the end value is then a one-sided mean of the last seconds.  (Odd padding, used before,
   makes the filtered value pass through the raw end sample, so a clip that starts or ends in motion
   had its limb acceleration read as tilt: 22° on the gait scenarios of the tests.)
3. 9D: the heading target (9) is unwrapped and smoothed by a two-sided exponential kernel
   :math:`e^{-|t_k - t_j|/\tau}` (``offline_tau_mag_s``; the bias-corrected strapdown frame drifts
   so little that a longer window than the causal ``tau_mag_s`` pays off) — a positive kernel, so long
   disturbances are bridged by the nearest clean field:
   :math:`\delta_s(k) = \sum_j w_j e^{-|t_k-t_j|/\tau}\delta^*_j / \sum_j w_j e^{-|t_k-t_j|/\tau}`. (14)
   The weights are zero for samples that either pass found away from its reference (11-12); the others
   get a Gaussian weight of their deviation from the recording's median norm and dip, with widths
   ``offline_mag_sigma`` × the rejection thresholds, so that mildly disturbed fields (below the
   thresholds) count less.                                                                   (15)
   *Guard* (15a): a sample counts only if every sample within ``offline_mag_guard_s`` on either side was
   near both references.  Before, a sample had to pass both passes' hysteresis (0.5 s after a disturbance in
   each direction of time), a 1 s exclusion around every disturbance: on a walking shank, whose clean swing
   lasts ≈ 0.5 s between stance-phase floor fields, that removed every clean sample, and the only samples
   left were disturbances that had passed (11) unseen (gait scenarios of the tests, seed 4: 12.8°).
   *Robust heading* (15b): a floor field that turns the horizontal field about the vertical keeps its norm
   and dip (in the scenario above: apparent north 24–41° off at a norm within 2 % and a dip within 9°), so no
   norm or dip test sees it.  But the earth's field is fixed in ``E``, and the bias-corrected strapdown
   drifts slowly, so clean targets :math:`\delta^*_j` follow :math:`\delta_s`; (14) is re-run with Cauchy
   weights :math:`w_j c^2/(c^2 + r_j^2)` of the residual :math:`r_j = \operatorname{wrap}(\delta^*_j -
   \delta_s(t_j))`, :math:`c` = ``offline_heading_width_rad`` (3 passes).

Online use
----------
The offline variant needs the whole recording, so :meth:`Chakamo.update` always runs the *causal*
filter (two half batches through ``update`` equal one causal batch); ``estimate`` runs the offline
smoother when ``params.offline`` is true and ``state_`` is then the forward filter's final state.
:meth:`Chakamo.estimate_causal` and :meth:`Chakamo.estimate_offline` are explicit entry points.

State layout: see :mod:`estimators.orientation.chakamo_kernels` (``STATE_SIZE`` = 152, first four = ``q``).

Accuracy and speed
------------------
Measured by ``python -m benchmarks.broad`` (10 BROAD trials, one parameter set: these defaults) and
``python -m benchmarks.speed``; the current numbers are in the README, beside VQF run in the same tables.

Tuned on BROAD (so with a risk of overfitting these 10 trials): ``bias_sigma_motion_rad_s``,
``bias_motion_rate_scale``, ``offline_tau_mag_s``, ``offline_mag_sigma``; chosen on the simulated gait floor-disturbance seeds 0–5 of
the tests (held out: seeds 6–11, BROAD, ``benchmarks.heading``): ``offline_mag_guard_s``,
``offline_heading_width_rad``; from the project simulator's sensor model, not a grid key, though BROAD scans at
0.5 / 1 / 2 % had been seen (8b ix, xii): ``gyr_scale_sigma``; set by hand: ``gyr_scale_forgetting_s`` (8k); the
others are VQF's published defaults where the concepts correspond.  Weak spot: trial 35 (magnet attached at 4 cm)
in the causal 9D filter (≈ 55 s of field rejection, gyroscope heading drift); offline it is fixed by (13a).

Held out (``python -m benchmarks.broad``, parameters, ``offline_mag_bias`` among them, chosen on one half of the ten trials, scored on the other; undisturbed / disturbed total RMSE, °): 9D
A→B 1.11/2.77 (offline VQF 2.26/3.18), B→A 1.06/1.12 (VQF 1.26/2.73); 6D A→B 1.41/1.95 (VQF 6D 1.49/2.26), B→A
0.68/3.01 (VQF 6D 0.81/3.00: *not met*) before the scale states (8k); with them (prior fixed at the simulator's
0.5 %, not a grid key; (8b xii) says what of BROAD it had seen) 9D A→B 1.11/2.75, B→A 0.99/1.38; 6D A→B 1.42/1.59
(VQF 6D 1.49/2.26), B→A 0.58/2.41 (VQF 6D 0.81/3.00): met, for a fixed prior of 0.5–1 % (at 2 % A→B is lost;
with the prior in the grid, half A chooses 2 %).  These defaults' own numbers on all ten: 9D 1.08/2.10 (before
(8k) 1.08/2.13; 1.07/2.37 without (13a)), 6D 0.94/2.18 (before (8k) 1.01/2.49).

References
----------
* D. Laidig, T. Seel (2023), VQF: Highly accurate IMU orientation estimation with bias estimation and
  magnetic disturbance rejection. Information Fusion 91:187–204. doi:10.1016/j.inffus.2022.10.014
* D. C. Fraser, J. E. Potter (1969), The optimum linear smoother as a combination of two optimum
  linear filters. IEEE Trans. Automatic Control 14(4):387–390.
* D. Laidig, M. Caruso, A. Cereatti, T. Seel (2021), BROAD — A Benchmark for Robust Inertial
  Orientation Estimation. Data 6(7):72.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Self

import numpy as np
from numpy.typing import ArrayLike

from estimators import quaternion as quat
from estimators.orientation import chakamo_kernels as kern
from estimators.orientation import chakamo_reference as ref
from estimators.orientation.chakamo_offline import (
    ROBUST_ITERATIONS, butterworth, field_weights, guarded, heading_blocks, robust_heading, zero_phase_inclination,
    zero_phase_lowpass,
)
from estimators.orientation.base import (
    Alignment, FloatArray, ImuInput, OrientationMethod, SampleFlags, check_flag, check_parameter,
)

_DEG = math.pi / 180.0
#: reference correlation time of the motion bias measurement (8), s (see ``coefficients``)
MOTION_NOISE_TAU_S = 3.0


@dataclass(frozen=True)
class ChakamoParams:
    """Parameters of :class:`Chakamo` (time constants in s, rates in rad/s; rate-independent).

    Attributes
    ----------
    tau_acc_s: time constant of the quasi-inertial acceleration low-pass (2), s. Default 3.0.
    tau_mag_s: time constant of the causal heading correction (10), s. Default 9.0.
    rest_bias: estimate the gyroscope bias at rest (7). Default True.
    motion_bias: estimate the gyroscope bias during motion (8). Default True.
    mag_rejection: reject magnetically disturbed samples (11-12). Default True.
    bias_sigma_init_rad_s: initial bias standard deviation, rad/s. Default 0.5°/s.
    bias_forgetting_s: time over which the bias uncertainty grows back to ``bias_sigma_init_rad_s``
        (random-walk process noise (5)), s. Default 100.
    bias_clip_rad_s: largest bias magnitude per axis, rad/s. Default 2°/s.
    bias_sigma_motion_rad_s: noise of the motion bias measurement (8), rad/s. Default 0.2°/s.
    bias_sigma_rest_rad_s: noise of the rest bias measurement (7), rad/s. Default 0.03°/s.
    rest_min_s: time the rest conditions must hold before the sensor counts as at rest, s. Default 1.5.
    rest_tau_s: time constant of the rest-detection low-passes, s. Default 0.5.
    rest_gyr_th_rad_s: rest threshold on angular rate and its deviation, rad/s. Default 2°/s.
    rest_acc_th_m_s2: rest threshold on the deviation of the acceleration, m/s². Default 0.5.
    mag_ref_tau_s: time constant with which the field reference follows undisturbed samples, s. Default 20.
    mag_norm_th: allowed relative deviation of the field norm from its reference (-). Default 0.1.
    mag_dip_th_rad: allowed deviation of the dip angle from its reference, rad. Default 10°.
    mag_new_field_s: time a new field must stay stable to be accepted as the reference, s. Default 20.
    mag_max_rejection_s: rejection time after which a stable new field is accepted, s. Default 60.
    mag_min_undisturbed_s: time the field must stay near the reference before it corrects heading again
        (hysteresis of (11)), s. Default 0.5.
    mag_bias: 9D only, the causal filter estimates the gyroscope bias also from the heading corrections (12b).
        Default False (on BROAD it hurts the causal filter: field inhomogeneity leaks into the bias; the offline
        smoother's passes have their own switch, ``offline_mag_bias``).
    bias_sigma_mag_rad_s: noise of the heading bias measurement (12b), rad/s. Default 0.2°/s.
    bias_motion_rate_scale: rate-proportional part of the motion bias noise (8), rad/s per rad/s (-).
        Default 0.002.
    offline: ``estimate`` runs the offline forward-backward smoother (13-15). Default True.
    offline_tau_mag_s: time constant of the offline heading kernel (14), s. Default 20.
    offline_mag_sigma: widths of the offline field weights (15) as a fraction of ``mag_norm_th`` and
        ``mag_dip_th_rad`` (-). Default 0.5.
    offline_mag_guard_s: time, s, on either side of a sample within which every field sample must have been
        near both passes' references for it to count in the offline heading (15a). Default 0.25 (half the
        causal hysteresis, on each side).
    offline_heading_width_rad: width of the Cauchy weights of the offline heading residual (15b), rad;
        0 = the plain weighted mean (14). Default 5°.
    offline_mag_bias: 9D only, the offline smoother's forward and backward passes estimate the bias also from
        the heading corrections (12b), whatever ``mag_bias`` (the causal filter's switch) says (13a). Default True.
    gyr_scale_sigma: prior standard deviation of the per-axis gyroscope scale errors (8k) (-); 0 = no scale
        states (the 3-state bias filter); at most 0.05 (the clip of the estimate). Default 0.005 (0.5 %: the
        project simulator's MetaMotionR scale-error draw; not a grid key, see (8b xii) for what it had seen).
    gyr_scale_forgetting_s: time over which the scale uncertainty grows back to ``gyr_scale_sigma`` (slow random
        walk of (8k): sensitivity drifts with temperature), s. Default 10000.
    """

    tau_acc_s: float = 3.0
    tau_mag_s: float = 9.0
    rest_bias: bool = True
    motion_bias: bool = True
    mag_rejection: bool = True
    bias_sigma_init_rad_s: float = 0.5 * _DEG
    bias_forgetting_s: float = 100.0
    bias_clip_rad_s: float = 2.0 * _DEG
    bias_sigma_motion_rad_s: float = 0.2 * _DEG
    bias_sigma_rest_rad_s: float = 0.03 * _DEG
    bias_motion_rate_scale: float = 0.002
    rest_min_s: float = 1.5
    rest_tau_s: float = 0.5
    rest_gyr_th_rad_s: float = 2.0 * _DEG
    rest_acc_th_m_s2: float = 0.5
    mag_ref_tau_s: float = 20.0
    mag_norm_th: float = 0.1
    mag_dip_th_rad: float = 10.0 * _DEG
    mag_new_field_s: float = 20.0
    mag_max_rejection_s: float = 60.0
    mag_min_undisturbed_s: float = 0.5
    mag_bias: bool = False
    bias_sigma_mag_rad_s: float = 0.2 * _DEG
    offline: bool = True
    offline_tau_mag_s: float = 20.0
    offline_mag_sigma: float = 0.5
    offline_mag_guard_s: float = 0.25
    offline_heading_width_rad: float = 5.0 * _DEG
    offline_mag_bias: bool = True
    gyr_scale_sigma: float = 0.005
    gyr_scale_forgetting_s: float = 10000.0

    def __post_init__(self) -> None:
        positive = ("tau_acc_s", "tau_mag_s", "bias_sigma_init_rad_s", "bias_forgetting_s", "bias_clip_rad_s",
                    "bias_sigma_motion_rad_s", "bias_sigma_rest_rad_s", "bias_sigma_mag_rad_s", "rest_tau_s",
                    "rest_gyr_th_rad_s", "rest_acc_th_m_s2", "mag_ref_tau_s", "mag_norm_th", "mag_dip_th_rad",
                    "offline_tau_mag_s", "offline_mag_sigma", "gyr_scale_forgetting_s")
        for name in positive:
            check_parameter(name, getattr(self, name), low_open=True)
        non_negative = ("rest_min_s", "bias_motion_rate_scale", "mag_min_undisturbed_s", "mag_new_field_s",
                        "mag_max_rejection_s", "offline_mag_guard_s", "offline_heading_width_rad")
        for name in non_negative:
            check_parameter(name, getattr(self, name))
        # a prior wider than the clip of the estimate (±K_CLIP) would not be a prior of the clipped state
        check_parameter("gyr_scale_sigma", self.gyr_scale_sigma, high=kern.K_CLIP,
                        hint="the scale estimate is clipped to ±5 %")
        check_parameter("mag_dip_th_rad", self.mag_dip_th_rad, low_open=True, high=math.pi, unit="rad")
        for name in ("rest_bias", "motion_bias", "mag_rejection", "mag_bias", "offline", "offline_mag_bias"):
            check_flag(name, getattr(self, name))


def _gain(tau_s: float, dt_s: float) -> float:
    """First-order low-pass gain :math:`1 - e^{-dt/\\tau}`."""
    return 1.0 - math.exp(-dt_s / tau_s)


def coefficients(p: ChakamoParams, fs_hz: float) -> FloatArray:
    """The kernel's coefficient vector (layout ``chakamo_kernels.C_*``) for rate ``fs_hz``."""
    dt = 1.0 / fs_hz
    b, a = butterworth(p.tau_acc_s, fs_hz)
    c = np.zeros(kern.COEFF_SIZE)
    c[kern.C_DT] = dt
    c[kern.C_B0], c[kern.C_B1], c[kern.C_B2] = b
    c[kern.C_A1], c[kern.C_A2] = a[1], a[2]
    c[kern.C_NINIT] = math.ceil(p.tau_acc_s * fs_hz)
    c[kern.C_KREST] = _gain(p.rest_tau_s, dt)
    c[kern.C_THG2] = p.rest_gyr_th_rad_s ** 2
    c[kern.C_THA2] = p.rest_acc_th_m_s2 ** 2
    c[kern.C_RESTMIN] = p.rest_min_s
    c[kern.C_RREST] = p.bias_sigma_rest_rad_s ** 2 * p.rest_tau_s / dt
    c[kern.C_RMOT] = p.bias_sigma_motion_rad_s ** 2 * MOTION_NOISE_TAU_S ** 2 / (p.tau_acc_s * dt)
    c[kern.C_QBIAS] = p.bias_sigma_init_rad_s ** 2 * dt / p.bias_forgetting_s
    c[kern.C_CLIP] = p.bias_clip_rad_s
    c[kern.C_RESTON] = float(p.rest_bias)
    c[kern.C_MOTON] = float(p.motion_bias)
    c[kern.C_KMAG] = _gain(p.tau_mag_s, dt)
    c[kern.C_KREF] = _gain(p.mag_ref_tau_s, dt)
    c[kern.C_NORMTH] = p.mag_norm_th
    c[kern.C_DIPTH] = p.mag_dip_th_rad
    c[kern.C_NEWS] = p.mag_new_field_s
    c[kern.C_MAXREJ] = p.mag_max_rejection_s
    c[kern.C_REJON] = float(p.mag_rejection)
    c[kern.C_KCAND] = _gain(p.mag_ref_tau_s, dt)
    c[kern.C_KW2] = _gain(p.tau_acc_s, dt)
    c[kern.C_MINUND] = p.mag_min_undisturbed_s
    c[kern.C_P0] = p.bias_sigma_init_rad_s ** 2
    c[kern.C_MAGBIAS] = float(p.mag_bias)  # 6D: never read (no field sample corrects)
    c[kern.C_NMAGINIT] = math.ceil(p.tau_mag_s * fs_hz)
    c[kern.C_RMAG] = p.bias_sigma_mag_rad_s ** 2 * p.tau_mag_s / dt
    c[kern.C_TAUMAG] = p.tau_mag_s
    c[kern.C_MAGGATE] = 3.0 * p.bias_sigma_init_rad_s * p.tau_mag_s  # (12b) gate: the lag of a 3σ bias error

    c[kern.C_SCALE2] = (p.bias_motion_rate_scale / p.bias_sigma_motion_rad_s) ** 2
    c[kern.C_PK0] = p.gyr_scale_sigma ** 2
    c[kern.C_QK] = p.gyr_scale_sigma ** 2 * dt / p.gyr_scale_forgetting_s
    return c


class Chakamo(OrientationMethod):
    """ChakaMo's default filter (theory in the module docstring); 6D and 9D, causal and offline."""

    name = "chakamo"
    params_type = ChakamoParams
    state_size = kern.STATE_SIZE
    #: the plain window mean seeds the quasi-inertial low-pass (2); the velocity regression of the base module
    #: moved the floor-disturbance scenario of the tests (heading RMS median 3.9° → 5.3°) and helped nothing else
    align_by_regression = False
    #: the running means (2) and the field reference (11) start from the alignment window, also from a ``q0``
    seeds_from_window = True

    # ------------------------------------------------------------- entry points
    def estimate_causal(self, acc: ArrayLike, gyr: ArrayLike, mag: ArrayLike | None = None, *, fs_hz: float,
                        q0: ArrayLike | None = None) -> Self:
        """Run the causal (real-time) filter regardless of ``params.offline``."""
        return self._with_offline(False).estimate(acc, gyr, mag, fs_hz=fs_hz, q0=q0)._copy_results(self)

    def estimate_offline(self, acc: ArrayLike, gyr: ArrayLike, mag: ArrayLike | None = None, *, fs_hz: float,
                         q0: ArrayLike | None = None) -> Self:
        """Run the offline forward-backward smoother regardless of ``params.offline``."""
        return self._with_offline(True).estimate(acc, gyr, mag, fs_hz=fs_hz, q0=q0)._copy_results(self)

    def _run_online(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``update`` runs the *causal* filter: the offline smoother needs the whole recording."""
        q, new_state, _ = self._causal(data, state0, reference=False, want_aux=False)
        return q, new_state

    # ------------------------------------------------------------ base contract
    def _state_from_quaternion(self, q: FloatArray, data: ImuInput) -> FloatArray:
        s = np.zeros(kern.STATE_SIZE)
        s[kern.S_Q:kern.S_Q + 4] = q
        s[kern.S_QIS:kern.S_QIS + 4] = q
        s[kern.S_QEI] = 1.0
        var0 = self.params.bias_sigma_init_rad_s ** 2
        for i in range(3):
            s[kern.S_P6 + 7 * i] = var0
            s[kern.S_P6 + 7 * (3 + i)] = self.params.gyr_scale_sigma ** 2
        first = int(np.flatnonzero(data.acc_ok)[0]) if data.acc_ok.any() else 0
        s[kern.S_AREST:kern.S_AREST + 3] = data.acc[first]
        return s

    def _state_from_alignment(self, alignment: Alignment, data: ImuInput) -> FloatArray:
        """The aligned start: its heading comes from the window's field rows, so the heading mean (10) starts
        with their weight; the rest of the window seed is :meth:`_seed_from_window`."""
        s = self._state_from_quaternion(alignment.q, data)
        if _window_field_reference(alignment) is not None:
            s[kern.S_NMAG] = float(alignment.n_mag)
        return s

    def _seed_from_window(self, state: FloatArray, alignment: Alignment, data: ImuInput) -> None:
        """Seed the running means with the alignment window's, for an aligned start and a ``q0`` alike.

        The acceleration mean in ``I`` (2) starts as the window's motion-compensated mean, rotated into ``I`` by
        the start attitude ``q_IS`` (the aligned or the given one), with the weight of its rows (capped below
        ``n_init`` so that the Butterworth states are still set to steady state); the field reference (11) with
        the window's mean norm and the dip of its mean field: a reference learnt on the window, not on one
        sample seen with an unconverged inclination.  Neither needs the attitude's heading or tilt to be
        right.  From a ``q0`` the two used to start empty, so the inclination (3-4), applied in full at every
        sample, took sample 0's raw specific force for gravity: gait seeds 6–7 with ``q0`` = truth read tilt up
        to 56° and heading RMS 8.6–15° (against 4.3–6.5° from the aligned start); from the window they read the
        aligned start's tilt (5.5–7.2° max) and heading RMS 5.2–7.8° (test
        ``test_a_heel_strike_on_sample_0_with_q0_given``; offline 0.1–1.2°, was 0.4–1.6°).  The heading mean (10)
        still starts empty from a ``q0``, as a start that may be wrong is corrected fast (base module docstring);
        seeded with the window's field rows it trusted the given heading and read 4.1–5.0° on those clips, which
        only a true ``q0`` earns.  The rest-detection low-pass ``a_rest`` starts from sample 0 in both starts (it
        only delays the rest detection after an impact there).
        """
        n_init = math.ceil(self.params.tau_acc_s * data.fs_hz)
        state[kern.S_ALP:kern.S_ALP + 3] = quat.rotate(state[kern.S_QIS:kern.S_QIS + 4], alignment.acc_mean)
        state[kern.S_NACC] = float(max(0, min(alignment.n_acc, n_init - 1)))
        reference = _window_field_reference(alignment)
        if reference is not None:
            state[kern.S_MREFN] = state[kern.S_MCANDN] = reference[0]
            state[kern.S_MREFD] = state[kern.S_MCANDD] = reference[1]
            state[kern.S_MREFOK] = 1.0
            state[kern.S_TUND] = self.params.mag_min_undisturbed_s
            state[kern.S_TSUP] = alignment.n_mag / data.fs_hz  # the window's field rows confirm it

    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        return self._batch(data, state0, reference=False)

    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        return self._batch(data, state0, reference=True)

    # ----------------------------------------------------------------- helpers
    def _with_offline(self, offline: bool) -> "Chakamo":
        return Chakamo(replace(self.params, offline=offline))

    def _copy_results(self, target: "Chakamo") -> "Chakamo":
        target.orientation_, target.state_, target.flags_ = self.orientation_, self.state_, self.flags_
        return target

    def _batch(self, data: ImuInput, state0: FloatArray, *, reference: bool) -> tuple[FloatArray, FloatArray]:
        if self.params.offline:
            return self._offline(data, state0, reference=reference)
        q, s, _ = self._causal(data, state0, reference=reference, want_aux=False)
        return q, s

    def _causal(self, data: ImuInput, state0: FloatArray, *, reference: bool, want_aux: bool,
                params: ChakamoParams | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
        coeffs = coefficients(self.params if params is None else params, data.fs_hz)
        batch = ref.chakamo_batch_reference if reference else kern.chakamo_batch
        return batch(data.acc, _gyr_with_gaps(data), data.mag_array, data.acc_ok, data.mag_ok, coeffs,
                     np.asarray(state0, np.float64), want_aux)

    def _offline(self, data: ImuInput, state0: FloatArray, *, reference: bool) -> tuple[FloatArray, FloatArray]:
        p = self.params
        dt = data.dt_s
        # forward and backward causal passes: independent (each aligns on its own first samples), so the
        # compiled kernels run them concurrently on two cores; the numpy reference runs them in turn
        # time reversed: gyroscope sample k is the rate over (k-1, k], so the backward step k+1 -> k uses
        # -gyr[k+1]; the first backward sample has no step before it (rate 0)
        def step_aligned(x: np.ndarray, fill) -> np.ndarray:
            out = np.full_like(x, fill)
            out[1:] = x[:0:-1]
            return out

        flags = data.flags
        rev = ImuInput(acc=np.ascontiguousarray(data.acc[::-1]), gyr=-step_aligned(data.gyr, 0.0),
                       mag=None if data.mag is None else np.ascontiguousarray(data.mag[::-1]),
                       acc_ok=np.ascontiguousarray(data.acc_ok[::-1]), mag_ok=np.ascontiguousarray(data.mag_ok[::-1]),
                       fs_hz=data.fs_hz, flags=SampleFlags(
                           np.ascontiguousarray(flags.acc_missing[::-1]), step_aligned(flags.gyr_missing, False),
                           np.ascontiguousarray(flags.mag_missing[::-1]), np.ascontiguousarray(flags.acc_saturated[::-1]),
                           step_aligned(flags.gyr_saturated, False)))
        state0_b = self._initial_state_for(rev, None)
        passes = replace(p, mag_bias=p.offline_mag_bias)  # (13a): the passes learn the vertical bias from the field
        if reference:
            _, s_fwd, aux_f = self._causal(data, state0, reference=True, want_aux=True, params=passes)
            _, _, aux_b = self._causal(rev, state0_b, reference=True, want_aux=True, params=passes)
        else:
            with ThreadPoolExecutor(max_workers=1) as pool:
                backward = pool.submit(self._causal, rev, state0_b, reference=False, want_aux=True, params=passes)
                _, s_fwd, aux_f = self._causal(data, state0, reference=False, want_aux=True, params=passes)
                _, _, aux_b = backward.result()
        aux_b = aux_b[::-1]
        # (13) two-filter bias smoother
        smooth = ref.smooth_bias_reference if reference else kern.smooth_bias_batch
        bias = smooth(aux_f[:, kern.A_BIAS:kern.A_BIAS + 3], np.ascontiguousarray(aux_f[:, kern.A_P:kern.A_P + 6]),
                      np.ascontiguousarray(-aux_b[:, kern.A_BIAS:kern.A_BIAS + 3]),
                      np.ascontiguousarray(aux_b[:, kern.A_P:kern.A_P + 6]))
        if p.gyr_scale_sigma > 0.0:  # (13) for the scale states (8k): per axis, weighted by the variances
            kf, pf = aux_f[:, kern.A_K:kern.A_K + 3], aux_f[:, kern.A_PK:kern.A_PK + 3]
            kb, pb = aux_b[:, kern.A_K:kern.A_K + 3], aux_b[:, kern.A_PK:kern.A_PK + 3]
            bias = bias + (kf * pb + kb * pf) / (pf + pb) * np.nan_to_num(data.gyr)
        # strapdown with the smoothed bias, zero-phase inclination
        strap = ref.strapdown_reference if reference else kern.strapdown_batch
        q_is = strap(_gyr_with_gaps(data), bias, np.asarray(state0[:4], np.float64), dt)
        if reference:  # the readable numpy form
            q_ei = zero_phase_inclination(q_is, data.acc, data.acc_ok, p.tau_acc_s, data.fs_hz)
            q_es = quat.multiply(q_ei, q_is)
            mag_e = quat.rotate(q_es, data.mag_array)
        else:  # the same steps fused per sample in numba
            acc_lp = zero_phase_lowpass(kern.rotate_batch(q_is, data.acc), data.acc_ok, p.tau_acc_s, data.fs_hz)
            q_es, mag_e = kern.compose_offline(q_is, np.ascontiguousarray(acc_lp), data.mag_array)
        if data.mag is None:  # 6D keeps the heading of the strapdown
            return quat.normalize(q_es), s_fwd
        # 9D: smooth the heading (14-15)
        if p.mag_rejection:  # near both passes' references, edges guarded on both sides (15a)
            near_f, near_b = aux_f[:, kern.A_MAGNEAR] > 0.5, aux_b[:, kern.A_MAGNEAR] > 0.5
            weight = guarded(data.mag_ok & near_f & near_b, round(p.offline_mag_guard_s * data.fs_hz))
            if not weight.any():
                weight = data.mag_ok & (near_f | near_b)
        else:
            weight = data.mag_ok.copy()
        weight = field_weights(mag_e, weight, p.mag_norm_th * p.offline_mag_sigma,
                               p.mag_dip_th_rad * p.offline_mag_sigma)
        target = np.arctan2(mag_e[:, 0], mag_e[:, 1])
        if reference:
            delta = robust_heading(target, weight, p.offline_tau_mag_s, dt, p.offline_heading_width_rad)
            return quat.normalize(quat.multiply(quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), delta), q_es)), s_fwd
        block, decay = heading_blocks(p.offline_tau_mag_s, dt)
        delta = kern.robust_heading_batch(target, weight, decay, block, p.offline_heading_width_rad ** 2,
                                          ROBUST_ITERATIONS)
        return kern.apply_heading(q_es, delta), s_fwd


def _window_field_reference(alignment: Alignment) -> tuple[float, float] | None:
    """The field reference (11) the alignment window holds: its mean norm and the dip of its mean field (rad)
    against its gravity; ``None`` without a field row there."""
    if alignment.mag_mean is None or alignment.n_mag == 0:
        return None
    m_norm = float(np.linalg.norm(alignment.mag_mean))
    if m_norm == 0.0 or alignment.mag_norm_mean <= 0.0:
        return None
    up = alignment.acc_mean / np.linalg.norm(alignment.acc_mean)
    return alignment.mag_norm_mean, math.asin(min(max(-float(alignment.mag_mean @ up) / m_norm, -1.0), 1.0))


def _gyr_with_gaps(data: ImuInput) -> FloatArray:
    """The gyroscope with missing rows as NaN: the kernels then hold the orientation there."""
    missing = data.flags.gyr_missing
    if not missing.any():
        return data.gyr
    gyr = data.gyr.copy()
    gyr[missing] = np.nan
    return gyr
