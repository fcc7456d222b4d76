r"""Gait events from the shank gyroscope's sagittal rate, and turns from the segments' yaw rate.

Standard library at import (numpy inside the functions): the task registry imports the gait task module,
which imports this one, and listing the tasks must load no numerics.

Sagittal rate
-------------
:math:`\omega(t) = \mathbf{g}_{shank}(t)\cdot\hat{\mathbf z}_s` with :math:`\hat{\mathbf z}_s` the shank's
flexion axis (ISB segment :math:`z`, to the right on both legs) in shank-sensor coordinates:
:math:`\hat{\mathbf z}_s = q_{sensor,segment}\otimes(0,0,0,1)\otimes q_{sensor,segment}^*`.  Forward rotation
of the shank (swing) is then positive on both legs.

Events (Salarian et al., IEEE TBME 51(8):1434–1443, 2004, §II-B; Aminian et al., J Biomech 35:689–699,
2002, §2.3; the IC rule of Catalfamo et al., Sensors 10:5683, 2010)
--------------------------------------------------------------------------------------------------------
E1  :math:`\omega` is low-passed (2nd-order Butterworth forward and backward, ``lowpass_hz``, 5 Hz).
E2  **Mid-swing** (MS): local maxima of the low-passed rate above ``mid_swing_min_rad_s`` (Salarian's
    50°/s) that are the largest within ± ``mid_swing_separation_s`` (0.4 s): the shank's fastest forward
    rotation in swing (Aminian's "peaks", Salarian's MS).  Sub-sample time by a parabola through the peak.
E3  **Initial contact** (IC): after each MS the shank's forward rotation stops at heel strike; IC is the first
    positive → negative zero crossing of the low-passed rate after MS (Catalfamo et al. 2010, who found the
    crossing within −25 ms of the pressure-insole IC), linearly interpolated, plus ``ic_latency_s``.
    Salarian's and Aminian's IC is the local minimum right after it, which on real shanks is the sharp
    heel-strike trough; on smooth (or heavily filtered) signals that minimum falls in the loading response
    (+80 ms on the simulator), hence the crossing.
E4  **Toe-off** (TO): the minimum of the low-passed rate before MS (Salarian's TC, Aminian's toe-off: the
    shank's fastest backward rotation in pre-swing), searched in ``[MS − to_search_s, MS]`` and after the
    previous IC, parabola-refined, plus ``to_latency_s``.
E5  Latencies: ``ic_latency_s`` (+15 ms) and ``to_latency_s`` (+45 ms) are systematic corrections chosen on
    the tuning seeds of ``benchmarks/gait.py`` against the simulator's truth (whose TO is the 60 % mark of its
    phase, where the shank rate is still rising from its minimum).  Set both to 0 for the published rules as
    they are; they are the first thing to re-tune on footswitch or force-plate data.

Turns
-----
T1  Yaw rate of a segment about the vertical: :math:`r(t) = [q_{earth,sensor}\otimes \mathbf g \otimes
    q_{earth,sensor}^*]_z` (earth z up).  The thigh and shank yaw oscillates with hip and tibial rotation at
    the stride frequency, so :math:`r` is averaged over ``turn_window_s`` (1 s, about one stride); a sample
    is *turning* when the averaged :math:`|r|` of the thigh or of the shank exceeds ``turn_rate_rad_s``
    (20°/s: a 180° turn in 2 s averages 90°/s; straight walking stays below 5°/s on the simulator).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

__all__ = ["GaitEventParams", "GaitEvents", "detect_gait_events", "sagittal_rate", "turning_mask", "yaw_rate"]


@dataclass(frozen=True)
class GaitEventParams:
    """Parameters of the gait-event detector and the turn detector (module docstring E1–E5, T1); SI units, rad.

    lowpass_hz : cut-off of the sagittal-rate low-pass (E1).  Default 5 Hz.
    mid_swing_min_rad_s : smallest mid-swing peak (E2).  Default 50°/s (0.873 rad/s), as Salarian et al.
    mid_swing_separation_s : a mid-swing peak is the largest within ± this (E2).  Default 0.4 s.
    to_search_s : toe-off is searched this long before mid-swing (E4).  Default 0.5 s.
    ic_latency_s, to_latency_s : systematic corrections added to IC and TO (E5).  Defaults 0.015 s, 0.045 s.
    min_stride_s, max_stride_s : an IC → IC interval outside this is no stride (a bout starts or ends).
        Defaults 0.6 s and 2.5 s.
    turn_rate_rad_s : averaged yaw rate above which a sample is turning (T1).  Default 20°/s (0.349 rad/s).
    turn_window_s : averaging window of the yaw rate (T1).  Default 1.0 s.
    """

    lowpass_hz: float = 5.0
    mid_swing_min_rad_s: float = math.radians(50.0)
    mid_swing_separation_s: float = 0.4
    to_search_s: float = 0.5
    ic_latency_s: float = 0.015
    to_latency_s: float = 0.045
    min_stride_s: float = 0.6
    max_stride_s: float = 2.5
    turn_rate_rad_s: float = math.radians(20.0)
    turn_window_s: float = 1.0

    def __post_init__(self) -> None:
        for name, v in asdict(self).items():
            ok = isinstance(v, (int, float)) and math.isfinite(v)
            if not ok or (v <= 0 and not name.endswith("latency_s")):
                raise ValueError(f"GaitEventParams.{name} must be a {'finite' if 'latency' in name else 'positive'} "
                                 f"number, got {v!r}")
        if self.min_stride_s >= self.max_stride_s:
            raise ValueError(f"GaitEventParams.min_stride_s ({self.min_stride_s}) must be below max_stride_s "
                             f"({self.max_stride_s})")


@dataclass(frozen=True, eq=False)
class GaitEvents:
    """Events of one shank, in fractional samples (sample 0 = the first of the recording).

    mid_swing, initial_contact, toe_off : (M,) one of each per detected mid-swing peak j: TO_j < MS_j < IC_j
        (NaN where the rule found none, e.g. a crossing after the end of the recording).
    omega_lp_rad_s : (N,) the low-passed sagittal rate used (E1).
    """

    mid_swing: object
    initial_contact: object
    toe_off: object
    omega_lp_rad_s: object


def sagittal_rate(gyr_shank_rad_s, shank_axis_sensor):
    """(N,) shank sagittal rate, rad/s: gyroscope (N, 3) in sensor axes · flexion axis (3,) in sensor axes."""
    import numpy as np

    g = np.asarray(gyr_shank_rad_s, dtype=np.float64)
    z = np.asarray(shank_axis_sensor, dtype=np.float64).reshape(-1)
    if g.ndim != 2 or g.shape[1] != 3:
        raise ValueError(f"gyr_shank_rad_s must have shape (N, 3) in sensor axes, got {g.shape}")
    if z.shape != (3,) or not np.all(np.isfinite(z)) or np.linalg.norm(z) == 0.0:
        raise ValueError(f"shank_axis_sensor must be a finite non-zero 3-vector (the shank's flexion axis in sensor "
                         f"coordinates), got {shank_axis_sensor!r}")
    if not np.all(np.isfinite(g)):
        raise ValueError("gyr_shank_rad_s contains NaN or infinite values; interpolate or trim them first")
    return g @ (z / np.linalg.norm(z))


def _parabola(y, i):
    """Sub-sample position of the extremum of y through samples i-1, i, i+1."""
    if i <= 0 or i >= len(y) - 1:
        return float(i)
    a, b, c = y[i - 1], y[i], y[i + 1]
    d = a - 2.0 * b + c
    return float(i) if d == 0.0 else float(i) + 0.5 * (a - c) / d


def detect_gait_events(omega_rad_s, fs_hz: float, params: GaitEventParams | None = None) -> GaitEvents:
    """Mid-swing, initial contact and toe-off from the shank's sagittal rate (module docstring E1–E5).

    omega_rad_s : (N,) sagittal rate, rad/s, forward swing positive (:func:`sagittal_rate`).
    fs_hz : sampling rate, Hz.   params : :class:`GaitEventParams`.
    """
    import numpy as np

    from estimators.signal import butter_lowpass, filtfilt

    p = GaitEventParams() if params is None else params
    w = np.asarray(omega_rad_s, dtype=np.float64).reshape(-1)
    n = len(w)
    nan = np.zeros(0)
    if n < 10:
        return GaitEvents(nan, nan, nan, w.copy())
    b, a = butter_lowpass(min(p.lowpass_hz, 0.45 * fs_hz), fs_hz)
    wf = filtfilt(b, a, w)
    half = max(1, int(round(p.mid_swing_separation_s * fs_hz)))
    # E2: local maxima above the threshold, largest within ± half
    cand = np.flatnonzero((wf[1:-1] >= wf[:-2]) & (wf[1:-1] > wf[2:]) & (wf[1:-1] > p.mid_swing_min_rad_s)) + 1
    peaks = [i for i in cand if wf[i] >= wf[max(0, i - half):min(n, i + half + 1)].max()]
    ms, ic, to = [], [], []
    prev_ic = -np.inf
    n_search = int(round(p.to_search_s * fs_hz))
    for i in peaks:
        ms.append(_parabola(wf, i))
        # E3: first positive → negative crossing after MS
        neg = np.flatnonzero(wf[i:] < 0.0)
        if len(neg):
            j = i + int(neg[0])
            ic_j = (j - 1) + wf[j - 1] / (wf[j - 1] - wf[j]) + p.ic_latency_s * fs_hz
        else:
            ic_j = np.nan
        # E4: minimum before MS, after the previous IC
        lo = int(max(0, i - n_search, math.ceil(prev_ic) if np.isfinite(prev_ic) else 0))
        if i - lo >= 2 and wf[lo:i].min() < 0.0:
            k = lo + int(np.argmin(wf[lo:i]))
            to_j = _parabola(wf, k) + p.to_latency_s * fs_hz if k > lo else np.nan
        else:
            to_j = np.nan
        ic.append(ic_j)
        to.append(to_j)
        if np.isfinite(ic_j):
            prev_ic = ic_j
    return GaitEvents(np.asarray(ms), np.asarray(ic), np.asarray(to), wf)


def yaw_rate(q_earth_sensor, gyr_rad_s):
    """(N,) rate about the earth vertical, rad/s (T1): z of the gyroscope rotated into the earth frame."""
    import numpy as np

    from estimators import quaternion as quat

    return quat.rotate(np.asarray(q_earth_sensor, dtype=np.float64), np.asarray(gyr_rad_s, dtype=np.float64))[:, 2]


def turning_mask(yaw_rates_rad_s, fs_hz: float, params: GaitEventParams | None = None):
    """(N,) bool: the averaged |yaw rate| of any of the given segments exceeds ``turn_rate_rad_s`` (T1)."""
    import numpy as np

    p = GaitEventParams() if params is None else params
    win = max(1, int(round(p.turn_window_s * fs_hz)))
    out = None
    for r in yaw_rates_rad_s:
        r = np.asarray(r, dtype=np.float64).reshape(-1)
        c = np.concatenate([[0.0], np.cumsum(r)])
        idx = np.arange(len(r))
        lo, hi = np.clip(idx - win // 2, 0, len(r)), np.clip(idx - win // 2 + win, 0, len(r))
        avg = (c[hi] - c[lo]) / np.maximum(hi - lo, 1)
        m = np.abs(avg) > p.turn_rate_rad_s
        out = m if out is None else (out | m)
    return out
