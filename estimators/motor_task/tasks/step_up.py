"""Single-leg step-up (seed 004 §8.1, Fig. 8.2, Tables 8.1/8.3; DESIGN.md §3).

Rest flexed with the foot on the step (0 % of the cycle) → *impulse*: flexion first rises 5–10° while the
other foot pushes off (peak flexion, ~30 % in Fig. 8.2; the thesis measured 34 %) → *extension* to ~0°,
held while the body stands on the leg (~50 %) → *fall* from leaving full extension back to the start
posture (75 %: the other foot touches the floor; 100 %: at rest).  The exact cycle and phase definition
used by the detector is in the :mod:`estimators.motor_task` docstring.
"""

from estimators.motor_task.spec import PhaseSpec, TaskSpec

SPEC = TaskSpec(
    name="step_up", excursion="extension", countermovement=True,
    phases=(PhaseSpec("impulse", "onset", "countermovement_peak"),
            PhaseSpec("extension", "countermovement_peak", "far_left"),
            PhaseSpec("fall", "far_left", "rest_reached")),
    far_label="full extension",
    description="single-leg step-up (seed 004 §8.1; DESIGN.md §3): rest flexed on the step, impulse "
                "(flexion rises 5–10°), extension to ~0° held, fall back to the start posture",
    heading_bound="tilt")  # the 3° bound was chosen on these motions (benchmarks.robustness, seeds 0-11)


def analyse(angles_rad, fs_hz: float, *, params=None, t0_s: float = 0.0, gyr_thigh_rad_s=None, gyr_shank_rad_s=None,
            shank_axis_sensor=None, exclude=()):
    """The shared analysis (:func:`~estimators.motor_task.analyse_task`) with the event fits on the D7 flexion when
    both gyroscopes are given: ``gyr_thigh_rad_s``, ``gyr_shank_rad_s`` (N, 3) bias-corrected, rad/s, sensor axes,
    and ``shank_axis_sensor`` (3,) the shank's flexion axis (segment z) in shank-sensor coordinates
    (:func:`~estimators.motor_task.detection.gyroscope_flexion`).  Without them, the angles alone (as before).
    ``exclude``: the cycles the clinician excluded (:func:`~estimators.motor_task.analysis.reject_cycles`)."""
    from estimators.motor_task.analysis import analyse_task, checked_inputs
    from estimators.motor_task.detection import gyroscope_flexion
    from estimators.motor_task.spec import MotorTaskParams

    a, fs, p = checked_inputs(angles_rad, fs_hz, MotorTaskParams() if params is None else params)
    fit = None
    if gyr_thigh_rad_s is not None and gyr_shank_rad_s is not None and shank_axis_sensor is not None:
        fit = gyroscope_flexion(a[:, 0], fs, gyr_thigh_rad_s, gyr_shank_rad_s, shank_axis_sensor, p.gyro_crossover_hz)
    return analyse_task(a, fs, task=SPEC, params=p, t0_s=t0_s, fit_flexion_rad=fit, exclude=exclude)
