r"""Detection: task span, excursions, still regions and the five events of each cycle (sample indices).

Everything here works in *sample units* (fractional indices); :mod:`.analysis` converts to seconds.
The equations (D1–D6) are those of the package docstring.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from estimators.signal import butter_lowpass_sos, sosfiltfilt

from estimators.motor_task.spec import MotorTaskParams, TaskSpec
from estimators.windows import moving_variance, true_runs

FloatArray = NDArray[np.float64]

#: Fractions of a transition whose crossing times feed the minimum-jerk fit (D5).
FRACTIONS = np.arange(1, 10) / 10.0


def _min_jerk_inverse(f: FloatArray) -> FloatArray:
    """τ such that :math:`10τ^3 - 15τ^4 + 6τ^5 = f` (monotone on [0, 1])."""
    tau = np.linspace(0.0, 1.0, 20001)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    return np.interp(f, s, tau)


TAU_F = _min_jerk_inverse(FRACTIONS)


def lowpass(x: FloatArray, fs_hz: float, cutoff_hz: float) -> FloatArray:
    """Zero-phase 2nd-order Butterworth low-pass along axis 0 (D1); returned unchanged when not applicable."""
    if cutoff_hz >= 0.45 * fs_hz or len(x) < 16:
        return np.array(x, dtype=np.float64, copy=True)
    sos = butter_lowpass_sos(cutoff_hz, fs_hz)
    return sosfiltfilt(sos, x, axis=0, padlen=min(len(x) - 1, 3 * int(fs_hz / cutoff_hz)))


def gyroscope_flexion(flex: FloatArray, fs_hz: float, gyr_thigh: FloatArray, gyr_shank: FloatArray,
                      shank_axis_sensor: FloatArray, crossover_hz: float) -> FloatArray | None:
    r"""Knee flexion for the event fits (D7): its shape from the two gyroscopes, its level from ``flex``.

    The flexion rate is the shank's angular velocity about its flexion axis minus the thigh's about its own
    (K1: flexing turns the tibia negatively about z),

    .. math:: \dot\phi_g = -(\omega_{shank}\cdot\hat z_{shank} - \omega_{thigh}\cdot\hat z_{thigh}),\qquad
        \phi_g(t) = \textstyle\int_0^t \dot\phi_g, \qquad
        \phi_{fit} = \phi_g + \mathrm{LP}_{f_c}(\phi - \phi_g) \quad (D7)

    with :math:`\hat z_{shank}` the calibrated flexion axis in shank-sensor coordinates and :math:`\hat z_{thigh}`
    the thigh gyroscope's principal axis (dominant eigenvector of :math:`\sum\omega\omega^\top`: the hip flexes
    about the thigh's z in a step-up), of the sign whose :math:`\phi_{fit}` stays closer to :math:`\phi` (the
    wrong sign gives the difference instead of the sum of the hip's and the shank's rotation: in the simulator
    +0.6 φ and −0.4 φ about z, so 0.2 φ instead of φ; no orientation is needed).  :math:`\mathrm{LP}_{f_c}` is the zero-phase Butterworth low-pass at
    ``crossover_hz`` (a complementary filter): below it the orientation filters' flexion, above it the
    integrated gyroscopes.  Why: with an accelerometer bias the orientation filters' tilt moves between the
    solutions of two poses over a few seconds, and an offline smoother starts that move *before* the motion
    does, so the flexion of a still knee ramps by ~1° in the 2–3 s before an impulse (seed 34 of
    ``benchmarks/robustness.py``: −0.46° → +0.69°); a 5–10° impulse lasting 2 s is then timed 0.2 s early.  The
    gyroscopes see no rotation while the knee is still.  Drift (residual gyroscope bias, scale) is slower than
    :math:`f_c` and is removed by it.  None when a gyroscope is missing, not (N, 3) or not finite.
    """
    gt, gs = np.asarray(gyr_thigh, dtype=np.float64), np.asarray(gyr_shank, dtype=np.float64)
    zs = np.asarray(shank_axis_sensor, dtype=np.float64).reshape(-1)
    n = len(flex)
    if (gt.shape != (n, 3) or gs.shape != (n, 3) or zs.shape != (3,) or n < 16
            or not (np.all(np.isfinite(gt)) and np.all(np.isfinite(gs)) and np.all(np.isfinite(zs)))):
        return None
    zs = zs / np.linalg.norm(zs)
    rate_s = gs @ zs
    rate_t = gt @ np.linalg.eigh(gt.T @ gt)[1][:, -1]
    f = np.asarray(flex, dtype=np.float64)
    best, best_res = None, np.inf
    for sign in (1.0, -1.0):  # the principal axis' sign: the one whose fast part matches the flexion's
        phi_g = np.cumsum(-(rate_s - sign * rate_t)) / fs_hz
        fit = phi_g + lowpass(f - phi_g, fs_hz, crossover_hz)
        res = float(np.sum((f - fit) ** 2))
        if res < best_res:
            best, best_res = fit, res
    return best


def moving_sd(x: FloatArray, n: int) -> FloatArray:
    """Centred moving standard deviation over ``n`` samples (shorter at the ends), via cumulative sums (D2)."""
    return np.sqrt(moving_variance(x, max(int(n), 2)))


def merge_runs(r: NDArray[np.int64], max_gap: int) -> NDArray[np.int64]:
    """Merge runs separated by fewer than ``max_gap`` samples."""
    if len(r) < 2 or max_gap <= 0:
        return r
    keep = np.concatenate([[True], r[1:, 0] - r[:-1, 1] >= max_gap])
    starts = r[keep, 0]
    ends = np.append(r[np.flatnonzero(keep)[1:] - 1, 1], r[-1, 1])
    return np.column_stack([starts, ends])


def task_span(flex: FloatArray, fs_hz: float, p: MotorTaskParams) -> tuple[int, int] | None:
    """``[start, end)`` from the first to the last sample whose moving SD of flexion exceeds the threshold (D2),
    widened by half a window; None when the knee never moves that much."""
    n = int(round(p.activity_window_s * fs_hz))
    active = np.flatnonzero(moving_sd(flex, n) > p.activity_sd_rad)
    if len(active) == 0:
        return None
    return max(0, int(active[0]) - n // 2), min(len(flex), int(active[-1]) + n // 2 + 1)


def excursions(y: FloatArray, span: tuple[int, int], p: MotorTaskParams) -> NDArray[np.int64]:
    """Runs where ``y`` is above the midline between its 5th and 95th percentile in the task span, with
    hysteresis of ±15 % of that amplitude (D3); empty when the amplitude is below ``min_excursion_rad``."""
    lo, hi = np.percentile(y[span[0]:span[1]], [5.0, 95.0])
    if hi - lo < p.min_excursion_rad:
        return np.zeros((0, 2), dtype=np.int64)
    mid, h = 0.5 * (lo + hi), 0.15 * (hi - lo)
    state = np.where(y > mid + h, 1, np.where(y < mid - h, 0, -1))
    idx = np.where(state >= 0, np.arange(len(y)), 0)
    np.maximum.accumulate(idx, out=idx)
    filled = state[idx]
    filled[filled < 0] = (y[0] > mid)  # undecided before the first clear sample: side of the midline
    return true_runs(filled == 1)


@dataclass
class Region:
    """A still region ``[start, end)`` (a rest, a hold or a turning point) and its levels next to each edge."""

    start: int
    end: int
    level_in: float   # median of y over the first level_window of the region
    level_out: float  # median of y over the last level_window of the region

    @property
    def length(self) -> int:
        return self.end - self.start


def _region(y: FloatArray, start: int, end: int, w: int) -> Region:
    end = max(end, start + 1)
    return Region(start, end, float(np.median(y[start:min(end, start + w)])),
                  float(np.median(y[max(start, end - w):end])))


def _longest_still(still: NDArray[np.int64], lo: int, hi: int) -> tuple[int, int] | None:
    """The longest still run clipped to ``[lo, hi)``."""
    if hi <= lo or len(still) == 0:
        return None
    s = np.clip(still[:, 0], lo, hi)
    e = np.clip(still[:, 1], lo, hi)
    length = e - s
    k = int(np.argmax(length))
    return (int(s[k]), int(e[k])) if length[k] > 0 else None


def _containing(still: NDArray[np.int64], i: int, lo: int, hi: int) -> tuple[int, int]:
    """The still run containing sample ``i``, clipped to ``[lo, hi)``; ``[i, i+1)`` when none does."""
    k = int(np.searchsorted(still[:, 0], i, side="right")) - 1 if len(still) else -1
    if k >= 0 and still[k, 1] > i:
        return max(int(still[k, 0]), lo), min(int(still[k, 1]), hi)
    return i, i + 1


def fit_transition(y: FloatArray, i0: int, i1: int, level0: float, level1: float,
                   p: MotorTaskParams) -> tuple[float, float]:
    """Start and end (fractional samples) of the monotone transition of ``y`` from ``level0`` to ``level1``
    within samples ``[i0, i1]`` (D5 minimum-jerk fit or D6 threshold); NaN when it cannot be measured."""
    a = level1 - level0
    if i1 - i0 < 2 or a == 0.0:
        return float("nan"), float("nan")
    u = (y[i0:i1 + 1] - level0) / a
    above = np.flatnonzero(u >= 0.5)
    if len(above) == 0 or above[0] == 0:
        return float("nan"), float("nan")
    jm = int(above[0])

    def crossing(f: float) -> float:
        if f < 0.5:
            below = np.flatnonzero(u[:jm] < f)
            if len(below) == 0:
                return 0.0
            j = int(below[-1])
        else:
            hit = np.flatnonzero(u[jm:] >= f)
            if len(hit) == 0:
                return float(len(u) - 1)
            j = jm + int(hit[0]) - 1
        du = u[j + 1] - u[j]
        return j + ((f - u[j]) / du if du > 0 else 0.0)

    if p.boundary_model == "threshold":
        f = float(np.clip(p.boundary_threshold_rad / abs(a), 1e-3, 0.5))
        return i0 + crossing(f), i0 + crossing(1.0 - f)
    c = np.array([crossing(f) for f in FRACTIONS])
    tau_c = TAU_F - TAU_F.mean()
    duration = float(np.dot(tau_c, c - c.mean()) / np.dot(tau_c, tau_c))  # D5: c_f = t0 + T τ_f
    if not duration > 0.0:
        return float("nan"), float("nan")
    low, high = FRACTIONS <= 0.5, FRACTIONS >= 0.5
    t0 = float(np.mean(c[low] - duration * TAU_F[low]))
    t1 = float(np.mean(c[high] + duration * (1.0 - TAU_F[high])))
    return i0 + t0, i0 + t1


def fit_onset(y: FloatArray, lo: int, t_end: float) -> float:
    r"""Start (fractional sample) of a minimum-jerk movement ending at ``t_end``, least squares over ``y[lo:t_end]``.

    D5b: for each candidate start :math:`c` the model
    :math:`y_i = L + b\,(i - c)_{-} + A\,m(\mathrm{clip}((i-c)/(t_{end}-c),0,1))`, with
    :math:`(i-c)_{-} = \min(i-c, 0)`, is linear in the rest level :math:`L`, a drift :math:`b` of the rest
    (a converging orientation filter) and the amplitude :math:`A`, solved in closed form; the start is the
    candidate of least residual, refined by a parabola through its neighbours.  Every sample votes, so a
    small slow movement (the 5–10° impulse) is timed far better than by its crossing times.  NaN when the
    window holds fewer than 6 samples.
    """
    i1 = int(np.floor(t_end))
    if i1 - lo < 6:
        return float("nan")
    idx = np.arange(lo, i1 + 1, dtype=np.float64)
    yy = y[lo:i1 + 1]
    cand = np.arange(lo, i1 - 2, dtype=np.float64)
    d = idx[None, :] - cand[:, None]
    tau = np.clip(d / (t_end - cand[:, None]), 0.0, 1.0)
    x = np.stack([np.ones_like(tau), np.minimum(d, 0.0), _mj(tau)], axis=2)  # (C, N, 3)
    g = np.einsum("cni,cnj->cij", x, x) + 1e-9 * np.eye(3)
    b = np.einsum("cni,n->ci", x, yy)
    sol = np.linalg.solve(g, b[..., None])[..., 0]
    res = yy @ yy - np.einsum("ci,ci->c", b, sol)
    j = int(np.argmin(res))
    if 0 < j < len(res) - 1:
        den = res[j - 1] - 2.0 * res[j] + res[j + 1]
        if den > 0:
            return float(cand[j] + 0.5 * (res[j - 1] - res[j + 1]) / den)
    return float(cand[j])


def _mj(tau: FloatArray) -> FloatArray:
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def _split_residuals(t_s: FloatArray, yy: FloatArray, f0: float, t_end: float, t1: FloatArray, t0: FloatArray,
                     chunk: int = 1024) -> FloatArray:
    """Residual sums of squares of the fall–rest–impulse model (D5c) for candidate pairs (t1, t0), and the
    levels (F, L, P) of the last chunk's pairs."""
    out = np.empty(len(t1))
    last = np.zeros((0, 3))
    for c in range(0, len(t1), chunk):
        a1, a0 = t1[c:c + chunk, None], t0[c:c + chunk, None]
        fall, rest = t_s < a1, (t_s >= a1) & (t_s < a0)
        m1 = _mj(np.clip((t_s - f0) / (a1 - f0), 0.0, 1.0))
        x_f = np.where(fall, 1.0 - m1, 0.0)
        x_p = np.where(t_s >= a0, _mj(np.clip((t_s - a0) / (t_end - a0), 0.0, 1.0)), 0.0)
        x_l = 1.0 - x_f - x_p
        x_b = np.where(fall, (a1 - a0) * m1, np.where(rest, t_s - a0, 0.0))  # drift of the rest, ends at L
        x = np.stack([x_f, x_l, x_p, x_b], axis=2)                 # (C, N, 4)
        g = np.einsum("cni,cnj->cij", x, x) + 1e-9 * np.eye(4)
        b = np.einsum("cni,n->ci", x, yy)
        sol = np.linalg.solve(g, b[..., None])[..., 0]
        out[c:c + chunk] = yy @ yy - np.einsum("ci,ci->c", b, sol)
        last = sol
    return out, last


def _split_rss_kernel(t_s, yy, f0, t_end, t1, t0):  # pragma: no cover - compiled by numba (tested against numpy)
    """The residual of :func:`_split_residuals` per candidate pair, one pair at a time: the 4×4 normal equations
    accumulated over the samples and solved by Gaussian elimination (the same ridge), no (C, N, 4) arrays."""
    n_c, n = t1.shape[0], t_s.shape[0]
    out = np.empty(n_c)
    yy2 = 0.0
    for k in range(n):
        yy2 += yy[k] * yy[k]
    x = np.empty(4)
    for c in range(n_c):
        a1, a0 = t1[c], t0[c]
        g = np.zeros((4, 4))
        b = np.zeros(4)
        for k in range(n):
            t = t_s[k]
            tau = min(max((t - f0) / (a1 - f0), 0.0), 1.0)
            m1 = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau)
            fall = t < a1
            x_f = 1.0 - m1 if fall else 0.0
            if t >= a0:
                tp = min(max((t - a0) / (t_end - a0), 0.0), 1.0)
                x_p = tp * tp * tp * (10.0 - 15.0 * tp + 6.0 * tp * tp)
            else:
                x_p = 0.0
            x[0], x[1], x[2] = x_f, 1.0 - x_f - x_p, x_p
            x[3] = (a1 - a0) * m1 if fall else (t - a0 if t < a0 else 0.0)
            for i in range(4):
                b[i] += x[i] * yy[k]
                for j in range(4):
                    g[i, j] += x[i] * x[j]
        for i in range(4):
            g[i, i] += 1e-9
        sol = b.copy()
        a = g.copy()
        for i in range(4):  # Gaussian elimination with partial pivoting (4×4, symmetric positive definite)
            p = i
            for r in range(i + 1, 4):
                if abs(a[r, i]) > abs(a[p, i]):
                    p = r
            if p != i:
                for j in range(4):
                    a[i, j], a[p, j] = a[p, j], a[i, j]
                sol[i], sol[p] = sol[p], sol[i]
            for r in range(i + 1, 4):
                f = a[r, i] / a[i, i]
                for j in range(i, 4):
                    a[r, j] -= f * a[i, j]
                sol[r] -= f * sol[i]
        for i in range(3, -1, -1):
            s = sol[i]
            for j in range(i + 1, 4):
                s -= a[i, j] * sol[j]
            sol[i] = s / a[i, i]
        out[c] = yy2 - (b[0] * sol[0] + b[1] * sol[1] + b[2] * sol[2] + b[3] * sol[3])
    return out


_RSS = None


def split_rss(t_s: FloatArray, yy: FloatArray, f0: float, t_end: float, t1: FloatArray, t0: FloatArray) -> FloatArray:
    """Residual sums of squares of the D5c model for candidate pairs: :func:`_split_rss_kernel` compiled with numba
    (cached on disk; imported on first use), equal to :func:`_split_residuals`' first result (the readable
    reference, which the tests compare it with)."""
    global _RSS
    if _RSS is None:
        import numba

        _RSS = numba.njit(cache=True, nogil=True)(_split_rss_kernel)
    f = np.ascontiguousarray
    return _RSS(f(t_s, dtype=np.float64), f(yy, dtype=np.float64), float(f0), float(t_end),
                f(t1, dtype=np.float64), f(t0, dtype=np.float64))


def split_levels(y: FloatArray, f0: float, t_end: float, t1: float, t0: float) -> FloatArray:
    """(F, L, P, b): far, rest (at the onset) and peak levels and the rest's drift (per sample) of the D5c model
    fitted with the given ``t1``, ``t0``."""
    i0, i1 = int(np.ceil(f0)), int(np.floor(t_end))
    idx = np.arange(i0, i1 + 1, dtype=np.float64)
    return _split_residuals(idx, y[i0:i1 + 1], f0, t_end, np.array([t1]), np.array([t0]))[1][0]


def fit_split(y: FloatArray, f0: float, t_end: float, fs_hz: float, min_pause: float = 0.0) -> tuple[float, float]:
    r"""End of a fall and start of the next impulse (fractional samples) by least squares (D5c).

    Between leaving the far plateau at :math:`f_0` (D5) and the next peak at :math:`t_{end}` the knee falls
    back to the rest level, may rest there, and starts the impulse.  Model, linear in the far level
    :math:`F`, the rest level :math:`L`, its drift :math:`b` and the peak :math:`P`:

    .. math:: y = F + (L_1-F)\,m\!\left(\tfrac{t-f_0}{t_1-f_0}\right)\ (t<t_1),\quad
              L + b\,(t-t_0)\ (t_1\le t<t_0),\quad L + (P-L)\,m\!\left(\tfrac{t-t_0}{t_{end}-t_0}\right)\ (t\ge t_0)

    with the minimum-jerk :math:`m` and :math:`L_1 = L + b\,(t_1-t_0)` (a rest that drifts slowly, an orientation
    filter settling during a pause, is not taken for the start of the impulse).  :math:`(t_1, t_0)`, :math:`t_1 \le t_0`, minimise the residual: a grid
    at ~25 Hz over a ~25 Hz decimation, then every sample ±2 coarse steps around the best pair (moved until the
    best is inside).  Every sample
    votes, so a slow 5–10° impulse right after the fall (no rest at all, the thesis' continuous cycles) or
    after a pause of any length is timed to a few samples, and the rest level needs no separate estimate.
    A rest (:math:`t_0 > t_1`) is kept only when it is at least ``min_pause`` samples long and lowers the
    residual by more than the Bayesian information criterion charges for its parameters
    (:math:`2\ln N` residual variances: the rest's length and drift); otherwise :math:`t_1 = t_0`, the best continuous split.
    """
    i0, i1 = int(np.ceil(f0)), int(np.floor(t_end))
    if i1 - i0 < 8:
        return float("nan"), float("nan")
    step = max(1, int(round(fs_hz / 25.0)))
    idx = np.arange(i0, i1 + 1, dtype=np.float64)
    lo_gap = 2.0 * step

    def grid(cands1: FloatArray, cands0: FloatArray, sub: int) -> tuple[float, float]:
        t1g, t0g = np.meshgrid(cands1, cands0, indexing="ij")
        keep = (t0g >= t1g) & (t1g > f0 + 1.0) & (t0g < t_end - 1.0)
        t1v, t0v = t1g[keep], t0g[keep]
        if len(t1v) == 0:
            return float("nan"), float("nan"), float("nan")
        res = split_rss(idx[::sub], y[i0:i1 + 1:sub], f0, t_end, t1v, t0v)
        j = int(np.argmin(res))
        return float(t1v[j]), float(t0v[j]), float(res[j])

    cands = np.arange(f0 + lo_gap, t_end - lo_gap, step, dtype=np.float64)
    t1, t0, _ = grid(cands, cands, step)
    if not np.isfinite(t1):
        return t1, t0
    # every sample around the best pair, moved until the best lies inside the window (the slow impulse start
    # trades against the fall's end on the coarse grid)
    fine = np.arange(-2 * step, 2 * step + 1, dtype=np.float64)
    res = float("nan")
    for _ in range(6):
        b1, b0, res = grid(t1 + fine, t0 + fine, 1)
        if not np.isfinite(b1):
            break
        inside = abs(b1 - t1) < 2 * step and abs(b0 - t0) < 2 * step
        t1, t0 = b1, b0
        if inside:
            break
    if t0 > t1 and np.isfinite(res):
        # a rest between fall and impulse is one more parameter: kept only when it lowers the residual by more
        # than the Bayesian information criterion charges for it (ln N residual variances)
        c = np.arange(min(t1, t0) - 2 * step, max(t1, t0) + 2 * step + 1, dtype=np.float64)
        c = c[(c > f0 + 1.0) & (c < t_end - 1.0)]
        if len(c):
            res_c = split_rss(idx, y[i0:i1 + 1], f0, t_end, c, c)
            j = int(np.argmin(res_c))
            n_s = len(idx)
            if t0 - t1 < min_pause or res_c[j] - res < 2.0 * np.log(n_s) * res / max(n_s - 6, 1):
                return float(c[j]), float(c[j])
    return t1, t0


@dataclass
class Gap:
    """What lies between two excursions: the rest region and (countermovement tasks) the countermovement peak.

    rest : the still region holding the split (``None``: no rest).   cm_index : sample of the countermovement
    peak (None: none measurable).   level : the rest level at the split (countermovement gaps; the level both
    the fall before and the impulse after are fitted to).   split : sample where the knee is stillest.
    """

    rest: Region | None
    cm_index: int | None
    level: float = float("nan")
    split: int | None = None


def analyse_gap(y: FloatArray, v: tuple[FloatArray, ...], g0: int, g1: int, still: NDArray[np.int64], task: TaskSpec,
                p: MotorTaskParams, w: int, expect_cm: bool) -> Gap:
    """Rest, split and countermovement between two excursions (D4)."""
    if g1 <= g0:
        return Gap(None, None)
    if task.countermovement and expect_cm:
        cm = g0 + int(np.argmin(y[g0:g1]))
        # the split lies before the countermovement peak, at least half the minimum countermovement above it:
        # the stillest sample there (a pause of any length, or the instant the fall turns into the impulse)
        ok = np.flatnonzero(y[g0:cm] >= y[cm] + 0.5 * p.min_countermovement_rad)
        if len(ok):
            hi = g0 + int(ok[-1]) + 1
            for rate in v:  # the averaged rate first (a slow impulse in noise), then the plain one (fast cycles)
                split = g0 + int(np.argmin(np.abs(rate[g0:hi])))
                half = max(1, w // 3)
                level = float(np.median(y[max(g0, split - half):min(hi, split + half + 1)]))
                if level - y[cm] >= p.min_countermovement_rad:
                    r = _containing(still, split, g0, hi)
                    return Gap(_region(y, r[0], r[1], w), cm, level, split)
        # no countermovement distinguishable from the rest: the rest is the still run at the lowest point
        r = _containing(still, cm, g0, g1)
        return Gap(_region(y, r[0], r[1], w), None)
    r = _longest_still(still, g0, g1)
    if r is None:
        return Gap(None, None)
    return Gap(_region(y, r[0], r[1], w), None)


@dataclass
class CycleEvents:
    """Events of one detected cycle in fractional samples (NaN when unknown) and why it is incomplete."""

    events: FloatArray          # (5,) onset, countermovement_peak, far_reached, far_left, rest_reached
    incomplete: str | None      # None, or the reason code
    message: str = ""
    amplitude: float = float("nan")


def detect_cycles(y: FloatArray, fs_hz: float, span: tuple[int, int], task: TaskSpec,
                  p: MotorTaskParams, y_raw: FloatArray | None = None) -> list[CycleEvents]:
    """All cycles (one per excursion) with their events, from the sign-normalised smoothed flexion ``y``;
    the least-squares fits (D5b, D5c) use ``y_raw``, the same before smoothing, when given (the low-pass
    bends the slow start of the impulse that those fits time)."""
    n = len(y)
    y_fit = y if y_raw is None else np.asarray(y_raw, dtype=np.float64)
    exc = excursions(y, span, p)
    if len(exc) == 0:
        return []
    v = np.gradient(y) * fs_hz
    n_avg = max(1, int(round(0.2 * fs_hz)))  # D4 split: the rate averaged over 0.2 s (slow impulses vs noise)
    v_split = np.convolve(v, np.ones(n_avg) / n_avg, mode="same") if len(v) >= n_avg else v
    still = merge_runs(true_runs(np.abs(v) < p.stationary_rad_s), int(round(p.merge_gap_s * fs_hz)))
    w = max(1, int(round(p.level_window_s * fs_hz)))
    edge_rest = int(round(p.min_edge_rest_s * fs_hz))
    k_n = len(exc)
    gaps = []
    for k in range(k_n + 1):
        g0 = int(exc[k - 1, 1]) if k > 0 else 0
        g1 = int(exc[k, 0]) if k < k_n else n
        gaps.append(analyse_gap(y, (v_split, v), g0, g1, still, task, p, w, expect_cm=k < k_n))
    out = []
    for k in range(k_n):
        a, b = int(exc[k, 0]), int(exc[k, 1])
        ev = np.full(5, np.nan)
        before, after = gaps[k], gaps[k + 1]
        top = a + int(np.argmax(y[a:b]))
        pr = _containing(still, top, a, b)
        far = _region(y, pr[0], pr[1], w)
        reason, msg = None, ""
        if a == 0:
            reason, msg = "incomplete_start", "the recording starts during this cycle"
        elif b == n:
            reason, msg = "incomplete_end", "the recording ends during this cycle"
        elif before.rest is None or (k == 0 and before.rest.length < edge_rest * (1 if before.rest.start == 0 else 2)):
            reason, msg = "incomplete_start", "no rest in the start posture before this cycle"
        elif after.rest is None or (k == k_n - 1 and after.rest.length < edge_rest * (1 if after.rest.end == n else 2)):
            reason, msg = "incomplete_end", "no return to rest in the start posture after this cycle"
        amplitude = float("nan")
        if before.rest is not None:
            rest = before.rest
            amplitude = far.level_in - rest.level_out
            plain = before.cm_index is None
            if not plain:
                cm = before.cm_index
                # impulse: from the split level to the peak, fitted over the whole gap before the peak (the fall
                # before it lies below the 10 % crossing, so the outward crossing search never reaches it)
                g0 = int(exc[k - 1, 1]) if k > 0 else 0
                amplitude = far.level_in - before.level
                e0, e1 = fit_transition(y, cm, min(far.end, far.start + w), y[cm], far.level_in, p)
                peak = e0 if np.isfinite(e0) else float(cm)
                # D5b: the impulse onset by least squares on every sample from the previous fall's end (or the
                # rest's start) to the peak; the crossing fit (D5) only where that is impossible
                s0 = float("nan")
                lo = rest.start
                if p.boundary_model == "min_jerk":
                    prev_left = out[k - 1].events[3] if k > 0 else float("nan")
                    if np.isfinite(prev_left):  # D5c: the previous fall's end and this onset together
                        t1, s0 = fit_split(y_fit, prev_left, peak, fs_hz, p.min_pause_samples(fs_hz))
                        if np.isfinite(t1) and np.isfinite(s0):
                            _, lev_l, lev_p, _ = split_levels(y_fit, prev_left, peak, t1, s0)
                            if lev_l - lev_p < p.min_countermovement_rad:  # the fit finds no impulse
                                plain = True
                            else:
                                out[k - 1].events[4] = t1
                                lo = min(lo, int(np.floor(t1)))
                    elif k == 0:  # D5b: a rest before, no fall; the window starts half an impulse before
                        # its onset (3 × peak − 50 % crossing), so a slow drift of the rest (a converging
                        # filter) does not pass for the start of the impulse
                        mid = 0.5 * (before.level + y[cm])
                        above = np.flatnonzero(y[:cm] >= mid)
                        half_imp = peak - above[-1] if len(above) else peak
                        lo = max(0, int(np.floor(peak - 3.0 * half_imp)))
                        s0 = fit_onset(y_fit, lo, peak)
                if not np.isfinite(s0):
                    s0, _ = fit_transition(y, g0, cm, before.level, y[cm], p)
                ev[0] = np.clip(s0, lo, cm)
                ev[1] = np.clip(peak, ev[0], far.end)
                ev[2] = np.clip(e1, ev[1], far.end)
            if plain:
                if before.cm_index is not None:  # no impulse after all: the rest is the still run at the peak
                    g0 = int(exc[k - 1, 1]) if k > 0 else 0
                    r = _containing(still, before.cm_index, g0, a)
                    rest = _region(y, r[0], r[1], w)
                    gaps[k] = Gap(rest, None)
                    amplitude = far.level_in - rest.level_out
                e0, e1 = fit_transition(y, max(rest.start, rest.end - w), min(far.end, far.start + w),
                                        rest.level_out, far.level_in, p)
                ev[0] = np.clip(e0, rest.start, far.start + 1)
                ev[1] = ev[0] if task.countermovement else np.nan
                ev[2] = np.clip(e1, ev[0], far.end)
        if after.rest is not None:
            rest = after.rest
            if after.cm_index is not None:  # fall to the split level, fitted up to the next peak
                f0, f1 = fit_transition(y, max(far.start, far.end - w), after.cm_index, far.level_out,
                                        after.level, p)
            else:
                f0, f1 = fit_transition(y, max(far.start, far.end - w), min(rest.end, rest.start + w),
                                        far.level_out, rest.level_in, p)
            ev[3] = np.clip(f0, far.start, rest.end)
            ev[4] = np.clip(f1, ev[3], rest.end)
        if reason == "incomplete_start":  # events before the excursion are not measurable
            ev[:2] = np.nan
            if a == 0:
                ev[2] = np.nan
        elif reason == "incomplete_end":
            ev[4] = np.nan
            if b == n:
                ev[3] = np.nan
        if reason is None and not np.all(np.isfinite(ev[[0, 2, 3, 4]])):
            reason, msg = "unmeasurable", "a transition of this cycle could not be measured"
        # the recording's edges: the first onset and the last return to rest must also be fitted inside the
        # recording (a still run at the edge may hold the slow start or end of a movement the edge cut)
        if reason is None and k == 0 and not ev[0] >= 1.0:
            reason, msg = "incomplete_start", "the recording starts before the knee is seen at rest for this cycle"
            ev[:2] = np.nan
        elif reason is None and k == k_n - 1 and not ev[4] <= n - 2.0:
            reason, msg = "incomplete_end", "the recording ends before this cycle is back at rest"
            ev[4] = np.nan
        if reason is None and amplitude < p.min_excursion_rad:
            reason, msg = "small_excursion", "the excursion towards the far plateau is too small"
        out.append(CycleEvents(ev, reason, msg, amplitude))
    return out
