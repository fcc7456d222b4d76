"""Physics, error-model, clock and motion checks of the ground-truth generator."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators import simulation as sim

G = np.array([0.0, 0.0, 9.81])


def _integrate_gyro(q0: np.ndarray, gyr: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Strapdown integration q_{k+1} = q_k ⊗ exp(ω_{k+1} Δt): each sample is the mean rate over the interval before it."""
    inc = quat.exp(gyr[1:] * np.diff(t_s)[:, None])
    out = np.empty((len(gyr), 4))
    out[0] = q0
    for k in range(len(inc)):
        out[k + 1] = quat.multiply(out[k], inc[k])
    return out


def _mean_rate(traj: sim.Trajectory, t_s: np.ndarray, dt_s: float) -> np.ndarray:
    """Body rate averaged over [t − dt, t] (the simulator's gyroscope model S2)."""
    return quat.log(quat.multiply(quat.conjugate(traj.orientation(t_s - dt_s)), traj.orientation(t_s))) / dt_s


@pytest.fixture(scope="module")
def rot_traj() -> sim.Trajectory:
    return sim.rotations(20.0, seed=3)


# ---------------------------------------------------------------------------------------- trajectory
def test_trajectory_rejects_bad_input():
    t = np.arange(10) / 100.0
    q = np.tile([1.0, 0, 0, 0], (10, 1))
    p = np.zeros((10, 3))
    with pytest.raises(ValueError, match="strictly increasing"):
        sim.Trajectory(t[::-1], q, p)
    with pytest.raises(ValueError, match="q_earth_body"):
        sim.Trajectory(t, q[:, :3], p)
    with pytest.raises(ValueError, match="at least 4"):
        sim.Trajectory(t[:3], q[:3], p[:3])
    tr = sim.Trajectory(t, q, p)
    with pytest.raises(ValueError, match="inside the trajectory"):
        tr.at([0.5])


def test_trajectory_sign_continuity_and_readonly():
    t = np.arange(100) / 100.0
    q = quat.from_axis_angle([0, 0, 1], np.linspace(0, 3.0, 100))
    q[::2] *= -1.0  # alternate signs: the same rotations
    tr = sim.Trajectory(t, q, np.zeros((100, 3)))
    assert np.all(np.sum(tr.q_earth_body[1:] * tr.q_earth_body[:-1], axis=1) > 0)
    np.testing.assert_allclose(tr.angular_velocity(t[10:90]), np.tile([0, 0, 3.0 / 0.99], (80, 1)), atol=1e-9)
    with pytest.raises(ValueError):
        tr.t_s[0] = 1.0


def test_known_rates_and_accelerations():
    """A body spinning at 2 rad/s about a tilted axis on a circle of radius 0.5 m at 1.5 rad/s."""
    axis = np.array([1.0, 2.0, 2.0]) / 3.0

    def q_fn(t):
        return quat.from_axis_angle(axis, 2.0 * t)

    def p_fn(t):
        return 0.5 * np.column_stack([np.cos(1.5 * t), np.sin(1.5 * t), np.zeros_like(t)])

    tr = sim.Trajectory.from_functions(q_fn, p_fn, 5.0)
    st = tr.at(np.linspace(0.5, 4.5, 50))
    np.testing.assert_allclose(st.gyr_rad_s, np.tile(2.0 * axis, (50, 1)), atol=1e-7)
    np.testing.assert_allclose(st.ang_acc_rad_s2, 0.0, atol=1e-5)
    np.testing.assert_allclose(st.acc_m_s2, -(1.5**2) * st.pos_m, atol=1e-6)


def test_angular_acceleration_is_the_derivative_of_the_rate(rot_traj):
    t = rot_traj.t_s[2000:12000]
    st = rot_traj.at(t)
    assert np.max(np.abs(st.ang_acc_rad_s2)) > 5.0
    # ∫α dt (trapezoid) reproduces the change of ω (a finite difference would be wrong at the jerk steps)
    integral = np.vstack([np.zeros(3), np.cumsum(0.5 * (st.ang_acc_rad_s2[1:] + st.ang_acc_rad_s2[:-1])
                                                 * np.diff(t)[:, None], axis=0)])
    np.testing.assert_allclose(integral, st.gyr_rad_s - st.gyr_rad_s[0], atol=1e-4)


# ---------------------------------------------------------------------------------------- physics
@pytest.mark.parametrize("fs_hz, tol_deg", [(1000.0, 1e-6), (100.0, 1e-6)])  # mean rates integrate exactly
def test_gyro_integration_reproduces_orientation(rot_traj, fs_hz, tol_deg):
    spec = sim.ImuSpec.perfect(sim.ClockSpec(acc_fs_hz=fs_hz, gyr_fs_hz=fs_hz))
    s = sim.simulate(rot_traj, spec, q_segment_sensor=sim.random_rotation(0.6, seed=2))
    n = int(10.0 * fs_hz) + 1
    g = s.gyr
    assert np.max(np.linalg.norm(g.values[:n], axis=1)) > np.deg2rad(150)  # really moving
    q = _integrate_gyro(g.q_earth_sensor[0], g.values[:n], g.t_true_s[:n])
    err_deg = np.rad2deg(quat.angle_between(q, g.q_earth_sensor[:n]))
    assert err_deg.max() < tol_deg
    # the mounting is applied: sensor truth = segment truth ⊗ q_segment_sensor, ω_sensor = R_seg_sensorᵀ ω_segment
    seg = rot_traj.orientation(g.t_true_s[:n])
    np.testing.assert_allclose(
        quat.angle_between(quat.multiply(seg, s.q_segment_sensor), g.q_earth_sensor[:n]), 0.0, atol=1e-7)
    w_seg = _mean_rate(rot_traj, g.t_true_s[1:n], 1.0 / fs_hz)
    np.testing.assert_allclose(g.values[1:n], quat.rotate(quat.conjugate(s.q_segment_sensor), w_seg), atol=1e-6)


def test_rest_accelerometer_reads_gravity_on_up_axis():
    s = sim.simulate(sim.static_pose(3.0), sim.ImuSpec.perfect())
    np.testing.assert_allclose(s.acc.values, np.tile([0, 0, 9.81], (len(s.acc), 1)), atol=1e-9)
    np.testing.assert_allclose(s.gyr.values, 0.0, atol=1e-12)
    np.testing.assert_allclose(s.mag.values, np.tile([0, 20, -40], (len(s.mag), 1)), atol=1e-9)
    # sensor x axis pointing up (rotate -90° about y: x_sensor -> z_earth)
    q = quat.from_axis_angle([0, 1, 0], -np.pi / 2)
    s = sim.simulate(sim.static_pose(2.0, q), sim.ImuSpec.perfect())
    np.testing.assert_allclose(s.acc.values[0], [9.81, 0, 0], atol=1e-9)


def test_mag_norm_constant_without_iron_and_iron_as_specified():
    tr = sim.figure_eight(12.0)
    s = sim.simulate(tr, sim.ImuSpec.perfect())
    np.testing.assert_allclose(np.linalg.norm(s.mag.values, axis=1), np.hypot(20, 40), rtol=1e-9)
    mag = sim.MagErrors(noise_density_ut_rthz=0.0, hard_iron_ut=[10, -5, 30],
                        soft_iron=[[1.1, 0.05, 0], [0.05, 0.9, 0.02], [0, 0.02, 1.0]], range_ut=None)
    s2 = sim.simulate(tr, replace(sim.ImuSpec.perfect(), mag=mag))
    np.testing.assert_allclose(s2.mag.values, s.mag.values @ np.asarray(mag.soft_iron).T + [10, -5, 30], atol=1e-9)
    np.testing.assert_allclose(s2.mag.bias, np.tile([10, -5, 30], (len(s2.mag), 1)))


def test_double_integration_reproduces_position():
    tr = sim.figure_eight(10.0)
    spec = sim.ImuSpec.perfect(sim.ClockSpec(acc_fs_hz=1000.0, gyr_fs_hz=1000.0))
    lever = np.array([0.05, -0.1, 0.03])
    s = sim.simulate(tr, spec, q_segment_sensor=sim.random_rotation(1.0, seed=5), lever_arm_m=lever)
    a = s.acc
    i0, i1 = 4000, 6000  # a 2 s window in the middle of the figure
    acc_e = quat.rotate(a.q_earth_sensor[i0:i1 + 1], a.values[i0:i1 + 1]) - G
    dt = np.diff(a.t_true_s[i0:i1 + 1])[:, None]
    st0 = s.sensor.at(a.t_true_s[i0:i0 + 1])
    vel = st0.vel_m_s[0] + np.vstack([np.zeros(3), np.cumsum(0.5 * (acc_e[1:] + acc_e[:-1]) * dt, axis=0)])
    pos = st0.pos_m[0] + np.vstack([np.zeros(3), np.cumsum(0.5 * (vel[1:] + vel[:-1]) * dt, axis=0)])
    truth = s.sensor.position(a.t_true_s[i0:i1 + 1])
    assert np.max(np.linalg.norm(pos - truth, axis=1)) < 1e-3
    assert np.max(np.linalg.norm(truth - truth[0], axis=1)) > 0.1  # it did move
    # the lever arm is applied: sensor position = segment origin + R·r
    np.testing.assert_allclose(truth, tr.position(a.t_true_s[i0:i1 + 1])
                               + quat.rotate(tr.orientation(a.t_true_s[i0:i1 + 1]), lever), atol=1e-9)


# ---------------------------------------------------------------------------------------- sensor errors
def test_bias_scale_cross_axis_applied_exactly(rot_traj):
    gyr = sim.GyrErrors(noise_density_rad_s_rthz=0.0, bias_rad_s=[0.01, -0.02, 0.03], bias_walk_rad_s_rts=0.0,
                        scale_error=[0.01, -0.02, 0.005], cross_axis=[[0, 0.01, 0], [0, 0, -0.02], [0.005, 0, 0]],
                        range_rad_s=None)
    acc = sim.AccErrors(noise_density_m_s2_rthz=0.0, bias_m_s2=[0.1, 0.2, -0.3], bias_walk_m_s2_rts=0.0,
                        scale_error=0.0, cross_axis=np.zeros((3, 3)), range_m_s2=None)
    s = sim.simulate(rot_traj, replace(sim.ImuSpec.perfect(), gyr=gyr, acc=acc))
    t_mat = np.diag([1.01, 0.98, 1.005]) @ (np.eye(3) + np.asarray(gyr.cross_axis))
    np.testing.assert_allclose(s.gyr.values, s.gyr.clean @ t_mat.T + [0.01, -0.02, 0.03], atol=1e-12)
    np.testing.assert_allclose(s.acc.values, s.acc.clean + [0.1, 0.2, -0.3], atol=1e-12)
    np.testing.assert_allclose(s.gyr.bias, np.tile([0.01, -0.02, 0.03], (len(s.gyr), 1)))


def test_noise_and_bias_walk_follow_their_densities():
    spec = replace(sim.ImuSpec.noise_only(), gyr=replace(sim.GyrErrors.noise_only(), bias_walk_rad_s_rts=1e-3))
    s = sim.simulate(sim.static_pose(200.0, fs_hz=100.0), spec, seed=11)
    acc_sd = np.std(s.acc.values - s.acc.clean, axis=0)
    np.testing.assert_allclose(acc_sd, 2e-3 * np.sqrt(100.0), rtol=0.05)  # 0.02 m/s² rms at 100 Hz
    mag_sd = np.std(s.mag.values - s.mag.clean, axis=0)
    np.testing.assert_allclose(mag_sd, 0.1 * np.sqrt(20.0), rtol=0.08)
    walk_steps = np.diff(s.gyr.bias, axis=0)
    np.testing.assert_allclose(np.std(walk_steps, axis=0), 1e-3 * np.sqrt(0.01), rtol=0.05)
    white = s.gyr.values - s.gyr.clean - s.gyr.bias
    np.testing.assert_allclose(np.std(white, axis=0), 7e-4 * np.sqrt(100.0), rtol=0.05)


def test_saturation_clips_and_flags(rot_traj):
    gyr = replace(sim.GyrErrors.perfect(), range_rad_s=2.0)
    s = sim.simulate(rot_traj, replace(sim.ImuSpec.perfect(), gyr=gyr))
    over = np.any(np.abs(s.gyr.clean) >= 2.0, axis=1)
    assert over.any()
    np.testing.assert_array_equal(s.gyr.saturated, over)
    assert np.max(np.abs(s.gyr.values)) <= 2.0


def test_default_spec_is_representative_and_errors_are_validated():
    spec = sim.ImuSpec()
    assert spec.gyr.noise_density_rad_s_rthz * 10.0 == pytest.approx(0.007)
    assert spec.acc.noise_density_m_s2_rthz * 10.0 == pytest.approx(0.02)
    assert spec.clock.acc_fs_hz == 100.0 and spec.clock.mag_fs_hz == 20.0
    with pytest.raises(ValueError, match="noise_density_rad_s_rthz"):
        sim.GyrErrors(noise_density_rad_s_rthz=-1.0)
    with pytest.raises(ValueError, match="bias_m_s2"):
        sim.AccErrors(bias_m_s2=[1.0, 2.0])
    with pytest.raises(ValueError, match="soft_iron"):
        sim.MagErrors(soft_iron=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="mag_fs_hz"):
        sim.ClockSpec(mag_fs_hz=0.0)
    with pytest.raises(ValueError, match="q_segment_sensor"):
        sim.simulate(sim.static_pose(1.0), q_segment_sensor=np.ones((2, 4)))
    r = sim.ImuSpec.random(seed=4)
    assert not np.allclose(r.mag.hard_iron_ut, sim.ImuSpec.random(seed=5).mag.hard_iron_ut)


# ---------------------------------------------------------------------------------------- clocks
def test_clock_drift_offsets_and_sample_counts():
    tr = sim.static_pose(60.0)
    s = sim.simulate(tr, sim.ImuSpec.perfect())
    assert (len(s.acc), len(s.gyr), len(s.mag)) == (6001, 6001, 1201)
    clock = sim.ClockSpec(clock_drift_ppm=5000.0, acc_start_s=0.003, mag_start_s=0.017, clock_offset_s=100.0)
    s = sim.simulate(tr, sim.ImuSpec.perfect(clock))
    # a clock 0.5 % fast logs 0.5 % more samples over the same 60 true seconds
    assert len(s.gyr) == 6031
    assert len(s.acc) == int(np.floor((60.0 * 1.005 - 0.003) * 100.0)) + 1
    assert len(s.mag) == int(np.floor((60.0 * 1.005 - 0.017) * 20.0)) + 1
    assert s.acc.t_s[0] == pytest.approx(100.003) and s.mag.t_s[0] == pytest.approx(100.017)
    np.testing.assert_allclose(np.diff(s.gyr.t_s), 0.01, atol=1e-9)  # nominal on the device clock
    np.testing.assert_allclose(np.diff(s.gyr.t_true_s), 0.01 / 1.005, atol=1e-9)
    np.testing.assert_allclose(s.device_to_true_time(s.mag.t_s), s.mag.t_true_s, atol=1e-9)
    assert s.gyr.t_true_s[-1] <= tr.t_end_s


def test_jitter_keeps_stamps_ordered_with_the_given_spread():
    clock = sim.ClockSpec(jitter_s=0.001)
    s = sim.simulate(sim.static_pose(30.0), sim.ImuSpec.perfect(clock), seed=3)
    dev = s.gyr.t_s - np.arange(len(s.gyr)) / 100.0
    assert np.std(dev) == pytest.approx(0.001, rel=0.1)
    assert np.all(np.diff(s.gyr.t_s) > 0) and np.all(np.diff(s.acc.t_s) > 0)


def test_on_grid_ideal_clock_and_realistic_clock(rot_traj):
    s = sim.simulate(rot_traj, sim.ImuSpec.perfect())
    g = s.on_grid()
    assert g.fs_hz == 100.0 and g.acc.shape == g.gyr.shape == g.mag.shape == (len(g.t_s), 3)
    np.testing.assert_allclose(g.gyr, s.gyr.values[: len(g.t_s)], atol=1e-12)
    np.testing.assert_allclose(g.acc, s.acc.values[: len(g.t_s)], atol=1e-12)
    np.testing.assert_allclose(g.mag[::5], s.mag.values[: len(g.mag[::5])], atol=1e-9)
    np.testing.assert_allclose(g.q_earth_sensor, s.gyr.q_earth_sensor[: len(g.t_s)], atol=1e-12)
    # linear interpolation of the 20 Hz magnetometer is close to the true field for this motion
    clean = quat.rotate(quat.conjugate(g.q_earth_sensor), [0, 20, -40])
    assert np.median(np.linalg.norm(g.mag - clean, axis=1)) < 1.0
    # simulate_on_grid(fs_hz=...) samples acc/gyr at that rate (not an interpolation of 100 Hz data)
    g200 = sim.simulate_on_grid(rot_traj, sim.ImuSpec.perfect(), fs_hz=200.0)
    assert g200.fs_hz == 200.0
    np.testing.assert_allclose(g200.gyr[1:], _mean_rate(rot_traj, g200.t_true_s[1:], 1.0 / 200.0), atol=1e-12)
    g2 = sim.simulate_on_grid(rot_traj, sim.ImuSpec.perfect(sim.ClockSpec.metamotion()), seed=1)
    assert g2.t_s[0] == pytest.approx(0.017, abs=0.002)  # starts when all streams have started
    np.testing.assert_allclose(np.diff(g2.t_s), 0.01, atol=1e-9)
    np.testing.assert_allclose(g2.t_true_s, (g2.t_s - 0.0) / (1 + 40e-6), atol=1e-9)


def test_seeds_make_runs_reproducible(rot_traj):
    spec = replace(sim.ImuSpec(), clock=sim.ClockSpec.metamotion())
    a = sim.simulate(rot_traj, spec, seed=7)
    b = sim.simulate(rot_traj, spec, seed=7)
    c = sim.simulate(rot_traj, spec, seed=8)
    for name in ("acc", "gyr", "mag"):
        np.testing.assert_array_equal(getattr(a, name).values, getattr(b, name).values)
        np.testing.assert_array_equal(getattr(a, name).t_s, getattr(b, name).t_s)
        assert not np.array_equal(getattr(a, name).values, getattr(c, name).values)
    # switching the magnetometer noise off leaves the gyroscope's draws unchanged
    d = sim.simulate(rot_traj, replace(spec, mag=sim.MagErrors.perfect()), seed=7)
    np.testing.assert_array_equal(a.gyr.values, d.gyr.values)
    np.testing.assert_array_equal(sim.rotations(20.0, seed=3).q_earth_body, rot_traj.q_earth_body)


# ---------------------------------------------------------------------------------------- motions
def test_rotations_cover_axes_with_rests_and_bounded_rate(rot_traj):
    w = rot_traj.angular_velocity(rot_traj.t_s)
    rate = np.linalg.norm(w, axis=1)
    assert rate.max() <= np.deg2rad(300.0) * 1.01
    assert np.mean(rate < 1e-6) > 0.2  # rest periods
    assert np.all(np.max(np.abs(w), axis=0) > 2.0)  # every axis turns fast at some point
    assert rot_traj.duration_s == pytest.approx(20.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_figure_eight_covers_the_sphere_of_directions(seed):
    tr = sim.figure_eight(60.0, seed=seed)
    s = sim.simulate(tr, sim.ImuSpec.perfect())
    d = s.mag.values / np.linalg.norm(s.mag.values, axis=1, keepdims=True)
    # 400 nearly uniform directions (Fibonacci sphere): each must be within 25° of some field direction
    k = np.arange(400) + 0.5
    z = 1 - 2 * k / 400
    phi = np.pi * (1 + 5**0.5) * k
    bins = np.column_stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z])
    closest = np.max(bins @ d.T, axis=1)
    assert np.all(closest > np.cos(np.deg2rad(25.0)))
    assert np.max(np.linalg.norm(s.gyr.values, axis=1)) < np.deg2rad(400.0)


def test_walking_foot_stance_truth_is_still_and_loop_closes():
    walk = sim.walking_foot(path="rectangle", seed=2)
    tr = walk.trajectory
    assert walk.closed_loop and walk.distance_m == pytest.approx(22.1, abs=1e-9)
    t = tr.t_s
    stance = walk.stance_mask(t)
    st = tr.at(t)
    assert np.max(np.linalg.norm(st.vel_m_s[stance], axis=1)) < 1e-6
    assert np.max(np.linalg.norm(st.gyr_rad_s[stance], axis=1)) < 1e-5  # spline ringing only
    assert np.max(np.linalg.norm(st.vel_m_s[~stance], axis=1)) > 2.0
    np.testing.assert_allclose(tr.pos_m[-1], tr.pos_m[0], atol=1e-12)
    # each stance is spent on its placement
    mid = walk.stance_intervals_s.mean(axis=1)
    np.testing.assert_allclose(tr.position(mid), walk.placements_m, atol=1e-9)
    straight = sim.walking_foot(6, 1.2, facing_rad=np.pi / 2)
    assert len(straight.stance_intervals_s) == 7
    np.testing.assert_allclose(straight.trajectory.pos_m[-1], [0, 7.2, 0], atol=1e-9)
    s = sim.simulate(straight.trajectory, sim.ImuSpec.perfect())
    rest = straight.stance_mask(s.acc.t_true_s)
    # at rest the accelerometer reads gravity only (spline ringing next to an event stays < 1e-3 m/s²)
    np.testing.assert_allclose(np.linalg.norm(s.acc.values[rest], axis=1), 9.81, atol=1e-3)


# ---------------------------------------------------------------------------------------- knee
@pytest.mark.parametrize("shape", ["thesis", "rest_between"])
@pytest.mark.parametrize("step_height_m, start_deg", [(0.17, 60.0), (0.34, 90.0)])
def test_step_up_cycles_match_the_flexion_curve(step_height_m, start_deg, shape):
    if shape == "thesis":  # seed 004 Tables 8.2/8.4: peak flexion 83° / 111°, start 7.5° below
        start_deg = {0.17: 75.5, 0.34: 103.5}[step_height_m]
    leg = sim.step_up(n_cycles=4, step_height_m=step_height_m, side="right", seed=1, shape=shape)
    flex = np.rad2deg(leg.knee_angles_rad[:, 0])
    t = leg.t_s
    assert leg.cycles_s.shape == (4, 2) and leg.phases_s.shape == (4, 4)
    # DESIGN.md §3: a cycle runs onset → back at rest; continuous cycles meet, a rest between them is in none
    np.testing.assert_allclose(leg.cycles_s, leg.phases_s[:, [0, 3]])
    if shape == "thesis":
        np.testing.assert_allclose(leg.cycles_s[1:, 0], leg.cycles_s[:-1, 1])
    else:
        assert np.all(leg.cycles_s[1:, 0] - leg.cycles_s[:-1, 1] > 1.0)
    dflex = np.gradient(flex, t)
    for (c0, c1), (on, peak, leave, rest) in zip(leg.cycles_s, leg.phases_s):
        assert c0 < peak < leave < rest == c1
        cyc = (t >= c0) & (t < c1)
        start = np.interp(on, t, flex)
        assert start == pytest.approx(start_deg, abs=3.5)
        assert t[cyc][np.argmax(flex[cyc])] == pytest.approx(peak, abs=2e-3)
        assert 5.0 <= flex[cyc].max() - start <= 10.0  # impulse rise before the extension
        ext = (t >= peak) & (t < leave)
        assert np.min(flex[ext]) <= 3.0 + 1e-9  # full extension reached and held ...
        hold = (t > leave - 0.25) & (t <= leave)
        assert np.all(np.abs(dflex[hold]) < 1e-3)
        after = (t > leave) & (t < leave + 0.2)
        assert np.all(dflex[after] > 0)  # ... then left (the fall)
        assert abs(np.interp(rest, t, dflex)) < 1e-3 and abs(np.interp(on, t, dflex)) < 1e-3
    # the foot stays on the step: ankle = knee − R_shank·[0, L, 0] is fixed
    ankle = leg.shank.pos_m - quat.rotate(leg.shank.q_earth_body, [0, sim.SHANK_LENGTH_M, 0])
    np.testing.assert_allclose(ankle, np.tile([0, 0, step_height_m + 0.08], (len(t), 1)), atol=1e-12)
    # the true angles are those of the two segment orientations
    np.testing.assert_allclose(leg.knee_angles_at(t[::50]), leg.knee_angles_rad[::50], atol=1e-9)


@pytest.mark.parametrize("h, cycle_s", [(0.17, 3.38), (0.34, 3.54)])
def test_thesis_step_up_follows_the_measured_phase_proportions(h, cycle_s):
    """seed 004 Tables 8.1/8.3: cycle 3.38 s / 3.54 s; impulse 34.0 / 33.3 %, extension 31.7 / 32.8 %,
    fall 34.0 / 33.9 % of the cycle (SD 0.9–3 %); the three phases sum to the cycle."""
    leg = sim.step_up(n_cycles=60, step_height_m=h, seed=3)
    dur = leg.cycles_s[:, 1] - leg.cycles_s[:, 0]
    pct = 100 * np.diff(leg.phases_s, axis=1) / dur[:, None]
    np.testing.assert_allclose(pct.sum(axis=1), 100.0)
    assert np.mean(dur) == pytest.approx(cycle_s, abs=0.03) and np.std(dur) < 0.07
    np.testing.assert_allclose(pct.mean(axis=0), [34.0, 32.0, 34.0], atol=1.0)
    assert np.all(pct.std(axis=0, ddof=1) < 3.0)
    # Fig. 8.2: full extension reached about half-way through the cycle
    flex = leg.knee_angles_rad[:, 0]
    for k in range(5):
        c = (leg.t_s >= leg.cycles_s[k, 0]) & (leg.t_s < leg.cycles_s[k, 1])
        reached = leg.t_s[c][np.argmax(flex[c] < np.deg2rad(3.5))]
        assert 0.4 < (reached - leg.cycles_s[k, 0]) / dur[k] < 0.6


def test_step_up_pauses_rests_and_cycle_length():
    pauses = [0.0, 4.0, 0.0, 6.0]
    leg = sim.step_up(n_cycles=5, step_height_m=0.34, side="left", seed=2, pauses_s=pauses, initial_rest_s=0.0,
                      final_rest_s=3.0, cycle_s=2.0)
    t, flex = leg.t_s, leg.knee_angles_rad[:, 0]
    np.testing.assert_allclose(leg.cycles_s[1:, 0] - leg.cycles_s[:-1, 1], pauses, atol=1e-9)
    assert leg.cycles_s[0, 0] == 0.0 and t[-1] == pytest.approx(leg.cycles_s[-1, 1] + 3.0)
    assert np.mean(leg.cycles_s[:, 1] - leg.cycles_s[:, 0]) == pytest.approx(2.0, abs=0.05)
    for k in (1, 3):  # the knee holds the start posture through each pause, which no cycle contains
        gap = (t > leg.cycles_s[k, 1]) & (t < leg.cycles_s[k + 1, 0])
        assert np.ptp(flex[gap]) < 1e-9
        assert not np.any((leg.cycles_s[:, 0] < t[gap].mean()) & (t[gap].mean() < leg.cycles_s[:, 1]))
    with pytest.raises(ValueError, match="pauses_s"):
        sim.step_up(n_cycles=3, pauses_s=[1.0, -1.0])
    with pytest.raises(ValueError, match="cycle_s"):
        sim.step_up(n_cycles=3, cycle_s=7.0)
    with pytest.raises(ValueError, match="shape"):
        sim.step_up(n_cycles=3, shape="square")


def test_step_up_left_leg_keeps_clinical_signs():
    right = sim.step_up(n_cycles=2, side="right", seed=4)
    left = sim.step_up(n_cycles=2, side="left", seed=4)
    np.testing.assert_allclose(left.knee_angles_rad, right.knee_angles_rad)
    np.testing.assert_allclose(left.knee_angles_at(left.t_s[::100]), left.knee_angles_rad[::100], atol=1e-9)
    assert left.thigh_lever_arm_m[2] < 0 < right.thigh_lever_arm_m[2]  # sensors on the lateral side


def test_calibration_postures_point_the_segment_axes_up():
    up = np.array([0.0, 0.0, 1.0])
    stand = sim.standing(5.0, facing_rad=0.7)
    lie = sim.supine(5.0, head_rad=-1.2)
    for seg in (stand.thigh, stand.shank):
        np.testing.assert_allclose(quat.rotate(seg.q_earth_body[0], [0, 1.0, 0]), up, atol=1e-12)
    for seg in (lie.thigh, lie.shank):
        np.testing.assert_allclose(quat.rotate(seg.q_earth_body[0], [1.0, 0, 0]), up, atol=1e-12)
    np.testing.assert_allclose(stand.knee_angles_at(stand.t_s[:5]), 0.0, atol=1e-12)
    # a sensor on the standing thigh reads gravity along R_segment_sensorᵀ·y
    mount = sim.random_rotation(0.5, seed=9)
    s = sim.simulate(stand.thigh, sim.ImuSpec.perfect(), q_segment_sensor=mount, lever_arm_m=stand.thigh_lever_arm_m)
    np.testing.assert_allclose(s.acc.values[0], quat.rotate(quat.conjugate(mount), [0, 9.81, 0]), atol=1e-9)
    # hip above knee when standing, hip towards the head when supine
    assert stand.thigh.pos_m[0, 2] - stand.shank.pos_m[0, 2] == pytest.approx(sim.THIGH_LENGTH_M)
    d = lie.thigh.pos_m[0] - lie.shank.pos_m[0]
    np.testing.assert_allclose(d, sim.THIGH_LENGTH_M * np.array([np.cos(-1.2), np.sin(-1.2), 0]), atol=1e-12)


def test_two_sensor_session_runs():
    leg = sim.step_up(n_cycles=3)
    mount = sim.random_rotation(np.deg2rad(20), seed=1)
    th = sim.simulate(leg.thigh, q_segment_sensor=mount, lever_arm_m=leg.thigh_lever_arm_m, seed=1)
    sh = sim.simulate(leg.shank, q_segment_sensor=mount, lever_arm_m=leg.shank_lever_arm_m, seed=2)
    g_th, g_sh = th.on_grid(), sh.on_grid()
    q_knee = quat.multiply(quat.conjugate(g_th.q_earth_segment), g_sh.q_earth_segment)
    # the two segments' simulated orientations realise the knee angles the motion was generated from
    truth = np.column_stack([np.interp(g_th.t_true_s, leg.t_s, leg.knee_angles_rad[:, i]) for i in range(3)])
    np.testing.assert_allclose(sim.knee_angles(q_knee), truth, atol=1e-9)
    assert not np.any(th.acc.saturated | sh.acc.saturated)
