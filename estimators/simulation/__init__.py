r"""Ground-truth generator: a physically consistent magneto-inertial sensor simulator.

Tests, benchmarks, ``chakamo demo``, the knee pipeline and pedestrian dead reckoning all draw
their synthetic data from here.  Three layers:

1. **Trajectories** (:mod:`.trajectory`) — :class:`Trajectory` ``(t_s, q_earth_body, pos_m)``
   sampled densely (1 kHz) from a smooth definition; cubic splines give velocity, acceleration,
   body angular velocity :math:`\omega = 2\,\mathrm{vec}(q^*\otimes\dot q)` and the truth at any
   time (:meth:`Trajectory.at`, :meth:`~Trajectory.orientation`).  Build your own with
   ``Trajectory(t_s, q, pos)`` or :meth:`Trajectory.from_functions`.
2. **Sensor model** (:mod:`.spec`, :mod:`.imu`) — :func:`simulate` turns a segment trajectory into three
   streams (acc 100 Hz, gyr 100 Hz, mag 20 Hz by default), each with its own time stamps, using

   * specific force :math:`f_s = R_{es}^\top(\ddot p_s + [0, 0, 9.81])` (ENU; +9.81 on the up axis at rest),
   * gyroscope :math:`\omega_s`, magnetometer :math:`R_{es}^\top m_e` with :math:`m_e = [0, 20, -40]` µT,
   * errors: white noise (densities), constant bias + random-walk drift, scale and cross-axis
     errors, hard/soft iron :math:`m = A m_s + b`, saturation (:class:`AccErrors`,
     :class:`GyrErrors`, :class:`MagErrors`),
   * mounting: the sensor rotated on the segment by ``q_segment_sensor`` (:func:`random_rotation`)
     and placed at ``lever_arm_m``,
   * clock (:class:`ClockSpec`): rates, per-stream start offsets, drift (ppm), offset, stamp jitter.

   :class:`ImuSpec` groups them: ``ImuSpec()`` a representative MetaMotionR (BMI160/BMM150),
   ``ImuSpec.perfect()`` noise-free, ``ImuSpec.noise_only()``, ``ImuSpec.random(seed)``.
   The result :class:`SimulatedImu` holds a :class:`Stream` per sensor (``t_s`` reported stamps,
   ``values``, ``t_true_s``, ``clean``, ``bias``, ``saturated``, ``q_earth_sensor``) and
   :meth:`SimulatedImu.on_grid` resamples everything onto one uniform grid for filter tests:
   :class:`ImuOnGrid` ``(t_s, acc, gyr, mag, fs_hz, q_earth_sensor, ...)``;
   :func:`simulate_on_grid` (``fs_hz`` = the acc/gyr output rate) does both in one call.
3. **Motions** (:mod:`.motions`, :mod:`.knee`) — :func:`static_pose`, :func:`rotations`,
   :func:`figure_eight`, :func:`walking_foot` (→ :class:`WalkingMotion` with stance truth),
   :func:`step_up`, :func:`standing`, :func:`supine` (→ :class:`LegMotion`: thigh and shank in ISB
   frames, Grood & Suntay knee angles, cycle and phase boundaries); :func:`knee_quaternion` /
   :func:`knee_angles` define the knee angle convention (K1) used for the truth.

Example
-------
>>> from estimators import simulation as sim
>>> leg = sim.step_up(n_cycles=3, step_height_m=0.17, side="right")
>>> mount = sim.random_rotation(0.2, seed=1)
>>> thigh = sim.simulate(leg.thigh, sim.ImuSpec(), q_segment_sensor=mount,
...                      lever_arm_m=leg.thigh_lever_arm_m, seed=1)
>>> grid = thigh.on_grid()          # acc, gyr, mag (N, 3) at 100 Hz + truth
>>> grid.acc.shape == (len(grid.t_s), 3)
True

Equations S1–S8 are in :mod:`.imu`, K1 in :mod:`.knee`.  Everything is vectorised numpy: a 60 s
two-sensor step-up session (motion, two sensors, both on a grid) takes about 0.3 s.

Accuracy of the truth: the built-in motions place their events on the 1 kHz grid, so the splines
ring into rests by less than 1e-6 m/s, 1e-5 rad/s and 1e-3 m/s² (next to an event only).
"""

from __future__ import annotations

from estimators.simulation.imu import ImuOnGrid, SimulatedImu, Stream, simulate, simulate_on_grid
from estimators.simulation.spec import (
    GRAVITY_M_S2,
    MAG_EARTH_UT,
    AccErrors,
    ClockSpec,
    GyrErrors,
    ImuSpec,
    MagErrors,
    random_rotation,
)
from estimators.simulation.knee import (
    SHANK_LENGTH_M,
    THIGH_LENGTH_M,
    LegMotion,
    knee_angles,
    knee_quaternion,
    segment_frame,
    standing,
    step_up,
    supine,
)
from estimators.simulation.motions import WalkingMotion, figure_eight, rotations, static_pose, walking_foot
from estimators.simulation.trajectory import KinematicState, Trajectory, bump, min_jerk, time_grid

__all__ = [
    "AccErrors", "ClockSpec", "GRAVITY_M_S2", "GyrErrors", "ImuOnGrid", "ImuSpec", "KinematicState", "LegMotion",
    "MAG_EARTH_UT", "MagErrors", "SHANK_LENGTH_M", "SimulatedImu", "Stream", "THIGH_LENGTH_M", "Trajectory",
    "WalkingMotion", "bump", "figure_eight", "knee_angles", "knee_quaternion", "min_jerk", "random_rotation",
    "rotations", "segment_frame", "simulate", "simulate_on_grid", "standing", "static_pose", "step_up", "supine",
    "time_grid", "walking_foot",
]
