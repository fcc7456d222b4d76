r"""Two-segment leg motions (thigh, shank) with true knee angles: step-up task and calibration postures.

Segment frames (ISB, shared/DESIGN.md §3): x anterior, y proximal along the long axis, z to the
right, for both legs.  The thigh origin is the hip joint centre, the shank origin the knee joint
centre.  A standing segment has ``q_earth_segment`` with columns
:math:`[\hat f, \hat z_{up}, \hat f \times \hat z_{up}]`, where :math:`\hat f = (\cos\psi, \sin\psi, 0)`
is the anterior (facing) direction at ENU yaw :math:`\psi` (``facing_rad``).

Knee angles (Grood & Suntay joint coordinate system)
----------------------------------------------------
The JCS axes are the femoral z (flexion), the tibial y (internal/external rotation) and the
floating axis perpendicular to both (ad/abduction).  That is the intrinsic Cardan sequence Z-X'-Y''
from thigh to shank:

.. math::
    q_{thigh,shank} = \exp(-\phi\,\hat z) \otimes \exp(s\,\alpha\,\hat x) \otimes \exp(s\,\rho\,\hat y)
    \qquad\text{(K1)}

with flexion :math:`\phi` (+ flexed), adduction :math:`\alpha` (+ varus), internal rotation
:math:`\rho` (+ internal), and :math:`s = +1` for the right leg, :math:`-1` for the left (mirror:
z points laterally on the right leg and medially on the left, so the clinical signs are kept).
Flexion is a *negative* rotation about z because flexing the knee swings the tibia's distal end
posteriorly.  :func:`knee_quaternion` is (K1) and :func:`knee_angles` its inverse: both are defined once,
in :mod:`estimators.knee`, and re-exported here so the truth uses the pipeline's own convention.

Single-leg step-up (seed 004 §2.2, §8.1, DESIGN.md §3)
------------------------------------------------------
The tested foot stands on the step (ankle fixed at ``step_height_m + 0.08`` m), the body rises by
extending the knee and lowers back.  Flexion is a chain of minimum-jerk ramps between key frames.

``shape="thesis"`` (default), re-derived from seed 004 §8.1: Fig. 8.2's sequence (0 % flexed on the
step; ~30 % the other foot leaves the floor at the impulse's extra flexion; ~50 % full extension carrying
the weight; 75 % the other foot lands, knee flexing; 100 % back near the start flexion) with the measured
proportions of Tables 8.1/8.3 (cycle 3.38 s at 17 cm, 3.54 s at 34 cm; impulse 34.0/33.3 %, extension
31.7/32.8 %, fall 34.0/33.9 %, SD 1–3 %).  Per cycle of duration :math:`T_k` (mean ``cycle_s``, ±2 %):
*impulse* :math:`0.34\,T_k` (±1.5 %) from the start posture :math:`\phi_0` up 5.5–9.5° to the peak;
*extension* :math:`0.32\,T_k` (±3 %): 60 % (±10 %) of it a ramp to 0–3°, the rest held; *fall* the
remainder, back to the next start posture.  Cycles follow each other without rest (the fall ends at the
instant the next impulse starts, both with zero rate) unless ``pauses_s`` puts a rest between them.
:math:`\phi_0`: the thesis' peak flexion (ROM max, Tables 8.2/8.4: 83° at 17 cm, 111° at 34 cm, linear in
the height) minus 7.5°, ±3° per cycle.  Adduction :math:`2° + 4°\,\phi/\phi_0` and internal rotation
:math:`-2° + 7°\,\phi/\phi_0` (screw-home; rotation ROM 6.5–7.5° as in Tables 8.2/8.4).

``shape="rest_between"`` (the project's first shape): rest :math:`\phi_0 = 30° + 176.5°/\mathrm{m}\cdot h`
(60° / 90°) → impulse 0.45 s → extension 1.0 s → hold 0.8 s → fall 1.2 s (±``variability``) → ``rest_s``
(1.5 s) in the start posture; adduction :math:`2° + 3°\,\phi/\phi_0`, rotation :math:`-2° + 10°\,\phi/\phi_0`.

Both: the thigh is hip-flexed by :math:`0.6\,\phi` (plus a small ad/abduction and rotation), the shank is
the thigh times (K1), so it tilts forward by about :math:`0.4\,\phi`; the knee is at
:math:`A + R_{shank}[0, L_s, 0]` and the hip at :math:`K + R_{thigh}[0, L_t, 0]`
(:math:`L_s = 0.40`, :math:`L_t = 0.42` m).

True boundaries, per cycle k (columns of ``phases_s``): impulse onset (= cycle start), peak flexion
(impulse → extension), leaving full extension (extension → fall), back at rest in the start posture
(end of the fall = cycle end).  ``cycles_s[k] = [onset_k, back at rest_k]`` (DESIGN.md §3): continuous
cycles meet; a pause (``pauses_s``, ``rest_s``) lies between two cycles, in neither.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.knee import knee_angles, knee_quaternion, side_sign
from estimators.simulation.trajectory import (
    DEFAULT_FS_HZ,
    Trajectory,
    intrinsic_rotation,
    min_jerk,
    time_grid,
)

FloatArray = NDArray[np.float64]

__all__ = [
    "SHANK_LENGTH_M",
    "STEP_UP_SHAPES",
    "THIGH_LENGTH_M",
    "LegMotion",
    "knee_angles",
    "knee_quaternion",
    "segment_frame",
    "standing",
    "step_up",
    "supine",
]

THIGH_LENGTH_M = 0.42
SHANK_LENGTH_M = 0.40
ANKLE_HEIGHT_M = 0.08


def segment_frame(facing_rad: float = 0.0, posture: str = "standing") -> FloatArray:
    """``q_earth_segment`` (4,) of a segment standing upright (y up, x facing) or lying supine (x up, y = facing).

    For ``"supine"``, ``facing_rad`` is the ENU yaw of the direction from the feet to the head.
    """
    h = np.array([np.cos(facing_rad), np.sin(facing_rad), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    if posture == "standing":
        x, y = h, up
    elif posture == "supine":
        x, y = up, h
    else:
        raise ValueError(f"posture must be 'standing' or 'supine', got {posture!r}")
    return quat.from_matrix(np.column_stack([x, y, np.cross(x, y)]))


@dataclass(frozen=True, eq=False)
class LegMotion:
    """Thigh and shank trajectories of one leg with the true knee kinematics.

    t_s : (M,) dense true times, s (the grid of both trajectories).
    thigh, shank : :class:`Trajectory` in ISB segment frames (origins: hip and knee joint centres).
    knee_angles_rad : (M, 3) Grood & Suntay flexion, adduction, internal rotation, rad (clinical signs).
    side : ``"right"`` or ``"left"``.
    thigh_lever_arm_m, shank_lever_arm_m : (3,) typical sensor positions in segment coordinates (lateral,
        mid-thigh / below the knee), to pass as ``simulate(..., lever_arm_m=...)``.
    cycles_s : (K, 2) true cycle [start, end) times (empty for postures).
    phases_s : (K, 4) per cycle: impulse onset, peak flexion, leaving full extension, back at rest.
    """

    t_s: FloatArray
    thigh: Trajectory
    shank: Trajectory
    knee_angles_rad: FloatArray
    side: str
    thigh_lever_arm_m: FloatArray
    shank_lever_arm_m: FloatArray
    cycles_s: FloatArray
    phases_s: FloatArray

    def knee_angles_at(self, t_s: ArrayLike) -> FloatArray:
        """True knee angles (n, 3), rad, at arbitrary times (from the segments' orientations, K1 inverted)."""
        q = quat.multiply(quat.conjugate(self.thigh.orientation(t_s)), self.shank.orientation(t_s))
        return knee_angles(q, self.side)


def _lever_arms(side: str) -> tuple[FloatArray, FloatArray]:
    s = side_sign(side)
    return np.array([0.0, -0.21, 0.08 * s]), np.array([0.03, -0.12, 0.05 * s])


def _keyframes(t: FloatArray, times: FloatArray, values: FloatArray) -> FloatArray:
    """Minimum-jerk ramps between key frames (C²); constant before the first and after the last."""
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    tau = (t - times[i]) / (times[i + 1] - times[i])
    return values[i] + (values[i + 1] - values[i]) * min_jerk(tau)


def _leg(t: FloatArray, flex: FloatArray, flex_ref: float, side: str, facing_rad: float,
         ankle_m: FloatArray, coupling: tuple[FloatArray, FloatArray] | None = None
         ) -> tuple[Trajectory, Trajectory, FloatArray]:
    """Thigh and shank of one leg from its flexion; ``coupling`` = ((a0, a1), (r0, r1)) rad makes adduction
    a0 + a1 φ/φ_ref and internal rotation r0 + r1 φ/φ_ref (default 2° + 3°·r and −2° + 10°·r)."""
    s = side_sign(side)
    r = flex / flex_ref
    (a0, a1), (r0, r1) = coupling if coupling is not None else (np.deg2rad([2.0, 3.0]), np.deg2rad([-2.0, 10.0]))
    angles = np.column_stack([flex, a0 + a1 * r, r0 + r1 * r])
    q_face = segment_frame(facing_rad, "standing")
    hip = np.column_stack([0.6 * flex, s * np.deg2rad(1.5) * r, s * np.deg2rad(3.0) * r])
    q_thigh = quat.multiply(q_face, intrinsic_rotation(hip, "ZXY"))
    q_shank = quat.multiply(q_thigh, knee_quaternion(angles, side))
    knee = ankle_m + quat.rotate(q_shank, np.array([0.0, SHANK_LENGTH_M, 0.0]))
    hip_pos = knee + quat.rotate(q_thigh, np.array([0.0, THIGH_LENGTH_M, 0.0]))
    return Trajectory(t, q_thigh, hip_pos), Trajectory(t, q_shank, knee), angles


#: The selectable step-up motion shapes (:func:`step_up` ``shape``).
STEP_UP_SHAPES: tuple[str, ...] = ("thesis", "rest_between")


def _thesis_defaults(step_height_m: float) -> tuple[float, float]:
    """Mean cycle duration (s) and start-posture flexion (rad) at a step height, from seed 004 Tables 8.1–8.4:
    cycles of 3.38 s at 17 cm and 3.54 s at 34 cm; peak flexion (ROM max) 83° and 111°, the start posture
    7.5° below it (the impulse rises 5–10°); linear in the height between and beyond."""
    cycle_s = 3.38 + (3.54 - 3.38) * (step_height_m - 0.17) / 0.17
    peak_deg = 83.0 + (111.0 - 83.0) * (step_height_m - 0.17) / 0.17
    return float(np.clip(cycle_s, 2.0, 6.0)), float(np.deg2rad(np.clip(peak_deg - 7.5, 20.0, 115.0)))


def step_up(
    n_cycles: int = 10,
    step_height_m: float = 0.17,
    side: str = "right",
    *,
    shape: str = "thesis",
    cycle_s: float | None = None,
    pauses_s: float | ArrayLike | None = None,
    facing_rad: float = 0.0,
    rest_s: float = 1.5,
    initial_rest_s: float = 2.0,
    final_rest_s: float = 2.0,
    variability: float = 0.1,
    seed: int | np.random.Generator | None = 0,
    fs_hz: float = DEFAULT_FS_HZ,
) -> LegMotion:
    """Single-leg step-up cycles with true knee angles, cycles and phases (see module docstring).

    n_cycles : number of cycles (>= 1).   step_height_m : step height, m (0.05–0.5).
    side : ``"right"`` or ``"left"``.   facing_rad : ENU yaw of the patient's anterior direction.
    shape : ``"thesis"`` (default: seed 004 §8.1, continuous cycles with the measured proportions, impulse
        34 %, extension 32 %, fall 34 %) or ``"rest_between"`` (the project's first shape: impulse 0.45 s,
        extension 1.0 s, hold 0.8 s, fall 1.2 s, then ``rest_s`` in the start posture).
    cycle_s : ``"thesis"`` only: mean cycle duration, s (2–6; default 3.38 s at 17 cm, 3.54 s at 34 cm).
    pauses_s : rest in the start posture between cycles k and k+1, s: a number (every gap) or n_cycles − 1
        values (>= 0).  Default: none for ``"thesis"``, ``rest_s`` ± ``variability`` for ``"rest_between"``.
        A pause ends the cycle before it (DESIGN.md §3): it never lies inside ``cycles_s``.
    rest_s : ``"rest_between"`` only: mean rest between cycles when ``pauses_s`` is None, s.
    initial_rest_s, final_rest_s : rest in the start posture before the first / after the last cycle, s (>= 0).
    variability : relative random spread of durations and amplitudes (0 gives identical cycles).
    """
    if int(n_cycles) != n_cycles or n_cycles < 1:
        raise ValueError(f"n_cycles must be a positive integer, got {n_cycles!r}")
    if not (0.05 <= step_height_m <= 0.5):
        raise ValueError(f"step_height_m must be between 0.05 and 0.5 m, got {step_height_m!r}")
    if not (0.0 <= variability < 0.5):
        raise ValueError(f"variability must be in [0, 0.5), got {variability!r}")
    if shape not in STEP_UP_SHAPES:
        raise ValueError(f"shape must be one of {STEP_UP_SHAPES}, got {shape!r}")
    for name, v in (("rest_s", rest_s), ("initial_rest_s", initial_rest_s), ("final_rest_s", final_rest_s)):
        if not (np.isfinite(v) and v >= 0.0):
            raise ValueError(f"{name} must be a finite number of seconds >= 0, got {v!r}")
    side_sign(side)
    rng = np.random.default_rng(seed)
    n = int(n_cycles)
    thesis = shape == "thesis"
    mean_cycle_s, f0_thesis = _thesis_defaults(step_height_m)
    if cycle_s is not None:
        if not (np.isfinite(cycle_s) and 2.0 <= cycle_s <= 6.0):
            raise ValueError(f"cycle_s must be between 2 and 6 s, got {cycle_s!r}")
        mean_cycle_s = float(cycle_s)
    f0_ref = f0_thesis if thesis else np.deg2rad(np.clip(30.0 + 176.5 * step_height_m, 20.0, 110.0))
    vk = variability / 0.1  # 1 at the default spread

    def spread(mean: float, size: int) -> FloatArray:
        return mean * rng.uniform(1.0 - variability, 1.0 + variability, size)

    f0 = f0_ref + np.deg2rad(3.0) * vk * rng.uniform(-1.0, 1.0, n + 1)
    rise = np.deg2rad(rng.uniform(5.5, 9.5, n) if variability > 0 else np.full(n, 7.5))
    ext = np.deg2rad(rng.uniform(0.0, 3.0, n) if variability > 0 else np.full(n, 1.5))
    if thesis:
        # seed 004 Tables 8.1/8.3: cycle SD 0.01–0.07 s; impulse 34.0/33.3 % (SD 0.9–1.1), extension
        # 31.7/32.8 % (SD 2.3–3.0), fall the rest; Fig. 8.2: full extension reached at ~50 % of the cycle
        dur = mean_cycle_s * (1.0 + 0.02 * vk * rng.uniform(-1.0, 1.0, n))
        p_imp = 0.34 + 0.015 * vk * rng.uniform(-1.0, 1.0, n)
        p_ext = 0.32 + 0.03 * vk * rng.uniform(-1.0, 1.0, n)
        d_imp, d_ext_phase = p_imp * dur, p_ext * dur
        d_move = d_ext_phase * (0.6 + 0.1 * vk * rng.uniform(-1.0, 1.0, n))  # ramp to ~0°, then held
        d_ext, d_hold = d_move, d_ext_phase - d_move
        d_fall = dur - d_imp - d_ext_phase
    else:
        d_imp, d_ext, d_hold, d_fall = spread(0.45, n), spread(1.0, n), spread(0.8, n), spread(1.2, n)
    if pauses_s is None:
        pause = np.zeros(max(n - 1, 0)) if thesis else spread(rest_s, max(n - 1, 0))
    else:
        pause = np.broadcast_to(np.asarray(pauses_s, dtype=np.float64), (max(n - 1, 0),)).copy()
        if not np.all(np.isfinite(pause) & (pause >= 0.0)):
            raise ValueError(f"pauses_s must be seconds >= 0 (one number or n_cycles - 1 values), got {pauses_s!r}")
    times, values = [0.0], [f0[0]]
    phases = np.zeros((n, 4))
    t = initial_rest_s
    for k in range(n):  # key frames: a handful per cycle
        phases[k, 0] = t
        times += [t, t + d_imp[k]]
        values += [f0[k], f0[k] + rise[k]]
        t += d_imp[k]
        phases[k, 1] = t
        times += [t + d_ext[k], t + d_ext[k] + d_hold[k]]
        values += [ext[k], ext[k]]
        t += d_ext[k] + d_hold[k]
        phases[k, 2] = t
        t += d_fall[k]
        times.append(t)
        values.append(f0[k + 1])
        phases[k, 3] = t
        if k < n - 1:
            t += pause[k]
    duration = t + final_rest_s
    times.append(duration)
    values.append(f0[n])
    # events on the dense grid (keeps the spline from ringing into the rests); coincident key frames
    # (no pause, no initial/final rest) are merged
    times_a = np.round(np.array(times) * fs_hz) / fs_hz
    values_a = np.array(values)
    keep = np.concatenate([[True], np.diff(times_a) > 0.0])
    times_a, values_a = times_a[keep], values_a[keep]
    if len(times_a) == 1:
        times_a, values_a = np.array([0.0, 1.0 / fs_hz]), np.repeat(values_a, 2)
    phases = np.round(phases * fs_hz) / fs_hz
    duration = float(times_a[-1])
    tt = time_grid(duration, fs_hz)
    flex = _keyframes(tt, times_a, values_a)
    ankle = np.array([0.0, 0.0, step_height_m + ANKLE_HEIGHT_M])
    # Tables 8.2/8.4: internal rotation ROM 6.5–7.5°, ab/adduction ROM 4.3° at 17 cm
    coupling = (np.deg2rad([2.0, 4.0]), np.deg2rad([-2.0, 7.0])) if thesis else None
    thigh, shank, angles = _leg(tt, flex, f0_ref, side, facing_rad, ankle, coupling)
    cycles = phases[:, [0, 3]].copy()  # onset → back at rest: a pause after it is in no cycle (DESIGN.md §3)
    la_t, la_s = _lever_arms(side)
    return LegMotion(tt, thigh, shank, angles, side, la_t, la_s, cycles, phases)


def _posture(duration_s: float, side: str, facing_rad: float, posture: str, fs_hz: float,
             roll_out_rad: float = 0.0) -> LegMotion:
    s = side_sign(side)
    t = time_grid(duration_s, fs_hz)
    # roll about the long axis y: toes out (external rotation) turns x towards the lateral side, which is +z on
    # the right leg (a negative turn about y) and -z on the left
    q = quat.multiply(segment_frame(facing_rad, posture), quat.from_axis_angle([0.0, 1.0, 0.0], -s * roll_out_rad))
    if posture == "standing":
        knee = np.array([0.0, 0.0, ANKLE_HEIGHT_M + SHANK_LENGTH_M])
    else:
        knee = np.array([0.0, 0.0, 0.55])  # on an examination table
    hip = knee + quat.rotate(q, np.array([0.0, THIGH_LENGTH_M, 0.0]))
    thigh = Trajectory.static(duration_s, q, hip, fs_hz=fs_hz)
    shank = Trajectory.static(duration_s, q, knee, fs_hz=fs_hz)
    la_t, la_s = _lever_arms(side)
    return LegMotion(t, thigh, shank, np.zeros((len(t), 3)), side, la_t, la_s, np.zeros((0, 2)), np.zeros((0, 4)))


def standing(duration_s: float = 30.0, side: str = "right", *, facing_rad: float = 0.0,
             fs_hz: float = DEFAULT_FS_HZ) -> LegMotion:
    """Static standing posture for sensor-to-segment calibration: both segments' y axes up, knee straight."""
    return _posture(duration_s, side, facing_rad, "standing", fs_hz)


def supine(duration_s: float = 30.0, side: str = "right", *, head_rad: float = 0.0, roll_out_rad: float = 0.0,
           fs_hz: float = DEFAULT_FS_HZ) -> LegMotion:
    """Static supine lying posture: both segments' x (anterior) axes up, y towards the head (ENU yaw ``head_rad``).

    ``roll_out_rad``: the leg rolled outwards about its long axis (toes out), as a relaxed leg lies when
    nobody holds the toes up; the static calibration takes the anterior axis from this posture."""
    return _posture(duration_s, side, head_rad, "supine", fs_hz, roll_out_rad)
