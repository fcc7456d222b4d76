"""Readable numpy twins of the kernels in :mod:`estimators.orientation.chakamo_kernels`.

Same maths as the compiled kernels, written with vector operations and :mod:`estimators.quaternion`
(slow; for tests and study).  Theory and equation numbers: :mod:`estimators.orientation.chakamo`;
state and coefficient layouts: :mod:`estimators.orientation.chakamo_kernels`.
"""

from __future__ import annotations

import numpy as np

from estimators import quaternion as quat
from estimators.orientation.chakamo_kernels import (
    AUX_SIZE, A_BIAS, A_K, A_MAGNEAR, A_MAGUSED, A_P, A_PK, A_REST, C_A1, C_A2, C_B0, C_B1, C_B2, C_CLIP, C_DIPTH, C_DT, C_KCAND,
    C_KMAG, C_KREF, C_KREST, C_KW2, C_MAGBIAS, C_MAGGATE, C_MAXREJ, C_MINUND, C_MOTON, C_NEWS, C_NINIT, C_NMAGINIT,
    C_NORMTH, C_P0, C_PK0, C_QBIAS, C_QK, C_REJON, C_RESTMIN, C_RESTON, C_RMAG, C_RMOT, C_RREST, C_SCALE2, C_TAUMAG,
    C_THA2, C_THG2, S_ALP, S_AREST, S_BIAS, S_DELTA, S_GREST, S_LP, S_MCANDD, S_MCANDN, S_MDIST, S_MLP,
    S_MREFD, S_MREFN, S_MREFOK, S_NACC, S_NMAG, S_Q, S_QEI, S_QIS, S_REST, S_RLP, S_RLPOUT, S_TCAND,
    S_TREJ, S_TREST, S_TSUP, S_TUND, S_ULP, S_W2, S_K, S_P6, S_WLP, S_WLPOUT, K_CLIP,
)


def _bias_update_reference(x, p, h, innov, r, clip):
    """Scalar Kalman update of ``x = (b, k)`` (6,) with covariance ``p`` (6, 6); b clipped to ±clip, k to ±K_CLIP."""
    gain = p @ h / (h @ p @ h + r)
    limit = np.r_[np.full(3, clip), np.full(3, K_CLIP)]
    return np.clip(x + gain * innov, -limit, limit), p - np.outer(gain, h @ p)


def _unpack(s):
    """``x = (b, k)`` and its 6×6 covariance (``S_P6``)."""
    return np.r_[s[S_BIAS:S_BIAS + 3], s[S_K:S_K + 3]], s[S_P6:S_P6 + 36].reshape(6, 6).copy()


def _pack(s, x, p):
    s[S_BIAS:S_BIAS + 3] = x[:3]
    s[S_K:S_K + 3] = x[3:]
    s[S_P6:S_P6 + 36] = p.ravel()


def chakamo_step_reference(s, c, acc, gyr, mag, acc_ok, mag_ok):
    """Numpy twin of :func:`chakamo_step` (``s`` updated in place); returns 1.0 if heading was corrected."""
    dt = c[C_DT]
    x, p = _unpack(s)  # without the scale states (8k) their block of p is zero and k stays 0
    # (1) strapdown
    gyr_ok = bool(np.all(np.isfinite(gyr)))  # a missing row (NaN) holds the orientation
    # the bias integrated at this sample; the scale errors act as the rate-proportional bias diag(k) ω
    b_hat = x[:3].copy()  # b̂ alone, for the heading bias rows (12b): they treat k̂ as known
    b_used = x[:3] + x[3:] * gyr if gyr_ok else x[:3].copy()
    omega = gyr - b_used
    if gyr_ok:
        s[S_W2] += c[C_KW2] * (omega @ omega - s[S_W2])
        if np.linalg.norm(omega) * dt > 1e-12:
            s[S_QIS:S_QIS + 4] = quat.normalize(quat.multiply(s[S_QIS:S_QIS + 4], quat.exp(omega * dt)))
    # (2) rest detection (paused on a missing gyroscope row), bias random walk, bias at rest
    g_lp = s[S_GREST:S_GREST + 3]
    if gyr_ok:
        s[S_GREST:S_GREST + 3] += c[C_KREST] * (gyr - s[S_GREST:S_GREST + 3])
        rest_now = np.sum((gyr - g_lp) ** 2) < c[C_THG2] and np.sum(g_lp ** 2) < c[C_THG2]
        if acc_ok:
            s[S_AREST:S_AREST + 3] += c[C_KREST] * (acc - s[S_AREST:S_AREST + 3])
            rest_now = rest_now and np.sum((acc - s[S_AREST:S_AREST + 3]) ** 2) < c[C_THA2]
        s[S_TREST] = s[S_TREST] + dt if rest_now else 0.0
        s[S_REST] = float(s[S_TREST] >= c[C_RESTMIN])
    diag = np.diag(p)
    q, p0 = np.r_[np.full(3, c[C_QBIAS]), np.full(3, c[C_QK])], np.r_[np.full(3, c[C_P0]), np.full(3, c[C_PK0])]
    p = p + np.diag(np.minimum(diag + q, np.maximum(diag, p0)) - diag)
    if s[S_REST] > 0.5 and c[C_RESTON] > 0.5:
        for i in range(3):
            x, p = _bias_update_reference(x, p, np.eye(6)[i], g_lp[i] - x[i], c[C_RREST], c[C_CLIP])
    # (3) inclination
    if acc_ok:
        acc_i = quat.rotate(s[S_QIS:S_QIS + 4], acc)
        n = s[S_NACC]
        bb = c[[C_B0, C_B1, C_B2]]
        aa = c[[C_A1, C_A2]]
        if n < c[C_NINIT]:
            s[S_ALP:S_ALP + 3] += (acc_i - s[S_ALP:S_ALP + 3]) / (n + 1.0)
            s[S_LP + 3:S_LP + 6] = (bb[2] - aa[1]) * s[S_ALP:S_ALP + 3]
            s[S_LP:S_LP + 3] = (1.0 - bb[0]) * s[S_ALP:S_ALP + 3]
        else:
            y = bb[0] * acc_i + s[S_LP:S_LP + 3]
            s[S_LP:S_LP + 3] = bb[1] * acc_i - aa[0] * y + s[S_LP + 3:S_LP + 6]
            s[S_LP + 3:S_LP + 6] = bb[2] * acc_i - aa[1] * y
            s[S_ALP:S_ALP + 3] = y
        s[S_NACC] = n + 1.0
        r_is = quat.to_matrix(s[S_QIS:S_QIS + 4])
        r_lp = _biquad_reference(s, S_RLP, 9, r_is.ravel(), bb, aa, n < c[C_NINIT]).reshape(3, 3)
        u_lp = _biquad_reference(s, S_ULP, 3, r_is @ b_used, bb, aa, n < c[C_NINIT])
        s[S_RLPOUT:S_RLPOUT + 9] = r_lp.ravel()
        s[S_RLPOUT + 9:S_RLPOUT + 12] = u_lp
        # LP(R_IS diag ω), a missing gyroscope row as ω = 0
        w_lp = _biquad_reference(s, S_WLP, 9, (r_is * (gyr if gyr_ok else np.zeros(3))).ravel(), bb, aa,
                                 n < c[C_NINIT]).reshape(3, 3)
        s[S_WLPOUT:S_WLPOUT + 9] = w_lp.ravel()
        acc_e = quat.rotate(s[S_QEI:S_QEI + 4], s[S_ALP:S_ALP + 3])
        if np.linalg.norm(acc_e) > 1e-9:
            acc_e = acc_e / np.linalg.norm(acc_e)
            if 1.0 + acc_e[2] < 1e-12:
                corr = np.array([0.0, 1.0, 0.0, 0.0])
            else:
                corr = quat.normalize(np.array([1.0 + acc_e[2], acc_e[1], -acc_e[0], 0.0]))
            s[S_QEI:S_QEI + 4] = quat.normalize(quat.multiply(corr, s[S_QEI:S_QEI + 4]))
            if c[C_MOTON] > 0.5 and s[S_REST] < 0.5 and n >= c[C_NINIT]:
                rate = quat.log(corr) / dt  # rotation vector of the correction per second
                r_ei = quat.to_matrix(s[S_QEI:S_QEI + 4])
                m_mat = r_ei @ r_lp
                v = r_ei @ u_lp
                n_mat = r_ei @ w_lp  # (8k)
                h_mat = np.hstack([m_mat, n_mat])
                r_mot = c[C_RMOT] * (1.0 + c[C_SCALE2] * s[S_W2])
                for j in range(2):
                    innov = np.clip(rate[j] - v[j] + h_mat[j] @ x, -c[C_CLIP], c[C_CLIP])
                    x, p = _bias_update_reference(x, p, -h_mat[j], innov, r_mot, c[C_CLIP])
    _pack(s, x, p)
    # (5) heading
    used = 0.0
    if mag_ok:
        mag_e = quat.rotate(quat.multiply(s[S_QEI:S_QEI + 4], s[S_QIS:S_QIS + 4]), mag)
        norm = np.linalg.norm(mag_e)
        if norm > 1e-9:
            dip = np.arcsin(np.clip(-mag_e[2] / norm, -1.0, 1.0))

            def near(ref_norm, ref_dip):
                return abs(norm - ref_norm) < c[C_NORMTH] * ref_norm and abs(dip - ref_dip) < c[C_DIPTH]

            if s[S_MREFOK] < 0.5:
                s[[S_MREFN, S_MREFD, S_MREFOK]] = norm, dip, 1.0
                s[[S_MCANDN, S_MCANDD, S_TCAND]] = norm, dip, 0.0
                s[S_TUND] = c[C_MINUND]
                s[S_TSUP] = 0.0
            near_ref = near(s[S_MREFN], s[S_MREFD])
            s[S_TUND] = s[S_TUND] + dt if near_ref else 0.0
            ok = (near_ref and s[S_TUND] >= c[C_MINUND]) or c[C_REJON] < 0.5
            if near(s[S_MCANDN], s[S_MCANDD]):
                s[[S_MCANDN, S_MCANDD]] += c[C_KCAND] * (np.array([norm, dip]) - s[[S_MCANDN, S_MCANDD]])
                s[S_TCAND] += dt
            else:
                s[[S_MCANDN, S_MCANDD, S_TCAND]] = norm, dip, 0.0
            if not ok:
                s[S_TREJ] += dt
                young = not near_ref and s[S_TSUP] < c[C_NEWS] and s[S_TCAND] > s[S_TSUP]  # (12), young reference
                if (s[S_TREJ] >= c[C_MAXREJ] and s[S_TCAND] >= c[C_NEWS]) or young:
                    s[[S_MREFN, S_MREFD]] = s[[S_MCANDN, S_MCANDD]]
                    s[S_NMAG] = 0.0
                    s[S_TUND] = c[C_MINUND]
                    s[S_TSUP] = s[S_TCAND]
                    ok = True
            if ok:
                s[S_TREJ] = 0.0
                s[S_TSUP] += dt
                s[[S_MREFN, S_MREFD]] += c[C_KREF] * (np.array([norm, dip]) - s[[S_MREFN, S_MREFD]])
                k = max(c[C_KMAG], 1.0 / (s[S_NMAG] + 1.0))
                err = _wrap_reference(np.arctan2(mag_e[0], mag_e[1]) - s[S_DELTA])
                if c[C_MAGBIAS] > 0.5:
                    r_es = quat.to_matrix(quat.multiply(s[S_QEI:S_QEI + 4], s[S_QIS:S_QIS + 4]))
                    # E' z axis in sensor coordinates and its bias term, with b̂ alone (no k̂ω: the rows have no
                    # scale columns, so with the state exact the innovation is zero)
                    x = np.append(r_es[2], r_es[2] @ b_hat)
                    steady = s[S_NMAG] < c[C_NMAGINIT]
                    s[S_MLP:S_MLP + 4] = x if steady else s[S_MLP:S_MLP + 4] + c[C_KMAG] * (x - s[S_MLP:S_MLP + 4])
                    if not steady and s[S_REST] < 0.5 and abs(err) < c[C_MAGGATE]:
                        m_z, v_z = s[S_MLP:S_MLP + 3], s[S_MLP + 3]
                        x, p = _unpack(s)
                        innov = np.clip(err / c[C_TAUMAG] - v_z + m_z @ x[:3], -c[C_CLIP], c[C_CLIP])
                        x, p = _bias_update_reference(x, p, -np.r_[m_z, np.zeros(3)], innov, c[C_RMAG], c[C_CLIP])
                        _pack(s, x, p)
                s[S_NMAG] += 1.0
                s[S_DELTA] = _wrap_reference(s[S_DELTA] + k * err)
                used = 1.0
            s[S_MDIST] = 0.0 if ok else 1.0
    # (6) output
    heading = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), s[S_DELTA])
    s[S_Q:S_Q + 4] = quat.normalize(
        quat.multiply(heading, quat.multiply(s[S_QEI:S_QEI + 4], s[S_QIS:S_QIS + 4])))
    return used


def _biquad_reference(s, start, m, x, bb, aa, steady):
    """Numpy twin of ``_biquad9`` (and of the step's R_IS·b̂ filter) on ``m`` channels whose state is
    ``s[start:start + 2m]``."""
    z1, z2 = slice(start, start + m), slice(start + m, start + 2 * m)
    if steady:
        s[z1] = (1.0 - bb[0]) * x
        s[z2] = (bb[2] - aa[1]) * x
        return x.copy()
    y = bb[0] * x + s[z1]
    s[z1] = bb[1] * x - aa[0] * y + s[z2]
    s[z2] = bb[2] * x - aa[1] * y
    return y


def _wrap_reference(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def chakamo_batch_reference(acc, gyr, mag, acc_ok, mag_ok, coeffs, state0, want_aux):
    """Numpy twin of :func:`chakamo_batch`."""
    n = acc.shape[0]
    s = np.array(state0, dtype=np.float64)
    out = np.empty((n, 4))
    aux = np.empty((n if want_aux else 0, AUX_SIZE))
    for k in range(n):
        used = chakamo_step_reference(s, coeffs, acc[k], gyr[k], mag[k], bool(acc_ok[k]), bool(mag_ok[k]))
        out[k] = s[S_Q:S_Q + 4]
        if want_aux:
            aux[k, A_BIAS:A_BIAS + 3] = s[S_BIAS:S_BIAS + 3]
            aux[k, A_P:A_P + 6] = s[S_P6:S_P6 + 36][[0, 1, 2, 7, 8, 14]]  # the bias block of P6, upper triangle
            aux[k, A_REST] = s[S_REST]
            aux[k, A_K:A_K + 3] = s[S_K:S_K + 3]
            aux[k, A_PK:A_PK + 3] = np.diag(s[S_P6:S_P6 + 36].reshape(6, 6))[3:]
            aux[k, A_MAGUSED] = used
            aux[k, A_MAGNEAR] = 1.0 if mag_ok[k] and s[S_TUND] > 0.0 else 0.0
    return out, s, aux


def strapdown_reference(gyr, bias, q0, dt):
    """Numpy twin of :func:`strapdown_batch`."""
    out = np.empty((gyr.shape[0], 4))
    q = np.array(q0, dtype=np.float64)
    for k in range(gyr.shape[0]):
        omega = gyr[k] - bias[k]
        if np.all(np.isfinite(omega)) and np.linalg.norm(omega) * dt > 1e-12:
            q = quat.normalize(quat.multiply(q, quat.exp(omega * dt)))
        out[k] = q
    return out


def smooth_bias_reference(b_f, p_f, b_b, p_b):
    r"""Numpy twin of :func:`smooth_bias_batch`: (13) as written, in information form,
    :math:`\hat b_s = (P_f^{-1} + P_b^{-1})^{-1}(P_f^{-1}\hat b_f + P_b^{-1}\hat b_b)` — an independent check of the
    kernel's covariance form :math:`\hat b_f + P_f (P_f + P_b)^{-1}(\hat b_b - \hat b_f)` (same value)."""
    i_f = np.linalg.inv(_sym_reference(p_f))
    i_b = np.linalg.inv(_sym_reference(p_b))
    rhs = np.einsum("nij,nj->ni", i_f, b_f) + np.einsum("nij,nj->ni", i_b, b_b)
    return np.linalg.solve(i_f + i_b, rhs[..., None])[..., 0]


def _sym_reference(p6):
    """``(N, 6)`` upper triangles → ``(N, 3, 3)`` symmetric matrices."""
    rows, cols = [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]
    p = np.empty((p6.shape[0], 3, 3))
    p[:, rows, cols] = p6
    p[:, cols, rows] = p6
    return p
