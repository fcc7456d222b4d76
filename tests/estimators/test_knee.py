"""Knee kinematics and sensor-to-segment calibration against the simulator's truth."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import knee
from estimators import quaternion as quat
from estimators import simulation as sim

DEG = np.pi / 180.0
FS_HZ = 100.0


def _codes(warnings) -> list[str]:
    return [w.code for w in warnings]


def _calibrate(side: str, segment: str, mount, spec, seed: int = 0, **kwargs) -> knee.SegmentCalibration:
    st = getattr(sim.standing(8.0, side, facing_rad=0.7), segment)
    su = getattr(sim.supine(8.0, side, head_rad=-1.2), segment)
    gs = sim.simulate_on_grid(st, spec, q_segment_sensor=mount, seed=seed)
    gu = sim.simulate_on_grid(su, spec, q_segment_sensor=mount, seed=seed + 1)
    return knee.calibrate_segment(gs.acc, gs.gyr, gu.acc, gu.gyr, fs_hz=gs.fs_hz, label=segment, **kwargs)


def _static(direction, n: int = 1000, seed: int = 0, acc_sd: float = 0.02, gyr_sd: float = 0.007):
    rng = np.random.default_rng(seed)
    d = np.asarray(direction, dtype=float)
    acc = 9.81 * d / np.linalg.norm(d) + rng.normal(0.0, acc_sd, (n, 3))
    return acc, rng.normal(0.0, gyr_sd, (n, 3))


# ------------------------------------------------------------------------------------------ angle convention
@pytest.mark.parametrize("side", ["right", "left"])
def test_clinical_signs_of_k1(side):
    s = knee.side_sign(side)
    # flexion: the distal tibia (−y) swings posteriorly (−x)
    d = quat.rotate(knee.knee_quaternion([0.5, 0.0, 0.0], side), [0.0, -1.0, 0.0])
    assert d[0] < -0.4
    # adduction (varus): the distal tibia moves medially, i.e. −z on the right leg and +z on the left
    d = quat.rotate(knee.knee_quaternion([0.0, 0.2, 0.0], side), [0.0, -1.0, 0.0])
    assert np.sign(d[2]) == -s
    # internal rotation: the tibia's anterior axis turns medially
    a = quat.rotate(knee.knee_quaternion([0.0, 0.0, 0.3], side), [1.0, 0.0, 0.0])
    assert np.sign(a[2]) == -s


@pytest.mark.parametrize("side", ["right", "left"])
def test_knee_angles_invert_k1_and_agree_with_intrinsic_zxy(side):
    rng = np.random.default_rng(1)
    ang = np.column_stack([rng.uniform(-0.3, 2.3, 200), rng.uniform(-0.5, 0.5, 200), rng.uniform(-1.0, 1.0, 200)])
    q = knee.knee_quaternion(ang, side)
    np.testing.assert_allclose(knee.knee_angles(q, side), ang, atol=1e-10)
    np.testing.assert_allclose(knee.knee_angles(-q, side), ang, atol=1e-10)  # sign of q is irrelevant
    e = quat.to_euler(q, "ZXY")
    s = knee.side_sign(side)
    np.testing.assert_allclose(knee.knee_angles(q, side), np.column_stack([-e[:, 0], s * e[:, 1], s * e[:, 2]]),
                               atol=1e-10)


def test_simulator_uses_the_same_definition():
    assert sim.knee_angles is knee.knee_angles
    assert sim.knee_quaternion is knee.knee_quaternion


def test_thesis_zyx_option():
    q = knee.knee_quaternion([[0.03, 0.02, -0.04], [1.0, 0.05, 0.1]], "left")
    raw = quat.euler_zyx_thesis(q)
    th = knee.knee_angles(q, "left", method="thesis_zyx")
    np.testing.assert_allclose(th, np.column_stack([raw[:, 0], raw[:, 2], raw[:, 1]]))  # left: s = −1
    gs = knee.knee_angles(q, "left")
    np.testing.assert_allclose(th[0], gs[0], atol=2e-3)  # first order: the same angles
    assert abs(th[1, 0] - gs[1, 0]) < 0.01 and abs(th[1, 2] - gs[1, 2]) > 0.05  # large flexion: crosstalk
    with pytest.raises(ValueError, match="method"):
        knee.knee_angles(q, "left", method="xyz")
    with pytest.raises(ValueError, match="side"):
        knee.knee_angles(q, "up")


# ------------------------------------------------------------------------------------------ calibration
@pytest.mark.parametrize("side", ["right", "left"])
@pytest.mark.parametrize("seed", [0, 1])
def test_calibration_recovers_the_mounting(side, seed):
    mount = sim.random_rotation(15 * DEG, seed=seed)  # the simulator's q_segment_sensor = our inverse
    cal = _calibrate(side, "thigh", mount, sim.ImuSpec.noise_only(), seed)
    assert quat.angle_between(cal.q_sensor_segment, quat.conjugate(mount)) < 0.05 * DEG
    assert abs(cal.angle_between_postures_rad - np.pi / 2) < 0.5 * DEG
    assert cal.warnings == ()
    assert cal.standing.still and cal.supine.still and cal.standing.duration_s == 5.0
    # the full MetaMotionR error model (acc bias, scale, cross-axis): within ~1°
    cal = _calibrate(side, "shank", mount, sim.ImuSpec(), seed)
    assert quat.angle_between(cal.q_sensor_segment, quat.conjugate(mount)) < 1.5 * DEG


def test_calibrated_axes_follow_the_seed_construction():
    acc_st, gyr_st = _static([0.1, 1.0, 0.05])
    acc_su, gyr_su = _static([1.0, -0.1, 0.2], seed=1)
    cal = knee.calibrate_segment(acc_st, gyr_st, acc_su, gyr_su, fs_hz=FS_HZ)
    r = quat.to_matrix(cal.q_sensor_segment)
    y = acc_st[:500].mean(axis=0)  # any still window: the means agree within noise
    np.testing.assert_allclose(r[:, 1], y / np.linalg.norm(y), atol=2e-3)  # eq. 8.1: y = g_standing
    a = acc_su.mean(axis=0)
    a /= np.linalg.norm(a)
    x_seed = np.cross(r[:, 1], a)  # eq. 8.3: X = Y × Z_aux is −z in ISB names
    np.testing.assert_allclose(-x_seed / np.linalg.norm(x_seed), r[:, 2], atol=2e-3)
    assert np.dot(r[:, 0], a) > 0.98  # x anterior ≈ supine gravity


@pytest.mark.parametrize("angle_deg, distinct", [(40.0, False), (135.0, False), (70.0, True), (110.0, True)])
def test_postures_not_distinct_warn(angle_deg, distinct):
    acc_st, gyr_st = _static([0.0, 1.0, 0.0])
    a = np.deg2rad(angle_deg)
    acc_su, gyr_su = _static([np.sin(a), np.cos(a), 0.0], seed=1)
    cal = knee.calibrate_segment(acc_st, gyr_st, acc_su, gyr_su, fs_hz=FS_HZ, label="thigh")
    assert abs(np.rad2deg(cal.angle_between_postures_rad) - angle_deg) < 0.5
    assert ("postures_not_distinct" in _codes(cal.warnings)) is not distinct
    if not distinct:
        assert "thigh" in cal.warnings[0].message
        p = cal.warnings[0].params
        assert p["segment"] == "thigh" and p["angle_deg"] == pytest.approx(angle_deg, abs=0.5)
        assert (p["min_deg"], p["max_deg"]) == pytest.approx((np.rad2deg(knee.CalibrationParams().min_angle_rad),
                                                              np.rad2deg(knee.CalibrationParams().max_angle_rad)))
        assert f"{p['angle_deg']:.0f}°" in cal.warnings[0].message
    acc_su, gyr_su = _static([np.sin(0.05), np.cos(0.05), 0.0], seed=1)  # ~3°: no anterior axis at all
    with pytest.raises(knee.CalibrationError, match="undefined"):
        knee.calibrate_segment(acc_st, gyr_st, acc_su, gyr_su, fs_hz=FS_HZ)


def test_stillest_window_is_found_and_not_still_warns():
    acc_st, gyr_st = _static([0.0, 1.0, 0.0], n=3000)
    acc_su, gyr_su = _static([1.0, 0.0, 0.0], n=3000, seed=1)
    t = np.arange(3000) / FS_HZ
    wobble = (t < 12.0)[:, None] * np.sin(2 * np.pi * 1.5 * t)[:, None] * np.array([0.4, 0.1, -0.3])
    cal = knee.calibrate_segment(acc_st + 2.0 * wobble, gyr_st + wobble, acc_su, gyr_su, fs_hz=FS_HZ)
    assert cal.standing.start_s >= 12.0 and cal.standing.still
    assert "posture_not_still" not in _codes(cal.warnings)
    assert quat.angle_between(cal.q_sensor_segment, quat.identity()) < 0.2 * DEG
    # moving all the time: warned, still computed
    wobble_all = np.sin(2 * np.pi * 1.5 * t)[:, None] * np.array([0.4, 0.1, -0.3])
    cal = knee.calibrate_segment(acc_st + 2.0 * wobble_all, gyr_st + wobble_all, acc_su, gyr_su, fs_hz=FS_HZ,
                                 label="shank")
    assert _codes(cal.warnings) == ["posture_not_still"] and not cal.standing.still
    assert "shank" in cal.warnings[0].message and "standing" in cal.warnings[0].message
    p = cal.warnings[0].params
    assert (p["segment"], p["posture"], p["still_s"]) == ("shank", "standing", cal.standing.duration_s)
    assert p["gyr_sd_deg_s"] == pytest.approx(np.rad2deg(cal.standing.gyr_sd_rad_s))
    assert p["acc_sd_m_s2"] == cal.standing.acc_sd_m_s2


def test_missing_rows_short_recordings_and_wrong_units():
    acc_st, gyr_st = _static([0.0, 1.0, 0.0], n=1500)
    acc_su, gyr_su = _static([1.0, 0.0, 0.0], n=1500, seed=1)
    acc_st[300:1400:100] = np.nan  # only [1400, 1500) and the first 300 samples are free of NaN rows
    cal = knee.calibrate_segment(acc_st, gyr_st, acc_su, gyr_su, fs_hz=FS_HZ, params=knee.CalibrationParams(
        window_s=2.0))
    assert cal.standing.stop <= 300 or cal.standing.start >= 1301
    assert np.all(np.isfinite(cal.q_sensor_segment))
    with pytest.raises(knee.CalibrationError, match="missing"):
        knee.calibrate_segment(acc_st, gyr_st, acc_su, gyr_su, fs_hz=FS_HZ)
    with pytest.raises(knee.CalibrationError, match="no finite"):
        knee.calibrate_segment(acc_st * np.nan, gyr_st, acc_su, gyr_su, fs_hz=FS_HZ)
    cal = knee.calibrate_segment(acc_su[:200] / 9.81, gyr_su[:200], acc_st[:200], gyr_st[:200], fs_hz=FS_HZ)
    assert set(_codes(cal.warnings)) == {"gravity_magnitude", "posture_too_short"}
    short = next(w for w in cal.warnings if w.code == "posture_too_short")
    assert dict(short.params) == {"segment": "sensor", "posture": "standing", "duration_s": 200 / FS_HZ,
                                  "window_s": 5.0}
    g = next(w for w in cal.warnings if w.code == "gravity_magnitude").params
    assert g["g_m_s2"] == pytest.approx(1.0, abs=0.05) and g["gravity_m_s2"] == knee.CalibrationParams().gravity_m_s2
    with pytest.raises(ValueError, match="shape"):
        knee.calibrate_segment(acc_st[:, :2], gyr_st, acc_su, gyr_su, fs_hz=FS_HZ)


def test_params_validation():
    with pytest.raises(ValueError, match="window_s"):
        knee.CalibrationParams(window_s=0.0)
    with pytest.raises(ValueError, match="min_angle_rad"):
        knee.CalibrationParams(min_angle_rad=2.0)


def test_upside_down_sensor_warns():
    ok = _calibrate("right", "thigh", sim.random_rotation(15 * DEG, seed=2), sim.ImuSpec.noise_only())
    assert knee.mounting_warnings(ok, label="thigh") == []
    flipped = quat.multiply(sim.random_rotation(15 * DEG, seed=2), quat.from_axis_angle([0, 0, 1], np.pi))
    bad = _calibrate("right", "thigh", flipped, sim.ImuSpec.noise_only())
    assert bad.warnings == ()  # the calibration itself is fine
    assert quat.angle_between(bad.q_sensor_segment, quat.conjugate(flipped)) < 0.05 * DEG
    (w,) = knee.mounting_warnings(bad, label="thigh")
    assert w.code == "sensor_upside_down" and w.params["angle_deg"] > 150.0
    assert (w.params["segment"], w.params["axis"]) == ("thigh", "0, 1, 0") and "[0, 1, 0]" in w.message


# ------------------------------------------------------------------------------------------ knee angles
def _session(side: str, spec, seed: int = 0, step_height_m: float = 0.17):
    """Calibrate both sensors on the simulated postures, then segment orientations from the TRUE sensor
    orientations of a step-up composed with the calibration."""
    leg = sim.step_up(2, step_height_m, side, seed=seed, facing_rad=0.4)
    seg = {}
    for k, name in enumerate(("thigh", "shank")):
        mount = sim.random_rotation(15 * DEG, seed=10 * seed + k)
        cal = _calibrate(side, name, mount, spec, seed)
        g = sim.simulate_on_grid(getattr(leg, name), sim.ImuSpec.perfect(), q_segment_sensor=mount)
        seg[name] = knee.segment_orientation(g.q_earth_sensor, cal.q_sensor_segment)
        t_true = g.t_true_s
    # the truth: the angles the simulator generated the motion from (not recomputed by knee.knee_angles)
    truth = np.column_stack([np.interp(t_true, leg.t_s, leg.knee_angles_rad[:, i]) for i in range(3)])
    return leg, seg["thigh"], seg["shank"], truth


@pytest.mark.parametrize("side, height", [("right", 0.17), ("left", 0.34)])
def test_knee_angles_match_the_truth(side, height):
    leg, q_f, q_t, truth = _session(side, sim.ImuSpec.noise_only(), step_height_m=height)
    ang = knee.knee_angles(knee.q_femur_tibia(q_f, q_t), side)
    assert np.max(np.abs(ang - truth)) < 0.5 * DEG
    assert np.max(truth[:, 0]) > 60 * DEG  # a real step-up, not a trivial motion
    assert knee.task_warnings(ang) == []
    # full error model of the postures (acc bias/scale): flexion still ~exact, the others within 2°
    leg, q_f, q_t, truth = _session(side, sim.ImuSpec(), seed=1, step_height_m=height)
    err = np.abs(knee.knee_angles(knee.q_femur_tibia(q_f, q_t), side) - truth)
    assert np.max(err[:, 0]) < 0.5 * DEG and np.max(err) < 2.0 * DEG


def test_left_leg_mirror():
    leg_r, qf_r, qt_r, truth_r = _session("right", sim.ImuSpec.noise_only())
    leg_l, qf_l, qt_l, truth_l = _session("left", sim.ImuSpec.noise_only())
    np.testing.assert_allclose(truth_l, truth_r)  # the same clinical motion on both legs
    ang_l = knee.knee_angles(knee.q_femur_tibia(qf_l, qt_l), "left")
    np.testing.assert_allclose(ang_l, truth_l, atol=0.5 * DEG)
    # read with the wrong side, adduction and rotation change sign
    wrong = knee.knee_angles(knee.q_femur_tibia(qf_l, qt_l), "right")
    np.testing.assert_allclose(wrong * [1, -1, -1], truth_l, atol=0.5 * DEG)


def test_swapped_sensors_warn():
    _, q_f, q_t, _ = _session("right", sim.ImuSpec.noise_only())
    swapped = knee.knee_angles(knee.q_femur_tibia(q_t, q_f), "right")
    (w,) = knee.task_warnings(swapped)
    assert w.code == "flexion_negative" and w.params["min_deg"] == pytest.approx(-15.0)
    assert w.params["pct"] > 20.0 and w.params["median_deg"] == pytest.approx(np.rad2deg(np.median(swapped[:, 0])))


# ------------------------------------------------------------------------------------------ heading
def test_heading_offset_from_standing_recovers_the_offset():
    side = "left"
    st = sim.standing(5.0, side, facing_rad=2.0)
    seg = {}
    for k, name in enumerate(("thigh", "shank")):
        mount = sim.random_rotation(15 * DEG, seed=k)
        cal = _calibrate(side, name, mount, sim.ImuSpec.noise_only())
        g = sim.simulate_on_grid(getattr(st, name), sim.ImuSpec.perfect(), q_segment_sensor=mount)
        seg[name] = knee.segment_orientation(g.q_earth_sensor, cal.q_sensor_segment)
    # 6D: the shank filter's earth frame is turned by 25° about the vertical
    q_t6 = knee.apply_heading_offset(seg["shank"], -25 * DEG)
    h = knee.heading_offset(seg["thigh"], q_t6)
    assert abs(h.offset_rad - 25 * DEG) < 0.05 * DEG and h.residual_rad < 0.1 * DEG and h.warnings == ()
    ang = knee.knee_angles(knee.q_femur_tibia(seg["thigh"], q_t6, h.offset_rad), side)
    assert np.max(np.abs(ang)) < 0.1 * DEG
    # 9D: both share north, so a 25° offset in the standing posture is a magnetic problem
    mismatch = knee.heading_offset(seg["thigh"], q_t6, max_offset_rad=10 * DEG).warnings
    assert _codes(mismatch) == ["heading_mismatch"] and mismatch[0].params["angle_deg"] == pytest.approx(25.0, abs=0.05)
    # a heading that drifts between the sensors
    drift = knee.apply_heading_offset(seg["shank"], 0.0)
    drift = quat.multiply(quat.from_axis_angle([0, 0, 1], np.linspace(0, 30 * DEG, len(drift))), drift)
    assert "heading_drift" in _codes(knee.heading_offset(seg["thigh"], drift).warnings)


def test_heading_offset_during_the_task():
    _, q_f, q_t, truth = _session("right", sim.ImuSpec.noise_only())
    q_t6 = knee.apply_heading_offset(q_t, -10 * DEG)
    hinge = knee.heading_offset(q_f, q_t6, method="hinge")  # biased by the true adduction/rotation
    assert abs(hinge.offset_rad - 10 * DEG) < 4 * DEG
    ext = truth[:, 0] < 3.5 * DEG  # the full-extension holds
    h = knee.heading_offset(q_f[ext], q_t6[ext])
    assert abs(h.offset_rad - 10 * DEG) < 2.5 * DEG
    bent = knee.heading_offset(q_f, q_t6)  # the straight-knee assumption over the whole task: flagged
    assert "heading_residual" in _codes(bent.warnings)
    with pytest.raises(ValueError, match="method"):
        knee.heading_offset(q_f, q_t6, method="magic")


def test_gyroscope_bias_measured_on_the_still_postures():
    """The postures' still windows measure the gyroscope bias the pipeline removes before filtering."""
    from estimators import simulation as sim

    spec = sim.ImuSpec.random(11)
    mount = sim.random_rotation(np.deg2rad(15.0), 11)
    grids = [sim.simulate_on_grid(sim.standing(30.0).thigh if k == 0 else sim.supine(30.0).thigh,
                                  spec, fs_hz=100.0, q_segment_sensor=mount, seed=k) for k in range(2)]
    cal = knee.calibrate_segment(grids[0].acc, grids[0].gyr, grids[1].acc, grids[1].gyr, fs_hz=100.0)
    true_bias = grids[0].gyr_bias_rad_s.mean(axis=0)
    assert np.linalg.norm(true_bias) > np.deg2rad(0.5)  # a realistic, noticeable bias
    np.testing.assert_allclose(cal.gyr_bias_rad_s, true_bias, atol=np.deg2rad(0.1))


# ------------------------------------------------------------------------------------------ functional calibration
@pytest.mark.parametrize("side", ["right", "left"])
def test_functional_calibration_uses_the_true_flexion_axis(side):
    """A lying posture rolled 12° outwards turns the static frame about y; given the femur's true z (in sensor
    coordinates, either sign) the functional frame is the true one again."""
    mount = sim.random_rotation(15 * DEG, seed=5)
    spec = sim.ImuSpec.noise_only()
    st = sim.standing(8.0, side).thigh
    su = sim.supine(8.0, side, roll_out_rad=12 * DEG).thigh
    gs = sim.simulate_on_grid(st, spec, q_segment_sensor=mount, seed=1)
    gu = sim.simulate_on_grid(su, spec, q_segment_sensor=mount, seed=2)
    cal = knee.calibrate_segment(gs.acc, gs.gyr, gu.acc, gu.gyr, fs_hz=gs.fs_hz, label="thigh")
    truth = quat.conjugate(mount)  # q_sensor_segment
    assert quat.angle_between(cal.q_sensor_segment, truth) > 11 * DEG
    z_sensor = quat.rotate(truth, [0.0, 0.0, 1.0])
    for sign in (1.0, -1.0):
        fc = knee.functional_calibration(cal, sign * 3.0 * z_sensor, label="thigh")
        assert quat.angle_between(fc.q_sensor_segment, truth) < 0.1 * DEG
        assert fc.method == "functional" and abs(fc.axis_change_rad - 12 * DEG) < 0.3 * DEG
        assert fc.warnings == cal.warnings  # 12° is within the 25° warning limit
    far = knee.functional_calibration(cal, z_sensor, max_change_rad=5 * DEG)
    assert _codes(far.warnings)[-1] == "functional_axis_far"
    assert dict(far.warnings[-1].params) == pytest.approx({"segment": "sensor", "angle_deg": np.rad2deg(
        far.axis_change_rad), "max_deg": 5.0})


def test_functional_calibration_refuses_a_long_axis_and_bad_input():
    acc, gyr = _static([0.0, 1.0, 0.0])
    acc2, gyr2 = _static([1.0, 0.0, 0.0], seed=1)
    cal = knee.calibrate_segment(acc, gyr, acc2, gyr2, fs_hz=FS_HZ)
    with pytest.raises(knee.CalibrationError, match="within 30° of the segment's long axis"):
        knee.functional_calibration(cal, [0.1, 1.0, 0.0])
    with pytest.raises(knee.CalibrationError, match="finite non-zero"):
        knee.functional_calibration(cal, [np.nan, 0.0, 1.0])


def test_turn_about_long_axis_turns_the_standing_heading():
    acc, gyr = _static([0.0, 1.0, 0.0])
    acc2, gyr2 = _static([1.0, 0.0, 0.0], seed=1)
    cal = knee.calibrate_segment(acc, gyr, acc2, gyr2, fs_hz=FS_HZ)
    turned = knee.turn_about_long_axis(cal, 0.3)
    q_earth_sensor = quat.from_axis_angle([1.0, 0.0, 0.0], 0.4)  # any sensor orientation while standing
    before = knee.segment_orientation(q_earth_sensor, cal.q_sensor_segment)
    after = knee.segment_orientation(q_earth_sensor, turned.q_sensor_segment)
    # the long axis keeps its direction; the segment turned by 0.3 rad about it
    assert np.allclose(quat.rotate(after, [0, 1, 0]), quat.rotate(before, [0, 1, 0]), atol=1e-12)
    assert abs(quat.angle_between(before, after) - 0.3) < 1e-9
    assert np.allclose(knee.turn_about_long_axis(turned, -0.3).q_sensor_segment * np.sign(
        knee.turn_about_long_axis(turned, -0.3).q_sensor_segment[0]), cal.q_sensor_segment * np.sign(
        cal.q_sensor_segment[0]), atol=1e-12)
