"""Compiled kernels of :mod:`estimators.orientation.valenti_cf` (numba; theory and equation numbers there).

:func:`valenti_cf_step` advances one sample in place, :func:`valenti_cf_batch` loops it; the readable
numpy twin is ``ValentiCF._run_reference`` (tests check both agree to ≤ 1e-9).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from estimators.orientation.quat_kernels import qrot


@njit(cache=True)
def to_identity(dw, dx, dy, dz, gain, eps):
    """Eqs. (50)–(52): interpolate a unit delta quaternion (dw >= 0) towards the identity."""
    if dw > eps:  # LERP, then normalise
        w = (1.0 - gain) + gain * dw
        x = gain * dx
        y = gain * dy
        z = gain * dz
    else:  # SLERP
        omega = math.acos(dw)
        s = math.sin(omega)
        a = math.sin((1.0 - gain) * omega) / s
        b = math.sin(gain * omega) / s
        w = a + b * dw
        x = b * dx
        y = b * dy
        z = b * dz
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return w / n, x / n, y / n, z / n


@njit(cache=True)
def valenti_cf_step(st, gx, gy, gz, ax, ay, az, mx, my, mz, gyr_ok, acc_ok, mag_ok,
                    dt_s, alpha, beta, eps, adaptive, t1, t2, grav, est_bias, alpha_b,
                    th_w, th_dw, th_a):
    """One sample; updates the state ``st`` (11,) in place (the caller advances ``st[10]``)."""
    w = st[0]
    x = st[1]
    y = st[2]
    z = st[3]
    na = math.sqrt(ax * ax + ay * ay + az * az) if acc_ok else 0.0

    # 5. bias at rest (before the prediction)
    if gyr_ok:
        if est_bias and acc_ok:
            if (abs(na - grav) < th_a
                    and abs(gx - st[7]) < th_dw and abs(gy - st[8]) < th_dw and abs(gz - st[9]) < th_dw
                    and abs(gx - st[4]) < th_w and abs(gy - st[5]) < th_w and abs(gz - st[6]) < th_w):
                st[4] += alpha_b * (gx - st[4])
                st[5] += alpha_b * (gy - st[5])
                st[6] += alpha_b * (gz - st[6])
        st[7] = gx
        st[8] = gy
        st[9] = gz
        # 1. prediction, eqs. (38)-(42): q + 0.5 q ⊗ (0, ω - b) Δt
        ux = gx - st[4]
        uy = gy - st[5]
        uz = gz - st[6]
        h = 0.5 * dt_s
        w, x, y, z = (w + h * (-x * ux - y * uy - z * uz),
                      x + h * (w * ux + y * uz - z * uy),
                      y + h * (w * uy - x * uz + z * ux),
                      z + h * (w * uz + x * uy - y * ux))
        n = math.sqrt(w * w + x * x + y * y + z * z)
        w /= n
        x /= n
        y /= n
        z /= n

    # 2-3. accelerometer correction (tilt)
    if acc_ok:
        gain = alpha
        if adaptive:
            em = abs(na - grav) / grav
            if em >= t2:
                gain = 0.0
            elif em > t1:
                gain = alpha * (t2 - em) / (t2 - t1)
        if gain > 0.0:
            ax /= na
            ay /= na
            az /= na
            # eq. (44): predicted gravity g_p = R(q) a
            px, py, pz = qrot(w, x, y, z, ax, ay, az)
            if pz > 1.0:
                pz = 1.0
            if pz + 1.0 > 1e-12:  # eq. (47), conjugated
                r = math.sqrt(2.0 * (pz + 1.0))
                dw = 0.5 * r
                dx = py / r
                dy = -px / r
            else:  # upside down: half turn about x
                dw = 0.0
                dx = 1.0
                dy = 0.0
            dw, dx, dy, dz = to_identity(dw, dx, dy, 0.0, gain, eps)
            # q' = Δq_acc ⊗ q  (dz == 0)
            w, x, y, z = (dw * w - dx * x - dy * y,
                          dw * x + dx * w + dy * z,
                          dw * y - dx * z + dy * w,
                          dw * z + dx * y - dy * x)

    # 4. magnetometer correction (heading), ENU
    if mag_ok and beta > 0.0:
        lx, ly, _ = qrot(w, x, y, z, mx, my, mz)
        gam = lx * lx + ly * ly
        if gam > 1e-300:
            sg = math.sqrt(gam)
            if ly >= 0.0:
                s = math.sqrt(gam + ly * sg)
                dw = s / math.sqrt(2.0 * gam)
                dz = lx / (math.sqrt(2.0) * s)
            else:
                s = math.sqrt(gam - ly * sg)
                dw = abs(lx) / (math.sqrt(2.0) * s)
                dz = s / math.sqrt(2.0 * gam)
                if lx < 0.0:
                    dz = -dz
            dw, _, _, dz = to_identity(dw, 0.0, 0.0, dz, beta, eps)
            # q = Δq_mag ⊗ q'  (rotation about the earth z axis)
            w, x, y, z = (dw * w - dz * z, dw * x - dz * y, dw * y + dz * x, dw * z + dz * w)

    n = math.sqrt(w * w + x * x + y * y + z * z)
    st[0] = w / n
    st[1] = x / n
    st[2] = y / n
    st[3] = z / n


@njit(cache=True)
def valenti_cf_batch(acc, gyr, mag, acc_ok, mag_ok, dt_s, tau_acc_s, tau_mag_s, eps, adaptive,
                     t1, t2, grav, est_bias, tau_bias_s, th_w, th_dw, th_a, warmup_s, tau_warmup_s,
                     gyr_ok, state0):
    """Run :func:`valenti_cf_step` over ``(N, 3)`` inputs (6D: ``mag_ok`` all false, ``mag`` zeros).

    ``gyr_ok`` (N,) marks usable gyroscope rows (a missing row holds the orientation and the bias).
    Returns ``q (N, 4)`` and the final state ``(11,)`` (a copy; ``state0`` is not modified).
    """
    alpha_run = -math.expm1(-dt_s / tau_acc_s)
    beta_run = -math.expm1(-dt_s / tau_mag_s)
    gain_warm = -math.expm1(-dt_s / tau_warmup_s)
    alpha_warm = max(alpha_run, gain_warm)
    beta_warm = max(beta_run, gain_warm)
    alpha_b = -math.expm1(-dt_s / tau_bias_s)
    n = acc.shape[0]
    out = np.empty((n, 4))
    st = state0.copy()
    for k in range(n):
        if st[10] < warmup_s:
            alpha = alpha_warm
            beta = beta_warm
        else:
            alpha = alpha_run
            beta = beta_run
        st[10] = min(st[10] + dt_s, warmup_s)
        valenti_cf_step(st, gyr[k, 0], gyr[k, 1], gyr[k, 2], acc[k, 0], acc[k, 1], acc[k, 2],
                        mag[k, 0], mag[k, 1], mag[k, 2], gyr_ok[k], acc_ok[k], mag_ok[k], dt_s, alpha, beta,
                        eps, adaptive, t1, t2, grav, est_bias, alpha_b, th_w, th_dw, th_a)
        for j in range(4):
            out[k, j] = st[j]
    return out, st
