r"""Walk metrics (seed 001 §4.5, eqs. 4.3–4.5) and strides.

.. math::
    EP = \frac{\lVert p_{xy}(t_{end}) - p_{xy}(0)\rVert}{D_T} \quad\text{(4.3)},\qquad
    ED = \frac{D_E - D_T}{D_T} \quad\text{(4.4)},\qquad
    EA = |p_z(t_{end})| \quad\text{(4.5)}

:math:`D_T` the true distance walked (22.1 m for the IEZ circuit: §4.5 "DT é a distância total percorrida",
the dashed centre line of Fig. 18 — so EP is over 22.1 m, not over the estimated path length),
:math:`D_E` the estimated one ("distância total estimada"; the thesis' published code,
github.com/pajaraca/IEZ ``IEZ-9states.py``, sums the horizontal step between consecutive samples), computed
two ways:

* sample-wise (the thesis): :math:`\sum_k \lVert p_{xy,k+1} - p_{xy,k}\rVert` — it also counts the
  small back-and-forth jumps of the ZUPT corrections, so it over-estimates;
* stance-to-stance: :math:`\sum_i \lVert \bar p_{xy,i+1} - \bar p_{xy,i}\rVert` with :math:`\bar p_i` the
  mean position over stance *i* — the walked path as the foot placements draw it.

A stride is the motion between two consecutive stances i, i+1: length :math:`\lVert \bar p_{xy,i+1} -
\bar p_{xy,i}\rVert`, duration :math:`t^{start}_{i+1} - t^{start}_i` (stance onsets; the first stance
holds the initial rest, so its onset is taken one median stance duration before its end), cadence 60/duration (strides per
minute; steps per minute are twice that for symmetric gait), speed length/duration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.pdr.detectors import stance_intervals

FloatArray = NDArray[np.float64]

__all__ = ["Stride", "WalkMetrics", "stance_positions", "strides", "walk_metrics"]


@dataclass(frozen=True)
class WalkMetrics:
    """EP (fraction), ED sample-wise and stance-to-stance (fractions, signed), EA (m), distances (m)."""

    ep: float
    ed: float
    ed_stance: float
    ea_m: float
    distance_m: float
    distance_stance_m: float
    true_distance_m: float


@dataclass(frozen=True)
class Stride:
    """One stride: start_s, end_s (stance onsets), length_m, duration_s, cadence_strides_min, speed_m_s."""

    start_s: float
    end_s: float
    length_m: float
    duration_s: float
    cadence_strides_min: float
    speed_m_s: float


def stance_positions(pos_m: ArrayLike, stance: ArrayLike, min_samples: int = 5) -> tuple[FloatArray, NDArray[np.int64]]:
    """Mean position (K, 3) of each stance run of at least ``min_samples`` and the runs (K, 2)."""
    pos = np.asarray(pos_m, dtype=np.float64)
    runs = stance_intervals(stance, min_samples)
    if len(runs) == 0:
        return np.zeros((0, 3)), runs
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(pos, axis=0)])
    means = (c[runs[:, 1]] - c[runs[:, 0]]) / (runs[:, 1] - runs[:, 0])[:, None]
    return means, runs


def walk_metrics(pos_m: ArrayLike, stance: ArrayLike, true_distance_m: float | None = None,
                 min_stance_samples: int = 5) -> WalkMetrics:
    """EP, ED, ED stance-to-stance and EA (eqs. 4.3–4.5) of a closed-loop walk; ``true_distance_m`` None
    uses the stance-to-stance estimate as the reference (then ED_stance = 0)."""
    pos = np.asarray(pos_m, dtype=np.float64)
    d_sample = float(np.sum(np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1)))
    sp, _ = stance_positions(pos, stance, min_stance_samples)
    d_stance = float(np.sum(np.linalg.norm(np.diff(sp[:, :2], axis=0), axis=1))) if len(sp) > 1 else 0.0
    d_true = d_stance if true_distance_m is None else float(true_distance_m)
    if not d_true > 0.0:
        raise ValueError("the walk has no distance (no strides detected); check the stance detector")
    ep = float(np.linalg.norm(pos[-1, :2] - pos[0, :2]) / d_true)
    return WalkMetrics(ep, (d_sample - d_true) / d_true, (d_stance - d_true) / d_true, float(abs(pos[-1, 2])),
                       d_sample, d_stance, d_true)


def strides(t_s: ArrayLike, pos_m: ArrayLike, stance: ArrayLike, min_stance_samples: int = 5) -> list[Stride]:
    """The strides between consecutive stances (see the module docstring)."""
    t = np.asarray(t_s, dtype=np.float64)
    sp, runs = stance_positions(pos_m, stance, min_stance_samples)
    out = []
    onset = t[runs[:, 0]] if len(runs) else t[:0]
    if len(runs) > 2:  # the first stance holds the initial rest: start its stride one typical stance before toe-off
        typical = float(np.median(t[runs[1:-1, 1] - 1] - t[runs[1:-1, 0]]))
        onset = onset.copy()
        onset[0] = max(float(t[runs[0, 1] - 1]) - typical, float(t[0]))
    for i in range(len(runs) - 1):
        t0, t1 = float(onset[i]), float(onset[i + 1])
        length = float(np.linalg.norm(sp[i + 1, :2] - sp[i, :2]))
        dur = t1 - t0
        out.append(Stride(t0, t1, length, dur, 60.0 / dur, length / dur))
    return out
