"""Foot-mounted PDR: kernels against their numpy references, simulated closed-loop walks, detectors, metrics."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.pdr import METHODS, reconstruct
from estimators.pdr.desaturation import clipped_attitude_variance, rebuild_saturated
from estimators.pdr.detectors import (PitchParams, ShoeParams, moving_majority, moving_variance, pitch_detector,
                                      stance_c123, stance_intervals)
from estimators.pdr.ekf import EkfParams, run_ekf
from estimators.pdr.ekf_reference import run_ekf_reference
from estimators.pdr.mechanisation import align, cayley, first_still_period, strapdown, strapdown_reference
from estimators.pdr.metrics import strides, walk_metrics
from estimators.simulation.imu import simulate_on_grid
from estimators.simulation.motions import walking_foot
from estimators.simulation.spec import ImuSpec


@pytest.fixture(scope="module")
def rect_walk():
    walk = walking_foot(path="rectangle", seed=1)
    grid = simulate_on_grid(walk.trajectory, ImuSpec.perfect(), fs_hz=100.0)
    return walk, grid, walk.stance_mask(grid.t_true_s)


@pytest.fixture(scope="module")
def noisy_walk():
    walk = walking_foot(n_strides=4, seed=2)
    grid = simulate_on_grid(walk.trajectory, ImuSpec(), fs_hz=100.0, seed=5)
    return walk, grid, walk.stance_mask(grid.t_true_s)


def test_cayley_closed_form_is_the_pade_rotation():
    a = np.array([0.3, -0.2, 0.5])
    r = cayley(a)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    out = np.empty((3, 3))
    from estimators.pdr.mechanisation import _cayley_inplace
    _cayley_inplace(*a, out)
    np.testing.assert_allclose(out, r, atol=1e-14)
    # rotation angle 2 atan(|a|/2) about a
    ang = np.arccos((np.trace(r) - 1) / 2)
    assert ang == pytest.approx(2 * np.arctan(np.linalg.norm(a) / 2), abs=1e-12)


def test_strapdown_kernel_matches_reference(noisy_walk):
    _, g, _ = noisy_walk
    dt = np.full(len(g.t_s), 0.01)
    al = align(g.acc, g.gyr, (0, 100))
    a = strapdown(g.acc[:300], g.gyr[:300], dt[:300], al.c0, al.gyr_bias_rad_s)
    b = strapdown_reference(g.acc[:300], g.gyr[:300], dt[:300], al.c0, al.gyr_bias_rad_s)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, atol=1e-9)


def test_alignment_roll_pitch_and_bias():
    roll, pitch = 0.2, -0.4
    f = 9.81 * np.array([-np.sin(pitch), np.cos(pitch) * np.sin(roll), np.cos(pitch) * np.cos(roll)])
    acc = np.tile(f, (200, 1))
    gyr = np.tile([0.01, -0.02, 0.005], (200, 1))
    al = align(acc, gyr, first_still_period(gyr, 100.0))
    assert al.roll_rad == pytest.approx(roll, abs=1e-12) and al.pitch_rad == pytest.approx(pitch, abs=1e-12)
    np.testing.assert_allclose(al.c0.T @ [0, 0, 9.81], f, atol=1e-9)
    np.testing.assert_allclose(al.gyr_bias_rad_s, [0.01, -0.02, 0.005])
    with pytest.raises(ValueError, match="still"):
        first_still_period(np.tile([1.0, 0, 0], (200, 1)), 100.0)


@pytest.mark.parametrize("params", [
    EkfParams(n_states=9),
    EkfParams(n_states=15, zaru=True),
    EkfParams(n_states=15, zaru=True, heading_update=True, height_update=True, init_att_std_rad=0.01),
])
def test_ekf_kernel_matches_reference(noisy_walk, params):
    _, g, truth = noisy_walk
    n = 420
    dt = np.full(n, 0.01)
    dt[200] = 0.024  # a clock gap
    al = align(g.acc, g.gyr, (0, 100))
    a = run_ekf(g.acc[:n], g.gyr[:n], dt, truth[:n], al.c0, al.gyr_bias_rad_s, params)
    b = run_ekf_reference(g.acc[:n], g.gyr[:n], dt, truth[:n], al.c0, al.gyr_bias_rad_s, params)
    for name in ("pos_m", "vel_m_s", "c_nav_body", "gyr_bias_rad_s", "acc_bias_m_s2", "p_diag"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-9, err_msg=name)


def test_ekf_external_attitude_matches_reference(noisy_walk):
    _, g, truth = noisy_walk
    from estimators import quaternion as quat
    n = 300
    c_ext = quat.to_matrix(g.q_earth_sensor[:n])
    al = align(g.acc, g.gyr, (0, 100))
    args = (g.acc[:n], g.gyr[:n], np.full(n, 0.01), truth[:n], al.c0, al.gyr_bias_rad_s, EkfParams())
    a, b = run_ekf(*args, c_ext=c_ext), run_ekf_reference(*args, c_ext=c_ext)
    np.testing.assert_allclose(a.pos_m, b.pos_m, atol=1e-9)
    np.testing.assert_allclose(a.c_nav_body, c_ext, atol=1e-15)


@pytest.mark.parametrize("method", ["9iez", "15iez_zaru", "chakamo"])
def test_closed_rectangle_noise_free_closes(rect_walk, method):
    walk, g, truth = rect_walk
    assert walk.closed_loop and walk.distance_m == pytest.approx(22.1)
    for stance in (truth, None):
        r = reconstruct(g.t_s, g.acc, g.gyr, method=method, stance=stance)
        m = r.metrics(walk.distance_m)
        assert m.ep <= 0.003, (stance is None, m)
        assert abs(m.ed_stance) <= 0.003
        assert m.ea_m <= 0.02


def test_every_method_runs_on_a_noisy_walk(noisy_walk):
    walk, g, _ = noisy_walk
    for method in METHODS:
        r = reconstruct(g.t_s, g.acc, g.gyr, method=method)
        end = r.pos_m[-1, :2]
        # straight walk of 4 × 1.4 m along the initial heading: distance right within 5 %
        assert np.linalg.norm(end) == pytest.approx(walk.distance_m, rel=0.05), method
        assert np.all(np.isfinite(r.q_earth_sensor))
    with pytest.raises(ValueError, match="unknown PDR method"):
        reconstruct(g.t_s, g.acc, g.gyr, method="nope")
    with pytest.raises(ValueError, match="unknown stance detector"):
        reconstruct(g.t_s, g.acc, g.gyr, detector="nope")


def test_stride_lengths_and_cadence(rect_walk):
    walk, g, truth = rect_walk
    r = reconstruct(g.t_s, g.acc, g.gyr, method="15iez_zaru", stance=truth)
    true_len = np.linalg.norm(np.diff(walk.placements_m[:, :2], axis=0), axis=1)
    est = np.array([s.length_m for s in r.strides])
    np.testing.assert_allclose(est, true_len, atol=0.01)
    dur = np.array([s.duration_s for s in r.strides[1:]])
    true_dur = np.diff(walk.stance_intervals_s[1:, 0])
    np.testing.assert_allclose(dur, true_dur, atol=0.011)
    assert all(s.cadence_strides_min == pytest.approx(60 / s.duration_s) for s in r.strides)


def test_c123_detector_against_simulated_stance(noisy_walk, rect_walk):
    for _walk, g, truth in (noisy_walk, rect_walk):
        det = stance_c123(g.acc, g.gyr)
        assert np.mean(det == truth) > 0.9
        assert np.mean(det[~truth]) < 0.02          # never "still" while the foot swings
        # every true stance is found
        runs = stance_intervals(truth)
        assert all(det[a:b].any() for a, b in runs)


def test_pitch_detector_against_simulated_stance(rect_walk):
    walk, g, truth = rect_walk
    r = reconstruct(g.t_s, g.acc, g.gyr, method="9iez", detector="pitch")
    assert np.mean(r.stance[~truth]) < 0.05
    assert all(r.stance[a:b].any() for a, b in stance_intervals(truth))
    pitch = np.zeros(100)
    pitch[40:60] = 0.5
    m = pitch_detector(pitch, 0.0, PitchParams())
    assert m[:25].all() and not m[45:55].any()


def test_detector_helpers_and_validation():
    x = np.array([0.0, 0, 0, 1, 1, 1])
    v = moving_variance(x, 2)
    assert v[0] == 0.0 and v[3] == pytest.approx(0.25)
    assert moving_majority([1, 0, 1, 1, 0, 0, 0], 3).tolist() == [True, True, True, True, False, False, False]
    np.testing.assert_array_equal(stance_intervals([0, 1, 1, 0, 1, 0, 1, 1, 1], 2), [[1, 3], [6, 9]])
    with pytest.raises(ValueError, match="gyr_max_rad_s"):
        ShoeParams(gyr_max_rad_s=0.0)
    with pytest.raises(ValueError, match="n_states"):
        EkfParams(n_states=12)
    with pytest.raises(ValueError, match="zaru"):
        EkfParams(n_states=9, zaru=True)


def test_metrics_definitions():
    t = np.arange(7) * 1.0
    pos = np.array([[0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 0], [0.1, 0, 0.05]], float)
    stance = np.array([1, 1, 0, 1, 0, 1, 1], bool)
    m = walk_metrics(pos, stance, 4.0, min_stance_samples=1)
    assert m.ep == pytest.approx(0.1 / 4) and m.ea_m == pytest.approx(0.05)
    d_stance = 1.0 + np.linalg.norm([0.55 - 1, 0.5 - 0])  # stance means (0,0), (1,0), (0.55,0.5)
    assert m.ed_stance == pytest.approx((d_stance - 4) / 4)
    assert len(strides(t, pos, stance, min_stance_samples=1)) == 2


def test_saturated_gyroscope_rebuilt_by_edge_parabola():
    t = np.arange(200) * 0.01
    true = np.zeros((200, 3))
    true[:, 1] = 6.0 * np.exp(-((t - 1.0) / 0.08) ** 2)      # a swing peak of 6 rad/s
    rng = np.deg2rad(250.0)
    clipped = np.clip(true, -rng, rng)
    sat = np.any(np.abs(clipped) >= rng, axis=1)
    rebuilt = rebuild_saturated(np.full(200, 0.01), clipped, sat, rng)
    lost = np.sum(true[:, 1] - clipped[:, 1]) * 0.01
    err = abs(np.sum(true[:, 1] - rebuilt[:, 1]) * 0.01)
    assert err < 0.5 * lost  # a Gaussian peak is not a parabola: most, not all, of the loss comes back
    np.testing.assert_array_equal(rebuilt[~sat], clipped[~sat])


def test_heading_and_floor_updates_bound_drift(rect_walk):
    """A gyroscope z bias that appears after the alignment (2 mrad/s) turns the 9IEZ rectangle; the
    default method's stride-direction heading updates keep it closed, its floor update keeps z at 0."""
    walk, g, truth = rect_walk
    gyr = g.gyr.copy()
    gyr[300:, 2] += 0.002
    acc = g.acc.copy()
    acc[300:, 2] += 0.2  # vertical accelerometer bias: altitude drift
    plain = reconstruct(g.t_s, acc, gyr, method="9iez", stance=truth).metrics(walk.distance_m)
    best = reconstruct(g.t_s, acc, gyr, method="chakamo", stance=truth).metrics(walk.distance_m)
    assert best.ep < 0.5 * plain.ep and best.ep < 0.005
    assert best.ea_m < 0.01 < plain.ea_m


def test_ekf_kernel_matches_reference_with_heading_and_floor_updates(rect_walk):
    """The whole rectangle (several heading and floor updates fire) with a drifting gyroscope."""
    walk, g, truth = rect_walk
    gyr = g.gyr.copy()
    gyr[300:, 2] += 0.002
    acc = g.acc + np.array([0.0, 0.0, 0.2])
    al = align(acc, gyr, (0, 150))
    params = EkfParams(n_states=9, gyr_noise_rad2_s=3e-6, acc_noise_m2_s3=1e-3, heading_update=True,
                       height_update=True)
    dt = np.full(len(acc), 0.01)
    a = run_ekf(acc, gyr, dt, truth, al.c0, al.gyr_bias_rad_s, params)
    b = run_ekf_reference(acc, gyr, dt, truth, al.c0, al.gyr_bias_rad_s, params)
    np.testing.assert_allclose(a.pos_m, b.pos_m, atol=1e-9)
    np.testing.assert_allclose(a.c_nav_body, b.c_nav_body, atol=1e-9)
    # the heading updates did act: the yaw variance drops at some stance ends
    assert np.any(np.diff(a.p_diag[:, 2]) < -1e-7)


def _clipped_rectangle(seed: int, range_rad_s: float):
    """A noisy simulated rectangle whose gyroscope clips at ``range_rad_s`` during every swing."""
    from dataclasses import replace

    walk = walking_foot(path="rectangle", seed=seed, stride_length_m=1.1, swing_s=0.4)
    spec = ImuSpec.noise_only()
    spec = replace(spec, gyr=replace(spec.gyr, range_rad_s=range_rad_s))
    g = simulate_on_grid(walk.trajectory, spec, fs_hz=100.0, seed=seed)
    sat = np.any(np.abs(g.gyr) >= 0.999 * range_rad_s, axis=1)
    return walk, g, sat, walk.stance_mask(g.t_true_s)


def test_clipped_attitude_variance_only_on_clipped_runs():
    rng = np.deg2rad(250.0)
    gyr = np.zeros((50, 3))
    gyr[10:16, 1] = rng * np.array([1.0, 1.2, 1.5, 1.5, 1.2, 1.0])   # rebuilt run, 6 samples
    sat = np.zeros(50, bool)
    sat[10:16] = True
    dt = np.full(50, 0.01)
    v = clipped_attitude_variance(dt, gyr, sat, rng, rel_std=0.5, floor_rad_s=0.1)
    assert np.all(v[:10] == 0) and np.all(v[16:] == 0) and np.all(v[:, [0, 2]] == 0)
    sigma = 0.5 * (np.abs(gyr[10:16, 1]) - 0.995 * rng) + 0.1
    np.testing.assert_allclose(v[10:16, 1], 6 * (sigma * 0.01) ** 2)
    assert v[12, 1] > v[10, 1]                     # more excess, more doubt
    with pytest.raises(ValueError, match="att_var_body"):
        run_ekf(np.zeros((50, 3)), gyr, dt, sat, np.eye(3), np.zeros(3), att_var_body=-v)


def test_ekf_kernel_matches_reference_with_clipped_attitude_variance():
    walk, g, sat, truth = _clipped_rectangle(0, np.deg2rad(250.0))
    n = 900
    dt = np.full(n, 0.01)
    gr = rebuild_saturated(dt, g.gyr[:n], sat[:n], np.deg2rad(250.0))
    v = clipped_attitude_variance(dt, gr, sat[:n], np.deg2rad(250.0))
    assert v.sum() > 0
    al = align(g.acc, g.gyr, (0, 150))
    params = EkfParams(n_states=15, heading_update=True)
    a = run_ekf(g.acc[:n], gr, dt, truth[:n], al.c0, al.gyr_bias_rad_s, params, att_var_body=v)
    b = run_ekf_reference(g.acc[:n], gr, dt, truth[:n], al.c0, al.gyr_bias_rad_s, params, att_var_body=v)
    for name in ("pos_m", "vel_m_s", "c_nav_body", "p_diag"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-9, err_msg=name)


def test_clipped_gyroscope_walk_closes_with_its_attitude_variance():
    """±250 °/s clips every swing of the simulated rectangle: the edge parabola alone leaves ~2.5 %
    closure error; with the clipped runs' attitude variance the default method closes within 0.3 %."""
    rng = np.deg2rad(250.0)
    walk, g, sat, truth = _clipped_rectangle(1, rng)
    assert sat.sum() > 100
    best = reconstruct(g.t_s, g.acc, g.gyr, gyr_saturated=sat, gyr_range_rad_s=rng, stance=truth)
    m = best.metrics(walk.distance_m)
    assert m.ep < 0.003
    # the same rebuilt rates without the variance
    dt = np.full(len(g.t_s), 0.01)
    al = align(g.acc, g.gyr, first_still_period(g.gyr, 100.0))
    from estimators.pdr.pipeline import _EKF
    plain = run_ekf(g.acc, best.gyr_used, dt, truth, al.c0, al.gyr_bias_rad_s, _EKF["chakamo"],
                    gravity_m_s2=al.gravity_m_s2)
    assert walk_metrics(plain.pos_m, truth, walk.distance_m).ep > 5 * m.ep
