r"""The magneto-inertial sensor model: physics, sensor errors, clocks.

Physics (ideal sensor at true time :math:`t`, sensor frame s, ENU earth frame e)
------------------------------------------------------------------------------
.. math::
    \mathbf f_s &= R_{es}^\top(\ddot{\mathbf p}_s + [0, 0, g]^\top) &\text{(S1, specific force)}\\
    \boldsymbol\omega_{s,k} &= \tfrac{1}{\Delta t}\,\log\!\big(q_{es}(t_k - \Delta t)^* \otimes q_{es}(t_k)\big) &\text{(S2)}\\
    \mathbf m_s &= R_{es}^\top\,\mathbf m_e, \quad \mathbf m_e = [0, B_h, -B_v] &\text{(S3)}

with :math:`g = 9.81` m/s², :math:`\mathbf p_s` the sensor's own position (segment origin plus the
lever arm) and :math:`q_{es} = q_{e,segment} \otimes q_{segment,s}` (mounting).

(S2) is the *mean* body rate over the gyroscope's output interval :math:`\Delta t` (true time), not
the instantaneous :math:`2\operatorname{vec}(q^* \dot q)`: a MEMS gyroscope low-pass filters before it
samples, and the mean rate is what strapdown integration :math:`q_k = q_{k-1} \otimes \exp(\omega_k
\Delta t)` reproduces exactly.  Instantaneous rates would put a lag of :math:`|\omega|\Delta t / 2` into
every filter (0.5° RMS at 300 °/s and 100 Hz) that no real sensor shows.  The first sample, which has
no interval before the trajectory starts, reports the instantaneous rate.

Errors (per stream, vectorised over samples :math:`k`)
------------------------------------------------------
.. math::
    \mathbf y_k &= \operatorname{sat}\big(T\,\mathbf x_k + \mathbf b_0 + \mathbf w_k + \mathbf n_k\big),
      \quad T = \operatorname{diag}(1 + \mathbf s)\,(I + C) &\text{(S4, acc and gyr)}\\
    \mathbf w_k &= \sum_{j \le k} \sigma_{rw}\sqrt{\Delta t}\,\boldsymbol\eta_j
      &\text{(S5, bias random walk)}\\
    \mathbf n_k &\sim \mathcal N(0, \sigma^2 I), \quad \sigma = N\sqrt{f_s}
      &\text{(S6, white noise from its density)}\\
    \mathbf m^{meas}_k &= \operatorname{sat}(A\,\mathbf m_{s,k} + \mathbf b_{hi} + \mathbf n_k)
      &\text{(S7, soft and hard iron)}

:math:`\mathbf s` is the per-axis scale error, :math:`C` the cross-axis (misalignment) matrix with
zero diagonal, :math:`N` the white-noise density (unit/√Hz, Allan-variance convention, so that
the per-sample standard deviation is :math:`N\sqrt{f_s}`), :math:`\sigma_{rw}` the bias random-walk
density (unit/s/√Hz = unit/√s), ``sat`` clips to ``±range`` and flags the sample.

Clocks (S8)
-----------
A sensor has one device clock that reads :math:`c(t) = c_0 + (1 + \delta)(t - t_0)`
(``clock_offset_s`` :math:`c_0`, ``clock_drift_ppm`` :math:`\delta\cdot 10^6`, :math:`t_0` the
trajectory start).  Stream *j* samples at device times :math:`\tau_k = c_0 + o_j + k/f_j`
(``*_start_s`` :math:`o_j`), i.e. at true times :math:`t_k = t_0 + (\tau_k - c_0)/(1 + \delta)`,
while :math:`t_0 \le t_k \le t_{end}`.  The stamps reported are :math:`\tau_k + \epsilon_k` with
Gaussian jitter ``jitter_s`` (clipped to ±0.45 of the sample period so stamps stay ordered).  A
clock 0.5 % fast (``clock_drift_ppm = 5000``) thus logs 0.5 % more samples over the same true time.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.simulation.spec import GRAVITY_M_S2, MAG_EARTH_UT, ClockSpec, ImuSpec, _vec3
from estimators.simulation.trajectory import Trajectory

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = ["ImuOnGrid", "SimulatedImu", "Stream", "simulate", "simulate_on_grid"]

@dataclass(frozen=True, eq=False)
class Stream:
    """One sensor stream with its truth, per sample (n samples).

    t_s : (n,) time stamps as the device reports them (device clock, jitter), s.
    values : (n, 3) measurements (m/s², rad/s or µT).
    t_true_s : (n,) true sampling instants (trajectory time), s.
    clean : (n, 3) what an ideal sensor would have read at ``t_true_s`` (S1–S3).
    bias : (n, 3) the true additive bias (constant + random walk; hard iron for mag), stream unit.
    saturated : (n,) bool, the sample was clipped at the range.
    q_earth_sensor : (n, 4) true sensor orientation at ``t_true_s``.
    """

    t_s: FloatArray
    values: FloatArray
    t_true_s: FloatArray
    clean: FloatArray
    bias: FloatArray
    saturated: BoolArray
    q_earth_sensor: FloatArray

    @property
    def fs_hz(self) -> float:
        """Nominal rate estimated from the stamps (median period)."""
        return float(1.0 / np.median(np.diff(self.t_s)))

    def __len__(self) -> int:
        return len(self.t_s)


@dataclass(frozen=True, eq=False)
class ImuOnGrid:
    """All three streams on one uniform device-clock grid, with the truth at the grid's true times.

    t_s : (N,) grid, device clock, s (``t_s[0] + k/fs_hz``).   t_true_s : (N,) true times, s.
    acc, gyr, mag : (N, 3) linearly interpolated measurements.   fs_hz : grid rate, Hz.
    q_earth_sensor, q_earth_segment : (N, 4) truth.   pos_m, vel_m_s : (N, 3) true sensor position/velocity.
    gyr_bias_rad_s, acc_bias_m_s2 : (N, 3) true biases (interpolated).
    mag_earth_ut : (3,) the earth field used.
    """

    t_s: FloatArray
    t_true_s: FloatArray
    acc: FloatArray
    gyr: FloatArray
    mag: FloatArray
    fs_hz: float
    q_earth_sensor: FloatArray
    q_earth_segment: FloatArray
    pos_m: FloatArray
    vel_m_s: FloatArray
    gyr_bias_rad_s: FloatArray
    acc_bias_m_s2: FloatArray
    mag_earth_ut: FloatArray


@dataclass(frozen=True, eq=False)
class SimulatedImu:
    """Result of :func:`simulate`: three streams, the mounting, and the trajectories for any further truth.

    acc, gyr, mag : :class:`Stream`.
    q_segment_sensor : (4,) mounting rotation.   lever_arm_m : (3,) sensor position in the segment frame.
    segment : the segment :class:`Trajectory`;  sensor : the sensor's own :class:`Trajectory`.
    spec : the :class:`ImuSpec` used.   mag_earth_ut : (3,) earth field, ENU µT.
    """

    acc: Stream
    gyr: Stream
    mag: Stream
    q_segment_sensor: FloatArray
    lever_arm_m: FloatArray
    segment: Trajectory
    sensor: Trajectory
    spec: ImuSpec
    mag_earth_ut: FloatArray

    def device_to_true_time(self, t_device_s: ArrayLike) -> FloatArray:
        """Invert the clock model (S8): true trajectory time of a device-clock reading."""
        c = self.spec.clock
        return self.segment.t_start_s + (np.asarray(t_device_s, dtype=np.float64) - c.clock_offset_s) / c.rate_factor

    def on_grid(self, fs_hz: float | None = None) -> ImuOnGrid:
        """Resample acc, gyr and mag (linear interpolation on the reported stamps) on a uniform grid.

        The grid starts at the latest first stamp of the three streams, ends by the earliest last one
        and steps ``1/fs_hz`` (default: the gyroscope's nominal rate) on the device clock.  With the
        default ideal clock the grid coincides with the acc/gyr stamps, so those are not interpolated.
        """
        fs = float(self.spec.clock.gyr_fs_hz if fs_hz is None else fs_hz)
        if not (np.isfinite(fs) and fs > 0.0):
            raise ValueError(f"fs_hz must be a positive rate in Hz, got {fs_hz!r}")
        streams = (self.acc, self.gyr, self.mag)
        if min(len(s) for s in streams) < 2:
            raise ValueError("every stream needs at least two samples to be resampled; simulate a longer trajectory")
        t0 = max(s.t_s[0] for s in streams)
        t1 = min(s.t_s[-1] for s in streams)
        n = int(np.floor((t1 - t0) * fs + 1e-6)) + 1
        t = t0 + np.arange(n) / fs

        def interp(x: FloatArray, y: FloatArray) -> FloatArray:
            return np.stack([np.interp(t, x, y[:, i]) for i in range(3)], axis=1)

        t_true = self.device_to_true_time(t)
        t_true = np.clip(t_true, self.segment.t_start_s, self.segment.t_end_s)
        state = self.sensor.at(t_true)
        return ImuOnGrid(
            t_s=t, t_true_s=t_true,
            acc=interp(self.acc.t_s, self.acc.values), gyr=interp(self.gyr.t_s, self.gyr.values),
            mag=interp(self.mag.t_s, self.mag.values), fs_hz=fs,
            q_earth_sensor=state.q_earth_body, q_earth_segment=self.segment.orientation(t_true),
            pos_m=state.pos_m, vel_m_s=state.vel_m_s,
            gyr_bias_rad_s=interp(self.gyr.t_s, self.gyr.bias), acc_bias_m_s2=interp(self.acc.t_s, self.acc.bias),
            mag_earth_ut=self.mag_earth_ut,
        )


def _mean_rate(sensor: Trajectory, t_true: FloatArray, dt_s: float) -> FloatArray:
    """(S2): body rate averaged over ``[t - dt_s, t]``; the instantaneous rate where that starts before the trajectory."""
    t_prev = t_true - dt_s
    inside = t_prev >= sensor.t_start_s
    rate = sensor.angular_velocity(t_true)
    if inside.any():
        q_prev = sensor.orientation(t_prev[inside])
        q_now = sensor.orientation(t_true[inside])
        rate[inside] = quat.log(quat.multiply(quat.conjugate(q_prev), q_now)) / dt_s
    return rate


def _sample_times(n_rng: np.random.Generator, clock: ClockSpec, fs_hz: float, start_s: float,
                  traj: Trajectory) -> tuple[FloatArray, FloatArray]:
    """(reported stamps, true times) of one stream (S8)."""
    k_max = int(np.floor((traj.duration_s * clock.rate_factor - start_s) * fs_hz + 1e-9))
    if k_max < 0:
        return np.empty(0), np.empty(0)
    tau = clock.clock_offset_s + start_s + np.arange(k_max + 1) / fs_hz
    t_true = np.minimum(traj.t_start_s + (tau - clock.clock_offset_s) / clock.rate_factor, traj.t_end_s)
    jitter = n_rng.normal(0.0, 1.0, len(tau)) * clock.jitter_s
    jitter = np.clip(jitter, -0.45 / fs_hz, 0.45 / fs_hz)
    return tau + jitter, t_true


def _inertial_errors(clean: FloatArray, fs_true_hz: float, rng_noise: np.random.Generator,
                     rng_walk: np.random.Generator, noise_density: float, bias0: FloatArray, walk_density: float,
                     scale: FloatArray, cross: FloatArray, range_: float | None,
                     ) -> tuple[FloatArray, FloatArray, BoolArray]:
    """(S4)–(S6) and saturation: returns (values, bias, saturated)."""
    n = len(clean)
    dt_s = 1.0 / fs_true_hz
    t_mat = np.diag(1.0 + scale) @ (np.eye(3) + cross)
    white = rng_noise.normal(0.0, 1.0, (n, 3)) * (noise_density * np.sqrt(fs_true_hz))
    walk = np.cumsum(rng_walk.normal(0.0, 1.0, (n, 3)), axis=0) * (walk_density * np.sqrt(dt_s))
    bias = bias0 + walk
    values, sat = _saturate(clean @ t_mat.T + bias + white, range_)
    return values, bias, sat


def _saturate(values: FloatArray, range_: float | None) -> tuple[FloatArray, BoolArray]:
    if range_ is None:
        return values, np.zeros(len(values), dtype=bool)
    sat = np.any(np.abs(values) >= range_, axis=1)
    return np.clip(values, -range_, range_), sat


def simulate(
    trajectory: Trajectory,
    spec: ImuSpec | None = None,
    *,
    q_segment_sensor: ArrayLike | None = None,
    lever_arm_m: ArrayLike | None = None,
    mag_earth_ut: ArrayLike = MAG_EARTH_UT,
    gravity_m_s2: float = GRAVITY_M_S2,
    seed: int | np.random.Generator | None = 0,
    mag_field_turn_rad_s: float = 0.0,
) -> SimulatedImu:
    """Simulate one sensor fixed to a segment moving along ``trajectory`` (equations S1–S8).

    Parameters
    ----------
    trajectory : the segment's :class:`Trajectory` (``q_earth_segment``, segment origin position).
    spec : sensor errors and clock; default ``ImuSpec()`` (representative MetaMotionR).
    q_segment_sensor : (4,) mounting rotation of the sensor on the segment (default identity);
        see :func:`random_rotation`.
    lever_arm_m : (3,) sensor position in segment coordinates, m (default the segment origin).
    mag_earth_ut : (3,) earth magnetic field, ENU µT (default [0, 20, −40]).
    gravity_m_s2 : gravity magnitude (default 9.81).
    seed : int, ``np.random.Generator`` or None; the same seed gives the same run.  Each error
        source draws from its own child generator, so switching one source on or off leaves the
        others' draws unchanged.
    mag_field_turn_rad_s : the field at the sensor turns about the vertical at this rate, rad/s, from the
        trajectory's start: m_e(t) = R_z(ω_f (t − t₀)) m_e (default 0, a
        constant field).  A local disturbance that drifts slowly (furniture steel, a device moved nearby)
        keeps the field's norm and dip, so no magnetometer check sees it, yet the sensor's 9D heading
        follows it: the case the pipeline's heading-drift check on the task exists for.
        ``SimulatedImu.mag_earth_ut`` stays the field at t₀.
    """
    spec = ImuSpec() if spec is None else spec
    q_ss = quat.identity() if q_segment_sensor is None else np.asarray(q_segment_sensor, dtype=np.float64)
    if q_ss.shape != (4,):
        raise ValueError(f"q_segment_sensor must have shape (4,), got {q_ss.shape}")
    q_ss = quat.normalize(q_ss)
    lever = np.zeros(3) if lever_arm_m is None else _vec3(lever_arm_m, "lever_arm_m")
    m_e = _vec3(mag_earth_ut, "mag_earth_ut")
    if not (np.isfinite(gravity_m_s2) and gravity_m_s2 > 0.0):
        raise ValueError(f"gravity_m_s2 must be positive, got {gravity_m_s2!r}")
    rng = np.random.default_rng(seed)
    (r_acc_n, r_acc_w, r_gyr_n, r_gyr_w, r_mag_n, r_t_acc, r_t_gyr, r_t_mag) = rng.spawn(8)
    clock = spec.clock
    sensor = trajectory.mounted(q_ss, lever)
    up = np.array([0.0, 0.0, float(gravity_m_s2)])

    # accelerometer (S1, S4–S6)
    t_rep, t_true = _sample_times(r_t_acc, clock, clock.acc_fs_hz, clock.acc_start_s, trajectory)
    q = sensor.orientation(t_true)
    clean = quat.rotate(quat.conjugate(q), sensor.acceleration(t_true) + up)
    ea = spec.acc
    vals, bias, sat = _inertial_errors(
        clean, clock.acc_fs_hz * clock.rate_factor, r_acc_n, r_acc_w, ea.noise_density_m_s2_rthz, ea.bias_m_s2,
        ea.bias_walk_m_s2_rts, ea.scale_error, ea.cross_axis, ea.range_m_s2)
    acc = Stream(t_rep, vals, t_true, clean, bias, sat, q)

    # gyroscope (S2, S4–S6)
    t_rep, t_true = _sample_times(r_t_gyr, clock, clock.gyr_fs_hz, clock.gyr_start_s, trajectory)
    clean = _mean_rate(sensor, t_true, 1.0 / (clock.gyr_fs_hz * clock.rate_factor))
    eg = spec.gyr
    vals, bias, sat = _inertial_errors(
        clean, clock.gyr_fs_hz * clock.rate_factor, r_gyr_n, r_gyr_w, eg.noise_density_rad_s_rthz, eg.bias_rad_s,
        eg.bias_walk_rad_s_rts, eg.scale_error, eg.cross_axis, eg.range_rad_s)
    gyr = Stream(t_rep, vals, t_true, clean, bias, sat, sensor.orientation(t_true))

    # magnetometer (S3, S6–S7)
    t_rep, t_true = _sample_times(r_t_mag, clock, clock.mag_fs_hz, clock.mag_start_s, trajectory)
    q = sensor.orientation(t_true)
    if mag_field_turn_rad_s == 0.0:
        clean = quat.rotate(quat.conjugate(q), m_e)
    else:
        if not np.isfinite(mag_field_turn_rad_s):
            raise ValueError(f"mag_field_turn_rad_s must be finite, got {mag_field_turn_rad_s!r}")
        turn = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]),
                                    float(mag_field_turn_rad_s) * (t_true - trajectory.t_s[0]))
        clean = quat.rotate(quat.conjugate(q), quat.rotate(turn, m_e))
    em = spec.mag
    white = r_mag_n.normal(0.0, 1.0, clean.shape) * (em.noise_density_ut_rthz
                                                     * np.sqrt(clock.mag_fs_hz * clock.rate_factor))
    vals, sat = _saturate(clean @ em.soft_iron.T + em.hard_iron_ut + white, em.range_ut)
    mag = Stream(t_rep, vals, t_true, clean, np.tile(em.hard_iron_ut, (len(clean), 1)), sat, q)

    return SimulatedImu(acc, gyr, mag, q_ss, np.array(lever), trajectory, sensor, spec, np.array(m_e))


def simulate_on_grid(
    trajectory: Trajectory,
    spec: ImuSpec | None = None,
    *,
    fs_hz: float | None = None,
    q_segment_sensor: ArrayLike | None = None,
    lever_arm_m: ArrayLike | None = None,
    mag_earth_ut: ArrayLike = MAG_EARTH_UT,
    gravity_m_s2: float = GRAVITY_M_S2,
    seed: int | np.random.Generator | None = 0,
) -> ImuOnGrid:
    """Acc, gyr, mag and the truth on one uniform grid (for filter tests).

    ``fs_hz`` is the accelerometer and gyroscope *output rate*: it replaces ``spec.clock.acc_fs_hz``
    and ``gyr_fs_hz`` (so noise and sampling are those of a sensor running at that rate), and the
    grid is that rate; ``None`` keeps the spec's rates.  The magnetometer keeps its own rate
    (``spec.clock.mag_fs_hz``) and is linearly interpolated.  Other arguments as :func:`simulate`.
    """
    spec = ImuSpec() if spec is None else spec
    if fs_hz is not None:
        spec = replace(spec, clock=replace(spec.clock, acc_fs_hz=fs_hz, gyr_fs_hz=fs_hz))
    sim = simulate(trajectory, spec, q_segment_sensor=q_segment_sensor, lever_arm_m=lever_arm_m,
                   mag_earth_ut=mag_earth_ut, gravity_m_s2=gravity_m_s2, seed=seed)
    return sim.on_grid()
