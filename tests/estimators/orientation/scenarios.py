"""Hard simulated scenarios for every orientation method (issue 13 §1, §6), composed from the simulator.

* :func:`gait_clip` — a shank swinging from its first sample (no rest at the start), walking forward,
  with heel-strike impacts of 3–6 g added to the accelerometer, the magnetometer in any unit, and
  optionally a field disturbance near the floor (each stance phase);
* :func:`fast_rotations` — turns of at least 600 °/s lasting 1–2 s, separated by rests.

The truth is the simulator's ``q_earth_sensor``; impacts and disturbances are added to the
measurements only, so they are errors the filters must reject, not motion.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from estimators import quaternion as quat
from estimators.simulation import ImuSpec, MAG_EARTH_UT, Trajectory, random_rotation, simulate_on_grid
from estimators.simulation.spec import GyrErrors

FS_HZ = 100.0
G = 9.81


@dataclass(frozen=True)
class Clip:
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray
    fs_hz: float
    q_earth_sensor: np.ndarray
    disturbed: np.ndarray  # (N,) True where a field disturbance was added


def _spec() -> ImuSpec:
    """White noise and a constant gyroscope bias (≈ 0.7 °/s per axis); factory-calibrated magnetometer."""
    spec = ImuSpec.noise_only()
    return replace(spec, gyr=replace(GyrErrors.noise_only(), bias_rad_s=(0.012, -0.010, 0.008)))


def shank_swing(duration_s: float, heading_rad: float, cadence_hz: float = 0.9) -> Trajectory:
    """A shank-like segment walking along ``heading_rad`` (ENU, from east), swinging from t = 0.

    Sagittal swing ±30° (with a harmonic) about the segment's lateral axis, ±6° frontal sway,
    forward speed 1.2 m/s and 3 cm vertical bounce; the origin is the knee (the sensor sits below it).
    """
    w = 2.0 * np.pi * cadence_hz

    def q_fn(t):
        swing = np.deg2rad(30.0) * np.sin(w * t + 0.7) + np.deg2rad(8.0) * np.sin(2 * w * t + 0.3)
        sway = np.deg2rad(6.0) * np.sin(w * t + 1.9)
        yaw = heading_rad + np.deg2rad(4.0) * np.sin(w * t)
        q = quat.from_axis_angle([0.0, 0.0, 1.0], yaw)
        q = quat.multiply(q, quat.from_axis_angle([0.0, 1.0, 0.0], swing))
        return quat.multiply(q, quat.from_axis_angle([1.0, 0.0, 0.0], sway))

    def pos_fn(t):
        fwd = np.array([np.cos(heading_rad), np.sin(heading_rad), 0.0])
        return 1.2 * t[:, None] * fwd + np.array([0.0, 0.0, 0.03])[None, :] * np.sin(2 * w * t)[:, None]

    return Trajectory.from_functions(q_fn, pos_fn, duration_s)


def _impacts(n: int, q_earth_sensor: np.ndarray, fs_hz: float, cadence_hz: float, rng) -> np.ndarray:
    """Heel-strike pulses (sensor frame, m/s²): a 30 ms half sine of 3–6 g once per cycle, mostly vertical."""
    out = np.zeros((n, 3))
    width = int(round(0.03 * fs_hz))
    shape = np.sin(np.pi * (np.arange(width) + 0.5) / width)
    for t0 in np.arange(0.35, n / fs_hz - 0.05, 1.0 / cadence_hz):
        k = int(round(t0 * fs_hz))
        direction = np.array([rng.normal(0, 0.3), rng.normal(0, 0.3), 1.0])
        direction /= np.linalg.norm(direction)
        peak = rng.uniform(3.0, 6.0) * G
        sl = slice(k, min(k + width, n))
        pulse_e = peak * shape[: sl.stop - sl.start, None] * direction[None, :]
        out[sl] += quat.rotate(quat.conjugate(q_earth_sensor[sl]), pulse_e)
    return out


def gait_clip(
    duration_s: float = 10.0,
    *,
    seed: int = 0,
    mag_scale: float = 1.0,
    floor_disturbance: float = 0.0,
    heading_rad: float | None = None,
    rest_s: float = 0.0,
    start_disturbance: float = 0.0,
    start_disturbance_s: float = 3.0,
    everywhere_disturbance: float = 0.0,
) -> Clip:
    """A walking shank clip that starts in motion (see module docstring).

    mag_scale : the field is reported in µT times this (0.01: gauss; 1/|m_earth|: normalised).
    floor_disturbance : size of the field added during each stance (near the floor), as a fraction of
        the earth field; its direction is random per step (0 = undisturbed).
    rest_s : a rest in the swing's start posture before the motion (0 = in motion from sample 0).
    start_disturbance : a constant extra field (fraction of the earth field, horizontal and down, turning the
        apparent north by ≈ 20° at 0.4) during the first ``start_disturbance_s``, fading out over 0.5 s: the
        recording starts next to a steel object.
    everywhere_disturbance : a field of this size (fraction of the earth field) whose direction wanders smoothly
        during the whole clip (≈ 0.3 Hz): no undisturbed period at all.
    """
    rng = np.random.default_rng(seed)
    if heading_rad is None:
        heading_rad = rng.uniform(-np.pi, np.pi)
    cadence_hz = 0.9
    traj = shank_swing(duration_s + rest_s, heading_rad, cadence_hz)
    if rest_s > 0.0:
        t = traj.t_s
        t_motion = np.clip(t - rest_s, 0.0, None)
        moving = shank_swing(duration_s + rest_s, heading_rad, cadence_hz)
        traj = Trajectory(t, moving.orientation(t_motion), moving.position(t_motion))
    mount = random_rotation(np.pi, seed=seed + 100)
    grid = simulate_on_grid(traj, _spec(), fs_hz=FS_HZ, q_segment_sensor=mount, lever_arm_m=(0.02, 0.05, -0.25),
                            seed=seed)
    n = len(grid.acc)
    q = grid.q_earth_sensor
    acc = grid.acc.copy()
    t = np.arange(n) / FS_HZ
    in_motion = t >= rest_s
    acc[in_motion] += _impacts(int(in_motion.sum()), q[in_motion], FS_HZ, cadence_hz, rng)
    mag = grid.mag.copy()
    disturbed = np.zeros(n, dtype=bool)
    if floor_disturbance > 0.0:
        field = np.linalg.norm(MAG_EARTH_UT)
        phase = ((t - rest_s - 0.3) * cadence_hz) % 1.0
        stance = (phase < 0.55) & in_motion
        window = np.where(stance, np.sin(np.pi * phase / 0.55) ** 2, 0.0)
        step = np.floor((t - rest_s - 0.3) * cadence_hz).astype(int)
        dirs = rng.normal(size=(step.max() - step.min() + 1, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        d_e = floor_disturbance * field * window[:, None] * dirs[step - step.min()]
        mag += quat.rotate(quat.conjugate(q), d_e)
        disturbed = window > 0.05
    field = np.linalg.norm(MAG_EARTH_UT)
    if start_disturbance > 0.0:
        fade = np.clip((start_disturbance_s + 0.5 - t) / 0.5, 0.0, 1.0)
        d_e = start_disturbance * field * np.array([0.8, 0.2, -0.55]) / np.linalg.norm([0.8, 0.2, -0.55])
        mag += quat.rotate(quat.conjugate(q), fade[:, None] * d_e[None, :])
        disturbed |= fade > 0.0
    if everywhere_disturbance > 0.0:
        phases = rng.uniform(0.0, 2 * np.pi, 3)
        d = np.stack([np.sin(2 * np.pi * f * t + ph) for f, ph in zip((0.31, 0.23, 0.17), phases)], axis=1)
        d_e = everywhere_disturbance * field * d / np.linalg.norm(d, axis=1, keepdims=True).clip(0.3)
        mag += quat.rotate(quat.conjugate(q), d_e)
        disturbed[:] = True
    return Clip(acc, grid.gyr.copy(), mag * mag_scale, FS_HZ, q, disturbed)


def fast_rotations(*, seed: int = 0, rate_deg_s: float = 700.0, n_turns: int = 4, gyr_errors: bool = False,
                   fs_hz: float = FS_HZ, lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Clip:
    """Rests of 2 s, each followed by a turn about a random axis at ``rate_deg_s`` for 1–2 s (min-jerk edges).

    gyr_errors : the simulator's default gyroscope errors (bias, random walk, 0.2–0.4 % scale and 0.1–0.4 %
        cross-axis errors: 2–4 °/s of rate error at 1000 °/s) instead of white noise and a constant bias.
    lever_arm_m : the sensor's offset from the centre of rotation, m (a hand-held sensor turned at the wrist:
        centripetal accelerations of ω²r, 3 g at 1000 °/s and 0.1 m).
    """
    rng = np.random.default_rng(seed)
    rest_s, ramp_s = 2.0, 0.15
    segments = []
    t_total = rest_s
    for _ in range(n_turns):
        hold = rng.uniform(1.0, 2.0)
        axis = rng.normal(size=3)
        segments.append((t_total, hold, axis / np.linalg.norm(axis)))
        t_total += hold + 2 * ramp_s + rest_s
    dt = 1e-3
    t = np.arange(0.0, t_total + dt / 2, dt)
    rate = np.zeros((len(t), 3))
    for t0, hold, axis in segments:
        up = np.clip((t - t0) / ramp_s, 0.0, 1.0)
        down = np.clip((t0 + hold + 2 * ramp_s - t) / ramp_s, 0.0, 1.0)
        prof = np.minimum(up, down)
        prof = prof ** 3 * (10 - 15 * prof + 6 * prof ** 2)  # min-jerk edges
        rate += np.deg2rad(rate_deg_s) * prof[:, None] * axis[None, :]
    q = np.empty((len(t), 4))
    q[0] = quat.from_euler([rng.uniform(-3, 3), 0.3, -0.2], "ZYX")
    for k in range(1, len(t)):
        q[k] = quat.multiply(q[k - 1], quat.exp(0.5 * (rate[k - 1] + rate[k]) * dt))
    traj = Trajectory(t, q, np.zeros((len(t), 3)))
    spec = replace(_spec(), gyr=GyrErrors()) if gyr_errors else _spec()
    grid = simulate_on_grid(traj, spec, fs_hz=fs_hz, lever_arm_m=lever_arm_m, seed=seed)
    return Clip(grid.acc, grid.gyr, grid.mag, fs_hz, grid.q_earth_sensor, np.zeros(len(grid.acc), dtype=bool))


def heading_error_rad(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Heading error about the earth vertical: the z rotation of ``q_est ⊗ q_true*`` after removing tilt.

    The error rotation in the earth frame, ``q_e = q_est ⊗ q_true*``, is split as swing × twist about z;
    the twist angle is the heading error (wrapped to (-π, π]).
    """
    q_e = quat.multiply(q_est, quat.conjugate(q_true))
    return np.angle(np.exp(1j * 2.0 * np.arctan2(q_e[:, 3], q_e[:, 0])))


def tilt_error_rad(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Angle between the estimated and true vertical seen from the sensor."""
    up_e = quat.rotate(quat.conjugate(q_est), [0.0, 0.0, 1.0])
    up_t = quat.rotate(quat.conjugate(q_true), [0.0, 0.0, 1.0])
    return np.arccos(np.clip(np.sum(up_e * up_t, axis=-1), -1.0, 1.0))
