"""Accelerometer bias and gain from still poses (:mod:`estimators.accelerometer`), against the simulator's truth:
the bias and scale errors it put into the sensor (equation S4 of :mod:`estimators.simulation.imu`)."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators import simulation as sim
from estimators.accelerometer import MIN_POSES_SCALE, fit_still_poses, still_poses

BIAS = np.array([0.15, -0.22, 0.09])  # m/s², within the BMI160's ±40 mg zero-g offset


def _spec(scale=(0.0, 0.0, 0.0)):
    acc = sim.AccErrors(bias_m_s2=BIAS, scale_error=scale, cross_axis=np.zeros((3, 3)), bias_walk_m_s2_rts=0.0)
    return sim.ImuSpec(acc, sim.GyrErrors.noise_only(), sim.MagErrors.noise_only())


def _poses(trajectory, spec, seed=0):
    imu = sim.simulate(trajectory, spec, seed=seed).on_grid()
    return still_poses(imu.acc, imu.gyr, fs_hz=imu.fs_hz)


def _still(q, seconds=5.0):
    return sim.static_pose(seconds, q)


# the protocol's three poses: the figure-eight's rest (z up), standing (y up), supine (x up)
Z_UP = (1.0, 0.0, 0.0, 0.0)
Y_UP = tuple(quat.from_axis_angle([1.0, 0.0, 0.0], np.pi / 2))
X_UP = tuple(quat.from_axis_angle([0.0, 1.0, 0.0], -np.pi / 2))


def test_three_orthogonal_poses_recover_the_bias():
    spec = _spec()
    poses = [_poses(_still(q), spec, seed=i) for i, q in enumerate((Z_UP, Y_UP, X_UP))]
    assert [len(p) for p in poses] == [1, 1, 1]
    cal = fit_still_poses(poses)
    assert cal.model == "bias" and cal.note == ""
    assert np.linalg.norm(cal.bias_m_s2 - BIAS) < 0.01, cal.bias_m_s2
    assert cal.information > 0.9  # three orthogonal directions: 1 (eq. A4)
    corrected = cal.apply(np.vstack(poses))
    assert np.allclose(np.linalg.norm(corrected, axis=1), 9.81, atol=0.005)


def test_a_scale_error_folds_into_the_bias_along_each_pose():
    """With a scale error and only three poses the bias model absorbs s_j·g along each pose's axis: the documented
    limit (module docstring) that the gain model needs more poses."""
    scale = np.array([0.006, -0.004, 0.005])
    poses = [_poses(_still(q), _spec(scale), seed=i) for i, q in enumerate((Z_UP, Y_UP, X_UP))]
    cal = fit_still_poses(poses)
    assert cal.model == "bias"
    assert np.allclose(cal.bias_m_s2, BIAS + 9.81 * scale, atol=0.01), cal.bias_m_s2


def test_rests_in_many_orientations_recover_bias_and_gain():
    scale = np.array([0.006, -0.004, 0.005])
    poses = _poses(sim.rotations(90.0, rest_s=1.5, seed=2), _spec(scale), seed=3)
    assert len(poses) >= MIN_POSES_SCALE
    cal = fit_still_poses(poses)
    assert cal.model == "bias_scale", (cal.model, cal.information, len(poses))
    assert np.linalg.norm(cal.bias_m_s2 - BIAS) < 0.02, cal.bias_m_s2
    assert np.allclose(cal.gain, 1.0 / (1.0 + scale), atol=1e-3), cal.gain
    assert cal.residual_rms_m_s2 < 0.01


def test_standing_and_supine_alone_do_not_observe_the_bias():
    """Two postures span one plane (no figure-eight: factory-calibrated sensors): nothing is corrected, and why."""
    poses = [_poses(_still(q), _spec(), seed=i) for i, q in enumerate((Y_UP, X_UP))]
    cal = fit_still_poses(poses)
    assert (cal.model, cal.note) == ("none", "few_poses")
    acc = np.array([[0.1, 9.8, 0.2]])
    assert np.array_equal(cal.apply(acc), acc)
    assert fit_still_poses([]).note == "few_poses"


def test_the_figure_eights_motion_is_never_a_pose():
    """Only the rests before and after the figure count: its motion (~1.5 m/s² of hand acceleration) never does."""
    poses = _poses(sim.figure_eight(60.0, seed=1), _spec())
    assert len(poses) == 2
    assert np.all(np.abs(np.linalg.norm(poses - BIAS, axis=1) - 9.81) < 0.01)


def test_a_pose_that_moved_is_not_used_to_correct():
    poses = np.array([[0.0, 0.0, 9.81], [0.0, 9.81, 0.0], [9.81, 0.0, 0.0], [0.0, 0.0, -9.81], [0.0, -10.6, 0.0]])
    cal = fit_still_poses(poses)
    assert (cal.model, cal.note) == ("none", "poses_not_still")


def test_a_bias_beyond_any_mems_offset_is_not_applied():
    """Three orthogonal still poses that read as a 2 m/s² bias (|b| > MAX_BIAS_M_S2, some 20× the BMI160's zero-g
    offset): the poses say nothing is right, so nothing is corrected and the warning's cause is said."""
    b = np.array([1.2, -1.2, 1.0])
    poses = np.array([[0.0, 0.0, 9.81], [0.0, 9.81, 0.0], [9.81, 0.0, 0.0]]) + b
    cal = fit_still_poses(poses)
    assert (cal.model, cal.note) == ("none", "implausible_bias")


@pytest.mark.parametrize("shape", [(5, 2), (5,)])
def test_bad_shapes_are_refused(shape):
    with pytest.raises(ValueError, match="shape"):
        still_poses(np.zeros(shape), np.zeros(shape), fs_hz=100.0)


def _up(u):
    """The still pose whose gravity reading points along the sensor direction ``u`` (plus the bias)."""
    u = np.asarray(u, dtype=np.float64) / np.linalg.norm(u)
    axis = np.cross(u, [0.0, 0.0, 1.0])
    s = np.linalg.norm(axis)
    return Z_UP if s < 1e-12 else tuple(quat.from_axis_angle(axis / s, np.arctan2(s, u[2])))


@pytest.mark.parametrize("alpha_deg, corrected", [(40.0, False), (44.0, False), (47.0, True), (55.0, True)])
def test_the_third_directions_angle_rule_holds_and_copies_count_once(alpha_deg, corrected):
    """Eq. A4a: with two orthogonal directions a third one alpha out of their plane gives information 1 - cos alpha,
    so MIN_INFORMATION (0.3) asks for alpha >= 45.6°, whatever its azimuth.  Repeating every pose three times (the
    figure-eight's rests before and after, the same posture recorded twice) adds no direction: the decision and
    the information are those of one copy (it tripled the information before, passing 40°), and the bias is the
    simulator's when corrected."""
    a, az = np.deg2rad(alpha_deg), np.deg2rad(30.0)
    third = (np.sin(a), np.cos(a) * np.sin(az), np.cos(a) * np.cos(az))
    qs = (Z_UP, Y_UP, _up(third))
    once = fit_still_poses([_poses(_still(q), _spec(), seed=i) for i, q in enumerate(qs)])
    thrice = fit_still_poses([_poses(_still(q), _spec(), seed=10 * k + i) for k in range(3) for i, q in enumerate(qs)])
    assert once.information == pytest.approx(1.0 - np.cos(a), abs=0.015)  # the readings carry the 0.28 m/s² bias
    assert thrice.directions == once.directions == 3 and len(thrice.poses_m_s2) == 9
    assert thrice.information == pytest.approx(once.information, abs=0.005)
    for cal in (once, thrice):
        assert (cal.model == "bias") is corrected and cal.note == ("" if corrected else "few_poses")
        if corrected:
            assert np.linalg.norm(cal.bias_m_s2 - BIAS) < 0.01


def test_without_a_spare_direction_the_fit_is_applied_but_not_validated():
    """The protocol's poses (the figure-eight's two rests in one orientation, standing, supine) are three
    directions for three bias parameters: the fit passes through them exactly and nothing checks it (rms was NaN
    and ``NaN > MAX_RESIDUAL`` passed silently).  The result says "not validated"; a fourth direction validates."""
    protocol = [_poses(_still(q), _spec(), seed=i) for i, q in enumerate((Z_UP, Z_UP, Y_UP, X_UP))]
    cal = fit_still_poses(protocol)
    assert (cal.model, cal.directions, cal.validated) == ("bias", 3, False)
    assert cal.residual_rms_m_s2 < 0.01 and cal.to_dict()["validated"] is False  # the two rests agree, no more
    three = fit_still_poses(protocol[1:])
    assert (three.model, three.validated) == ("bias", False) and np.isnan(three.residual_rms_m_s2)
    assert np.linalg.norm(cal.bias_m_s2 - BIAS) < 0.01  # still the simulator's bias: the correction is applied
    fourth = fit_still_poses(protocol + [_poses(_still(_up((1.0, 1.0, -1.0))), _spec(), seed=9)])
    assert (fourth.model, fourth.directions, fourth.validated) == ("bias", 4, True)
    assert fourth.residual_rms_m_s2 < 0.01 and fourth.to_dict()["validated"] is True
    assert np.linalg.norm(fourth.bias_m_s2 - BIAS) < 0.01
    assert fit_still_poses([]).validated is False
