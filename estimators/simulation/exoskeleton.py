r"""Hinge chains for exoskeleton studies: trunk/thigh/shank/foot linked by hinge joints, with encoders.

A chain of rigid segments in ISB frames (x anterior, y proximal along the long axis, z to the right).
Segment 0 (the root) has a prescribed orientation :math:`q_{earth,0}(t)` and position of its
*distal* joint is found from its length; every further segment ``i`` hangs from the distal end of
segment ``i-1`` by a hinge about the common z axis (lateral):

.. math:: q_{earth,i} = q_{earth,i-1}\otimes R_z(-\alpha_i),\qquad
          p_i = p_{i-1} + R_{earth,i-1}\,[0, -L_{i-1}, 0]^T,

so a positive joint angle :math:`\alpha_i` (flexion of the knee, for instance) swings the child's
distal end backwards, and in the sagittal plane the absolute angles obey
:math:`\alpha_i = \theta_{i-1} - \theta_i` (seed 002 eq. 17: :math:`\Delta_k = \Delta\theta_T-\Delta\theta_S`).
Each segment's origin is its proximal joint; ``lever_arm_m`` of a sensor is taken from there.

:func:`hinge_pair` — a thigh + shank moving in 3D (the thigh turns about all three axes) for the
joint-axis estimation; :func:`gait_chain` — a 2- to 4-segment leg with gait-like sagittal motion,
small out-of-plane wobble, a bobbing walking pelvis and encoder angles at the encoder rate
(50 Hz by default, seed 000 §3.2).  Trajectories are :class:`~estimators.simulation.Trajectory`
objects, so :func:`~estimators.simulation.simulate_on_grid` turns them into IMU data.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from estimators import quaternion as quat
from estimators.simulation.imu import simulate_on_grid
from estimators.simulation.spec import ImuSpec, random_rotation
from estimators.simulation.trajectory import Trajectory, intrinsic_rotation, min_jerk, time_grid

FloatArray = NDArray[np.float64]

__all__ = ["DEFAULT_LEVERS_M", "HingeChain", "gait_chain", "hinge_pair", "joint_in_sensor", "sagittal_mount",
           "simulate_chain"]


@dataclass
class HingeChain:
    """A simulated hinge chain.

    names : segment names, root first.   segments : one :class:`Trajectory` per segment (origin at
    its proximal joint).   lengths_m : segment lengths.   t_s : dense time grid (1 kHz).
    joint_rad : (n_t, n_segments − 1) hinge angles on ``t_s`` (α_i = θ_{i−1} − θ_i in the sagittal plane).
    """

    names: tuple[str, ...]
    segments: tuple[Trajectory, ...]
    lengths_m: tuple[float, ...]
    t_s: FloatArray
    joint_rad: FloatArray
    extra: dict = field(default_factory=dict)

    def joint_at(self, t_s: FloatArray) -> FloatArray:
        """Hinge angles (n, n_joints) at times ``t_s`` (linear interpolation of the dense truth)."""
        t = np.asarray(t_s, dtype=np.float64)
        return np.column_stack([np.interp(t, self.t_s, self.joint_rad[:, i]) for i in range(self.joint_rad.shape[1])])

    def encoders(self, fs_hz: float = 50.0, noise_rad: float = 0.0, seed: int = 0) -> tuple[FloatArray, FloatArray]:
        """Encoder readings ``(t_s, joint_rad)`` at ``fs_hz`` with optional white noise (rad)."""
        t = np.arange(0.0, self.t_s[-1] + 1e-12, 1.0 / fs_hz)
        rng = np.random.default_rng(seed)
        return t, self.joint_at(t) + rng.normal(0.0, noise_rad, (len(t), self.joint_rad.shape[1]))


def _chain(t: FloatArray, q_root: FloatArray, p_root: FloatArray, joints: FloatArray, lengths, names) -> HingeChain:
    qs, ps = [q_root], [p_root]
    for i in range(joints.shape[1]):
        ps.append(ps[-1] + quat.rotate(qs[-1], np.array([0.0, -lengths[i], 0.0])))
        qs.append(quat.multiply(qs[-1], intrinsic_rotation(-joints[:, i:i + 1], "Z")))
    segs = tuple(Trajectory(t, q, p) for q, p in zip(qs, ps))
    return HingeChain(tuple(names), segs, tuple(float(v) for v in lengths), t, joints)


def hinge_pair(duration_s: float = 10.0, *, seed: int = 0, fs_hz: float = 1000.0) -> HingeChain:
    """Thigh + shank, the thigh turning about all three axes (flexion, abduction, rotation) and the
    hip translating; knee 0.1–1.1 rad.  Random phases and frequencies from ``seed``."""
    rng = np.random.default_rng(seed)
    t = time_grid(duration_s, fs_hz)
    f = rng.uniform(0.7, 1.3, 6)
    ph = rng.uniform(0, 2 * np.pi, 8)
    flex = 0.45 * np.sin(2 * np.pi * 0.5 * f[0] * t + ph[0]) + 0.15 * np.sin(2 * np.pi * 1.3 * f[1] * t + ph[1])
    abd = 0.25 * np.sin(2 * np.pi * 0.37 * f[2] * t + ph[2])
    rot = 0.3 * np.sin(2 * np.pi * 0.29 * f[3] * t + ph[3])
    knee = 0.6 + 0.45 * np.sin(2 * np.pi * 0.8 * f[4] * t + ph[4]) + 0.05 * np.sin(2 * np.pi * 2.1 * f[5] * t + ph[5])
    q_thigh = intrinsic_rotation(np.column_stack([rot, abd, flex]), "YXZ")
    p_hip = np.column_stack([0.2 * np.sin(2 * np.pi * 0.21 * t + ph[6]), 0.1 * np.sin(2 * np.pi * 0.33 * t),
                             0.9 + 0.05 * np.sin(2 * np.pi * 0.9 * t + ph[7])])
    return _chain(t, q_thigh, p_hip, knee[:, None], (0.42, 0.43), ("thigh", "shank"))


def gait_chain(duration_s: float = 30.0, *, n_segments: int = 4, cadence_hz: float = 0.9, seed: int = 0,
               wobble_rad: float = 0.05, still_s: float = 0.0, fs_hz: float = 1000.0) -> HingeChain:
    """A walking leg: ``n_segments`` of (trunk, thigh, shank, foot) — 2: thigh + shank, 3: trunk +
    thigh + shank, 4: all.  Sagittal gait-like angles (hip ±25°, knee 5–60°, ankle ±15°, trunk
    3 ± 2°) with stride-to-stride variability, a pelvis moving forward at 1.1 m/s with a 4 cm bob and
    heel-strike-like jolts, and ``wobble_rad`` of out-of-plane root motion.  ``still_s`` > 0 starts with
    that long a rest upright (all angles zero), then a 1 s minimum-jerk ramp into walking."""
    if n_segments not in (2, 3, 4):
        raise ValueError(f"n_segments must be 2, 3 or 4, got {n_segments!r}")
    rng = np.random.default_rng(seed)
    t = time_grid(duration_s, fs_hz)
    # slowly varying phase: stride-to-stride variability of cadence
    cad = cadence_hz * (1.0 + 0.05 * np.sin(2 * np.pi * 0.05 * t + rng.uniform(0, 6.3)))
    phase = 2 * np.pi * np.cumsum(cad) / fs_hz
    trunk = 0.03 * np.sin(2 * phase + 0.4) + 0.05
    hip = 0.40 * np.sin(phase) + 0.06 * np.sin(2 * phase + 1.0) + 0.1      # thigh flexion (absolute)
    knee = 0.55 * (0.5 - 0.5 * np.cos(phase + 0.9)) ** 2 + 0.12 * (0.5 - 0.5 * np.cos(2 * phase)) + 0.08
    ankle = 0.22 * np.sin(phase - 0.6) + 0.05 * np.sin(2 * phase)
    wob_x = wobble_rad * np.sin(phase + rng.uniform(0, 6.3))
    wob_y = wobble_rad * np.sin(0.5 * phase + rng.uniform(0, 6.3))
    heel = np.exp((np.cos(phase - 0.2) - 1.0) / 0.05)                       # smooth jolt once per stride
    env = min_jerk((t - still_s) / 1.0) if still_s > 0 else np.ones_like(t)
    trunk, hip, knee, ankle, wob_x, wob_y, heel = (v * env for v in (trunk, hip, knee, ankle, wob_x, wob_y, heel))
    p_root = np.column_stack([0.02 * np.sin(phase) * env, 1.1 * np.cumsum(env) / fs_hz + 0.01 * heel,
                              1.35 + (0.02 * np.cos(2 * phase) - 0.02) * env - 0.015 * heel])
    names = ("trunk", "thigh", "shank", "foot")
    lengths = (0.5, 0.42, 0.43, 0.2)
    absolute = np.column_stack([trunk, hip, hip - knee, hip - knee - ankle])     # θ_B, θ_T, θ_S, θ_F
    first = 1 if n_segments == 2 else 0
    p_root = p_root - np.array([0.0, 0.0, 0.45])                                # p_root: the hip
    absolute = absolute[:, first:first + n_segments]
    joints = absolute[:, :-1] - absolute[:, 1:]                                  # α_i = θ_{i-1} − θ_i
    q_stand = quat.from_matrix(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))  # x→N, y→up, z→E
    q_root = quat.multiply(q_stand, intrinsic_rotation(np.column_stack([wob_y, wob_x, absolute[:, 0]]), "YXZ"))
    if first == 0:  # the trunk hangs from its top: place it so that its distal end (the hip) follows p_root
        p_root = p_root + quat.rotate(q_root, np.array([0.0, lengths[0], 0.0]))
    chain = _chain(t, q_root, p_root, joints, lengths[first:first + n_segments], names[first:first + n_segments])
    chain.extra["absolute_sagittal_rad"] = absolute
    return chain


def joint_in_sensor(q_segment_sensor: FloatArray, lever_arm_m: FloatArray, joint_in_segment_m: FloatArray,
                    axis_in_segment=(0.0, 0.0, 1.0)) -> tuple[FloatArray, FloatArray]:
    """True joint axis and centre in a sensor's frame: ``(j (3,), o (3,) m)``, sensor → joint."""
    j = quat.rotate(quat.conjugate(np.asarray(q_segment_sensor, float)), np.asarray(axis_in_segment, float))
    o = quat.rotate(quat.conjugate(np.asarray(q_segment_sensor, float)),
                    np.asarray(joint_in_segment_m, float) - np.asarray(lever_arm_m, float))
    return j, o


def sagittal_mount(misalign_rad: float = 0.0, seed: int | None = None) -> FloatArray:
    """``q_segment_sensor`` of a sensor whose x axis is the segment's lateral z axis (the seed's "roll" is
    the sagittal angle, seed 000 §2.3), y along the segment, z = x × y; optionally misaligned by a random
    rotation of up to ``misalign_rad``."""
    q = quat.from_matrix(np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]))
    if misalign_rad > 0.0:
        q = quat.multiply(q, random_rotation(misalign_rad, seed))
    return q


DEFAULT_LEVERS_M = {"trunk": (0.1, -0.25, 0.05), "thigh": (0.05, -0.2, 0.07), "shank": (0.04, -0.15, 0.05),
                    "foot": (0.05, -0.08, 0.03)}


def simulate_chain(chain: HingeChain, fs_hz: float = 100.0, spec=None, *, misalign_rad: float = 0.0,
                   seed: int = 0) -> list:
    """One :class:`~estimators.simulation.ImuOnGrid` per segment, sensors with :func:`sagittal_mount`
    (misaligned by up to ``misalign_rad``) at :data:`DEFAULT_LEVERS_M`; ``spec`` default ``ImuSpec()``."""
    out = []
    for i, (name, seg) in enumerate(zip(chain.names, chain.segments)):
        q = sagittal_mount(misalign_rad, seed=seed * 31 + i)
        out.append(simulate_on_grid(seg, ImuSpec() if spec is None else spec, fs_hz=fs_hz, q_segment_sensor=q,
                                    lever_arm_m=DEFAULT_LEVERS_M[name], seed=seed * 17 + i))
    return out
