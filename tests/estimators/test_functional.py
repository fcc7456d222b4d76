"""Functional sensor-to-segment calibration (standing + task, task only) against the simulator's truth.

Thresholds were chosen on seeds 0–2 (step-ups: random 15° mountings; gait: lateral mountings turned by up to
15°; ``ImuSpec.random`` sensors with biases, scale and axis errors); the tests run seeds 0 and 1.  Angles use
the TRUE sensor orientations composed with the calibration, so they measure the calibration alone.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from estimators import functional, knee
from estimators import quaternion as quat
from estimators import simulation as sim
from estimators.simulation import gait

DEG = np.pi / 180.0
FS_HZ = 100.0


def _session(kind: str, seed: int, side: str, step_height_m: float = 0.17, standing_start_s: float = 2.0,
             misalignment_rad: float = 15 * DEG):
    # full inertial error model; the magnetometer as after its ellipsoid fit (noise only)
    specs = [replace(sim.ImuSpec.random(seed * 10 + k), mag=sim.ImuSpec.noise_only().mag) for k in range(2)]
    if kind == "step_up":
        # the step-up these checks were stated on: a still full-extension hold in each cycle (the straight window)
        motion = sim.step_up(10, step_height_m, side, shape="rest_between", seed=seed, facing_rad=0.4)
        mounts = [sim.random_rotation(misalignment_rad, seed=100 * seed + k) for k in range(2)]
        imus = [sim.simulate(getattr(motion, n), specs[k], q_segment_sensor=mounts[k],
                             lever_arm_m=getattr(motion, f"{n}_lever_arm_m"), seed=7 * seed + k)
                for k, n in enumerate(("thigh", "shank"))]
    else:
        walk = gait.walking(12.0 + standing_start_s, standing_start_s=standing_start_s, seed=seed)
        leg = walk.leg(side)
        mounts = gait.lateral_mounting(side, misalignment_rad, seed=seed)
        imus = gait.simulate_leg(leg, specs[0], specs[1], q_thigh_sensor=mounts[0], q_shank_sensor=mounts[1],
                                 seed=seed)
        motion = leg.motion
    grids = [imu.on_grid() for imu in imus]
    n = min(len(g.t_s) for g in grids)
    standing = sim.standing(10.0, side, facing_rad=0.4)
    g_st = [sim.simulate_on_grid(getattr(standing, name), specs[k], q_segment_sensor=mounts[k], seed=7 * seed + 50 + k)
            for k, name in enumerate(("thigh", "shank"))]
    m = min(len(g.t_s) for g in g_st)
    truth = np.column_stack([np.interp(grids[0].t_true_s[:n], motion.t_s, motion.knee_angles_rad[:, i])
                             for i in range(3)])
    return {"task": [(g.acc[:n], g.gyr[:n]) for g in grids], "standing": [(g.acc[:m], g.gyr[:m]) for g in g_st],
            "q_true": [quat.conjugate(q) for q in mounts], "q_task": {"thigh": grids[0].q_earth_sensor[:n],
                                                                     "shank": grids[1].q_earth_sensor[:n]},
            "q_standing": {"thigh": g_st[0].q_earth_sensor[:m], "shank": g_st[1].q_earth_sensor[:m]},
            "bias": [g.gyr_bias_rad_s[:n].mean(axis=0) for g in grids], "truth": truth, "side": side,
            "mag": [g.mag[:n] for g in grids], "mag_standing": [g.mag[:m] for g in g_st]}


def _axis_errors(cal: knee.SegmentCalibration, q_true) -> np.ndarray:
    """Angle (rad) between the calibrated and the true segment x, y, z axes, in sensor coordinates."""
    r, r_true = quat.to_matrix(cal.q_sensor_segment), quat.to_matrix(q_true)
    return np.arccos(np.clip(np.sum(r * r_true, axis=0), -1.0, 1.0))


def _angle_errors(s, res: functional.FunctionalCalibration) -> np.ndarray:
    q_f = knee.segment_orientation(s["q_task"]["thigh"], res.thigh.q_sensor_segment)
    q_t = knee.segment_orientation(s["q_task"]["shank"], res.shank.q_sensor_segment)
    return knee.knee_angles(knee.q_femur_tibia(q_f, q_t), s["side"]) - s["truth"]


# ------------------------------------------------------------------------------------------ (c) standing + task
@pytest.mark.parametrize("side, height, seed", [("right", 0.17, 0), ("left", 0.34, 0), ("right", 0.34, 1),
                                                ("left", 0.17, 1)])
def test_standing_task_calibration_matches_the_static_accuracy(side, height, seed):
    s = _session("step_up", seed, side, height)
    res = functional.standing_task_calibration(*s["standing"], *s["task"], fs_hz=FS_HZ, q_standing=s["q_standing"],
                                               q_task=s["q_task"])
    for cal in res.segments.values():
        assert cal.method == "standing_functional" and cal.quality is res.fit
        assert cal.standing is cal.supine and cal.standing.still
    # gravity vs the hinge axis (ideal 90°): the femur's is sharp, Seel's shank axis tilts on sagittal tasks
    assert abs(res.thigh.angle_between_postures_rad - np.pi / 2) < 10 * DEG
    assert abs(res.shank.angle_between_postures_rad - np.pi / 2) < 40 * DEG
    assert res.fit.hinge_tilt_gap_rad == pytest.approx(abs(res.thigh.angle_between_postures_rad
                                                           - res.shank.angle_between_postures_rad))
    e_t, e_s = _axis_errors(res.thigh, s["q_true"][0]), _axis_errors(res.shank, s["q_true"][1])
    assert e_t[1] < 1.5 * DEG and e_s[1] < 1.5 * DEG           # long axes: standing gravity
    assert max(e_t[0], e_t[2]) < 6.5 * DEG                       # femur z: Seel's thigh axis
    err = _angle_errors(s, res)
    assert abs(np.mean(err[:, 0])) < 2.0 * DEG                   # flexion offset, the static target
    assert np.sqrt(np.mean(err[:, 1] ** 2)) < 3.0 * DEG          # adduction RMSE
    assert abs(np.mean(err[:, 2])) < 5.0 * DEG                   # rotation zero from the standing orientations
    assert res.fit.axes.relative_sign_source == "orientation" and res.fit.heading_offset_rad is not None
    assert res.fit.straight_source == "standing" and abs(res.fit.bend_rad) < 3 * DEG
    assert res.fit.sign_margin_rad > 30 * DEG
    # gyroscope bias from the standing posture
    np.testing.assert_allclose(res.thigh.gyr_bias_rad_s, s["bias"][0], atol=0.003)


def test_standing_task_without_orientations_keeps_flexion_and_adduction():
    s = _session("step_up", 0, "right")
    res = functional.standing_task_calibration(*s["standing"], *s["task"], fs_hz=FS_HZ)
    assert res.fit.axes.relative_sign_source == "mounting" and res.fit.heading_offset_rad is None
    err = _angle_errors(s, res)
    assert abs(np.mean(err[:, 0])) < 2.0 * DEG and np.sqrt(np.mean(err[:, 1] ** 2)) < 3.0 * DEG
    # without a heading the tibia's rotation zero is Seel's (ill-posed about the long axis on a step-up)
    assert abs(np.mean(err[:, 2])) < 20 * DEG


# ------------------------------------------------------------------------------------------ (d) task only
@pytest.mark.parametrize("side, height, seed", [("right", 0.17, 0), ("left", 0.34, 0), ("right", 0.34, 1),
                                                ("left", 0.17, 1)])
def test_task_only_on_step_ups(side, height, seed):
    s = _session("step_up", seed, side, height)
    res = functional.task_calibration(*s["task"], fs_hz=FS_HZ, q_task=s["q_task"])
    assert res.thigh.method == res.shank.method == "task_functional"
    fit = res.fit
    assert fit.straight_source == "task" and fit.n_straight_windows >= 5   # the extension holds
    assert fit.window["thigh"].still and fit.window["shank"].still
    assert fit.window["thigh"].start == fit.window["shank"].start
    e_t, e_s = _axis_errors(res.thigh, s["q_true"][0]), _axis_errors(res.shank, s["q_true"][1])
    assert e_t[1] < 2.0 * DEG and e_s[1] < 3.0 * DEG
    err = _angle_errors(s, res)
    assert abs(np.mean(err[:, 0])) < 3.0 * DEG                   # the (d) target
    assert np.sqrt(np.mean(err[:, 1] ** 2)) < 3.0 * DEG
    np.testing.assert_allclose(res.shank.gyr_bias_rad_s, s["bias"][1], atol=0.005)


@pytest.mark.parametrize("side, seed, start_s", [("right", 0, 2.0), ("left", 1, 1.0)])
def test_task_only_on_gait_with_a_standing_start(side, seed, start_s):
    s = _session("gait", seed, side, standing_start_s=start_s)
    res = functional.task_calibration(*s["task"], fs_hz=FS_HZ)
    w = res.fit.window["thigh"]
    assert w.stop <= int(start_s * FS_HZ) + 20                   # the standing start, not a stance phase
    err = _angle_errors(s, res)
    # the simulated walker stands with 2° of flexion, which the calibration takes as straight (0°)
    truth_at_window = np.mean(s["truth"][w.start:w.stop, 0])
    assert abs(np.mean(err[:, 0]) + truth_at_window) < 2.0 * DEG
    assert abs(np.mean(err[:, 0])) < 4.0 * DEG and np.sqrt(np.mean(err[:, 1] ** 2)) < 3.0 * DEG
    assert res.fit.sign_margin_rad > 30 * DEG and res.warnings == ()


def test_task_only_refuses_gait_without_standing():
    s = _session("gait", 2, "right", standing_start_s=0.0)
    with pytest.raises(knee.CalibrationError, match="standing still"):
        functional.task_calibration(*s["task"], fs_hz=FS_HZ)


def test_task_only_warns_or_refuses_when_only_flexed_moments_are_still():
    """A step-up cut so that only the flexed rests are still (the still extension holds removed): gravity cannot
    tell this from a straight reference, but the task overshoots it, which warns or refuses."""
    s = _session("step_up", 0, "right")
    (at, gt), (as_, gs) = s["task"]
    keep = (s["truth"][:, 0] > 30 * DEG) | (np.abs(np.gradient(s["truth"][:, 0])) > 0.002)
    try:
        res = functional.task_calibration((at[keep], gt[keep]), (as_[keep], gs[keep]), fs_hz=FS_HZ)
    except knee.CalibrationError as exc:
        assert "never still while straight" in str(exc)
    else:
        (w,) = [w for w in res.warnings if w.code == "functional_overshoot"]
        assert w.params["overshoot_deg"] > 5.0


@pytest.mark.parametrize("side, height", [("right", 0.17), ("left", 0.34)])
def test_the_pipeline_sequence_with_a_real_filter(side, height):
    """As the pipeline would: calibrate, run the default 9D filter on bias-free gyroscopes, calibrate again with
    the filter's orientations; the knee angles from the *estimated* orientations match the truth."""
    from estimators import orientation

    s = _session("step_up", 3, side, height)   # a seed not used to choose the thresholds
    args = (*s["standing"], *s["task"])
    first = functional.standing_task_calibration(*args, fs_hz=FS_HZ)

    def run(recs, mags, cal):
        return {seg: orientation.estimate(a, g - cal.segments[seg].gyr_bias_rad_s, m, fs_hz=FS_HZ)
                for seg, (a, g), m in zip(("thigh", "shank"), recs, mags)}

    q_task, q_standing = run(s["task"], s["mag"], first), run(s["standing"], s["mag_standing"], first)
    cal = functional.standing_task_calibration(*args, fs_hz=FS_HZ, q_standing=q_standing, q_task=q_task)
    only = functional.task_calibration(*s["task"], fs_hz=FS_HZ, q_task=q_task)
    for res in (cal, only):
        q_f = knee.segment_orientation(q_task["thigh"], res.thigh.q_sensor_segment)
        q_t = knee.segment_orientation(q_task["shank"], res.shank.q_sensor_segment)
        err = knee.knee_angles(knee.q_femur_tibia(q_f, q_t), side) - s["truth"]
        rmse = np.sqrt(np.mean(err**2, axis=0))
        assert rmse[0] < 1.5 * DEG and rmse[1] < 3.0 * DEG and rmse[2] < 4.0 * DEG, np.rad2deg(rmse)


# ------------------------------------------------------------------------------------------ signs and input
def test_relative_sign_from_orientations_overrides_a_flipped_mounting():
    """Shank sensor worn the other way round about its long axis: the mounting prior is wrong, orientations fix it."""
    s = _session("step_up", 0, "right", misalignment_rad=0.0)
    flip = quat.from_axis_angle([0.0, 1.0, 0.0], np.pi)                # sensor turned 180° about the long axis
    (as_, gs) = s["task"][1]
    r = quat.to_matrix(quat.conjugate(flip))
    task_shank = (as_ @ r.T, gs @ r.T)
    q_task = dict(s["q_task"], shank=quat.multiply(s["q_task"]["shank"], flip))
    res = functional.task_calibration(s["task"][0], task_shank, fs_hz=FS_HZ, q_task=q_task)
    assert res.fit.axes.relative_sign_source == "orientation"
    q_true = quat.multiply(quat.conjugate(flip), s["q_true"][1])
    assert np.max(_axis_errors(res.shank, q_true)) < 6 * DEG


def test_bad_input_is_refused():
    s = _session("step_up", 0, "right")
    (at, gt), (as_, gs) = s["task"]
    with pytest.raises(ValueError, match="one time grid"):
        functional.task_calibration((at, gt), (as_[:-5], gs[:-5]), fs_hz=FS_HZ)
    with pytest.raises(ValueError, match=r"\(acc, gyr\)"):
        functional.task_calibration(at, (as_, gs), fs_hz=FS_HZ)
    with pytest.raises(knee.CalibrationError, match="lasts"):
        functional.task_calibration((at[:60], gt[:60]), (as_[:60], gs[:60]), fs_hz=FS_HZ)
    with pytest.raises(ValueError, match="window_s"):
        functional.FunctionalParams(window_s=0.0)


def test_standing_task_calibration_refuses_a_task_shorter_than_its_still_window():
    """A task shorter than ``window_s`` (0.3 s at 1000 Hz, slow enough to count as still) raised IndexError."""
    fs = 1000.0

    def rec(n, w=0.0, phase=0.0):
        t = np.arange(n) / fs
        g = np.zeros((n, 3))
        g[:, 2], g[:, 0] = w * np.sin(2 * np.pi * 3 * t + phase), 0.2 * w * np.sin(2 * np.pi * 5 * t)
        return np.tile([0.0, 9.81, 0.0], (n, 1)), g

    with pytest.raises(knee.CalibrationError, match="lasts 0.30 s, shorter than the 0.5 s still window"):
        functional.standing_task_calibration(rec(3000), rec(3000), rec(300, 0.03), rec(300, -0.02, 0.5), fs_hz=fs)


def test_the_stillness_thresholds_have_one_definition():
    for p in (knee.CalibrationParams(), functional.FunctionalParams()):
        assert (p.max_gyr_sd_rad_s, p.max_acc_sd_m_s2) == (knee.STILL_MAX_GYR_SD_RAD_S, knee.STILL_MAX_ACC_SD_M_S2)
