"""Compiled kernels of :mod:`estimators.orientation.valenti_kf` (numba; theory and equation numbers there).

:func:`valenti_kf_step` advances one sample in place (prediction, AQUA measurement, gated Kalman
update), :func:`valenti_kf_batch` loops it; the readable numpy twin is ``valenti_kf._reference_step``
(tests check both agree to ≤ 1e-9).  State layout: ``0:4`` q_earth_sensor, ``4:20`` P (row-major).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

VIRTUAL_HEADING_STD_RAD = 2.0
"""Heading standard deviation (rad) of the virtual-field measurement (6D, missing or vertical field)."""
GAMMA_MIN = 1e-6
"""Smallest Γ (squared horizontal part of the unit field in the intermediate frame) giving a heading."""


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
    if gamma < GAMMA_MIN:
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
def _measure(ax, ay, az, mx, my, mz, mag_ok, acc_var, mag_var, xm, z, jt, r):
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
    if mag_ok:
        nm = math.sqrt(mx * mx + my * my + mz * mz)
        sm = mag_var  # the noise of the unit field vector: any field unit (valenti_kf module docstring)
        gamma, h0, h1, h2, h3 = _aqua(ax, ay, az, mx / nm, my / nm, mz / nm, False, xm, z, jt)
    if gamma < 0.0:
        sm = VIRTUAL_HEADING_STD_RAD * VIRTUAL_HEADING_STD_RAD
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
def valenti_kf_step(st, gx, gy, gz, ax, ay, az, mx, my, mz, acc_ok, mag_ok,
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
    if acc_ok and _measure(ax, ay, az, mx, my, mz, mag_ok, acc_var, mag_var, xm, z, jt, r):
        _update(st, xm, pm, z, r, tmp, v, gate)
    else:  # no accelerometer: prediction only
        for i in range(4):
            st[i] = xm[i]
        for i in range(16):
            st[4 + i] = pm[i]


@njit(cache=True)
def valenti_kf_batch(acc, gyr, mag, acc_ok, mag_ok, dt_s, gyr_var, acc_var, mag_var, gate, state0):
    """Run :func:`valenti_kf_step` over ``(N, 3)`` inputs (6D: ``mag_ok`` all false, ``mag`` zeros).

    Variances are per sample (``N² f_s``).  Returns ``q (N, 4)`` and the final state (a copy).
    """
    n = acc.shape[0]
    out = np.empty((n, 4))
    st = state0.copy()
    work = np.empty(104)
    for k in range(n):
        valenti_kf_step(st, gyr[k, 0], gyr[k, 1], gyr[k, 2], acc[k, 0], acc[k, 1], acc[k, 2],
                        mag[k, 0], mag[k, 1], mag[k, 2], acc_ok[k], mag_ok[k], dt_s, gyr_var, acc_var, mag_var,
                        gate, work)
        for j in range(4):
            out[k, j] = st[j]
    return out, st
