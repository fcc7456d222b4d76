r"""Built-in motions of one body: rest, a rotation sequence, the figure-eight, a walking foot.

Every motion is C²-smooth (minimum-jerk ramps and C² bumps from
:mod:`estimators.simulation.trajectory`), so the spline derivatives of the dense samples are the
motion's own, and deterministic for a given ``seed``.

* :func:`static_pose` — a body at rest.
* :func:`rotations` — rest, ±90° turns about each body axis, a multi-axis "wobble" with a
  continuously changing axis, then random-axis turns of 45–180° with rests between; peak rates
  up to ``max_rate_rad_s`` (300 °/s by default).  Optional small translation.
* :func:`figure_eight` — a hand drawing an "infinity" sign (Gerono lemniscate in a vertical
  plane) while the wrist rolls ±137°, pitches ±69° at twice the figure's frequency plus a slow
  ±34° sweep, and the heading turns through 360° three times, so that the earth field seen in
  the sensor frame covers the sphere of directions (no direction farther than ~20° from a
  sample: the magnetometer calibration recording).
* :func:`walking_foot` — a foot-mounted sensor (body frame: x toe, y left, z up) walking a
  straight line or a closed rectangle; the foot is exactly still during stance.  Swing ``i``
  moves the horizontal position with a minimum-jerk ramp, lifts the foot with a C² bump of height
  ``clearance_m``, turns the yaw with a minimum-jerk ramp and pitches the toe down then up,
  :math:`\theta(\tau) = 0.8\,\mathrm{bump}(\tau)\cos(\pi\tau)` rad.  Stance and swing events are
  put on the dense grid; the cubic splines then ring into the stance by less than 1e-6 m/s,
  1e-5 rad/s and 1e-3 m/s² (next to an event only), far below any sensor noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.simulation.trajectory import DEFAULT_FS_HZ, Trajectory, bump, intrinsic_rotation, min_jerk, time_grid

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = ["WalkingMotion", "figure_eight", "rotations", "static_pose", "walking_foot"]


def static_pose(
    duration_s: float,
    q_earth_body: ArrayLike = (1.0, 0.0, 0.0, 0.0),
    pos_m: ArrayLike = (0.0, 0.0, 0.0),
    *,
    fs_hz: float = DEFAULT_FS_HZ,
) -> Trajectory:
    """A body at rest in ``q_earth_body`` at ``pos_m`` for ``duration_s`` seconds."""
    return Trajectory.static(duration_s, q_earth_body, pos_m, fs_hz=fs_hz)


def _smooth_window(t: FloatArray, t0: float, t1: float, ramp_s: float) -> FloatArray:
    """0 before ``t0``, min-jerk up to 1 over ``ramp_s``, 1, then down to 0 at ``t1``."""
    return min_jerk((t - t0) / ramp_s) * min_jerk((t1 - t) / ramp_s)


def rotations(
    duration_s: float = 60.0,
    *,
    max_rate_rad_s: float = float(np.deg2rad(300.0)),
    rest_s: float = 1.0,
    q_start: ArrayLike = (1.0, 0.0, 0.0, 0.0),
    translation_m: float = 0.0,
    seed: int | np.random.Generator | None = 0,
    fs_hz: float = DEFAULT_FS_HZ,
) -> Trajectory:
    """A varied 3-D rotation sequence for orientation-filter tests (see module docstring).

    duration_s : total length (>= 10 s); moves are added while they fit, the rest is a final rest.
    max_rate_rad_s : upper bound of the peak angular rate of the single-axis turns, rad/s.
    rest_s : mean rest between moves, s (the first rest is 2 s).
    q_start : initial ``q_earth_body``.
    translation_m : amplitude of an optional smooth 3-D translation (0: pure rotation about the origin).
    """
    if not (np.isfinite(duration_s) and duration_s >= 10.0):
        raise ValueError(f"duration_s must be at least 10 s, got {duration_s!r}")
    if not (np.isfinite(max_rate_rad_s) and max_rate_rad_s > 0.0):
        raise ValueError(f"max_rate_rad_s must be positive, got {max_rate_rad_s!r}")
    rng = np.random.default_rng(seed)
    # moves: start, duration, rotation vector (single-axis turn) or amplitudes (wobble)
    starts, durs, rotvecs, wobble = [], [], [], []
    t = 2.0
    fixed = [(0, 0.5), (0, -0.5), (1, 0.5), (1, -0.5), (2, 1.0), (2, -0.5)]  # (axis, turns of π)

    def add(rv: FloatArray, dur: float, wob: bool) -> bool:
        nonlocal t
        if t + dur + 1.0 > duration_s:
            return False
        dur = round(dur * fs_hz) / fs_hz  # events on the dense grid
        t = round(t * fs_hz) / fs_hz
        starts.append(t)
        durs.append(dur)
        rotvecs.append(rv)
        wobble.append(wob)
        t += dur + rest_s * rng.uniform(0.5, 1.5)
        return True

    for axis, turns in fixed:
        rv = np.zeros(3)
        rv[axis] = turns * np.pi
        if not add(rv, max(1.875 * abs(rv[axis]) / max_rate_rad_s * rng.uniform(1.0, 1.6), 0.3), False):
            break
    else:
        # wobble: rotation vector r(τ) = A·window(τ)·[sin 4πτ, sin(6πτ+1), sin(3πτ)], rate ≲ max_rate
        wob_dur = 4.0
        amp = min(0.8, max_rate_rad_s * wob_dur / (6.0 * np.pi) * 0.8)
        if add(np.full(3, amp), wob_dur, True):
            while True:
                axis = rng.normal(size=3)
                angle = rng.uniform(np.pi / 4, np.pi) * rng.choice([-1.0, 1.0])
                dur = max(1.875 * abs(angle) / max_rate_rad_s * rng.uniform(1.0, 2.0), 0.3)
                if not add(axis / np.linalg.norm(axis) * angle, dur, False):
                    break
    starts_a = np.array(starts)
    durs_a = np.array(durs)
    rv_a = np.array(rotvecs).reshape(-1, 3)
    wob_a = np.array(wobble, dtype=bool)
    q0 = quat.normalize(np.asarray(q_start, dtype=np.float64))
    q_begin = [q0]
    for rv, wob in zip(rv_a, wob_a):  # a few dozen moves: the chain of start orientations
        q_begin.append(q_begin[-1] if wob else quat.multiply(q_begin[-1], quat.exp(rv)))
    q_begin_a = np.array(q_begin)

    tt = time_grid(duration_s, fs_hz)
    if len(starts_a) == 0:
        q = np.broadcast_to(q0, (len(tt), 4))
    else:
        m = np.searchsorted(starts_a, tt, side="right") - 1
        before = m < 0
        mi = np.maximum(m, 0)
        tau = np.clip((tt - starts_a[mi]) / durs_a[mi], 0.0, 1.0)
        rv_single = rv_a[mi] * min_jerk(tau)[:, None]
        w = min_jerk(tau / 0.2) * min_jerk((1.0 - tau) / 0.2)
        rv_wob = rv_a[mi] * w[:, None] * np.stack(
            [np.sin(4 * np.pi * tau), np.sin(6 * np.pi * tau + 1.0), np.sin(3 * np.pi * tau)],
            axis=1)
        rv = np.where(wob_a[mi][:, None], rv_wob, rv_single)
        q = quat.multiply(q_begin_a[mi], quat.exp(rv))
        q[before] = q0
    if translation_m:
        win = _smooth_window(tt, 1.0, duration_s - 1.0, 1.0)[:, None]
        wave = np.stack([np.sin(2 * np.pi * 0.23 * tt), np.sin(2 * np.pi * 0.31 * tt + 0.5),
                         0.5 * np.sin(2 * np.pi * 0.41 * tt)], axis=1)
        p = translation_m * win * wave
    else:
        p = np.zeros((len(tt), 3))
    return Trajectory(tt, q, p)


def figure_eight(
    duration_s: float = 60.0,
    *,
    size_m: float = 0.3,
    period_s: float = 4.0,
    facing_rad: float = 0.0,
    center_m: ArrayLike = (0.0, 0.0, 1.2),
    seed: int | np.random.Generator | None = 0,
    fs_hz: float = DEFAULT_FS_HZ,
) -> Trajectory:
    """A hand figure-eight ("infinity") for magnetometer calibration (see module docstring).

    duration_s : length (>= 8 s): 1 s rest, 2 s ramp in, the figure, 2 s ramp out, 1 s rest.
    size_m : half width of the lemniscate, m.   period_s : time of one figure-eight, s.
    facing_rad : ENU yaw of the person's anterior direction (from east towards north).
    center_m : ENU centre of the figure, m.
    seed : varies the person (turning direction, roll/pitch amplitudes ±7 %, phase of the wrist).
    """
    if not (np.isfinite(duration_s) and duration_s >= 8.0):
        raise ValueError(f"duration_s must be at least 8 s, got {duration_s!r}")
    if not (np.isfinite(period_s) and period_s > 0.5):
        raise ValueError(f"period_s must be longer than 0.5 s, got {period_s!r}")
    rng = np.random.default_rng(seed)
    turn = rng.choice([-1.0, 1.0])
    k_roll, k_pitch = rng.uniform(0.93, 1.07, 2)
    wrist = rng.uniform(-0.3, 0.3)
    t = time_grid(duration_s, fs_hz)
    w = _smooth_window(t, 1.0, duration_s - 1.0, 2.0)
    om = 2.0 * np.pi / period_s
    ph = om * (t - 1.0)
    progress = (t - 1.0) / (duration_s - 2.0)
    yaw = facing_rad + turn * 6.0 * np.pi * min_jerk(progress) + 0.6 * w * np.sin(ph)
    pitch = w * (1.2 * k_pitch * np.sin(2.0 * ph + wrist) + 0.6 * np.sin(3.0 * np.pi * progress))
    roll = 2.4 * k_roll * w * np.sin(ph)
    q = intrinsic_rotation(np.stack([yaw, pitch, roll], axis=1), "ZYX")
    lateral = np.array([-np.sin(facing_rad), np.cos(facing_rad), 0.0])  # left of the person
    up = np.array([0.0, 0.0, 1.0])
    shape = np.sin(ph)[:, None] * lateral + 0.5 * np.sin(2.0 * ph)[:, None] * up
    pos = np.asarray(center_m, dtype=np.float64) + size_m * w[:, None] * shape
    return Trajectory(t, q, pos)


@dataclass(frozen=True, eq=False)
class WalkingMotion:
    """A foot-mounted walk and its truth.

    trajectory : the foot's :class:`Trajectory` (body frame x toe, y left, z up; origin on the ground).
    stance_intervals_s : (K, 2) half-open ``[start, end)`` true times when the foot is still.
    placements_m : (K, 3) ENU foot positions of the K stances.   headings_rad : (K,) their yaw.
    distance_m : total horizontal path length.   closed_loop : the walk ends where it started.
    """

    trajectory: Trajectory
    stance_intervals_s: FloatArray
    placements_m: FloatArray
    headings_rad: FloatArray
    distance_m: float
    closed_loop: bool

    def stance_mask(self, t_s: ArrayLike) -> BoolArray:
        """True at the times (any shape) that fall inside a stance interval."""
        t = np.asarray(t_s, dtype=np.float64)
        k = np.searchsorted(self.stance_intervals_s[:, 0], t, side="right") - 1
        kk = np.maximum(k, 0)
        return (k >= 0) & (t < self.stance_intervals_s[kk, 1])


def _placements(n_strides: int, stride_length_m: float, path: str, rectangle_m: tuple[float, float],
                laps: int, facing_rad: float) -> tuple[FloatArray, FloatArray]:
    if path == "straight":
        d = np.array([np.cos(facing_rad), np.sin(facing_rad)])
        xy = np.arange(n_strides + 1)[:, None] * stride_length_m * d
        return xy, np.full(n_strides + 1, facing_rad)
    if path == "rectangle":
        pts = [np.zeros(2)]
        heads = [facing_rad]
        for _ in range(laps):
            for side, turn in zip((rectangle_m[0], rectangle_m[1], rectangle_m[0], rectangle_m[1]), range(4)):
                h = facing_rad + turn * np.pi / 2.0
                n = max(1, int(round(side / stride_length_m)))
                d = np.array([np.cos(h), np.sin(h)]) * side / n
                for _k in range(n):
                    pts.append(pts[-1] + d)
                    heads.append(h)
        xy = np.array(pts)
        xy[-1] = 0.0  # close the loop exactly
        return xy, np.array(heads)
    raise ValueError(f"path must be 'straight' or 'rectangle', got {path!r}")


def walking_foot(
    n_strides: int = 10,
    stride_length_m: float = 1.4,
    *,
    path: str = "straight",
    rectangle_m: tuple[float, float] = (6.55, 4.5),
    laps: int = 1,
    stance_s: float = 0.65,
    swing_s: float = 0.45,
    clearance_m: float = 0.12,
    rest_s: float = 2.0,
    facing_rad: float = 0.0,
    variability: float = 0.05,
    seed: int | np.random.Generator | None = 0,
    fs_hz: float = DEFAULT_FS_HZ,
    placements: tuple[ArrayLike, ArrayLike] | None = None,
) -> WalkingMotion:
    """A foot-mounted sensor walking, with true stance phases (see module docstring).

    n_strides : strides of the straight path (ignored for ``path="rectangle"``).
    stride_length_m : stride length (straight) or the nominal one (rectangle: each side is split
        into ``round(side/stride_length_m)`` equal strides).
    path : ``"straight"`` or ``"rectangle"`` (counter-clockwise, closed: back to the start, ``laps`` times).
    rectangle_m : the rectangle's sides, m (default 22.1 m perimeter, as the IEZ recordings).
    stance_s, swing_s : mean durations of one stance and one swing, s.
    clearance_m : peak foot lift during swing, m.
    rest_s : standing still before the first and after the last stride, s (added to those stances).
    facing_rad : ENU yaw of the first walking direction.
    variability : relative random spread of the stance and swing durations (uniform ±).
    placements : optional ``(xy (K, 2) m, headings (K,) rad)`` of the K ≥ 2 stances, used instead of
        ``path`` (e.g. :func:`estimators.simulation.footpath.lane_footprints`: a lane walked as feet land).
    """
    if path == "straight" and (int(n_strides) != n_strides or n_strides < 1):
        raise ValueError(f"n_strides must be a positive integer, got {n_strides!r}")
    for name, v in (("stride_length_m", stride_length_m), ("stance_s", stance_s), ("swing_s", swing_s)):
        if not (np.isfinite(v) and v > 0.0):
            raise ValueError(f"{name} must be positive, got {v!r}")
    if not (0.0 <= variability < 0.5):
        raise ValueError(f"variability must be in [0, 0.5), got {variability!r}")
    rng = np.random.default_rng(seed)
    if placements is None:
        xy, heads = _placements(int(n_strides), stride_length_m, path, rectangle_m, int(laps), facing_rad)
    else:
        xy = np.asarray(placements[0], dtype=np.float64)
        heads = np.asarray(placements[1], dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 2 or heads.shape != (len(xy),):
            raise ValueError(f"placements must be (xy (K, 2), headings (K,)) with K >= 2; got {xy.shape}, {heads.shape}")
    k = len(xy)
    stance_d = stance_s * rng.uniform(1 - variability, 1 + variability, k)
    swing_d = swing_s * rng.uniform(1 - variability, 1 + variability, k - 1)
    stance_d[0] += rest_s
    stance_d[-1] += rest_s
    bounds = np.zeros(2 * k)
    bounds[1:] = np.cumsum(np.ravel(np.column_stack([stance_d, np.append(swing_d, 0.0)]))[:-1])
    bounds = np.round(bounds * fs_hz) / fs_hz  # events on the dense grid: no spline ringing into stance
    st_start = bounds[0::2]
    st_end = bounds[1::2]
    duration = float(np.round((st_start[-1] + stance_d[-1]) * fs_hz) / fs_hz)
    t = time_grid(duration, fs_hz)
    i = np.clip(np.searchsorted(st_end, t, side="right") - 1, 0, k - 2)
    tau = np.clip((t - st_end[i]) / (st_start[i + 1] - st_end[i]), 0.0, 1.0)
    s = min_jerk(tau)
    pos_xy = xy[i] + (xy[i + 1] - xy[i]) * s[:, None]
    dyaw = np.angle(np.exp(1j * (heads[i + 1] - heads[i])))
    yaw = heads[i] + dyaw * s
    pitch = 0.8 * bump(tau) * np.cos(np.pi * tau)
    pos = np.column_stack([pos_xy, clearance_m * bump(tau)])
    q = intrinsic_rotation(np.column_stack([yaw, pitch]), "ZY")
    stance = np.column_stack([st_start, st_end])
    stance[-1, 1] = np.nextafter(duration, np.inf)  # the last stance includes the final sample
    distance = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
    closed = bool(np.linalg.norm(xy[-1] - xy[0]) < 1e-9 and k > 1)
    return WalkingMotion(Trajectory(t, q, pos), stance, np.column_stack([xy, np.zeros(k)]), np.array(heads),
                         distance, closed)
