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


@pytest.mark.parametrize("shape", [(5, 2), (5,)])
def test_bad_shapes_are_refused(shape):
    with pytest.raises(ValueError, match="shape"):
        still_poses(np.zeros(shape), np.zeros(shape), fs_hz=100.0)
