"""Valenti et al. (2016) Kalman filter: AQUA maths, kernel == reference, physics on synthetic motion."""

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.orientation import estimate
from estimators.orientation.valenti_kf import STATE_SIZE, ValentiKF, ValentiKFParams, aqua_reference

FS = 100.0
GRAVITY = np.array([0.0, 0.0, 9.81])
FIELD = np.array([0.0, 20.0, -40.0])


def simulate(omega, q0, noise_rng=None):
    """Integrate body rates ``omega (N, 3)`` from ``q0`` (the orientation before sample 0).

    Returns the truth after each sample and the sensor readings.
    """
    n = omega.shape[0]
    q = np.empty((n, 4))
    q_prev = q0
    for k in range(n):
        q[k] = q_prev = quat.multiply(q_prev, quat.exp(omega[k] / FS))
    acc = quat.rotate(quat.conjugate(q), GRAVITY)
    mag = quat.rotate(quat.conjugate(q), FIELD)
    gyr = omega.copy()
    if noise_rng is not None:
        acc = acc + noise_rng.normal(0.0, 0.1, acc.shape)
        gyr = gyr + noise_rng.normal(0.0, 0.01, gyr.shape)
        mag = mag + noise_rng.normal(0.0, 0.5, mag.shape)
    return q, acc, gyr, mag


Q_START = quat.from_euler([0.3, -0.2, 0.5])


def realistic_motion(n, seed=0, noise=True):
    t = np.arange(n) / FS
    omega = np.stack([1.5 * np.sin(2 * np.pi * 0.5 * t), 1.0 * np.cos(2 * np.pi * 0.3 * t),
                      2.0 * np.sin(2 * np.pi * 0.2 * t + 1.0)], axis=1)
    rng = np.random.default_rng(seed)
    return simulate(omega, Q_START, rng if noise else None)


def tilt_error_deg(q_est, q_true):
    """Angle between the estimated and the true 'up' axis in sensor coordinates (heading-free)."""
    up_est = quat.rotate(quat.conjugate(q_est), [0.0, 0.0, 1.0])
    up_true = quat.rotate(quat.conjugate(q_true), [0.0, 0.0, 1.0])
    return np.degrees(np.arccos(np.clip(np.sum(up_est * up_true, axis=-1), -1.0, 1.0)))


def err_deg(q_est, q_true):
    return np.degrees(quat.angle_between(q_est, q_true))


def quat_unit(v):
    return v / np.linalg.norm(v)


def random_orientations(n, seed):
    return quat.normalize(np.random.default_rng(seed).normal(size=(n, 4)))


def r_matrix(a, m, sa=1e-4, sm=1e-4):
    """The measurement covariance as the filter builds it (tangent-projected, plus the norm direction)."""
    z, ja, jm, _ = aqua_reference(a, m)
    jt = ja @ (np.eye(3) - np.outer(a, a))
    return z, sa * jt @ jt.T + sm * jm @ jm.T + 0.25 * sa * np.outer(z, z)


# ---------------------------------------------------------------------------------------- AQUA
def test_aqua_recovers_orientation_in_enu_on_both_branches():
    q_true = random_orientations(500, seed=1)
    a = quat.rotate(quat.conjugate(q_true), [0.0, 0.0, 1.0])
    assert (a[:, 2] < 0).any() and (a[:, 2] >= 0).any()
    for qt, ak in zip(q_true, a):
        m = quat.rotate(quat.conjugate(qt), FIELD / np.linalg.norm(FIELD))
        z = aqua_reference(ak, m)[0]
        assert err_deg(z, qt) < 1e-7


def test_aqua_frame_conventions():
    up = np.array([0.0, 0.0, 1.0])
    north_down = FIELD / np.linalg.norm(FIELD)
    np.testing.assert_allclose(quat.positive_scalar(aqua_reference(up, north_down)[0]), [1, 0, 0, 0], atol=1e-12)
    # sensor x axis pointing north: q_earth_sensor is +90° about the earth's z (up) axis
    q_true = quat.from_axis_angle([0, 0, 1], np.pi / 2)
    m = quat.rotate(quat.conjugate(q_true), north_down)
    np.testing.assert_allclose(quat.positive_scalar(aqua_reference(up, m)[0]), q_true, atol=1e-12)


def test_aqua_jacobians_match_finite_differences():
    eps = 1e-6
    for qt in random_orientations(60, seed=2):
        a = quat.rotate(quat.conjugate(qt), [0.0, 0.0, 1.0])
        m = quat.rotate(quat.conjugate(qt), FIELD / np.linalg.norm(FIELD))
        if abs(a[2]) < 1e-3:
            continue
        z, ja, jm, _ = aqua_reference(a, m)
        ja_tangent = ja @ (np.eye(3) - np.outer(a, a))
        for j in range(3):
            d = np.zeros(3)
            d[j] = eps
            num_a = (aqua_reference(quat_unit(a + d), m)[0] - aqua_reference(quat_unit(a - d), m)[0]) / (2 * eps)
            num_m = (aqua_reference(a, m + d)[0] - aqua_reference(a, m - d)[0]) / (2 * eps)
            np.testing.assert_allclose(num_a, ja_tangent[:, j], atol=1e-6)
            np.testing.assert_allclose(num_m, jm[:, j], atol=1e-6)


def test_measurement_and_its_covariance_are_continuous_across_az_zero():
    """The q_acc branch switch changes z only by its sign and leaves R unchanged."""
    for heading in np.linspace(-3.0, 3.0, 7):
        for tilt_axis in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]):
            q_base = quat.multiply(quat.from_axis_angle([0, 0, 1], heading), quat.from_axis_angle(tilt_axis, np.pi / 2))
            zs, rs = [], []
            for delta in (-1e-9, 1e-9):
                qt = quat.multiply(q_base, quat.from_axis_angle([1.0, -0.3, 0.2], delta))
                a = quat.rotate(quat.conjugate(qt), [0.0, 0.0, 1.0])
                m = quat.rotate(quat.conjugate(qt), FIELD / np.linalg.norm(FIELD))
                z, r = r_matrix(a, m)
                zs.append(z)
                rs.append(r)
            assert min(np.abs(zs[0] - zs[1]).max(), np.abs(zs[0] + zs[1]).max()) < 1e-7
            np.testing.assert_allclose(rs[0], rs[1], atol=1e-10)


# -------------------------------------------------------------------------- kernel == reference
@pytest.mark.parametrize("gate", [3.0, 0.0])
@pytest.mark.parametrize("use_mag", [True, False])
def test_kernel_matches_reference_with_noise_and_missing_samples(use_mag, gate):
    _, acc, gyr, mag = realistic_motion(400, seed=3)
    acc[50:55] = np.nan
    gyr[120:123] = np.nan
    mag[200:230] = np.nan
    acc[300:310] += 8.0  # a burst of linear acceleration: exercises the innovation gate
    method = ValentiKF(ValentiKFParams(innovation_gate=gate))
    m = mag if use_mag else None
    fast = method.estimate(acc, gyr, m, fs_hz=FS)
    q_ref = method.reference(acc, gyr, m, fs_hz=FS)
    np.testing.assert_allclose(fast.orientation_, q_ref, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(fast.orientation_, axis=1), 1.0, atol=1e-12)
    assert fast.state_.shape == (STATE_SIZE,)


def test_kernel_matches_reference_from_a_wrong_start_and_upside_down():
    t = np.arange(300) / FS
    omega = np.stack([2.0 * np.ones_like(t), 0.3 * np.sin(t), np.zeros_like(t)], axis=1)
    _, acc, gyr, mag = simulate(omega, quat.from_axis_angle([1, 0, 0], 2.8), np.random.default_rng(4))
    q0 = quat.from_euler([1.0, 0.5, -0.4])
    method = ValentiKF(ValentiKFParams(initial_std_rad=1.0))
    for m in (mag, None):
        np.testing.assert_allclose(method.estimate(acc, gyr, m, fs_hz=FS, q0=q0).orientation_,
                                   method.reference(acc, gyr, m, fs_hz=FS, q0=q0), atol=1e-9)


def test_vertical_field_falls_back_to_the_6d_measurement():
    q, acc, gyr, _ = realistic_motion(200, seed=11)
    vertical_field = -acc  # parallel to gravity: no heading information (Γ = 0)
    method = ValentiKF(ValentiKFParams(acc_lowpass_s=0.0))  # the field parallel to the sample the update reads
    q9 = method.estimate(acc, gyr, vertical_field, fs_hz=FS, q0=Q_START).orientation_
    q6 = method.estimate(acc, gyr, None, fs_hz=FS, q0=Q_START).orientation_
    np.testing.assert_allclose(q9, q6, atol=1e-12)
    np.testing.assert_allclose(method.reference(acc, gyr, vertical_field, fs_hz=FS, q0=Q_START), q6, atol=1e-9)


# ----------------------------------------------------------------------------------- behaviour
def test_converges_from_a_wrong_start_at_rest():
    q_true = quat.from_euler([0.7, -0.3, 0.4])
    q, acc, gyr, mag = simulate(np.zeros((400, 3)), q_true, np.random.default_rng(5))
    q_wrong = quat.multiply(q_true, quat.from_euler([1.2, 0.5, -0.6]))
    est = ValentiKF().estimate(acc, gyr, mag, fs_hz=FS, q0=q_wrong).orientation_
    assert err_deg(est[200:], q[200:]).max() < 2.0
    est6 = ValentiKF().estimate(acc, gyr, None, fs_hz=FS, q0=q_wrong).orientation_
    assert tilt_error_deg(est6[200:], q[200:]).max() < 2.0


def test_noisy_motion_is_accurate():
    q, acc, gyr, mag = realistic_motion(1500, seed=6)
    est = ValentiKF().estimate(acc, gyr, mag, fs_hz=FS).orientation_
    assert np.sqrt(np.mean(err_deg(est, q) ** 2)) < 2.0


@pytest.mark.parametrize("use_mag", [True, False])
def test_no_jump_through_az_zero_and_upside_down(use_mag):
    """A full turn about a horizontal axis passes a_z = 0 twice and the upside-down pose."""
    t = np.arange(int(8 * FS)) / FS
    omega = np.stack([1.0 * np.ones_like(t), 0.2 * np.cos(0.7 * t), 0.1 * np.ones_like(t)], axis=1)
    q_start = quat.from_axis_angle([0, 0, 1], 0.4)
    q, acc, gyr, mag = simulate(omega, q_start)
    assert acc[:, 2].min() < -9.0 and (np.diff(np.sign(acc[:, 2])) != 0).sum() >= 2
    est = ValentiKF().estimate(acc, gyr, mag if use_mag else None, fs_hz=FS, q0=q_start).orientation_
    assert err_deg(est, q).max() < 1.0
    step = err_deg(est[1:], est[:-1])
    true_step = np.degrees(np.linalg.norm(omega[1:], axis=1) / FS)
    assert (step - true_step).max() < 0.05


@pytest.mark.parametrize("pose", ["upside_down", "sideways"])
def test_static_noisy_pose_on_or_across_the_branch_switch_holds_orientation(pose):
    """Sideways, noise flips the sign of a_z from sample to sample: the output must not jump."""
    tilt = np.pi if pose == "upside_down" else np.pi / 2
    q_true = quat.multiply(quat.from_axis_angle([0, 0, 1], -2.0), quat.from_axis_angle([0.3, 1.0, 0.0], tilt))
    q, acc, gyr, mag = simulate(np.zeros((500, 3)), q_true, np.random.default_rng(7))
    if pose == "sideways":
        assert (np.diff(np.sign(acc[:, 2])) != 0).sum() > 100
    for m in (mag, None):
        est = ValentiKF().estimate(acc, gyr, m, fs_hz=FS, q0=q_true).orientation_
        assert err_deg(est, q).max() < 2.0
        assert err_deg(est[51:], est[50:-1]).max() < 0.2


def test_6d_heading_follows_the_gyroscope_only():
    t = np.arange(600) / FS
    omega = np.stack([np.zeros_like(t), np.zeros_like(t), 0.8 * np.sin(t)], axis=1)
    q_start = quat.from_axis_angle([0.2, 1.0, 0.0], 0.5)
    q, acc, gyr, _ = simulate(omega, q_start)
    est = ValentiKF().estimate(acc, gyr, None, fs_hz=FS, q0=q_start).orientation_
    assert err_deg(est, q).max() < 0.5  # heading is integrated, not pulled to zero


def test_innovation_gate_limits_gross_outliers():
    """A reversed field for 0.2 s (AQUA heading 180° off) barely moves the gated filter."""
    q_true = quat.from_euler([0.7, -0.3, 0.4])
    q, acc, gyr, mag = simulate(np.zeros((300, 3)), q_true)
    mag[150:170] = quat.rotate(quat.conjugate(q_true), FIELD * np.array([1.0, -1.0, 1.0]))
    errors = {}
    for gate in (3.0, 0.0):
        method = ValentiKF(ValentiKFParams(innovation_gate=gate))
        errors[gate] = err_deg(method.estimate(acc, gyr, mag, fs_hz=FS, q0=q_true).orientation_, q).max()
    assert errors[3.0] < 1.0
    assert errors[0.0] > 2.0 * errors[3.0]


def test_covariance_stays_symmetric_positive_definite():
    _, acc, gyr, mag = realistic_motion(1200, seed=8)
    acc[305:335] = np.nan  # a gap: prediction only, P grows (each block keeps a valid sample)
    method = ValentiKF()
    for m in (mag, None):
        state = method.initial_state(acc[:10], None if m is None else m[:10], fs_hz=FS)
        traces = []
        for start in range(0, 1200, 20):
            block = slice(start, start + 20)
            _, state = method.update(state, acc[block], gyr[block], None if m is None else m[block], fs_hz=FS)
            p = state[4:20].reshape(4, 4)
            assert np.array_equal(p, p.T)
            assert np.linalg.eigvalsh(p).min() > 0.0
            traces.append(np.trace(p))
        if m is not None:  # (6D: the slowly shrinking virtual-heading variance dominates the trace)
            assert traces[15] > traces[14]  # grows during the accelerometer gap (samples 305–335)


def test_correction_speed_does_not_depend_on_the_sampling_rate():
    """Noise densities make the filter's time constant rate independent (module docstring)."""
    q_true = quat.from_euler([0.2, 0.1, -0.1])
    q_wrong = quat.multiply(q_true, quat.from_axis_angle([1.0, 0.0, 0.0], np.radians(10.0)))
    errors = []
    for fs in (50.0, 100.0, 400.0):
        n = int(1.0 * fs)
        acc = np.tile(quat.rotate(quat.conjugate(q_true), GRAVITY), (n, 1))
        mag = np.tile(quat.rotate(quat.conjugate(q_true), FIELD), (n, 1))
        method = ValentiKF(ValentiKFParams(initial_std_rad=0.01))
        est = method.estimate(acc, np.zeros((n, 3)), mag, fs_hz=fs, q0=q_wrong).orientation_
        errors.append(err_deg(est[-1], q_true))
    assert 1.0 < errors[1] < 9.0  # partly corrected after 1 s
    assert max(errors) / min(errors) < 1.2


def test_registry_and_keyword_parameters():
    _, acc, gyr, mag = realistic_motion(50, seed=10)
    q = estimate(acc, gyr, mag, fs_hz=FS, method="valenti_kf", acc_noise_m_s2_sqrt_hz=0.1)
    assert q.shape == (50, 4)
    with pytest.raises(ValueError, match="unknown parameter"):
        estimate(acc, gyr, mag, fs_hz=FS, method="valenti_kf", beta=0.1)


@pytest.mark.parametrize("name", ["gyr_noise_rad_s_sqrt_hz", "acc_noise_m_s2_sqrt_hz", "mag_noise_rel_sqrt_hz",
                                  "initial_std_rad", "innovation_gate"])
@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), "0.1", True])
def test_parameter_validation(name, bad):
    if name == "innovation_gate" and bad == 0.0:
        assert ValentiKFParams(innovation_gate=0.0).innovation_gate == 0.0  # 0 = the paper's update
        return
    with pytest.raises(ValueError, match=name):
        ValentiKFParams(**{name: bad})
