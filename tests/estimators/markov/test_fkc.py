"""FKC: kernel == reference, convergence, tracking with gyroscope bias, continuation, validation."""

import numpy as np
import pytest

from estimators.markov import FkcParams, accelerometer_angles, fkc

FS = 100.0


def _signal(n=1500, bias=0.02, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    theta = 0.6 * np.sin(2 * np.pi * 0.4 * t) + 0.2 * np.sin(2 * np.pi * 1.1 * t)
    omega = np.gradient(theta, 1 / FS)
    gyr = omega + bias + rng.normal(0, 0.007, n)
    acc_angle = theta + rng.normal(0, 0.03, n)
    return theta, gyr, acc_angle


def test_kernel_equals_reference():
    theta, gyr, acc = _signal(400)
    ok = np.ones(400, bool)
    ok[100:180] = False
    a = fkc(gyr, acc, fs_hz=FS, abs_ok=ok)
    b = fkc(gyr, acc, fs_hz=FS, abs_ok=ok, reference=True)
    assert np.max(np.abs(a.theta_rad - b.theta_rad)) < 1e-9
    assert np.max(np.abs(a.state.p - b.state.p)) < 1e-9


def test_tracks_and_removes_bias():
    theta, gyr, acc = _signal(3000, bias=0.03)
    r = fkc(gyr, acc, fs_hz=FS, theta0_rad=0.0)
    err = r.theta_rad[500:] - theta[500:]
    assert np.sqrt(np.mean(err**2)) < np.deg2rad(1.0)
    plain = np.cumsum(gyr) / FS
    assert np.sqrt(np.mean((plain[500:] - theta[500:]) ** 2)) > np.deg2rad(5.0)
    assert abs(r.gyro_bias_rad_s[-1] - 0.03) < 0.01


def test_converges_from_wrong_start():
    n = 300
    r = fkc(np.zeros(n), np.full(n, 0.3), fs_hz=FS, theta0_rad=-0.5)
    assert abs(r.theta_rad[199] - 0.3) < np.deg2rad(2.0)


def test_two_halves_equal_one_batch():
    theta, gyr, acc = _signal(600)
    full = fkc(gyr, acc, fs_hz=FS)
    h1 = fkc(gyr[:250], acc[:250], fs_hz=FS, theta0_rad=acc[0])
    h2 = fkc(gyr[250:], acc[250:], fs_hz=FS, state=h1.state)
    assert np.allclose(np.concatenate([h1.theta_rad, h2.theta_rad]), full.theta_rad, atol=1e-12)


def test_covariance_symmetric_positive_definite():
    theta, gyr, acc = _signal(500)
    p = fkc(gyr, acc, fs_hz=FS).state.p
    assert np.allclose(p, p.T, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(p) > 0)


def test_accelerometer_angles_about_x():
    ang = np.linspace(-1.2, 1.2, 50)
    # body rotated by +ang about x; gravity (specific force) along +y at zero angle
    acc = 9.81 * np.column_stack([np.zeros(50), np.cos(ang), -np.sin(ang)])
    out, proj = accelerometer_angles(acc, gravity_ref=[0, 9.81, 0])
    assert np.allclose(out[:, 0], ang, atol=1e-12)
    assert np.allclose(proj[:, 0], 9.81)


@pytest.mark.parametrize("field", ["q_angle_rad2_s", "tau_gyro_s", "r_acc_rad2"])
def test_parameter_validation(field):
    with pytest.raises(ValueError, match=field):
        FkcParams(**{field: -1.0})
    with pytest.raises(ValueError, match="fs_hz"):
        fkc(np.zeros(3), np.zeros(3), fs_hz=0.0)
