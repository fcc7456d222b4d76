r"""Split one continuous recording of the whole protocol into figure-eight, standing, supine and task.

A sensor that records without stopping holds, in this order (seed 004 §8.4): the figure-eight for the
magnetometer (the sensor turned in the hand, ~60 s), standing still upright (~30 s), lying still supine
(~30 s) and the motor task, with transitions (strapping the sensor on, lying down, getting up) between
them.  The split reads only the sensor's own signals, per sensor:

**Stillness** (S1).  Over a centred window of ``still_window_s`` the spread of each signal,

.. math:: \sigma_\omega(k) = \sqrt{\textstyle\sum_{i} \operatorname{var}_{win}(\omega_i)}, \qquad
          \sigma_a(k) = \sqrt{\textstyle\sum_{i} \operatorname{var}_{win}(a_i)},

is compared with ``still_gyr_rad_s`` and ``still_acc_m_s2``: sample :math:`k` is still when both are below.
A variance, not a mean, so a gyroscope bias (a BMI160's reaches ±3 °/s) does not hide stillness.

**Postures** (S2).  Each still run of at least ``min_posture_s`` has a gravity direction in sensor axes,
:math:`\hat g = \bar a / |\bar a|` (specific force: at rest it points up).  The protocol wears each sensor with
its +y axis up the segment (seed 004 §8.2, within the mounting tolerance), so standing has :math:`\hat g`
near +y and supine lying, where gravity runs along the segment's anterior axis, far from it:

.. math:: \theta = \arccos(\hat g_y), \qquad \text{upright: } \theta \le \theta_{up}, \qquad
          \text{lying: } \theta \ge \theta_{lie}.

*Supine* is the first lying run that follows an upright one (a sensor resting flat on a table before it is
strapped on comes before any upright run and is skipped); *standing* is the longest upright run before it.

**Figure-eight** (S3).  Before standing, the sensor is *rotating* where its angular rate averaged over
``still_window_s`` exceeds ``rotating_rad_s``; runs closer than ``merge_gap_s`` are one.  Of the runs at least
``min_figure_s`` long, the one whose magnetometer directions (about the run's mean, so a hard-iron offset does
not matter) reach most of the eight octants of the sphere is the figure-eight — it must reach at least
``min_octants`` of them (a figure-eight turns the sensor every way: Vasconcelos et al., IEEE TIM 60(10), 2011,
need directions all round the ellipsoid for its fit).  Without one the split has no figure-eight and the
pipeline uses the sensors' factory calibration.

**Task** (S4).  After supine the person gets up and takes the task's start posture; the task begins with the
first still moment (``task_settle_s``) within ``task_search_s`` after supine ends — the task protocols start
at rest — and runs to the end of the recording.  Without such a moment it begins where supine ends.

Windows are half-open sample ranges ``[start, end)``; the postures' are their still runs shrunk by
``posture_margin_s`` at each end, so an edge's residual motion stays out of the calibration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.windows import moving_variance, true_runs

FloatArray = NDArray[np.float64]

#: the protocol's parts, in recording order (the pipeline's role names)
PARTS = ("mag_calibration", "standing", "lying", "task")

__all__ = ["PARTS", "ProtocolSplit", "SplitError", "SplitParams", "split_protocol"]


class SplitError(ValueError):
    """The recording does not hold the protocol's parts.  ``what`` names the part not found
    (``"standing"``, ``"lying"``, ``"signal"``); the message says what was found."""

    def __init__(self, what: str, message: str) -> None:
        super().__init__(message)
        self.what = what


@dataclass(frozen=True)
class SplitParams:
    """Thresholds of the split (module docstring, S1–S4), each with its unit.

    still_window_s : window of the stillness spreads and of the averaged rate, s (0.5).
    still_gyr_rad_s : gyroscope spread below which a sample is still, rad/s (0.05 ≈ 2.9 °/s; the BMI160's noise
        is 0.007 rad/s rms at 100 Hz, a person standing quietly sways well under 1 °/s at the thigh).
    still_acc_m_s2 : accelerometer spread below which a sample is still, m/s² (0.2; noise 0.02 rms).
    min_posture_s : shortest still run taken as a posture, s (5; the protocol holds each ~30 s, the step-up's
        rests last 1–2 s).
    upright_max_rad : gravity within this of the sensor's +y is upright (45°: mounting tolerance 15° plus a
        thigh that is not quite vertical).   lying_min_rad : gravity at least this far from +y is lying (60°).
    rotating_rad_s : averaged angular rate above which the sensor is rotating, rad/s (0.3).
    merge_gap_s : rotating runs closer than this are one, s (1).   min_figure_s : shortest figure-eight, s (10).
    min_octants : of the 8 octants of magnetometer directions, the figure-eight must reach this many (6).
    task_settle_s : the still moment that starts the task, s (0.5).   task_search_s : how long after supine
        to look for it, s (30).   posture_margin_s : cut from each end of a posture's still run, s (0.5).
    """

    still_window_s: float = 0.5
    still_gyr_rad_s: float = 0.05
    still_acc_m_s2: float = 0.2
    min_posture_s: float = 5.0
    upright_max_rad: float = float(np.deg2rad(45.0))
    lying_min_rad: float = float(np.deg2rad(60.0))
    rotating_rad_s: float = 0.3
    merge_gap_s: float = 1.0
    min_figure_s: float = 10.0
    min_octants: int = 6
    task_settle_s: float = 0.5
    task_search_s: float = 30.0
    posture_margin_s: float = 0.5


@dataclass(frozen=True)
class ProtocolSplit:
    """Where each part of the protocol lies in one continuous recording.

    windows : ``{part: (start, end)}`` half-open sample ranges on the recording's grid; ``mag_calibration``
        is absent when no figure-eight was found (S3).   fs_hz : the grid's rate.
    gravity_angle_rad : ``{"standing"|"lying": θ}`` (S2) of the two postures.
    octants : octants of magnetometer directions the figure-eight reached (0 without one).
    """

    windows: dict[str, tuple[int, int]]
    fs_hz: float
    gravity_angle_rad: dict[str, float]
    octants: int

    def spans_s(self) -> dict[str, tuple[float, float]]:
        """``{part: (start_s, end_s)}`` from the recording's first sample."""
        return {p: (a / self.fs_hz, b / self.fs_hz) for p, (a, b) in self.windows.items()}


def _filled(x: FloatArray) -> FloatArray:
    """``x`` (N, 3) with NaN rows replaced by the last valid row (the first valid one before it)."""
    ok = np.all(np.isfinite(x), axis=1)
    if ok.all():
        return x
    if not ok.any():
        raise SplitError("signal", "the recording holds no valid sample")
    idx = np.where(ok, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    idx[: np.argmax(ok)] = np.argmax(ok)
    return x[idx]


def _spread(x: FloatArray, n: int) -> FloatArray:
    return np.sqrt(sum(moving_variance(x[:, i], n) for i in range(3)))


def _moving_mean(x: FloatArray, n: int) -> FloatArray:
    c = np.concatenate([[0.0], np.cumsum(x)])
    lo = np.clip(np.arange(len(x)) - n // 2, 0, len(x))
    hi = np.clip(lo + n, 0, len(x))
    return (c[hi] - c[lo]) / np.maximum(hi - lo, 1)


def _octants(mag: FloatArray) -> int:
    """Octants of the sphere reached by at least 1 % of the directions of ``mag`` about its mean."""
    ok = np.all(np.isfinite(mag), axis=1)
    d = mag[ok] - mag[ok].mean(axis=0)
    if len(d) == 0:
        return 0
    code = (d[:, 0] > 0).astype(int) + 2 * (d[:, 1] > 0) + 4 * (d[:, 2] > 0)
    return int(np.sum(np.bincount(code, minlength=8) >= 0.01 * len(d)))


def split_protocol(acc: ArrayLike, gyr: ArrayLike, mag: ArrayLike, *, fs_hz: float,
                   params: SplitParams | None = None) -> ProtocolSplit:
    """Find the protocol's parts in one sensor's continuous recording (module docstring, S1–S4).

    acc : (N, 3) specific force, m/s².   gyr : (N, 3) rad/s.   mag : (N, 3) any unit (directions only).
    fs_hz : the grid's rate.  Rows with NaN (gaps) count as not still.
    Raises :class:`SplitError` when no standing or no supine posture is found.
    """
    p = params or SplitParams()
    acc, gyr, mag = (np.asarray(x, dtype=np.float64) for x in (acc, gyr, mag))
    if acc.ndim != 2 or acc.shape[1] != 3 or gyr.shape != acc.shape or mag.shape != acc.shape:
        raise ValueError(f"acc, gyr and mag must be (N, 3) arrays of one length, got {acc.shape}, {gyr.shape}, "
                         f"{mag.shape}")
    n_total = len(acc)
    valid = np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(gyr), axis=1)
    acc_f, gyr_f = _filled(acc), _filled(gyr)
    win = max(3, int(round(p.still_window_s * fs_hz)))
    still = (_spread(gyr_f, win) < p.still_gyr_rad_s) & (_spread(acc_f, win) < p.still_acc_m_s2) & valid

    # S2: postures
    runs = true_runs(still, int(round(p.min_posture_s * fs_hz)))
    theta = []
    for a, b in runs:
        g = acc_f[a:b].mean(axis=0)
        theta.append(float(np.arccos(np.clip(g[1] / np.linalg.norm(g), -1.0, 1.0))))
    upright = [i for i, t in enumerate(theta) if t <= p.upright_max_rad]
    lying = [i for i, t in enumerate(theta) if t >= p.lying_min_rad and any(u < i for u in upright)]
    # language-neutral (the message around it is translated): "30 s @ 65 s (4°)" = 30 s still from 65 s, 4° from +y
    found = ", ".join(f"{(b - a) / fs_hz:.0f} s @ {a / fs_hz:.0f} s ({np.rad2deg(t):.0f}°)"
                      for (a, b), t in zip(runs, theta)) or "-"
    if not upright:
        raise SplitError("standing", f"no still upright posture of {p.min_posture_s:.0f} s or more (gravity within "
                         f"{np.rad2deg(p.upright_max_rad):.0f}° of the sensor's +y); still postures found: {found}")
    if not lying:
        raise SplitError("lying", f"no still lying posture of {p.min_posture_s:.0f} s or more after the standing "
                         f"one (gravity {np.rad2deg(p.lying_min_rad):.0f}° or more from the sensor's +y); still "
                         f"postures found: {found}")
    i_lie = lying[0]
    i_stand = max((u for u in upright if u < i_lie), key=lambda u: runs[u, 1] - runs[u, 0])
    margin = int(round(p.posture_margin_s * fs_hz))
    windows: dict[str, tuple[int, int]] = {}

    # S3: the figure-eight, before standing
    rate = _moving_mean(np.linalg.norm(gyr_f, axis=1), win)
    rotating = rate > p.rotating_rad_s
    rotating[runs[i_stand, 0]:] = False
    gap = int(round(p.merge_gap_s * fs_hz))
    for a, b in true_runs(~rotating):  # short pauses inside a figure-eight do not end it
        if 0 < a and b < runs[i_stand, 0] and b - a < gap:
            rotating[a:b] = True
    best, octants = None, 0
    for a, b in true_runs(rotating, int(round(p.min_figure_s * fs_hz))):
        k = _octants(mag[a:b])
        if k > octants or (k == octants and best is not None and b - a > best[1] - best[0]):
            best, octants = (int(a), int(b)), k
    if best is not None and octants >= p.min_octants:
        windows["mag_calibration"] = best
    else:
        octants = 0

    for part, i in (("standing", i_stand), ("lying", i_lie)):
        a, b = runs[i]
        windows[part] = (int(a + margin), int(b - margin))

    # S4: the task, from the first still moment after supine
    end_lie = int(runs[i_lie, 1])
    search = still[end_lie:min(n_total, end_lie + int(round(p.task_search_s * fs_hz)))]
    settle = true_runs(search, max(1, int(round(p.task_settle_s * fs_hz))))
    start = end_lie + (int(settle[0, 0]) if len(settle) else 0)
    windows["task"] = (start, n_total)
    return ProtocolSplit({k: windows[k] for k in PARTS if k in windows}, float(fs_hz),
                         {"standing": theta[i_stand], "lying": theta[i_lie]}, octants)
