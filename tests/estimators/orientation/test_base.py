"""Input validation and initial alignment shared by every orientation method."""

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.orientation.base import align, initial_orientation, validate_imu

G = 9.81
FIELD_ENU = np.array([0.0, 20.0, -40.0])


def sensor_readings(q_earth_sensor, n=10):
    acc = np.tile(quat.rotate(quat.conjugate(q_earth_sensor), [0.0, 0.0, G]), (n, 1))
    mag = np.tile(quat.rotate(quat.conjugate(q_earth_sensor), FIELD_ENU), (n, 1))
    return acc, np.zeros((n, 3)), mag


@pytest.mark.parametrize("seed", range(5))
def test_align_recovers_orientation(seed):
    q = quat.normalize(np.random.default_rng(seed).normal(size=4))
    acc, _, mag = sensor_readings(q, 1)
    assert quat.angle_between(align(acc[0], mag[0]), q) < 1e-9


def test_align_without_mag_fixes_inclination_only():
    q = quat.from_euler([1.0, 0.3, -0.4], "ZYX")
    acc, _, _ = sensor_readings(q, 1)
    q_est = align(acc[0])
    up_est = quat.rotate(q_est, acc[0] / G)
    np.testing.assert_allclose(up_est, [0, 0, 1], atol=1e-12)
    assert q_est[3] == pytest.approx(0.0, abs=1e-12)  # shortest arc: no twist about the vertical


def test_initial_orientation_skips_missing_rows():
    q = quat.from_euler([0.5, 0.1, 0.2], "ZYX")
    acc, gyr, mag = sensor_readings(q, 20)
    acc[:3] = np.nan
    data = validate_imu(acc, gyr, mag, fs_hz=100.0)
    assert quat.angle_between(initial_orientation(data, use_mag=True), q) < 1e-9


def test_nan_rows_are_flagged_and_zeroed():
    acc, gyr, mag = sensor_readings(quat.identity(), 6)
    acc[1, 0] = np.nan
    gyr[2, 1] = np.nan
    mag[3] = np.nan
    data = validate_imu(acc, gyr, mag, fs_hz=100.0)
    assert data.flags.acc_missing.tolist() == [False, True, False, False, False, False]
    assert data.flags.gyr_missing[2] and data.flags.mag_missing[3]
    assert not data.acc_ok[1] and not data.mag_ok[3]
    assert np.isfinite(data.acc).all() and np.isfinite(data.gyr).all() and np.isfinite(data.mag).all()
    assert data.flags.any.sum() == 3


def test_6d_input_is_9d_with_every_field_sample_missing():
    acc, gyr, mag = sensor_readings(quat.identity(), 5)
    data = validate_imu(acc, gyr, None, fs_hz=100.0)
    assert data.mag is None and not data.mag_ok.any() and not data.flags.mag_missing.any()
    assert data.mag_array.shape == (5, 3) and not data.mag_array.any()
    nine = validate_imu(acc, gyr, mag, fs_hz=100.0)
    assert nine.mag_array is nine.mag and nine.mag_ok.all()


def test_saturation_marks_acc_unusable_and_flags_gyr():
    acc, gyr, mag = sensor_readings(quat.identity(), 4)
    acc[1, 2] = 16 * G
    gyr[2, 0] = 34.9
    data = validate_imu(acc, gyr, mag, fs_hz=100.0, acc_range_m_s2=16 * G, gyr_range_rad_s=34.9)
    assert data.flags.acc_saturated.tolist() == [False, True, False, False]
    assert not data.acc_ok[1]
    assert data.flags.gyr_saturated.tolist() == [False, False, True, False]


def test_rows_without_a_direction_are_unusable_not_flagged():
    """A row whose squared norm underflows below the smallest normal float64 (1e-170 per axis: 3e-340) has no
    direction a kernel can divide by, in either stream: unusable, yet not missing (no flag, it is a number);
    1e-150 per axis (3e-300) still has one."""
    acc, gyr, mag = sensor_readings(quat.identity(), 5)
    acc[1] = 1e-170
    acc[2] = 1e-150
    mag[3] = 1e-170
    data = validate_imu(acc, gyr, mag, fs_hz=100.0)
    assert data.acc_ok.tolist() == [True, False, True, True, True]
    assert data.mag_ok.tolist() == [True, True, True, False, True]
    assert not data.flags.any.any()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(acc=np.zeros((5, 2)), gyr=np.zeros((5, 3))), r"acc must have shape \(N, 3\)"),
        (dict(acc=np.zeros((0, 3)), gyr=np.zeros((0, 3))), "acc is empty"),
        (dict(acc=np.ones((5, 3)), gyr=np.zeros((4, 3))), "same number of samples"),
        (dict(acc=np.ones((5, 3)), gyr=np.zeros((5, 3)), mag=np.ones((2, 3))), "time grid"),
        (dict(acc=np.full((5, 3), np.inf), gyr=np.zeros((5, 3))), "infinite value at sample 0"),
        (dict(acc=np.full((5, 3), np.nan), gyr=np.zeros((5, 3))), "no valid sample"),
        (dict(acc=[["a", "b", "c"]], gyr=np.zeros((1, 3))), "numeric"),
    ],
)
def test_bad_inputs_name_the_problem(kwargs, message):
    with pytest.raises(ValueError, match=message):
        validate_imu(fs_hz=100.0, **kwargs)


@pytest.mark.parametrize("fs", [0.0, -100.0, np.nan, np.inf, "fast"])
def test_bad_sampling_rate(fs):
    with pytest.raises(ValueError, match="fs_hz"):
        validate_imu(np.ones((3, 3)), np.zeros((3, 3)), fs_hz=fs)
