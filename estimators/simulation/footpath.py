r"""Foot placements of a walk around a rectangular lane, as a walker's feet really land.

:func:`estimators.simulation.motions.walking_foot` with ``path="rectangle"`` steps the foot exactly on
the rectangle's corners, so its stance-to-stance length *is* the perimeter.  A walker does not: the body
follows a path with rounded corners, each foot lands half a step width to one side of that path, and the
foot touches the ground once per stride (~1.2 m), so the polygon of one foot's placements is shorter
than the lane's centre line.  This module builds that polygon, to measure what the stance-to-stance
distance of a *perfect* estimate reads against the centre line (seed 001's 22.1 m circuit, whose walks
start at a corner with the feet together and end there).

Model
-----
* Body path: the lane's centre line, a rectangle of sides ``rectangle_m`` walked from one corner
  (clockwise by default, as the IEZ walks), three corners rounded by arcs of ``corner_radius_m``
  (tangent to both sides; 0 = sharp), back to the start corner, where the walker stops.
* One foot's placements: at arc lengths :math:`s_0 = 0`, :math:`s_1 = f L`,
  :math:`s_k = s_1 + (k-1) L` while :math:`s_k < s_{end} - L/4`, then :math:`s_{end}` (feet together
  again); :math:`L` the stride length, :math:`f` ``first_stride_fraction`` (0.5: this foot leads with a
  half stride; 1: it follows with a whole one).  The last placement turns back into the first
  (the walker stops where and as it started, so the foot's loop closes).
* Each placement is offset by ``lateral_offset_m`` along the path's left normal (positive: the left
  foot; for a clockwise walk the right foot, negative, is the inner one) and faces along the path.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = ["lane_centre_length_m", "lane_footprints"]


def _centre_path(rectangle_m: tuple[float, float], corner_radius_m: float, clockwise: bool,
                 facing_rad: float, step_m: float) -> tuple[FloatArray, FloatArray]:
    """Dense points (M, 2) of the body path and their unit tangents (M, 2), about ``step_m`` apart."""
    a, b = float(rectangle_m[0]), float(rectangle_m[1])
    r = float(corner_radius_m)
    turn = -np.pi / 2.0 if clockwise else np.pi / 2.0
    pts: list[FloatArray] = []
    tans: list[FloatArray] = []
    pos = np.zeros(2)
    for i, side in enumerate((a, b, a, b)):
        h = facing_rad + i * turn
        d = np.array([np.cos(h), np.sin(h)])
        start_cut = r if i > 0 else 0.0          # the start corner is not turned: the walk stops there
        end_cut = r if i < 3 else 0.0
        n = max(2, int(np.ceil((side - start_cut - end_cut) / step_m)) + 1)
        u = np.linspace(start_cut, side - end_cut, n)
        pts.append(pos + u[:, None] * d)
        tans.append(np.tile(d, (n, 1)))
        if i < 3 and r > 0.0:                     # arc of radius r around the corner
            centre = pos + (side - r) * d + r * np.array([np.cos(h + np.sign(turn) * np.pi / 2),
                                                          np.sin(h + np.sign(turn) * np.pi / 2)])
            m = max(3, int(np.ceil(abs(turn) * r / step_m)) + 1)
            phi = h - np.sign(turn) * np.pi / 2 + np.linspace(0.0, turn, m)
            pts.append(centre + r * np.column_stack([np.cos(phi), np.sin(phi)]))
            head = h + np.linspace(0.0, turn, m)
            tans.append(np.column_stack([np.cos(head), np.sin(head)]))
        pos = pos + side * d
    return np.concatenate(pts), np.concatenate(tans)


def lane_centre_length_m(rectangle_m: tuple[float, float] = (8.95, 2.1), corner_radius_m: float = 0.0) -> float:
    """Length of the body path of :func:`lane_footprints`, m: the perimeter less (2 − π/2) r per rounded corner."""
    a, b = rectangle_m
    return float(2.0 * (a + b) - 3.0 * (2.0 - np.pi / 2.0) * corner_radius_m)


def lane_footprints(rectangle_m: tuple[float, float] = (8.95, 2.1), stride_length_m: float = 1.2, *,
                    corner_radius_m: float = 0.5, lateral_offset_m: float = -0.05, first_stride_fraction: float = 0.5,
                    clockwise: bool = True, facing_rad: float = 0.0) -> tuple[FloatArray, FloatArray]:
    """Placements (K, 2) ENU, m, and headings (K,) rad of one foot walking the lane (module docstring).

    rectangle_m : the centre line's sides, m (default 8.95 × 2.1 m, the 22.1 m IEZ circuit).
    stride_length_m : L, m.  corner_radius_m : r of the three turned corners, m, 0 ≤ r ≤ half the short side.
    lateral_offset_m : offset of the foot to the left of the body path, m (right foot: negative).
    first_stride_fraction : f in (0, 1].  clockwise : turning direction.  facing_rad : first heading.
    The result feeds :func:`estimators.simulation.motions.walking_foot` (``placements=``).
    """
    a, b = rectangle_m
    if not (a > 0 and b > 0 and 0.0 <= corner_radius_m <= 0.5 * min(a, b)):
        raise ValueError(f"need positive sides and 0 <= corner_radius_m <= half the short side; got {rectangle_m}, "
                         f"{corner_radius_m}")
    if not (stride_length_m > 0 and 0.0 < first_stride_fraction <= 1.0):
        raise ValueError(f"need stride_length_m > 0 and 0 < first_stride_fraction <= 1; got {stride_length_m}, "
                         f"{first_stride_fraction}")
    pts, tans = _centre_path(rectangle_m, corner_radius_m, clockwise, facing_rad, 0.002)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    s_end = float(s[-1])
    s_k = [0.0]
    nxt = first_stride_fraction * stride_length_m
    while nxt < s_end - 0.25 * stride_length_m:
        s_k.append(nxt)
        nxt += stride_length_m
    s_k.append(s_end)
    s_arr = np.array(s_k)
    xy = np.column_stack([np.interp(s_arr, s, pts[:, 0]), np.interp(s_arr, s, pts[:, 1])])
    idx = np.clip(np.searchsorted(s, s_arr), 0, len(s) - 1)
    t = tans[idx]
    left = np.column_stack([-t[:, 1], t[:, 0]])
    heads = np.unwrap(np.arctan2(t[:, 1], t[:, 0]))
    xy = xy + lateral_offset_m * left
    xy[-1] = xy[0]                                # the walker turns back into the start stance
    heads[-1] = heads[0] + (-2.0 * np.pi if clockwise else 2.0 * np.pi)
    return xy, heads
