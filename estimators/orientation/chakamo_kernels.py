r"""Compiled kernels of :mod:`estimators.orientation.chakamo`, and the state and coefficient layouts.

The theory is in the module docstring of :mod:`estimators.orientation.chakamo`; this module only
holds the per-sample arithmetic.  Every ``@njit`` entry point has a numpy twin (``*_reference``) in
:mod:`estimators.orientation.chakamo_reference` that runs the same maths with vector operations and
:mod:`estimators.quaternion`; the tests check that both agree to ≤ 1e-9.

State vector (1-D float64, ``STATE_SIZE`` entries; indices are the ``S_*`` constants)
-------------------------------------------------------------------------------------
====================  ==========================================================================
``0:4``   q           output ``q_earth_sensor`` = R_z(δ) ⊗ q_E'I ⊗ q_IS
``4:8``   q_IS        strapdown quaternion, sensor → quasi-inertial frame I
``8:12``  q_EI        inclination correction, I → heading-free earth frame E'
``12``    δ           heading offset (rad) about the earth z axis, E' → E
``13:19`` lp_state    Butterworth DF2T state of the I-frame acceleration, ``[z1(3), z2(3)]``
``19:22`` a_lp        last low-pass output (m/s², I frame)
``22``    n_acc       accelerometer samples seen (the first ``n_init`` are averaged, not filtered)
``23:26`` b           gyroscope bias estimate (rad/s, sensor frame)
``26:29`` g_rest      first-order low-pass of the gyroscope for rest detection (rad/s)
``29:32`` a_rest      first-order low-pass of the accelerometer for rest detection (m/s²)
``32``    t_rest      time the rest conditions have held (s)
``33``    rest        1 when at rest
``34``    m_norm_ref  reference field norm (µT); ``35`` dip_ref (rad); ``36`` reference valid (0/1)
``37``    t_reject    time the field has been rejected as disturbed (s)
``38``    m_norm_cand candidate norm; ``39`` candidate dip; ``40`` time the candidate has held (s)
``41``    n_mag       undisturbed magnetometer samples since the reference was (re)set
``42``    disturbed   1 when the last magnetometer sample was rejected
``43:61`` R_lp        Butterworth state of R_IS (row-major, ``[z1(9), z2(9)]``), for eq. (8)
``61:67`` u_lp        Butterworth state of R_IS·b̂ (``[z1(3), z2(3)]``), for eq. (8)
``67:79`` outputs     last outputs of those two filters (9 + 3; scratch, overwritten every sample)
``79``    w2_lp       first-order low-pass (τ_acc) of |ω - b̂|² (rad²/s²), scales the motion noise (8)
``80``    t_undist    time the field has stayed near the reference (s), for the hysteresis of (11)
``81:85`` m_lp        first-order low-passes (τ_mag) of the E' z axis in sensor coordinates (3) and of
                      its product with b̂ (1; without diag(k̂) ω), for the heading bias measurement (12b)
``85``    t_support   time the field reference has been confirmed by accepted samples (s), for (12)
``86:89`` k           per-axis gyroscope scale errors (-), ω_meas = (1 + diag k) ω + b, eq. (8k)
``89:125`` P6         covariance of x = (b, k) (rad²/s², -), 6×6 row-major
``125:143`` W_lp      Butterworth state of R_IS·diag(ω_meas) (row-major, ``[z1(9), z2(9)]``), for eq. (8k)
``143:152`` outputs   last outputs of that filter (9; scratch)
====================  ==========================================================================

Without the scale states (``gyr_scale_sigma`` = 0: ``c[C_PK0]`` = ``c[C_QK]`` = 0) the scale block of ``P6`` and
its cross terms stay zero, so k stays 0 and every update is the 3-state bias filter's (equal up to rounding).

Coefficient vector ``c`` (built by ``chakamo.coefficients``; indices are the ``C_*`` constants):
dt, Butterworth ``b0 b1 b2 a1 a2``, n_init, rest low-pass gain, squared rest thresholds, rest time,
bias noise terms, clip, switches, magnetometer gains and thresholds.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from estimators.orientation.quat_kernels import qmat, qmul, qrot


# --- state indices: numpy int64 scalars, not Python ints.  numba types a global Python int as a literal, and
# compiles a helper once per distinct literal argument (``_qnorm`` three times, ...): 0.5-1 s of a fresh
# compilation (benchmarks/speed.py, first call; benchmarks/compile_work.py counts it per function)
S_Q, S_QIS, S_QEI, S_DELTA, S_LP, S_ALP, S_NACC = np.array([0, 4, 8, 12, 13, 19, 22], np.int64)
S_BIAS, S_GREST, S_AREST, S_TREST, S_REST = np.array([23, 26, 29, 32, 33], np.int64)
S_MREFN, S_MREFD, S_MREFOK, S_TREJ, S_MCANDN, S_MCANDD, S_TCAND, S_NMAG, S_MDIST = np.array(
    [34, 35, 36, 37, 38, 39, 40, 41, 42], np.int64)
S_RLP, S_ULP, S_RLPOUT, S_W2, S_TUND, S_MLP, S_TSUP = np.array([43, 61, 67, 79, 80, 81, 85], np.int64)
# per-axis gyroscope scale errors k (ω_meas = (1+diag k) ω + b), the full 6×6 covariance of (b, k), and the
# Butterworth state / output of the columns of R_IS scaled by ω_j, for their measurement rows in (8)
S_K, S_P6, S_WLP, S_WLPOUT = np.array([86, 89, 125, 143], np.int64)  # (8k)
STATE_SIZE = 152
#: largest scale error per axis (-)
K_CLIP = 0.05

# --- coefficient indices
(C_DT, C_B0, C_B1, C_B2, C_A1, C_A2, C_NINIT, C_KREST, C_THG2, C_THA2, C_RESTMIN, C_RREST, C_RMOT,
 C_QBIAS, C_CLIP, C_RESTON, C_MOTON, C_KMAG, C_KREF, C_NORMTH, C_DIPTH, C_NEWS, C_MAXREJ, C_REJON,
 C_KCAND, C_KW2, C_SCALE2, C_MINUND, C_P0, C_MAGBIAS, C_NMAGINIT, C_RMAG, C_TAUMAG, C_MAGGATE, C_QK, C_PK0
 ) = range(36)
COEFF_SIZE = 36

# --- auxiliary per-sample outputs (columns of ``aux``)
A_BIAS, A_P, A_REST, A_MAGUSED, A_MAGNEAR, A_K, A_PK = 0, 3, 9, 10, 11, 12, 15
AUX_SIZE = 18


# =====================================================================================
# scalar helpers (numba)
# =====================================================================================
@njit(cache=True)
def _qnorm(s, i):
    n = math.sqrt(s[i] * s[i] + s[i + 1] * s[i + 1] + s[i + 2] * s[i + 2] + s[i + 3] * s[i + 3])
    s[i] /= n
    s[i + 1] /= n
    s[i + 2] /= n
    s[i + 3] /= n


@njit(cache=True)
def _motion_row(s, e, y, r, clip):
    r"""One row of the bias measurement during motion, (8) and (8k): ``e`` is a row (x or y) of :math:`R_{E'I}`,
    ``y`` the inclination correction's rate about that axis (rad/s), ``r`` its noise variance.

    The row's terms are :math:`m = e\,LP(R_{IS})`, :math:`v = e\,LP(R_{IS}\hat b)` and the scale columns
    :math:`n = e\,LP(R_{IS}\,\mathrm{diag}\,\omega)`; the innovation :math:`y - v + m\hat b + n\hat k` (clipped) is
    applied with :math:`h = -(m, n)` (:func:`_bias_update`).
    """
    rl, w = S_RLPOUT, S_WLPOUT
    m0 = e[0] * s[rl] + e[1] * s[rl + 3] + e[2] * s[rl + 6]
    m1 = e[0] * s[rl + 1] + e[1] * s[rl + 4] + e[2] * s[rl + 7]
    m2 = e[0] * s[rl + 2] + e[1] * s[rl + 5] + e[2] * s[rl + 8]
    v = e[0] * s[rl + 9] + e[1] * s[rl + 10] + e[2] * s[rl + 11]
    n0 = e[0] * s[w] + e[1] * s[w + 3] + e[2] * s[w + 6]
    n1 = e[0] * s[w + 1] + e[1] * s[w + 4] + e[2] * s[w + 7]
    n2 = e[0] * s[w + 2] + e[1] * s[w + 5] + e[2] * s[w + 8]
    innov = (y - v + m0 * s[S_BIAS] + m1 * s[S_BIAS + 1] + m2 * s[S_BIAS + 2]
             + n0 * s[S_K] + n1 * s[S_K + 1] + n2 * s[S_K + 2])
    _bias_update(s, -m0, -m1, -m2, -n0, -n1, -n2, min(max(innov, -clip), clip), r, clip)


@njit(cache=True)
def _biquad9(s, start, out, r, g0, g1, g2, c, steady):
    """One DF2T step of the Butterworth low-pass (coefficients ``c[C_B0..C_A2]``) on the nine channels
    ``r[i]·g[i % 3]`` (``R_IS diag(ω)`` row-major), state ``s[start:start + 18]`` (``[z1(9), z2(9)]``), outputs
    written to ``s[out:out + 9]``; ``steady`` sets the state to the steady state of the input instead."""
    b0, b1, b2, a1, a2 = c[C_B0], c[C_B1], c[C_B2], c[C_A1], c[C_A2]
    for i in range(9):
        x = r[i] * (g0, g1, g2)[i % 3]
        if steady:
            s[start + i] = (1.0 - b0) * x
            s[start + 9 + i] = (b2 - a2) * x
            s[out + i] = x
        else:
            y = b0 * x + s[start + i]
            s[start + i] = b1 * x - a1 * y + s[start + 9 + i]
            s[start + 9 + i] = b2 * x - a2 * y
            s[out + i] = y


@njit(cache=True)
def _wrap(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@njit(cache=True)
def _bias_update(s, h0, h1, h2, h3, h4, h5, innov, r, clip):
    """Scalar Kalman update of ``x = (b, k)`` with measurement row ``h`` and innovation ``innov``; the covariance
    is the 6×6 at ``S_P6`` (row-major).  b is clipped to ±``clip``, k to ±``K_CLIP``."""
    ph0 = ph1 = ph2 = ph3 = ph4 = ph5 = 0.0  # P6 h, summed over the columns j
    for j in range(6):
        hj = (h0, h1, h2, h3, h4, h5)[j]
        o = S_P6 + j
        ph0 += s[o] * hj
        ph1 += s[o + 6] * hj
        ph2 += s[o + 12] * hj
        ph3 += s[o + 18] * hj
        ph4 += s[o + 24] * hj
        ph5 += s[o + 30] * hj
    ph = (ph0, ph1, ph2, ph3, ph4, ph5)
    sv = r + h0 * ph[0] + h1 * ph[1] + h2 * ph[2] + h3 * ph[3] + h4 * ph[4] + h5 * ph[5]
    f = innov / sv
    for i in range(3):
        s[S_BIAS + i] = min(max(s[S_BIAS + i] + ph[i] * f, -clip), clip)
        s[S_K + i] = min(max(s[S_K + i] + ph[3 + i] * f, -K_CLIP), K_CLIP)
    for i in range(6):
        g = ph[i] / sv
        o = S_P6 + 6 * i
        for j in range(6):
            s[o + j] -= g * ph[j]


# =====================================================================================
# the causal filter, one sample (numba)
# =====================================================================================
@njit(cache=True)
def chakamo_step(s, c, ax, ay, az, gx, gy, gz, mx, my, mz, acc_ok, mag_ok):
    """Advance state ``s`` (in place) by one sample; returns 1.0 if the magnetometer corrected heading."""
    dt = c[C_DT]
    # (1) strapdown: q_IS <- q_IS ⊗ exp((ω - b) dt)                       [eq. 1]
    # a missing gyroscope row is NaN here: the orientation is held and rest detection paused
    gyr_ok = gx == gx and gy == gy and gz == gz
    bx, by, bz = s[S_BIAS], s[S_BIAS + 1], s[S_BIAS + 2]  # the bias used for this sample
    b0x, b0y, b0z = bx, by, bz  # b̂ alone (without diag(k̂) ω), for the heading bias rows (12b)
    if gyr_ok:  # the scale errors as a rate-proportional bias: b_used = b + diag(k) ω
        bx, by, bz = bx + s[S_K] * gx, by + s[S_K + 1] * gy, bz + s[S_K + 2] * gz
    wx, wy, wz = gx - bx, gy - by, gz - bz
    ang = math.sqrt(wx * wx + wy * wy + wz * wz) * dt
    if gyr_ok:
        s[S_W2] += c[C_KW2] * (wx * wx + wy * wy + wz * wz - s[S_W2])
    if gyr_ok and ang > 1e-12:
        sh = math.sin(0.5 * ang) / ang * dt
        d0, d1, d2, d3 = math.cos(0.5 * ang), wx * sh, wy * sh, wz * sh
        q = qmul(s[S_QIS], s[S_QIS + 1], s[S_QIS + 2], s[S_QIS + 3], d0, d1, d2, d3)
        s[S_QIS], s[S_QIS + 1], s[S_QIS + 2], s[S_QIS + 3] = q
        _qnorm(s, S_QIS)

    # (2) rest detection and bias at rest                                    [eqs. 6-7]
    kr = c[C_KREST]
    if gyr_ok:
        for i in range(3):
            s[S_GREST + i] += kr * ((gx, gy, gz)[i] - s[S_GREST + i])
        l0, l1, l2 = s[S_GREST], s[S_GREST + 1], s[S_GREST + 2]  # the gyroscope's low-pass
        dg2 = (gx - l0) * (gx - l0) + (gy - l1) * (gy - l1) + (gz - l2) * (gz - l2)
        lg2 = l0 * l0 + l1 * l1 + l2 * l2
        rest_now = dg2 < c[C_THG2] and lg2 < c[C_THG2]
        if acc_ok:
            for i in range(3):
                s[S_AREST + i] += kr * ((ax, ay, az)[i] - s[S_AREST + i])
            dax, day, daz = ax - s[S_AREST], ay - s[S_AREST + 1], az - s[S_AREST + 2]  # from its low-pass
            da2 = dax * dax + day * day + daz * daz
            rest_now = rest_now and da2 < c[C_THA2]
        s[S_TREST] = s[S_TREST] + dt if rest_now else 0.0
        s[S_REST] = 1.0 if s[S_TREST] >= c[C_RESTMIN] else 0.0
    # random walk: P <- P + q I, variances capped at the initial ones (bias [eq. 5], scale errors (8k))
    for i in range(3):
        d = S_P6 + 7 * i
        s[d] = min(s[d] + c[C_QBIAS], max(s[d], c[C_P0]))
        d = S_P6 + 7 * (i + 3)
        s[d] = min(s[d] + c[C_QK], max(s[d], c[C_PK0]))
    if s[S_REST] > 0.5 and c[C_RESTON] > 0.5:
        rr, clip = c[C_RREST], c[C_CLIP]  # one row per axis: h = e_i
        _bias_update(s, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, s[S_GREST] - s[S_BIAS], rr, clip)
        _bias_update(s, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, s[S_GREST + 1] - s[S_BIAS + 1], rr, clip)
        _bias_update(s, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, s[S_GREST + 2] - s[S_BIAS + 2], rr, clip)

    # (3) inclination from low-passed acceleration in the quasi-inertial frame  [eqs. 2-4]
    if acc_ok:
        aix, aiy, aiz = qrot(s[S_QIS], s[S_QIS + 1], s[S_QIS + 2], s[S_QIS + 3], ax, ay, az)
        n = s[S_NACC]
        if n < c[C_NINIT]:
            # initial phase: running mean, filter state set to its steady state
            f = 1.0 / (n + 1.0)
            s[S_ALP] += f * (aix - s[S_ALP])
            s[S_ALP + 1] += f * (aiy - s[S_ALP + 1])
            s[S_ALP + 2] += f * (aiz - s[S_ALP + 2])
            for i in range(3):
                s[S_LP + 3 + i] = (c[C_B2] - c[C_A2]) * s[S_ALP + i]
                s[S_LP + i] = (1.0 - c[C_B0]) * s[S_ALP + i]
        else:
            for i in range(3):
                x = (aix, aiy, aiz)[i]
                y = c[C_B0] * x + s[S_LP + i]
                s[S_LP + i] = c[C_B1] * x - c[C_A1] * y + s[S_LP + 3 + i]
                s[S_LP + 3 + i] = c[C_B2] * x - c[C_A2] * y
                s[S_ALP + i] = y
        s[S_NACC] = n + 1.0
        # low-passes of R_IS and R_IS·b̂ (same filter as the acceleration), for eq. (8)
        r = qmat(s[S_QIS], s[S_QIS + 1], s[S_QIS + 2], s[S_QIS + 3])
        ub = (r[0] * bx + r[1] * by + r[2] * bz, r[3] * bx + r[4] * by + r[5] * bz,
              r[6] * bx + r[7] * by + r[8] * bz)
        _biquad9(s, S_RLP, S_RLPOUT, r, 1.0, 1.0, 1.0, c, n < c[C_NINIT])
        # the same filter on the three channels of R_IS·b̂: _biquad9's step on x = ub[i], written here because a
        # scalar helper called in a loop was not inlined (2x the time per sample) and one more helper costs ~0.4 M
        # Python calls to compile (benchmarks/compile_work.py)
        for i in range(3):
            x = ub[i]
            if n < c[C_NINIT]:
                s[S_ULP + i] = (1.0 - c[C_B0]) * x
                s[S_ULP + 3 + i] = (c[C_B2] - c[C_A2]) * x
                s[S_RLPOUT + 9 + i] = x
            else:
                y = c[C_B0] * x + s[S_ULP + i]
                s[S_ULP + i] = c[C_B1] * x - c[C_A1] * y + s[S_ULP + 3 + i]
                s[S_ULP + 3 + i] = c[C_B2] * x - c[C_A2] * y
                s[S_RLPOUT + 9 + i] = y
        # low-passes of R_IS diag(ω) (a missing gyroscope row counts as ω = 0), for eq. (8k)
        g0, g1, g2 = (gx, gy, gz) if gyr_ok else (0.0, 0.0, 0.0)
        _biquad9(s, S_WLP, S_WLPOUT, r, g0, g1, g2, c, n < c[C_NINIT])
        ex, ey, ez = qrot(s[S_QEI], s[S_QEI + 1], s[S_QEI + 2], s[S_QEI + 3],
                           s[S_ALP], s[S_ALP + 1], s[S_ALP + 2])
        en = math.sqrt(ex * ex + ey * ey + ez * ez)
        if en > 1e-9:
            ex, ey, ez = ex / en, ey / en, ez / en
            # shortest rotation taking (ex, ey, ez) to (0, 0, 1): axis (ey, -ex, 0)
            cw = 1.0 + ez
            if cw < 1e-12:
                c0, c1, c2 = 0.0, 1.0, 0.0
            else:
                cn = math.sqrt(cw * cw + ey * ey + ex * ex)
                c0, c1, c2 = cw / cn, ey / cn, -ex / cn
            q = qmul(c0, c1, c2, 0.0, s[S_QEI], s[S_QEI + 1], s[S_QEI + 2], s[S_QEI + 3])
            s[S_QEI], s[S_QEI + 1], s[S_QEI + 2], s[S_QEI + 3] = q
            _qnorm(s, S_QEI)
            # (4) bias during motion from the correction rate                  [eq. 8]
            if c[C_MOTON] > 0.5 and s[S_REST] < 0.5 and n >= c[C_NINIT]:
                un = math.sqrt(c1 * c1 + c2 * c2)  # log of the correction (as quaternion.log)
                scale = (2.0 / c0 if un < 1e-12 else 2.0 * math.atan2(un, c0) / un) / dt
                r_mot = c[C_RMOT] * (1.0 + c[C_SCALE2] * s[S_W2])
                e0 = qrot(s[S_QEI], -s[S_QEI + 1], -s[S_QEI + 2], -s[S_QEI + 3], 1.0, 0.0, 0.0)  # rows of R_E'I
                e1 = qrot(s[S_QEI], -s[S_QEI + 1], -s[S_QEI + 2], -s[S_QEI + 3], 0.0, 1.0, 0.0)
                _motion_row(s, e0, c1 * scale, r_mot, c[C_CLIP])
                _motion_row(s, e1, c2 * scale, r_mot, c[C_CLIP])

    # (5) heading from the magnetometer with disturbance rejection          [eqs. 9-12]
    used = 0.0
    if mag_ok:
        qe = qmul(s[S_QEI], s[S_QEI + 1], s[S_QEI + 2], s[S_QEI + 3],
                   s[S_QIS], s[S_QIS + 1], s[S_QIS + 2], s[S_QIS + 3])
        ex, ey, ez = qrot(qe[0], qe[1], qe[2], qe[3], mx, my, mz)
        norm = math.sqrt(ex * ex + ey * ey + ez * ez)
        if norm > 1e-9:
            dip = math.asin(min(max(-ez / norm, -1.0), 1.0))
            if s[S_MREFOK] < 0.5:
                s[S_MREFN], s[S_MREFD], s[S_MREFOK] = norm, dip, 1.0
                s[S_MCANDN], s[S_MCANDD], s[S_TCAND] = norm, dip, 0.0
                s[S_TUND] = c[C_MINUND]
                s[S_TSUP] = 0.0
            near = (abs(norm - s[S_MREFN]) < c[C_NORMTH] * s[S_MREFN]
                    and abs(dip - s[S_MREFD]) < c[C_DIPTH])
            s[S_TUND] = s[S_TUND] + dt if near else 0.0
            ok = near and s[S_TUND] >= c[C_MINUND]
            if c[C_REJON] < 0.5:
                ok = True
            # candidate for a new reference: held while the field stays near it
            if (abs(norm - s[S_MCANDN]) < c[C_NORMTH] * s[S_MCANDN]
                    and abs(dip - s[S_MCANDD]) < c[C_DIPTH]):
                s[S_MCANDN] += c[C_KCAND] * (norm - s[S_MCANDN])
                s[S_MCANDD] += c[C_KCAND] * (dip - s[S_MCANDD])
                s[S_TCAND] += dt
            else:
                s[S_MCANDN], s[S_MCANDD], s[S_TCAND] = norm, dip, 0.0
            if not ok:
                s[S_TREJ] += dt
                # a young reference (confirmed < mag_new_field_s) gives way to a field that has held longer
                young = not near and s[S_TSUP] < c[C_NEWS] and s[S_TCAND] > s[S_TSUP]
                if (s[S_TREJ] >= c[C_MAXREJ] and s[S_TCAND] >= c[C_NEWS]) or young:
                    # a long, stable disturbance, or a reference learnt in one: the field there is the reference
                    s[S_MREFN], s[S_MREFD] = s[S_MCANDN], s[S_MCANDD]
                    s[S_NMAG] = 0.0
                    s[S_TUND] = c[C_MINUND]
                    s[S_TSUP] = s[S_TCAND]
                    ok = True
            if ok:
                s[S_TREJ] = 0.0
                s[S_TSUP] += dt
                s[S_MREFN] += c[C_KREF] * (norm - s[S_MREFN])
                s[S_MREFD] += c[C_KREF] * (dip - s[S_MREFD])
                k = max(c[C_KMAG], 1.0 / (s[S_NMAG] + 1.0))
                err = _wrap(math.atan2(ex, ey) - s[S_DELTA])
                if c[C_MAGBIAS] > 0.5:
                    # (12b) vertical bias from the heading lag: err ≈ -τ_mag LP(R_E'S e)_z.  The rows have no
                    # scale columns (k̂ taken as known here), so the known term is LP(r_z·b̂) without diag(k̂) ω:
                    # with b̂ and k̂ exact the innovation is then zero (with k̂ω in it, it would be -LP(r_z diag(ω) k̂))
                    rz = qrot(qe[0], -qe[1], -qe[2], -qe[3], 0.0, 0.0, 1.0)
                    uz = rz[0] * b0x + rz[1] * b0y + rz[2] * b0z
                    steady = s[S_NMAG] < c[C_NMAGINIT]
                    km = c[C_KMAG]
                    for i in range(3):
                        s[S_MLP + i] = rz[i] if steady else s[S_MLP + i] + km * (rz[i] - s[S_MLP + i])
                    s[S_MLP + 3] = uz if steady else s[S_MLP + 3] + km * (uz - s[S_MLP + 3])
                    if not steady and s[S_REST] < 0.5 and abs(err) < c[C_MAGGATE]:
                        clip = c[C_CLIP]
                        innov = (err / c[C_TAUMAG] - s[S_MLP + 3] + s[S_MLP] * s[S_BIAS]
                                 + s[S_MLP + 1] * s[S_BIAS + 1] + s[S_MLP + 2] * s[S_BIAS + 2])
                        _bias_update(s, -s[S_MLP], -s[S_MLP + 1], -s[S_MLP + 2], 0.0, 0.0, 0.0,
                                     min(max(innov, -clip), clip), c[C_RMAG], clip)
                s[S_NMAG] += 1.0
                s[S_DELTA] = _wrap(s[S_DELTA] + k * err)
                used = 1.0
            s[S_MDIST] = 0.0 if ok else 1.0

    # (6) output q = R_z(δ) ⊗ q_E'I ⊗ q_IS
    qe = qmul(s[S_QEI], s[S_QEI + 1], s[S_QEI + 2], s[S_QEI + 3],
               s[S_QIS], s[S_QIS + 1], s[S_QIS + 2], s[S_QIS + 3])
    hc, hs = math.cos(0.5 * s[S_DELTA]), math.sin(0.5 * s[S_DELTA])
    q = qmul(hc, 0.0, 0.0, hs, qe[0], qe[1], qe[2], qe[3])
    s[S_Q], s[S_Q + 1], s[S_Q + 2], s[S_Q + 3] = q
    _qnorm(s, S_Q)
    return used


@njit(cache=True, nogil=True)  # releases the GIL: the offline smoother runs its two passes concurrently
def chakamo_batch(acc, gyr, mag, acc_ok, mag_ok, coeffs, state0, want_aux):
    """Run :func:`chakamo_step` over ``(N, 3)`` arrays; returns ``(q (N, 4), state, aux (N, AUX) or (0, AUX))``.

    6D is 9D with every field sample missing: ``mag_ok`` all false (``mag`` zeros, never read).
    """
    n = acc.shape[0]
    s = state0.copy()
    out = np.empty((n, 4))
    aux = np.empty((n if want_aux else 0, AUX_SIZE))
    for k in range(n):
        used = chakamo_step(s, coeffs, acc[k, 0], acc[k, 1], acc[k, 2], gyr[k, 0], gyr[k, 1], gyr[k, 2],
                            mag[k, 0], mag[k, 1], mag[k, 2], acc_ok[k], mag_ok[k])
        for j in range(4):
            out[k, j] = s[S_Q + j]
        if want_aux:
            for j in range(3):
                aux[k, A_BIAS + j] = s[S_BIAS + j]
            for j in range(6):  # the bias block of P6, upper triangle
                aux[k, A_P + j] = s[S_P6 + (0, 1, 2, 7, 8, 14)[j]]
            aux[k, A_REST] = s[S_REST]
            for j in range(3):
                aux[k, A_K + j] = s[S_K + j]
                aux[k, A_PK + j] = s[S_P6 + 7 * (3 + j)]
            aux[k, A_MAGUSED] = used
            # the field was near the reference at this sample (hysteresis aside): t_undist runs
            aux[k, A_MAGNEAR] = 1.0 if mag_ok[k] and s[S_TUND] > 0.0 else 0.0
    return out, s, aux


@njit(cache=True)
def strapdown_batch(gyr, bias, q0, dt):
    """``q_IS`` (N, 4) integrated with a per-sample bias ``(N, 3)`` from ``q0``: eq. (1), bias known.

    Rows of ``gyr`` that are NaN (missing) hold the orientation.
    """
    n = gyr.shape[0]
    out = np.empty((n, 4))
    q = (q0[0], q0[1], q0[2], q0[3])
    for k in range(n):
        wx, wy, wz = gyr[k, 0] - bias[k, 0], gyr[k, 1] - bias[k, 1], gyr[k, 2] - bias[k, 2]
        ang = math.sqrt(wx * wx + wy * wy + wz * wz) * dt
        if ang > 1e-12:
            sh = math.sin(0.5 * ang) / ang * dt
            q = qmul(q[0], q[1], q[2], q[3], math.cos(0.5 * ang), wx * sh, wy * sh, wz * sh)
            nq = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            q = (q[0] / nq, q[1] / nq, q[2] / nq, q[3] / nq)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = q
    return out


@njit(cache=True)
def rotate_batch(q, v):
    """``v`` (N, 3) rotated by ``q`` (N, 4) per sample: the fused form of ``quaternion.rotate``."""
    n = v.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        out[k, 0], out[k, 1], out[k, 2] = qrot(q[k, 0], q[k, 1], q[k, 2], q[k, 3], v[k, 0], v[k, 1], v[k, 2])
    return out


@njit(cache=True)
def compose_offline(q_is, acc_lp_i, mag):
    """Offline step 2 per sample, fused: ``q_E'I`` = shortest rotation taking the low-passed acceleration in
    ``I`` to ``z`` (3-4), ``q_ES = q_E'I ⊗ q_IS``, and the field in ``E'`` (for the heading step, 14).

    Returns ``(q_es (N, 4), mag_e (N, 3))``; ``mag`` rows may be anything where unused (6D: zeros).
    """
    n = q_is.shape[0]
    q_es = np.empty((n, 4))
    mag_e = np.empty((n, 3))
    for k in range(n):
        ax, ay, az = acc_lp_i[k, 0], acc_lp_i[k, 1], acc_lp_i[k, 2]
        na = math.sqrt(ax * ax + ay * ay + az * az)
        ax, ay, az = ax / na, ay / na, az / na
        cw = 1.0 + az
        if cw < 1e-12:  # pointing down: any half turn about a horizontal axis
            c0, c1, c2 = 0.0, 1.0, 0.0
        else:
            cn = math.sqrt(cw * cw + ay * ay + ax * ax)
            c0, c1, c2 = cw / cn, ay / cn, -ax / cn
        q = qmul(c0, c1, c2, 0.0, q_is[k, 0], q_is[k, 1], q_is[k, 2], q_is[k, 3])
        q_es[k, 0], q_es[k, 1], q_es[k, 2], q_es[k, 3] = q
        mag_e[k, 0], mag_e[k, 1], mag_e[k, 2] = qrot(q[0], q[1], q[2], q[3], mag[k, 0], mag[k, 1], mag[k, 2])
    return q_es, mag_e


@njit(cache=True)
def apply_heading(q_es, delta):
    """``exp(δ ẑ) ⊗ q_ES`` per sample, normalised (offline heading, 14)."""
    n = q_es.shape[0]
    out = np.empty((n, 4))
    for k in range(n):
        h = 0.5 * delta[k]
        q = qmul(math.cos(h), 0.0, 0.0, math.sin(h), q_es[k, 0], q_es[k, 1], q_es[k, 2], q_es[k, 3])
        nq = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = q[0] / nq, q[1] / nq, q[2] / nq, q[3] / nq
    return out


# =====================================================================================
# offline: two-filter bias smoother (13)
# =====================================================================================
@njit(cache=True)
def smooth_bias_batch(b_f, p_f, b_b, p_b):
    r"""Information-weighted mean of forward and backward bias estimates (eq. 13); ``p_*`` are ``(N, 6)``.

    In the covariance form :math:`\hat b_s = \hat b_f + P_f (P_f + P_b)^{-1} (\hat b_b - \hat b_f)`, equal to (13)
    (:math:`(P_f^{-1} + P_b^{-1})^{-1} = P_f (P_f + P_b)^{-1} P_b`) with one 3×3 inverse per sample instead of three.
    """
    n = b_f.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        f0, f1, f2, f3, f4, f5 = p_f[k, 0], p_f[k, 1], p_f[k, 2], p_f[k, 3], p_f[k, 4], p_f[k, 5]
        a00, a01, a02 = f0 + p_b[k, 0], f1 + p_b[k, 1], f2 + p_b[k, 2]
        a11, a12, a22 = f3 + p_b[k, 3], f4 + p_b[k, 4], f5 + p_b[k, 5]
        # (P_f + P_b)^-1 by cofactors (upper triangle s0 s1 s2 s3 s4 s5)
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        det = a00 * c00 + a01 * c01 + a02 * c02
        s0, s1, s2 = c00 / det, c01 / det, c02 / det
        s3, s4, s5 = (a00 * a22 - a02 * a02) / det, (a01 * a02 - a00 * a12) / det, (a00 * a11 - a01 * a01) / det
        d0, d1, d2 = b_b[k, 0] - b_f[k, 0], b_b[k, 1] - b_f[k, 1], b_b[k, 2] - b_f[k, 2]
        r0 = s0 * d0 + s1 * d1 + s2 * d2
        r1 = s1 * d0 + s3 * d1 + s4 * d2
        r2 = s2 * d0 + s4 * d1 + s5 * d2
        out[k, 0] = b_f[k, 0] + f0 * r0 + f1 * r1 + f2 * r2
        out[k, 1] = b_f[k, 1] + f1 * r0 + f3 * r1 + f4 * r2
        out[k, 2] = b_f[k, 2] + f2 * r0 + f4 * r1 + f5 * r2
    return out


# =====================================================================================
# offline: robust heading (14-15b)
# =====================================================================================
@njit(cache=True)
def _two_sided_block_mean(x, w, decay, block, num, den, out):
    """(14) on blocks of ``block`` samples (``decay`` per block), linear between valid block centres into ``out``.

    ``num``, ``den`` are scratch ``(nb,)``; the twin of ``chakamo_offline._two_sided_mean``.
    """
    n = x.shape[0]
    nb = num.shape[0]
    for b in range(nb):
        sn, sd = 0.0, 0.0
        for i in range(b * block, min(n, (b + 1) * block)):
            sn += w[i] * x[i]
            sd += w[i]
        num[b], den[b] = sn, sd
    fn, fd = 0.0, 0.0  # forward pass of 1/(1 - decay z^-1), stored; then the backward pass adds its own
    fwd_n, fwd_d = np.empty(nb), np.empty(nb)
    for b in range(nb):
        fn = num[b] + decay * fn
        fd = den[b] + decay * fd
        fwd_n[b], fwd_d[b] = fn, fd
    bn, bd = 0.0, 0.0
    for b in range(nb - 1, -1, -1):
        bn = num[b] + decay * bn
        bd = den[b] + decay * bd
        tn, td = fwd_n[b] + bn - num[b], fwd_d[b] + bd - den[b]
        num[b] = tn / td if td > 1e-200 else np.nan  # gaps longer than ~700 τ: no value, interpolated over
    # the valid blocks (value, centre) packed to the front of (num, den), then linear between their centres and
    # constant beyond the first and the last
    half = 0.5 * (min(block, n) - 1)
    m = 0
    for b in range(nb):
        if num[b] == num[b]:
            num[m], den[m] = num[b], b * block + half
            m += 1
    if m == 0:  # no valid block (every weight below ~1e-200): no heading information, as with no weight at all
        for i in range(n):
            out[i] = 0.0
        return
    start = min(n, int(math.ceil(den[0])))
    for i in range(start):
        out[i] = num[0]
    for j in range(m - 1):  # the samples i with den[j] <= i < den[j + 1]
        c0, c1 = den[j], den[j + 1]
        end = min(n, int(math.ceil(c1)))
        for i in range(start, end):
            out[i] = num[j] + (num[j + 1] - num[j]) * (i - c0) / (c1 - c0)
        start = end
    for i in range(start, n):
        out[i] = num[m - 1]


@njit(cache=True)
def robust_heading_batch(target, weight, decay, block, c2, iterations):
    """Compiled twin of ``chakamo_offline.robust_heading`` (same blocks, decay per block and Cauchy passes)."""
    n = target.shape[0]
    x = np.zeros(n)
    last, acc, first = 0.0, 0.0, True
    for i in range(n):  # the target unwrapped over the used samples (zero elsewhere)
        if weight[i] > 0.0:
            if first:
                acc, first = target[i], False
            else:
                d = target[i] - last
                acc += d - 2.0 * math.pi * round(d / (2.0 * math.pi))
            last = target[i]
            x[i] = acc
    delta = np.zeros(n)
    if first:
        return delta
    nb = -(-n // block)
    num, den = np.empty(nb), np.empty(nb)
    _two_sided_block_mean(x, weight, decay, block, num, den, delta)
    if c2 > 0.0:
        w = np.empty(n)
        for _ in range(iterations):
            for i in range(n):
                r = x[i] - delta[i]
                w[i] = weight[i] * (c2 / (c2 + r * r))
            _two_sided_block_mean(x, w, decay, block, num, den, delta)
    return delta
