r"""The numpy steps of ChakaMo's offline smoother (13–15) and the Butterworth design (2) it shares with
the causal filter.  Theory and equation numbers: :mod:`estimators.orientation.chakamo`.
"""

from __future__ import annotations

import math

import numpy as np
from estimators import signal

from estimators import quaternion as quat
from estimators.orientation.base import BoolArray, FloatArray

#: reweighting passes of :func:`robust_heading` (the weights settle after 2–3 on the gait and BROAD data)
ROBUST_ITERATIONS = 3
#: blocks per heading time constant in the kernel sums of (14) (see :func:`robust_heading`)
BLOCKS_PER_TAU = 100


def butterworth(tau_s: float, fs_hz: float) -> tuple[FloatArray, FloatArray]:
    """Second-order Butterworth low-pass ``(b (3,), a (3,))`` with :math:`f_c = \\sqrt2/(2\\pi\\tau)` (2)."""
    fc_hz = math.sqrt(2.0) / (2.0 * math.pi * tau_s)
    fc_hz = min(fc_hz, 0.45 * fs_hz)
    b, a = signal.butter_lowpass(fc_hz, fs_hz)
    return b / a[0], a / a[0]


def zero_phase_lowpass(acc_i: FloatArray, acc_ok: FloatArray, tau_acc_s: float, fs_hz: float) -> FloatArray:
    """The acceleration in ``I`` low-passed forward and backward (zero phase; offline step 2); missing rows
    are interpolated first, the ends are mirror-extended (even padding: the end values are one-sided means)."""
    n = acc_i.shape[0]
    idx = np.flatnonzero(acc_ok)
    if idx.size < n:
        t = np.arange(n)
        acc_i = np.stack([np.interp(t, idx, acc_i[idx, j]) for j in range(3)], axis=1)
    b, a = butterworth(tau_acc_s, fs_hz)
    if n > 9:
        pad = min(n - 1, int(math.ceil(3.0 * tau_acc_s * fs_hz)))
        return signal.filtfilt(b, a, acc_i, axis=0, padtype="even", padlen=pad)
    return np.repeat(acc_i.mean(axis=0, keepdims=True), n, axis=0)


def zero_phase_inclination(q_is: FloatArray, acc: FloatArray, acc_ok: FloatArray, tau_acc_s: float,
                           fs_hz: float) -> FloatArray:
    """``q_E'I`` per sample from the zero-phase low-pass of the acceleration in ``I`` (offline step 2)."""
    acc_lp = zero_phase_lowpass(quat.rotate(q_is, acc), acc_ok, tau_acc_s, fs_hz)
    return quat.from_two_vectors(acc_lp, np.array([0.0, 0.0, 1.0]))


def field_weights(mag_e: FloatArray, accepted: FloatArray, norm_sigma: float, dip_sigma_rad: float) -> FloatArray:
    r"""Soft weights ``(N,)`` of the field samples for the offline heading (14).

    Offline, the reference norm and dip are the medians over the samples both passes accepted; each
    accepted sample is weighted by a Gaussian of its deviation,
    :math:`w = \exp(-\tfrac12[(|m| - |m|_{ref})/(\sigma_n |m|_{ref})]^2 - \tfrac12[(dip - dip_{ref})/\sigma_d]^2)`,
    so that slightly disturbed samples (below the rejection thresholds) count less.
    """
    w = np.zeros(mag_e.shape[0])
    if not accepted.any():
        return w
    norm = np.linalg.norm(mag_e, axis=1)
    dip = np.arcsin(np.clip(-mag_e[:, 2] / np.where(norm > 0, norm, 1.0), -1.0, 1.0))
    n_ref = np.median(norm[accepted])
    d_ref = np.median(dip[accepted])
    z2 = ((norm - n_ref) / (norm_sigma * n_ref)) ** 2 + ((dip - d_ref) / dip_sigma_rad) ** 2
    w[accepted] = np.exp(-0.5 * z2[accepted])
    return w


def guarded(near: BoolArray, guard: int) -> BoolArray:
    """The samples of ``near`` whose every neighbour within ``guard`` samples (either side) is also near (15a).

    The edges of a disturbance are not trusted on *both* sides: the causal hysteresis (11) guards only the
    time after a disturbance, and the two passes' hysteresis together would guard 2 × ``mag_min_undisturbed_s``
    around each one, more than a walking swing phase lasts (0.5 s).  The recording's own ends are no disturbance.
    """
    near = np.asarray(near, dtype=bool)
    if guard <= 0 or near.all():
        return near.copy()
    n = near.shape[0]
    idx = np.arange(n)
    last_bad = np.maximum.accumulate(np.where(near, -n - guard, idx))  # latest rejected sample at or before k
    next_bad = np.minimum.accumulate(np.where(near, 2 * n + guard, idx)[::-1])[::-1]  # earliest at or after k
    return (idx - last_bad > guard) & (next_bad - idx > guard)


def robust_heading(target_rad: FloatArray, weight: FloatArray, tau_s: float, dt_s: float, width_rad: float,
                   iterations: int = ROBUST_ITERATIONS) -> FloatArray:
    r"""Heading offset (14) with Cauchy weights of the residual (15b), by iterative reweighting.

    :math:`w_j \leftarrow w_j\,c^2/(c^2 + r_j^2)`, :math:`r_j = \delta^*_j - \delta_s(t_j)` (unwrapped target),
    :math:`c` = ``width_rad``, then (14) again (``iterations`` times).  The earth's field is fixed in ``E``, so the
    target of clean samples follows the smoothed heading; a field that a disturbance turns about the vertical
    keeps its norm and dip (it passes (11) and (15)) but not its target.  ``width_rad`` = 0: plain (14).

    The kernel sums of (14) are taken over blocks of ``τ/100`` (``BLOCKS_PER_TAU``): within a block the kernel
    weight :math:`e^{-|t_k - t_j|/\tau}` changes by under 1 %, and the smoothed heading is interpolated linearly
    between block centres.
    """
    w = np.asarray(weight, dtype=np.float64)
    n = target_rad.shape[0]
    used = w > 0.0
    if not used.any():
        return np.zeros(n)
    unwrapped = _unwrapped(target_rad, used)
    block, decay = heading_blocks(tau_s, dt_s)
    delta = _two_sided_mean(unwrapped, w, decay, block)
    if width_rad > 0.0:
        c2 = width_rad * width_rad
        for _ in range(iterations):
            r = unwrapped - delta
            delta = _two_sided_mean(unwrapped, w * (c2 / (c2 + r * r)), decay, block)
    return delta


def heading_blocks(tau_s: float, dt_s: float) -> tuple[int, float]:
    """Samples per block of the kernel sums of (14) (``τ/100``, at least one) and the kernel's decay per block."""
    block = max(1, int(tau_s / (BLOCKS_PER_TAU * dt_s)))
    return block, math.exp(-block * dt_s / tau_s)


def smooth_heading(target_rad: FloatArray, weight: FloatArray, tau_s: float, dt_s: float) -> FloatArray:
    """Heading offset (14): two-sided exponential, weighted mean of the unwrapped target ``(N,)``, rad."""
    return robust_heading(target_rad, weight, tau_s, dt_s, 0.0)


def _unwrapped(target_rad: FloatArray, used: BoolArray) -> FloatArray:
    """The target unwrapped (``np.unwrap``: each step between used samples taken into (−π, π]) over the used
    samples, zero elsewhere."""
    unwrapped = np.zeros(target_rad.shape[0])
    unwrapped[used] = np.unwrap(target_rad[used])
    return unwrapped


def _two_sided_mean(unwrapped: FloatArray, w: FloatArray, decay: float, block: int) -> FloatArray:
    """(14) for given weights on blocks of ``block`` samples (``decay`` per block), interpolated back."""
    n = unwrapped.shape[0]
    nb = -(-n // block)
    x = np.zeros((2, nb * block))
    np.multiply(w, unwrapped, out=x[0, :n])
    x[1, :n] = w
    sums = x.reshape(2, nb, block).sum(axis=2)

    def two_sided(v: FloatArray) -> FloatArray:
        y = signal.lfilter([1.0], [1.0, -decay], v)
        y += signal.lfilter([1.0], [1.0, -decay], np.ascontiguousarray(v[::-1]))[::-1]
        y -= v
        return y

    num, den = two_sided(sums[0]), two_sided(sums[1])
    ok = den > 1e-200  # gaps longer than ~700 τ: hold the nearest smoothed value
    if not ok.any():  # every weight below ~1e-200: no heading information, as with no weight at all
        return np.zeros(n)
    if not ok.all() or nb * block > n:  # the general form: linear between the (valid) block centres
        centre = np.arange(nb) * block + 0.5 * (min(block, n) - 1)
        return np.interp(np.arange(n), centre[ok], num[ok] / den[ok])
    # the same interpolation on the regular grid of full blocks, without a search
    v = num / den
    ends = np.concatenate([v[:1], v, v[-1:]])
    frac = (np.arange(block) - 0.5 * (block - 1)) / block
    ramp = np.where(frac >= 0.0, frac * (ends[2:] - v)[:, None], frac * (v - ends[:-2])[:, None])
    return (v[:, None] + ramp).reshape(-1)
