"""Madgwick (2011): kernel vs reference, oracle vs ahrs, convergence, tracking, validation, online form."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.orientation import make
from estimators.orientation.base import alignment_samples
from estimators.orientation.madgwick import Madgwick, MadgwickParams
from orientation_signals import FIELD_ENU_UT, FS_HZ, GRAVITY_ENU, Q_Z90, angle_deg, rotating_body


@pytest.mark.parametrize("use_mag", [False, True])
def test_kernel_matches_reference(use_mag):
    q, acc, gyr, mag, q_start = rotating_body(300, seed=1)
    acc[50] = np.nan            # missing accelerometer row: gyroscope only
    mag[120:125] = np.nan       # missing magnetometer rows: 6D objective
    gyr[200] = np.nan           # missing gyroscope row: zero rate
    m = Madgwick(MadgwickParams(beta_rad_s=0.2))
    q0 = quat.multiply(quat.from_axis_angle([1.0, 1.0, 0.0], 0.3), q_start)
    fast = m.estimate(acc, gyr, mag if use_mag else None, fs_hz=FS_HZ, q0=q0).orientation_
    slow = m.reference(acc, gyr, mag if use_mag else None, fs_hz=FS_HZ, q0=q0)
    assert np.abs(fast - slow).max() <= 1e-9
    np.testing.assert_allclose(np.linalg.norm(fast, axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize("use_mag", [False, True])
def test_equals_ahrs_madgwick_after_frame_change(use_mag):
    """ahrs works in NWU with the same q (sensor -> earth): q_ENU = q_z(90°) ⊗ q_NWU."""
    ahrs_filters = pytest.importorskip("ahrs.filters")
    q, acc, gyr, mag, q_start = rotating_body(400, seed=2)
    beta = 0.15
    q0 = quat.normalize(quat.multiply(quat.from_axis_angle([0.3, -1.0, 0.2], 0.25), q_start))
    # the published configuration: no warm-up, the raw accelerometer (acc_lowpass_s=0)
    ours = Madgwick(MadgwickParams(beta_rad_s=beta, warmup_s=0.0, acc_lowpass_s=0.0)).estimate(
        acc, gyr, mag if use_mag else None, fs_hz=FS_HZ, q0=q0).orientation_

    oracle = ahrs_filters.Madgwick(gain=beta, Dt=1.0 / FS_HZ)
    q_nwu = quat.multiply(quat.conjugate(Q_Z90), q0)
    theirs = np.empty_like(ours)
    for k in range(len(acc)):  # every gyro sample is non-zero, so ahrs never skips its correction
        if use_mag:
            q_nwu = oracle.updateMARG(q_nwu, gyr[k], acc[k], mag[k])
        else:
            q_nwu = oracle.updateIMU(q_nwu, gyr[k], acc[k])
        theirs[k] = q_nwu
    theirs = quat.multiply(Q_Z90, theirs)
    assert np.abs(quat.positive_scalar(ours) - quat.positive_scalar(theirs)).max() <= 1e-12  # issue: <= 1e-6


def test_published_filter_converges_at_its_rate_limit():
    """Without warm-up (the paper's filter) the estimate turns at most 2β rad/s: 10° takes about 1 s."""
    q, acc, gyr, mag, q_start = rotating_body(int(3.0 * FS_HZ), seed=3, still=True)
    wrong = quat.multiply(quat.from_axis_angle([1.0, -0.5, 0.3], np.radians(10.0)), q_start)
    est = Madgwick(MadgwickParams(beta_rad_s=0.1, warmup_s=0.0)).estimate(acc, gyr, mag, fs_hz=FS_HZ, q0=wrong).orientation_
    err = angle_deg(est, q)
    rate_deg_s = np.degrees(2.0 * 0.1)
    assert err[int(0.5 * FS_HZ)] > 10.0 - rate_deg_s * 0.5 - 0.5  # no faster than the rate limit
    assert err[int(3.0 * FS_HZ) - 1] < 2.0


def test_heading_follows_the_enu_north():
    """At rest with the field's horizontal part on sensor +x, the sensor x axis must point north (+y)."""
    n = 300
    q_true = quat.from_axis_angle([0.0, 0.0, 1.0], np.pi / 2)  # sensor x -> earth y (north)
    acc = np.tile(quat.rotate(quat.conjugate(q_true), GRAVITY_ENU), (n, 1))
    mag = np.tile(quat.rotate(quat.conjugate(q_true), FIELD_ENU_UT), (n, 1))
    gyr = np.full((n, 3), 1e-4)
    start = quat.from_axis_angle([0.0, 0.0, 1.0], np.pi / 2 + 0.3)
    est = Madgwick(MadgwickParams(beta_rad_s=0.3)).estimate(acc, gyr, mag, fs_hz=FS_HZ, q0=start).orientation_
    assert angle_deg(est[-1], q_true) < 0.5


def test_two_half_batches_equal_one_batch():
    q, acc, gyr, mag, q_start = rotating_body(300, seed=4)
    m = Madgwick(MadgwickParams(beta_rad_s=0.1))
    full = m.estimate(acc, gyr, mag, fs_hz=FS_HZ, q0=q_start)
    w = alignment_samples(FS_HZ)  # q0 gives the attitude; the stage still reads the window estimate reads
    state = m.initial_state(acc[:w], mag[:w], gyr=gyr[:w], fs_hz=FS_HZ, q0=q_start)
    # split inside the 1 s warm-up: the elapsed time travels in the state
    first, state = m.update(state, acc[:50], gyr[:50], mag[:50], fs_hz=FS_HZ)
    assert state[4] == pytest.approx(0.5)
    second, state = m.update(state, acc[50:], gyr[50:], mag[50:], fs_hz=FS_HZ)
    np.testing.assert_array_equal(np.vstack([first, second]), full.orientation_)
    np.testing.assert_array_equal(state, full.state_)


def test_registry_and_estimate_contract():
    _, acc, gyr, mag, _ = rotating_body(50, seed=5)
    m = make("madgwick", beta_rad_s=0.05)
    assert isinstance(m, Madgwick) and m.params.beta_rad_s == 0.05
    out = m.estimate(acc, gyr, mag, fs_hz=FS_HZ).orientation_
    assert out.shape == (50, 4) and np.isfinite(out).all()


@pytest.mark.parametrize("name", ["beta_rad_s", "warmup_s", "beta_warmup_rad_s"])
@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf"), "0.1", True])
def test_parameter_validation(name, bad):
    with pytest.raises(ValueError, match=name):
        MadgwickParams(**{name: bad})


