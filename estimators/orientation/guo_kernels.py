"""Compiled kernel of :mod:`estimators.orientation.guo` (numba; theory, deviations and equation numbers there).

:func:`guo_step` advances one sample in place (bias at rest, exact prediction of the joint (q, b)
covariance, measurement quaternion with robust weights, Cholesky Kalman update of q and of the gyroscope
bias state), :func:`guo_batch` loops it; the readable numpy twin is
``guo._reference_step`` (tests check both agree to ≤ 1e-9).  State layout: ``STATE_SIZE`` in ``guo``.

Speed decisions (same maths as the reference; only the rounding differs, by ~1e-14):

* The 28 distinct entries of the joint covariance (Σqq and Σbb symmetric: upper triangles only; Σqb)
  are read once into locals — tuples of rows handed to small inlined helpers — and written back once.
  A scratch array would make every store a possible alias of ``state`` for the compiler, forcing
  reloads and spills.  Entries of a product that the symmetric result does not need are never
  computed (dead code).  With the points below, a 9D sample went from ≈ 3 600 to ≈ 2 100
  instructions (callgrind) and from ≈ 0.30 to ≈ 0.19 µs (kernel only; ``estimate()`` adds validation).
* Φ Σ Φᵀ as Φ applied to the columns of Σ, then to the rows of Φ Σ (Φ = c I + s [Ω×] never stored).
* The Cholesky diagonal is kept as reciprocals; normalisations multiply by one reciprocal.
* ``fastmath={"contract"}`` only: lets LLVM fuse a·b + c into FMA instructions.  No other fast-math
  flag: ``nnan``/``ninf`` would let the compiler drop the NaN-propagating comparisons.
* cos and sin of the half rotation angle by their Taylor series to h⁸ when h < 0.1 (truncation
  < 3e-17: exact in double; the usual rates at 100 Hz), libm beyond.
* acos (tilt innovation) and atan2 (heading innovation) only feed ``max(1, innovation / tolerance)``;
  they are skipped when a cheap exact bound already puts the innovation inside the tolerance
  (cos t ≤ 1 − t²/2 + t⁴/24; atan x ≤ x).

Measure with ``python -m benchmarks.speed --methods guo`` (µs/sample) or, repeatable on a loaded machine,
with instruction counts under ``valgrind --tool=callgrind``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from estimators.orientation.acc_lowpass import lowpass_step
from estimators.physics import GRAVITY_M_S2 as G_M_S2

FREE_VAR_RAD2 = 1.0           # variance of unobserved directions (6D heading, quaternion norm)
MIN_FIELD_COS = 1e-3          # |m × a| below this: field parallel to gravity, heading undefined


@njit(cache=True, fastmath={"contract"})
def _phi(c, d1, d2, d3, x):
    """Φ x for Φ = c I + s [Ω×] of (5.42), d = s ω; ``x`` a 4-tuple."""
    return (c * x[0] - d1 * x[1] - d2 * x[2] - d3 * x[3],
            d1 * x[0] + c * x[1] + d3 * x[2] - d2 * x[3],
            d2 * x[0] - d3 * x[1] + c * x[2] + d1 * x[3],
            d3 * x[0] + d2 * x[1] - d1 * x[2] + c * x[3])


@njit(cache=True, fastmath={"contract"})
def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, fastmath={"contract"})
def _dot4(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]


@njit(cache=True, fastmath={"contract"})
def _sym3(b, e, g):
    """g + b E for a row b (3-tuple) and the symmetric E = Σbb given as (e00, e01, e02, e11, e12, e22)."""
    return (g[0] + b[0] * e[0] + b[1] * e[1] + b[2] * e[2],
            g[1] + b[0] * e[1] + b[1] * e[3] + b[2] * e[4],
            g[2] + b[0] * e[2] + b[1] * e[4] + b[2] * e[5])


@njit(cache=True, fastmath={"contract"})
def _solve_lower(ll, x):
    """L⁻¹ x for the Cholesky factor ``ll`` = (1/L00, L10, L20, L30, 1/L11, L21, L31, 1/L22, L32, 1/L33)."""
    y0 = x[0] * ll[0]
    y1 = (x[1] - ll[1] * y0) * ll[4]
    y2 = (x[2] - ll[2] * y0 - ll[5] * y1) * ll[7]
    y3 = (x[3] - ll[3] * y0 - ll[6] * y1 - ll[8] * y2) * ll[9]
    return (y0, y1, y2, y3)


@njit(cache=True, fastmath={"contract"})
def _nu_row(ci, txx, tyy, tyz, tzz):
    """Row i of Ψ̄ diag(free, Σθ) with Σθ = [[txx, 0, 0], [0, tyy, tyz], [0, tyz, tzz]]; ``ci`` row i of Ψ̄."""
    return (ci[0] * FREE_VAR_RAD2, ci[1] * txx, ci[2] * tyy + ci[3] * tyz, ci[2] * tyz + ci[3] * tzz)


@njit(cache=True, fastmath={"contract"})
def _store(state, q0, q1, q2, q3, s0, s1, s2, s3, m0, m1, m2, m3, e):
    """Write q, Σqq (rows s0..s3, upper triangle used), Σqb (rows m0..m3) and Σbb ``e`` into ``state``."""
    state[0] = q0; state[1] = q1; state[2] = q2; state[3] = q3
    state[4] = s0[0]; state[5] = s0[1]; state[6] = s0[2]; state[7] = s0[3]
    state[8] = s0[1]; state[9] = s1[1]; state[10] = s1[2]; state[11] = s1[3]
    state[12] = s0[2]; state[13] = s1[2]; state[14] = s2[2]; state[15] = s2[3]
    state[16] = s0[3]; state[17] = s1[3]; state[18] = s2[3]; state[19] = s3[3]
    state[26] = m0[0]; state[27] = m0[1]; state[28] = m0[2]
    state[29] = m1[0]; state[30] = m1[1]; state[31] = m1[2]
    state[32] = m2[0]; state[33] = m2[1]; state[34] = m2[2]
    state[35] = m3[0]; state[36] = m3[1]; state[37] = m3[2]
    state[38] = e[0]; state[39] = e[1]; state[40] = e[2]
    state[41] = e[1]; state[42] = e[3]; state[43] = e[4]
    state[44] = e[2]; state[45] = e[4]; state[46] = e[5]


@njit(cache=True, fastmath={"contract"})
def guo_step(state, ax, ay, az, gx, gy, gz, mx, my, mz, acc_ok, gyr_ok, mag_ok, dt_s,
             var_gyr, var_acc, var_mag, inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2,
             mag_innov_tol, ref_alpha, bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, var_bias_walk):
    """One sample in place on ``state`` (STATE_SIZE,).

    The 28 distinct covariance entries are read once into locals (tuples: rows of the symmetric
    blocks) and written back once, so the whole update runs in registers.
    """
    q0, q1, q2, q3 = state[0], state[1], state[2], state[3]
    # joint covariance: Σqq rows P0..P3 (symmetric), Σqb rows X0..X3 (Σbb: Eo below)
    P0 = (state[4], state[5], state[6], state[7])
    P1 = (state[5], state[9], state[10], state[11])
    P2 = (state[6], state[10], state[14], state[15])
    P3 = (state[7], state[11], state[15], state[19])
    X0 = (state[26], state[27], state[28])
    X1 = (state[29], state[30], state[31])
    X2 = (state[32], state[33], state[34])
    X3 = (state[35], state[36], state[37])
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
    Eo = (state[38], state[39], state[40], state[42], state[43], state[46])  # Σbb upper triangle
    # ---- prediction (5.42): q⁻ = Φ q, Φ = c I + s [Ω×]
    wn = math.sqrt(gx * gx + gy * gy + gz * gz)
    half = 0.5 * wn * dt_s
    if half < 0.1:  # Taylor series to h⁸: truncation < 3e-17, exact in double (rates ≤ 20 rad/s at 100 Hz)
        h2 = half * half
        c = 1.0 + h2 * (-1.0 / 2.0 + h2 * (1.0 / 24.0 + h2 * (-1.0 / 720.0 + h2 * (1.0 / 40320.0))))
        s = 0.5 * dt_s * (1.0 + h2 * (-1.0 / 6.0 + h2 * (1.0 / 120.0 + h2 * (-1.0 / 5040.0 + h2 * (1.0 / 362880.0)))))
    else:
        c = math.cos(half)
        s = math.sin(half) / wn
    d1 = s * gx
    d2 = s * gy
    d3 = s * gz
    p0, p1, p2, p3 = _phi(c, d1, d2, d3, (q0, q1, q2, q3))
    # ---- Σ⁻ = Φ Σ Φᵀ + (Δt/2)² σg² (I − q qᵀ)   (5.43, 5.44); columns of Φ Σ are Φ (rows of Σ)
    A0 = _phi(c, d1, d2, d3, P0)
    A1 = _phi(c, d1, d2, d3, P1)
    A2 = _phi(c, d1, d2, d3, P2)
    A3 = _phi(c, d1, d2, d3, P3)
    qn = 0.25 * dt_s * dt_s * var_gyr
    # rows of (Φ Σ) Φᵀ: Φ applied to the rows of Φ Σ; only the upper triangle is used later
    S0 = _phi(c, d1, d2, d3, (A0[0], A1[0], A2[0], A3[0]))
    S1 = _phi(c, d1, d2, d3, (A0[1], A1[1], A2[1], A3[1]))
    S2 = _phi(c, d1, d2, d3, (A0[2], A1[2], A2[2], A3[2]))
    S3 = _phi(c, d1, d2, d3, (A0[3], A1[3], A2[3], A3[3]))
    # ---- bias block (deviation 12): ∂q⁻/∂b = B = −(Δt/2) Ξ(q⁻), Ξ(q⁻) = [q⁻⊗i, q⁻⊗j, q⁻⊗k]
    # Σqb⁻ = M = Φ Σqb + B Σbb,  Σqq⁻ += M Bᵀ + B (Φ Σqb)ᵀ,  Σbb⁻ = Σbb + σbw² Δt I
    hb = -0.5 * dt_s if gyr_ok else 0.0
    B0 = (-p1 * hb, -p2 * hb, -p3 * hb)
    B1 = (p0 * hb, -p3 * hb, p2 * hb)
    B2 = (p3 * hb, p0 * hb, -p1 * hb)
    B3 = (-p2 * hb, p1 * hb, p0 * hb)
    Gc0 = _phi(c, d1, d2, d3, (X0[0], X1[0], X2[0], X3[0]))  # columns of Φ Σqb
    Gc1 = _phi(c, d1, d2, d3, (X0[1], X1[1], X2[1], X3[1]))
    Gc2 = _phi(c, d1, d2, d3, (X0[2], X1[2], X2[2], X3[2]))
    G0 = (Gc0[0], Gc1[0], Gc2[0])
    G1 = (Gc0[1], Gc1[1], Gc2[1])
    G2 = (Gc0[2], Gc1[2], Gc2[2])
    G3 = (Gc0[3], Gc1[3], Gc2[3])
    M0 = _sym3(B0, Eo, G0)
    M1 = _sym3(B1, Eo, G1)
    M2 = _sym3(B2, Eo, G2)
    M3 = _sym3(B3, Eo, G3)
    walk = var_bias_walk * dt_s
    E = (Eo[0] + walk, Eo[1], Eo[2], Eo[3] + walk, Eo[4], Eo[5] + walk)
    s00 = S0[0] - qn * q0 * q0 + qn + _dot3(M0, B0) + _dot3(B0, G0)
    s01 = S0[1] - qn * q0 * q1 + _dot3(M0, B1) + _dot3(B0, G1)
    s02 = S0[2] - qn * q0 * q2 + _dot3(M0, B2) + _dot3(B0, G2)
    s03 = S0[3] - qn * q0 * q3 + _dot3(M0, B3) + _dot3(B0, G3)
    s11 = S1[1] - qn * q1 * q1 + qn + _dot3(M1, B1) + _dot3(B1, G1)
    s12 = S1[2] - qn * q1 * q2 + _dot3(M1, B2) + _dot3(B1, G2)
    s13 = S1[3] - qn * q1 * q3 + _dot3(M1, B3) + _dot3(B1, G3)
    s22 = S2[2] - qn * q2 * q2 + qn + _dot3(M2, B2) + _dot3(B2, G2)
    s23 = S2[3] - qn * q2 * q3 + _dot3(M2, B3) + _dot3(B2, G3)
    s33 = S3[3] - qn * q3 * q3 + qn + _dot3(M3, B3) + _dot3(B3, G3)
    # Σ⁻ rows (symmetric)
    R0 = (s00, s01, s02, s03)
    R1 = (s01, s11, s12, s13)
    R2 = (s02, s12, s22, s23)
    R3 = (s03, s13, s23, s33)
    if not acc_ok:
        n = 1.0 / math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
        _store(state, p0 * n, p1 * n, p2 * n, p3 * n, R0, R1, R2, R3, M0, M1, M2, M3, E)
        return
    # Ψ̄ = [q, i⊗q, j⊗q, k⊗q] at q = q⁻: earth-frame rotations → quaternion changes (rows C0..C3)
    C0 = (p0, -p1, -p2, -p3)
    C1 = (p1, p0, p3, -p2)
    C2 = (p2, -p3, p0, p1)
    C3 = (p3, p2, -p1, p0)
    # ---- measurement quaternion (5.36–5.38)
    an = math.sqrt(ax * ax + ay * ay + az * az)
    ia = 1.0 / an
    ux = ax * ia; uy = ay * ia; uz = az * ia
    # rows of R(q⁻) (earth axes in sensor coordinates) for the robust weights (deviation 7)
    r00 = 1.0 - 2.0 * (p2 * p2 + p3 * p3); r01 = 2.0 * (p1 * p2 - p0 * p3); r02 = 2.0 * (p1 * p3 + p0 * p2)
    r10 = 2.0 * (p1 * p2 + p0 * p3); r11 = 1.0 - 2.0 * (p1 * p1 + p3 * p3); r12 = 2.0 * (p2 * p3 - p0 * p1)
    r20 = 2.0 * (p1 * p3 - p0 * p2); r21 = 2.0 * (p2 * p3 + p0 * p1); r22 = 1.0 - 2.0 * (p1 * p1 + p2 * p2)
    dg = an - G_M_S2
    cos_tilt = r20 * ux + r21 * uy + r22 * uz  # tilt innovation = acos(cos_tilt)
    # Huber bound ≥ the predicted tilt std √(2 (c₁ᵀΣ⁻c₁ + c₂ᵀΣ⁻c₂)) (deviation 13); c_k column k of Ψ̄
    c1 = (C0[1], C1[1], C2[1], C3[1])
    c2 = (C0[2], C1[2], C2[2], C3[2])
    v11 = _dot4(c1, (_dot4(R0, c1), _dot4(R1, c1), _dot4(R2, c1), _dot4(R3, c1)))
    v22 = _dot4(c2, (_dot4(R0, c2), _dot4(R1, c2), _dot4(R2, c2), _dot4(R3, c2)))
    tol_eff = max(acc_innov_tol, math.sqrt(max(2.0 * (v11 + v22), 0.0)))
    va = var_acc * (1.0 + dg * dg * inv_acc_tol2)
    # cos t ≤ 1 − t²/2 + t⁴/24 for every t: above that bound the tilt is within tol_eff and acos is not needed
    t2 = tol_eff * tol_eff
    if not cos_tilt >= 1.0 + t2 * (-0.5 + t2 / 24.0):
        va *= max(1.0, math.acos(min(max(cos_tilt, -1.0), 1.0)) / tol_eff)
    # ½(W_a + I) q⁻  (5.37): the accelerometer-consistent quaternion nearest to the prediction
    a0 = 0.5 * (p0 + uz * p0 + uy * p1 - ux * p2)
    a1 = 0.5 * (p1 + uy * p0 - uz * p1 + ux * p3)
    a2 = 0.5 * (p2 - ux * p0 - uz * p2 + uy * p3)
    a3 = 0.5 * (p3 + ux * p1 + uy * p2 + uz * p3)
    nrm = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
    if nrm < 1e-9:  # prediction exactly upside down: no nearest point, skip the correction
        _store(state, p0, p1, p2, p3, R0, R1, R2, R3, M0, M1, M2, M3, E)
        return
    nrm = 1.0 / nrm
    a0 *= nrm; a1 *= nrm; a2 *= nrm; a3 *= nrm
    m0 = a0; m1 = a1; m2 = a2; m3 = a3
    txx = va; tyy = va; tyz = 0.0; tzz = FREE_VAR_RAD2
    if mag_ok:
        mn = math.sqrt(mx * mx + my * my + mz * mz)
        im = 1.0 / mn
        vx = mx * im; vy = my * im; vz = mz * im
        # field direction in earth coordinates by the prediction
        lx = r00 * vx + r01 * vy + r02 * vz
        ly = r10 * vx + r11 * vy + r12 * vz
        lz = r20 * vx + r21 * vy + r22 * vz
        ex = vy * uz - vz * uy
        ey = vz * ux - vx * uz
        ez = vx * uy - vy * ux
        mN = math.sqrt(ex * ex + ey * ey + ez * ez)
        mD = ux * vx + uy * vy + uz * vz  # the dynamic dip m_D = â·m̂ (5.38): needs no attitude
        lh = 0.0
        if not paper_triad:
            lh = math.sqrt(lx * lx + ly * ly)
        if (mN if paper_triad else lh) > MIN_FIELD_COS:
            # disturbance: field norm and dip against tracked references, heading innovation
            if state[20] <= 0.0:  # first field sample: the references start from the data (deviation 10)
                state[20] = mn
                state[21] = mD
            rel = (mn - state[20]) / state[20]
            ddip = lz - state[21]
            vm = var_mag * (1.0 + rel * rel * inv_norm_tol2 + ddip * ddip * inv_dip_tol2)
            # heading innovation |atan2(l_x, l_y)|: within the tolerance when |l_x| ≤ tol · l_y (tan t ≥ t)
            if not (ly > 0.0 and abs(lx) <= mag_innov_tol * ly):
                vm *= max(1.0, abs(math.atan2(lx, ly)) / mag_innov_tol)
            state[20] += ref_alpha * (mn - state[20])
            state[21] += ref_alpha * (lz - state[21])
            if paper_triad:
                # fixed point of ¼(W_a+I)(W_m+I): rows of R_earth_sensor are east, north, up (Shepperd)
                imN = 1.0 / mN
                ex *= imN; ey *= imN; ez *= imN
                nx = uy * ez - uz * ey
                ny = uz * ex - ux * ez
                nz = ux * ey - uy * ex
                tr = ex + ny + uz
                if tr >= ex and tr >= ny and tr >= uz:
                    r = 2.0 * math.sqrt(1.0 + tr)
                    ir = 1.0 / r
                    m0 = 0.25 * r; m1 = (uy - nz) * ir; m2 = (ez - ux) * ir; m3 = (nx - ey) * ir
                elif ex >= ny and ex >= uz:
                    r = 2.0 * math.sqrt(max(1.0 + ex - ny - uz, 0.0))
                    ir = 1.0 / r
                    m0 = (uy - nz) * ir; m1 = 0.25 * r; m2 = (ey + nx) * ir; m3 = (ez + ux) * ir
                elif ny >= uz:
                    r = 2.0 * math.sqrt(max(1.0 - ex + ny - uz, 0.0))
                    ir = 1.0 / r
                    m0 = (ez - ux) * ir; m1 = (ey + nx) * ir; m2 = 0.25 * r; m3 = (nz + uy) * ir
                else:
                    r = 2.0 * math.sqrt(max(1.0 - ex - ny + uz, 0.0))
                    ir = 1.0 / r
                    m0 = (nx - ey) * ir; m1 = (ez + ux) * ir; m2 = (nz + uy) * ir; m3 = 0.25 * r
                tyz = mD * va * imN
                tzz = (vm + mD * mD * va) * (imN * imN)
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
    # ---- S = Σ⁻ + Σν, Σν = ¼ Ψ̄ diag(free, Σθ) Ψ̄ᵀ  (5.39–5.41); upper triangle
    N0 = _nu_row(C0, txx, tyy, tyz, tzz)
    N1 = _nu_row(C1, txx, tyy, tyz, tzz)
    N2 = _nu_row(C2, txx, tyy, tyz, tzz)
    N3 = _nu_row(C3, txx, tyy, tyz, tzz)
    t00 = s00 + 0.25 * _dot4(N0, C0)
    t01 = s01 + 0.25 * _dot4(N0, C1)
    t02 = s02 + 0.25 * _dot4(N0, C2)
    t03 = s03 + 0.25 * _dot4(N0, C3)
    t11 = s11 + 0.25 * _dot4(N1, C1)
    t12 = s12 + 0.25 * _dot4(N1, C2)
    t13 = s13 + 0.25 * _dot4(N1, C3)
    t22 = s22 + 0.25 * _dot4(N2, C2)
    t23 = s23 + 0.25 * _dot4(N2, C3)
    t33 = s33 + 0.25 * _dot4(N3, C3)
    # ---- Cholesky S = L Lᵀ, the diagonal kept as reciprocals (one division each)
    l00 = math.sqrt(t00)
    i00 = 1.0 / l00
    l10 = t01 * i00; l20 = t02 * i00; l30 = t03 * i00
    l11 = math.sqrt(t11 - l10 * l10)
    i11 = 1.0 / l11
    l21 = (t12 - l20 * l10) * i11
    l31 = (t13 - l30 * l10) * i11
    l22 = math.sqrt(t22 - l20 * l20 - l21 * l21)
    i22 = 1.0 / l22
    l32 = (t23 - l30 * l20 - l31 * l21) * i22
    i33 = 1.0 / math.sqrt(t33 - l30 * l30 - l31 * l31 - l32 * l32)
    L = (i00, l10, l20, l30, i11, l21, l31, i22, l32, i33)
    # ---- Y = L⁻¹ Σ⁻ (columns Y0..Y3), Z = L⁻¹ Σqb⁻ (columns Z0..Z2), z = L⁻¹ (q_am − q⁻)
    Y0 = _solve_lower(L, R0)
    Y1 = _solve_lower(L, R1)
    Y2 = _solve_lower(L, R2)
    Y3 = _solve_lower(L, R3)
    Z0 = _solve_lower(L, (M0[0], M1[0], M2[0], M3[0]))
    Z1 = _solve_lower(L, (M0[1], M1[1], M2[1], M3[1]))
    Z2 = _solve_lower(L, (M0[2], M1[2], M2[2], M3[2]))
    z = _solve_lower(L, (m0 - p0, m1 - p1, m2 - p2, m3 - p3))
    # ---- q = q⁻ + Yᵀ z ; b += w Zᵀ z (w = σa²/va, robust weight)
    p0 += _dot4(Y0, z); p1 += _dot4(Y1, z); p2 += _dot4(Y2, z); p3 += _dot4(Y3, z)
    wb = var_acc / va
    state[22] += wb * _dot4(Z0, z)
    state[23] += wb * _dot4(Z1, z)
    state[24] += wb * _dot4(Z2, z)
    # ---- Σ = Σ⁻ − YᵀY ; Σqb = Σqb⁻ − Yᵀ Z ; Σbb = Σbb⁻ − Zᵀ Z ; normalise
    Q0 = (s00 - _dot4(Y0, Y0), s01 - _dot4(Y0, Y1), s02 - _dot4(Y0, Y2), s03 - _dot4(Y0, Y3))
    Q1 = (0.0, s11 - _dot4(Y1, Y1), s12 - _dot4(Y1, Y2), s13 - _dot4(Y1, Y3))
    Q2 = (0.0, 0.0, s22 - _dot4(Y2, Y2), s23 - _dot4(Y2, Y3))
    Q3 = (0.0, 0.0, 0.0, s33 - _dot4(Y3, Y3))
    K0 = (M0[0] - _dot4(Y0, Z0), M0[1] - _dot4(Y0, Z1), M0[2] - _dot4(Y0, Z2))
    K1 = (M1[0] - _dot4(Y1, Z0), M1[1] - _dot4(Y1, Z1), M1[2] - _dot4(Y1, Z2))
    K2 = (M2[0] - _dot4(Y2, Z0), M2[1] - _dot4(Y2, Z1), M2[2] - _dot4(Y2, Z2))
    K3 = (M3[0] - _dot4(Y3, Z0), M3[1] - _dot4(Y3, Z1), M3[2] - _dot4(Y3, Z2))
    Eu = (E[0] - _dot4(Z0, Z0), E[1] - _dot4(Z0, Z1), E[2] - _dot4(Z0, Z2),
          E[3] - _dot4(Z1, Z1), E[4] - _dot4(Z1, Z2), E[5] - _dot4(Z2, Z2))
    n = 1.0 / math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
    _store(state, p0 * n, p1 * n, p2 * n, p3 * n, Q0, Q1, Q2, Q3, K0, K1, K2, K3, Eu)


@njit(cache=True, fastmath={"contract"})
def guo_batch(acc, gyr, mag, acc_ok, gyr_ok, mag_ok, dt_s, var_gyr, var_acc, var_mag,
              inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2, mag_innov_tol, ref_alpha,
              bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, var_bias_walk, state0, lp_coeffs, lp_offset):
    """Run :func:`guo_step` over ``(N, 3)`` inputs (6D: ``mag_ok`` all false, ``mag`` zeros).

    With ``lp_offset`` ≥ 0 each accelerometer row first passes the motion-compensated stage
    (:func:`acc_lowpass.lowpass_step`, block at ``state[lp_offset:]``), whose strapdown uses the rate minus
    the bias estimate before the sample (zero rate on a missing gyroscope row), as the filter's prediction does.
    Returns ``q (N, 4)`` and the final state (a copy; ``state0`` is not modified).
    """
    n = acc.shape[0]
    state = state0.copy()
    out = np.empty((n, 4))
    for k in range(n):
        ax, ay, az = acc[k, 0], acc[k, 1], acc[k, 2]
        if lp_offset >= 0:
            rx, ry, rz = 0.0, 0.0, 0.0
            if gyr_ok[k]:
                rx, ry, rz = gyr[k, 0] - state[22], gyr[k, 1] - state[23], gyr[k, 2] - state[24]
            ax, ay, az = lowpass_step(state, lp_offset, ax, ay, az, rx, ry, rz, acc_ok[k], dt_s, lp_coeffs)
        guo_step(state, ax, ay, az, gyr[k, 0], gyr[k, 1], gyr[k, 2],
                 mag[k, 0], mag[k, 1], mag[k, 2], acc_ok[k], gyr_ok[k], mag_ok[k], dt_s, var_gyr, var_acc,
                 var_mag, inv_acc_tol2, acc_innov_tol, inv_norm_tol2, inv_dip_tol2, mag_innov_tol, ref_alpha,
                 bias_alpha, rest_gyr, rest_acc, rest_min_s, paper_triad, var_bias_walk)
        for j in range(4):
            out[k, j] = state[j]
    return out, state
