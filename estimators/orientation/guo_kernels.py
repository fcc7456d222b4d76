"""Compiled kernel of :mod:`estimators.orientation.guo` (numba; theory, deviations and equation numbers there).

:func:`guo_step` advances one sample in place (bias at rest, exact prediction of the joint (q, b)
covariance, measurement quaternion with robust weights, Cholesky Kalman update of q and of the gyroscope
bias state), :func:`guo_batch` loops it; the readable numpy twin is
``guo._reference_step`` (tests check both agree to ≤ 1e-9).  State layout: ``STATE_SIZE`` in ``guo``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

G_M_S2 = 9.81
FREE_VAR_RAD2 = 1.0           # variance of unobserved directions (6D heading, quaternion norm)
MIN_FIELD_COS = 1e-3          # |m × a| below this: field parallel to gravity, heading undefined


@njit(cache=True)
def guo_step(state, ax, ay, az, gx, gy, gz, mx, my, mz, acc_ok, gyr_ok, mag_ok, dt_s,
             var_gyr, var_acc, var_mag, inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2,
             mag_innov_tol, ref_alpha, bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, var_bias_walk, w):
    """One sample in place on ``state`` (STATE_SIZE,); ``w`` is scratch (≥ 128)."""
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
    if gyr_ok:  # the bias estimate (deviation 8: at rest; deviation 12: Kalman state)
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
    # ---- bias block (deviation 12): ∂q⁻/∂b = B = −(Δt/2) Ξ(q⁻), Ξ(q⁻) = [q⁻⊗i, q⁻⊗j, q⁻⊗k]
    # Σqb⁻ = M = Φ Σqb + B Σbb,  Σqq⁻ += M Bᵀ + B (Φ Σqb)ᵀ,  Σbb⁻ = Σbb + σbw² Δt I
    Bm = w[80:92]  # 4×3
    hb = -0.5 * dt_s if gyr_ok else 0.0
    Bm[0] = -p1 * hb; Bm[1] = -p2 * hb; Bm[2] = -p3 * hb
    Bm[3] = p0 * hb; Bm[4] = -p3 * hb; Bm[5] = p2 * hb
    Bm[6] = p3 * hb; Bm[7] = p0 * hb; Bm[8] = -p1 * hb
    Bm[9] = -p2 * hb; Bm[10] = p1 * hb; Bm[11] = p0 * hb
    G = w[92:104]  # Φ Σqb
    M = w[104:116]  # Σqb⁻
    for i in range(4):
        for j in range(3):
            v = 0.0
            for k in range(4):
                v += F[4 * i + k] * state[26 + 3 * k + j]
            G[3 * i + j] = v
            u = v
            for k in range(3):
                u += Bm[3 * i + k] * state[38 + 3 * k + j]
            M[3 * i + j] = u
    for i in range(4):
        for j in range(i, 4):
            v = 0.0
            for k in range(3):
                v += M[3 * i + k] * Bm[3 * j + k] + Bm[3 * i + k] * G[3 * j + k]
            Sm[4 * i + j] += v
            if j != i:
                Sm[4 * j + i] += v
    for i in range(3):
        state[38 + 4 * i] += var_bias_walk * dt_s
    if not acc_ok:
        for i in range(16):
            state[4 + i] = Sm[i]
        for i in range(12):
            state[26 + i] = M[i]
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
    # Huber bound ≥ the predicted tilt std √(2 (c₁ᵀΣ⁻c₁ + c₂ᵀΣ⁻c₂)) (deviation 13)
    s11 = 0.0
    s22 = 0.0
    for i in range(4):
        u1 = 0.0
        u2 = 0.0
        for j in range(4):
            u1 += Sm[4 * i + j] * C[4 * j + 1]
            u2 += Sm[4 * i + j] * C[4 * j + 2]
        s11 += C[4 * i + 1] * u1
        s22 += C[4 * i + 2] * u2
    tol_eff = max(acc_innov_tol, math.sqrt(max(2.0 * (s11 + s22), 0.0)))
    va = var_acc * (1.0 + dg * dg * inv_acc_tol2) * max(1.0, tilt / tol_eff)
    # ½(W_a + I) q⁻  (5.37): the accelerometer-consistent quaternion nearest to the prediction
    a0 = 0.5 * (p0 + uz * p0 + uy * p1 - ux * p2)
    a1 = 0.5 * (p1 + uy * p0 - uz * p1 + ux * p3)
    a2 = 0.5 * (p2 - ux * p0 - uz * p2 + uy * p3)
    a3 = 0.5 * (p3 + ux * p1 + uy * p2 + uz * p3)
    nrm = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
    if nrm < 1e-9:  # prediction exactly upside down: no nearest point, skip the correction
        for i in range(16):
            state[4 + i] = Sm[i]
        for i in range(12):
            state[26 + i] = M[i]
        state[0] = p0; state[1] = p1; state[2] = p2; state[3] = p3
        return
    a0 /= nrm; a1 /= nrm; a2 /= nrm; a3 /= nrm
    m0 = a0; m1 = a1; m2 = a2; m3 = a3
    txx = va; tyy = va; tyz = 0.0; tzz = FREE_VAR_RAD2
    if mag_ok:
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
        if (mN if paper_triad else lh) > MIN_FIELD_COS:
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
        b0 = C[4 * i] * FREE_VAR_RAD2
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
    # ---- Y = L⁻¹ Σ⁻ (into A), Z = L⁻¹ Σqb⁻ (into G), z = L⁻¹ (q_am − q⁻)
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
        for j in range(3):
            v = M[3 * i + j]
            for k in range(i):
                v -= S[4 * i + k] * G[3 * k + j]
            G[3 * i + j] = v / S[4 * i + i]
    # ---- q = q⁻ + Yᵀ z ; Σ = Σ⁻ − YᵀY ; normalise
    for j in range(4):
        v = 0.0
        for k in range(4):
            v += A[4 * k + j] * z[k]
        w[4 + j] = v
    p0 += w[4]; p1 += w[5]; p2 += w[6]; p3 += w[7]
    # ---- b += w Zᵀ z (w = σa²/va, robust weight) ; Σqb = Σqb⁻ − Yᵀ Z ; Σbb = Σbb⁻ − Zᵀ Z
    wb = var_acc / va
    for j in range(3):
        v = 0.0
        for k in range(4):
            v += G[3 * k + j] * z[k]
        state[22 + j] += wb * v
    for i in range(4):
        for j in range(3):
            v = M[3 * i + j]
            u = 0.0
            for k in range(4):
                u += A[4 * k + i] * G[3 * k + j]
            state[26 + 3 * i + j] = v - u
    for i in range(3):
        for j in range(i, 3):
            v = 0.0
            for k in range(4):
                v += G[3 * k + i] * G[3 * k + j]
            state[38 + 3 * i + j] -= v
            if j != i:
                state[38 + 3 * j + i] = state[38 + 3 * i + j]
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
def guo_batch(acc, gyr, mag, acc_ok, gyr_ok, mag_ok, dt_s, var_gyr, var_acc, var_mag,
              inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2, mag_innov_tol, ref_alpha,
              bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, var_bias_walk, state0):
    """Run :func:`guo_step` over ``(N, 3)`` inputs (6D: ``mag_ok`` all false, ``mag`` zeros).

    Returns ``q (N, 4)`` and the final state (a copy; ``state0`` is not modified).
    """
    n = acc.shape[0]
    state = state0.copy()
    out = np.empty((n, 4))
    work = np.empty(128)
    for k in range(n):
        guo_step(state, acc[k, 0], acc[k, 1], acc[k, 2], gyr[k, 0], gyr[k, 1], gyr[k, 2],
                 mag[k, 0], mag[k, 1], mag[k, 2], acc_ok[k], gyr_ok[k], mag_ok[k], dt_s, var_gyr, var_acc,
                 var_mag, inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2, mag_innov_tol, ref_alpha,
                 bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, var_bias_walk, work)
        for j in range(4):
            out[k, j] = state[j]
    return out, state
