"""Valenti et al. (2015) complementary filter: kernel vs reference, ahrs AQUA, ENU heading, gains, bias."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.orientation import make
from estimators.orientation.base import alignment_samples, validate_imu
from estimators.orientation.valenti_cf import (
    TAU_DEFAULT_S,
    ValentiCF,
    ValentiCFParams,
    _delta_mag,
    per_sample_gain,
)
from orientation_signals import (
    FIELD_ENU_UT, FS_HZ, GRAVITY_ENU, GYR_BIAS, Q_Z90, angle_deg, rotating_body, tilt_deg,
)


@pytest.mark.parametrize("use_mag", [False, True])
@pytest.mark.parametrize("kwargs", [{}, {"adaptive_gain": False, "lerp_threshold": 0.999},
                                    {"estimate_bias": True, "warmup_s": 0.0}])
def test_kernel_matches_reference(use_mag, kwargs):
    q, acc, gyr, mag, q_start = rotating_body(300, seed=1)
    acc[60:90] *= 1.15          # accelerating: the adaptive gain ramps down
    acc[90:100] *= 1.4          # beyond the second threshold: no tilt correction
    acc[50] = np.nan            # missing accelerometer row
    mag[120:125] = np.nan       # missing magnetometer rows
    gyr[200] = np.nan           # missing gyroscope row
    m = ValentiCF(ValentiCFParams(**kwargs))
    q0 = quat.multiply(quat.from_axis_angle([1.0, 1.0, 0.3], 1.2), q_start)  # 69° off: SLERP at first
    fast = m.estimate(acc, gyr, mag if use_mag else None, fs_hz=FS_HZ, q0=q0)
    slow = m.reference(acc, gyr, mag if use_mag else None, fs_hz=FS_HZ, q0=q0)
    assert np.abs(fast.orientation_ - slow).max() <= 1e-9
    np.testing.assert_allclose(np.linalg.norm(fast.orientation_, axis=1), 1.0, atol=1e-12)


def test_reference_state_matches_kernel_state():
    _, acc, gyr, mag, q_start = rotating_body(200, seed=7, still=True, gyr_noise=0.001)
    m = ValentiCF(ValentiCFParams(estimate_bias=True))
    w = alignment_samples(FS_HZ)  # q0 gives the attitude; the stage still reads the window estimate reads
    state0 = m.initial_state(acc[:w], mag[:w], gyr=gyr[:w], fs_hz=FS_HZ, q0=q_start)
    _, s_fast = m.update(state0, acc, gyr, mag, fs_hz=FS_HZ)
    _, s_slow = m._filter(validate_imu(acc, gyr, mag, fs_hz=FS_HZ), state0, reference=True)
    assert np.abs(s_fast[4:7]).max() > 1e-3  # the bias estimate really moved
    np.testing.assert_allclose(s_fast, s_slow, atol=1e-12, rtol=0)


@pytest.mark.parametrize("use_mag", [False, True])
def test_equals_ahrs_aqua_after_frame_change(use_mag):
    """AQUA estimates the conjugate quaternion in NWU: q_ENU,s = q_z(90°) ⊗ conj(q_AQUA)."""
    ahrs_filters = pytest.importorskip("ahrs.filters")
    q, acc, gyr, mag, q_start = rotating_body(400, seed=2)
    # the published configuration: the paper's gains, no adaptive gain, no warm-up, the raw accelerometer
    params = ValentiCFParams(tau_acc_s=TAU_DEFAULT_S, tau_mag_s=TAU_DEFAULT_S, adaptive_gain=False, warmup_s=0.0,
                             acc_lowpass_s=0.0)
    q0 = quat.multiply(quat.from_axis_angle([0.3, -1.0, 0.2], 0.9), q_start)  # SLERP branch at first
    ours = ValentiCF(params).estimate(acc, gyr, mag if use_mag else None, fs_hz=FS_HZ, q0=q0).orientation_
    alpha = per_sample_gain(params.tau_acc_s, 1.0 / FS_HZ)
    assert alpha == pytest.approx(0.01, abs=1e-15)
    oracle = ahrs_filters.AQUA(alpha=alpha, beta=alpha, threshold=0.9, adaptive=False, Dt=1.0 / FS_HZ)
    q_aqua = quat.conjugate(quat.multiply(quat.conjugate(Q_Z90), q0))
    theirs = np.empty_like(ours)
    for k in range(len(acc)):  # gyro never exactly zero, field in the northern half-plane
        if use_mag:
            q_aqua = oracle.updateMARG(q_aqua, gyr[k], acc[k], mag[k])
        else:
            q_aqua = oracle.updateIMU(q_aqua, gyr[k], acc[k])
        theirs[k] = q_aqua
    theirs = quat.multiply(Q_Z90, quat.conjugate(theirs))
    assert np.abs(quat.positive_scalar(ours) - quat.positive_scalar(theirs)).max() <= 1e-9


def test_published_filter_converges_with_its_time_constant():
    """Without warm-up the error decays as exp(-t/τ): after τ about 37 % of a 10° tilt error is left."""
    q, acc, gyr, mag, q_start = rotating_body(int(3.0 * FS_HZ), seed=3, still=True, noise=False)
    wrong = quat.multiply(quat.from_axis_angle([1.0, 0.0, 0.0], np.radians(10.0)), q_start)
    published = ValentiCFParams(tau_acc_s=TAU_DEFAULT_S, tau_mag_s=TAU_DEFAULT_S, warmup_s=0.0)
    est = ValentiCF(published).estimate(acc, gyr, None, fs_hz=FS_HZ, q0=wrong).orientation_
    k_tau = int(round(TAU_DEFAULT_S * FS_HZ)) - 1
    assert tilt_deg(est[k_tau], q[k_tau]) == pytest.approx(10.0 * math.exp(-1.0), rel=0.02)


@pytest.mark.parametrize("heading_error_deg", [30.0, 120.0, 175.0, -175.0])
def test_heading_converges_to_enu_north_from_any_side(heading_error_deg):
    """The field's horizontal part ends on +y (north); the south branch turns the short way."""
    n = int(3.0 * FS_HZ)
    q_true = quat.from_euler([0.7, 0.1, -0.2], "ZYX")
    acc = np.tile(quat.rotate(quat.conjugate(q_true), GRAVITY_ENU), (n, 1))
    mag = np.tile(quat.rotate(quat.conjugate(q_true), FIELD_ENU_UT), (n, 1))
    gyr = np.zeros((n, 3))  # exactly zero: unlike ahrs, the correction still runs
    start = quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], np.radians(heading_error_deg)), q_true)
    params = ValentiCFParams(tau_mag_s=0.3, warmup_s=0.0)
    est = ValentiCF(params).estimate(acc, gyr, mag, fs_hz=FS_HZ, q0=start).orientation_
    err = angle_deg(est, q_true)
    assert err[-1] < 0.1
    assert np.all(np.diff(err) <= 1e-9)  # never turns the long way round
    # heading only: the tilt is never disturbed by the magnetometer correction
    assert tilt_deg(est, q_true).max() < 1e-6


def test_delta_mag_takes_the_field_to_north():
    rng = np.random.default_rng(0)
    for l_earth in rng.normal(size=(50, 3)):
        d = _delta_mag(l_earth)
        turned = quat.rotate(d, l_earth)
        assert d[0] >= 0.0 and d[1] == 0.0 and d[2] == 0.0
        np.testing.assert_allclose(turned[0], 0.0, atol=1e-12)
        assert turned[1] > 0.0


def test_adaptive_gain_ignores_strong_acceleration():
    """A sustained 0.8 g horizontal acceleration tilts the non-adaptive filter, not the adaptive one."""
    n = int(4.0 * FS_HZ)
    q_true = quat.from_euler([0.3, 0.0, 0.0], "ZYX")
    acc = np.tile(quat.rotate(quat.conjugate(q_true), GRAVITY_ENU + [8.0, 0.0, 0.0]), (n, 1))
    gyr = np.zeros((n, 3))  # exactly zero: unlike ahrs, the correction still runs
    adaptive = ValentiCF().estimate(acc, gyr, fs_hz=FS_HZ, q0=q_true).orientation_
    plain = ValentiCF(ValentiCFParams(adaptive_gain=False)).estimate(acc, gyr, fs_hz=FS_HZ, q0=q_true).orientation_
    assert tilt_deg(adaptive[-1], q_true) < 1e-6
    assert tilt_deg(plain[-1], q_true) > 30.0


def test_gyroscope_bias_is_estimated_at_rest():
    q, acc, gyr, mag, q_start = rotating_body(int(6.0 * FS_HZ), seed=4, still=True, gyr_noise=0.002)
    m = ValentiCF(ValentiCFParams(estimate_bias=True))
    result = m.estimate(acc, gyr, mag, fs_hz=FS_HZ, q0=q_start)
    np.testing.assert_allclose(result.state_[4:7], GYR_BIAS, atol=1e-3)
    off = ValentiCF().estimate(acc, gyr, mag, fs_hz=FS_HZ, q0=q_start)
    np.testing.assert_array_equal(off.state_[4:7], 0.0)


def test_rate_conversion_of_gains():
    p = ValentiCFParams.from_per_sample(0.01, 0.01, 100.0)  # the authors' gains
    assert p.tau_acc_s == pytest.approx(TAU_DEFAULT_S, rel=1e-12)
    assert per_sample_gain(p.tau_acc_s, 0.01) == pytest.approx(0.01, abs=1e-15)
    assert per_sample_gain(p.tau_mag_s, 0.01) == pytest.approx(0.01, abs=1e-15)
    # at 200 Hz the per-sample gain halves (to first order): same time constant
    assert per_sample_gain(p.tau_acc_s, 0.005) == pytest.approx(1.0 - math.sqrt(0.99), rel=1e-12)
    thesis = ValentiCFParams.from_per_sample(0.01, 0.001, 100.0)
    assert per_sample_gain(thesis.tau_mag_s, 0.01) == pytest.approx(0.001, rel=1e-12)


def test_two_half_batches_equal_one_batch():
    q, acc, gyr, mag, q_start = rotating_body(300, seed=5, gyr_noise=0.001)
    m = ValentiCF(ValentiCFParams(estimate_bias=True))
    full = m.estimate(acc, gyr, mag, fs_hz=FS_HZ, q0=q_start)
    w = alignment_samples(FS_HZ)  # q0 gives the attitude; the stage still reads the window estimate reads
    state = m.initial_state(acc[:w], mag[:w], gyr=gyr[:w], fs_hz=FS_HZ, q0=q_start)
    first, state = m.update(state, acc[:50], gyr[:50], mag[:50], fs_hz=FS_HZ)  # inside the warm-up
    assert state[10] == pytest.approx(0.5)
    second, state = m.update(state, acc[50:], gyr[50:], mag[50:], fs_hz=FS_HZ)
    np.testing.assert_array_equal(np.vstack([first, second]), full.orientation_)
    np.testing.assert_array_equal(state, full.state_)


def test_registry():
    _, acc, gyr, mag, _ = rotating_body(50, seed=6)
    m = make("valenti_cf", tau_mag_s=5.0)
    assert isinstance(m, ValentiCF) and m.params.tau_mag_s == 5.0
    assert m.estimate(acc, gyr, mag, fs_hz=FS_HZ).orientation_.shape == (50, 4)


@pytest.mark.parametrize(
    "kwargs, name",
    [({"tau_acc_s": 0.0}, "tau_acc_s"), ({"tau_mag_s": -1.0}, "tau_mag_s"), ({"tau_bias_s": float("nan")}, "tau_bias_s"),
     ({"lerp_threshold": 1.0}, "lerp_threshold"), ({"lerp_threshold": -0.1}, "lerp_threshold"),
     ({"adaptive_gain": 1}, "adaptive_gain"), ({"estimate_bias": "yes"}, "estimate_bias"),
     ({"acc_error_low": 0.3, "acc_error_high": 0.2}, "acc_error_high"), ({"gravity_m_s2": 0.0}, "gravity_m_s2"),
     ({"rest_gyr_rad_s": -0.2}, "rest_gyr_rad_s"), ({"rest_acc_m_s2": float("inf")}, "rest_acc_m_s2"),
     ({"warmup_s": -1.0}, "warmup_s"), ({"tau_warmup_s": 0.0}, "tau_warmup_s"), ({"tau_acc_s": "1"}, "tau_acc_s")],
)
def test_parameter_validation(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ValentiCFParams(**kwargs)


def test_from_per_sample_validation():
    with pytest.raises(ValueError, match="alpha"):
        ValentiCFParams.from_per_sample(1.5, 0.01, 100.0)
    with pytest.raises(ValueError, match="fs_hz"):
        ValentiCFParams.from_per_sample(0.01, 0.01, 0.0)
