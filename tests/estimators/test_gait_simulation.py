"""The gait simulator against published normative gait and against its own physics."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.simulation import ImuSpec, gait
from estimators.simulation.spec import GRAVITY_M_S2


@pytest.fixture(scope="module")
def walk():
    return gait.walking(12.0, seed=3)


def test_mean_knee_curve_has_the_published_features():
    # Winter 2009 App. A / Perry & Burnfield 2010: ~5° at IC, loading-response peak 15–20° at 12–15 %,
    # stance minimum 3–5°, peak swing 60–65° at 70–73 %, toe-off ~60 % at ~35–40°
    ph = np.linspace(0.0, 1.0, 10001)
    k = np.rad2deg(gait.normative_knee_rad(ph))
    lr = np.argmax(np.where(ph < 0.3, k, -np.inf))
    assert 0.12 <= ph[lr] <= 0.15 and 15.0 <= k[lr] <= 20.0
    mn = np.argmin(np.where((ph > 0.2) & (ph < 0.55), k, np.inf))
    assert 3.0 <= k[mn] <= 5.0 and 0.33 <= ph[mn] <= 0.45
    pk = np.argmax(k)
    assert 0.70 <= ph[pk] <= 0.73 and 60.0 <= k[pk] <= 65.0
    assert abs(k[0] - 5.0) < 0.5
    assert 33.0 <= k[np.searchsorted(ph, gait.TOE_OFF_FRACTION)] <= 42.0
    h = np.rad2deg(gait.normative_hip_rad(ph))
    assert 0.50 <= ph[np.argmin(h)] <= 0.60 and 0.80 <= ph[np.argmax(h)] <= 0.90


@pytest.mark.parametrize("side", ["right", "left"])
def test_events_are_ordered_and_at_the_published_percentages(walk, side):
    leg = walk.leg(side)
    ph = leg.motion.phases_s
    assert len(ph) >= 8
    assert np.all(np.diff(ph, axis=1) > 0.0)                       # IC < TO < mid-swing < next IC
    np.testing.assert_array_equal(leg.motion.cycles_s, ph[:, [0, 3]])
    stride = ph[:, 3] - ph[:, 0]
    to_pct = (ph[:, 1] - ph[:, 0]) / stride
    ms_pct = (ph[:, 2] - ph[:, 0]) / stride
    assert np.all(np.abs(to_pct - 0.60) < 0.02)
    assert np.all((ms_pct > 0.73) & (ms_pct < 0.87))               # Perry's mid-swing
    assert abs(np.mean(stride) - 120.0 / walk.cadence_steps_min) < 0.03 * 120.0 / walk.cadence_steps_min
    assert np.std(stride) > 0.0                                      # stride-to-stride variability
    # knee truth at the events: ~5° at IC, flexing at TO, per-stride ROM near the normative ~60°
    f = np.rad2deg(leg.knee_angles_at(ph[:, 0])[:, 0])
    assert np.all(np.abs(f - 5.0) < 4.0)
    for a, b in leg.motion.cycles_s:
        sel = (walk.t_s >= a) & (walk.t_s < b)
        rom = np.ptp(np.rad2deg(leg.motion.knee_angles_rad[sel, 0]))
        assert 52.0 < rom < 68.0


def test_legs_alternate_half_a_stride_apart(walk):
    r, l = walk.right.initial_contact_s, walk.left.initial_contact_s
    nxt = np.array([l[l > t][0] for t in r[:-1]])
    frac = (nxt - r[:-1]) / np.diff(r)
    assert np.all(np.abs(frac - 0.5) < 0.03)


def test_knee_truth_is_the_bones_relative_orientation(walk):
    leg = walk.right
    np.testing.assert_allclose(leg.knee_angles_at(walk.t_s[::50]), leg.motion.knee_angles_rad[::50], atol=1e-9)


def test_clip_starts_in_motion_anywhere_in_the_cycle():
    starts = []
    for seed in range(4):
        w = gait.walking(5.0, seed=seed)
        assert np.linalg.norm(w.right.motion.shank.angular_velocity([0.0])) > 0.1
        starts.append(w.right.initial_contact_s[0])
    assert np.ptp(starts) > 0.2


@pytest.mark.parametrize("segment", ["thigh", "shank"])
def test_wobble_amplitude_is_as_set(segment):
    w = gait.walking(8.0, seed=4, shank_wobble_rad=np.deg2rad(3.0), thigh_wobble_rad=np.deg2rad(1.0))
    leg = w.right
    bone = getattr(leg.motion, segment).q_earth_body
    mount = getattr(leg, f"{segment}_mount").q_earth_body
    ang = quat.angle_between(bone, mount)
    want = np.deg2rad(3.0 if segment == "shank" else 1.0)
    assert abs(ang.max() - want) < 0.01 * want
    # a damped oscillation after each heel strike: gone before the next one
    for t0 in leg.initial_contact_s[:-1]:
        late = (w.t_s > t0 + 0.5) & (w.t_s < t0 + 0.9)
        assert ang[late].max() < 0.01 * want
    still = gait.walking(8.0, seed=4, shank_wobble_rad=0.0, thigh_wobble_rad=0.0)
    assert quat.angle_between(getattr(still.right.motion, segment).q_earth_body,
                              getattr(still.right, f"{segment}_mount").q_earth_body).max() < 1e-9


def test_heel_strike_transient_has_the_set_peak_acceleration():
    w = gait.walking(8.0, seed=5, shank_impact_g=5.0, thigh_impact_g=1.5, shank_wobble_rad=0.0,
                     thigh_wobble_rad=0.0)
    leg = w.right
    for segment, g_set in (("shank", 5.0), ("thigh", 1.5)):
        lever = getattr(leg.motion, f"{segment}_lever_arm_m")
        rigid = getattr(leg.motion, segment).mounted(None, lever)
        mount = getattr(leg, f"{segment}_mount")
        t = w.t_s[10:-10]
        extra = np.linalg.norm(mount.acceleration(t) - rigid.acceleration(t), axis=1) / GRAVITY_M_S2
        assert abs(extra.max() - g_set) < 0.03 * g_set
        # each transient sits right after an initial contact
        for t0 in leg.initial_contact_s[:-1]:
            sel = (t > t0) & (t < t0 + 0.1)
            assert extra[sel].max() > 0.9 * g_set
    # the sampled 100 Hz shank accelerometer shows 3–6 g shocks at heel strike
    thigh_imu, shank_imu = gait.simulate_leg(leg, ImuSpec.perfect(), ImuSpec.perfect(), seed=0)
    acc = shank_imu.acc
    peaks = [np.linalg.norm(acc.values[(acc.t_true_s > t0) & (acc.t_true_s < t0 + 0.1)], axis=1).max()
             for t0 in leg.initial_contact_s[:-1]]
    assert 2.5 * GRAVITY_M_S2 < np.median(peaks) < 7.0 * GRAVITY_M_S2


def test_accelerometer_reads_gravity_while_standing_before_the_walk():
    w = gait.walking(8.0, seed=6, standing_start_s=3.0)
    leg = w.left
    assert leg.initial_contact_s[0] > 3.0
    thigh_imu, shank_imu = gait.simulate_leg(leg, ImuSpec.perfect(), ImuSpec.perfect(), seed=1)
    for imu in (thigh_imu, shank_imu):
        rest = imu.acc.t_true_s < 2.9
        q = imu.acc.q_earth_sensor[rest]
        want = quat.rotate(quat.conjugate(q), np.array([0.0, 0.0, GRAVITY_M_S2]))
        np.testing.assert_allclose(imu.acc.values[rest], want, atol=1e-6)
        assert np.abs(imu.gyr.values[imu.gyr.t_true_s < 2.9]).max() < 1e-6
        assert np.abs(imu.acc.values[~rest]).max() > 11.0         # and it walks afterwards


@pytest.mark.parametrize("turn", [None, 4.0])
def test_gyroscope_integrates_to_the_true_sensor_orientation(turn):
    w = gait.walking(10.0, seed=7, turn_at_s=turn)
    thigh_imu, shank_imu = gait.simulate_leg(w.right, ImuSpec.perfect(), ImuSpec.perfect(),
                                             q_shank_sensor=quat.from_axis_angle([1.0, 2.0, 3.0], 0.7), seed=2)
    for imu in (thigh_imu, shank_imu):
        g = imu.gyr
        dt = np.diff(g.t_true_s)
        q = [g.q_earth_sensor[0]]
        for k in range(1, len(g.values)):
            q.append(quat.multiply(q[-1], quat.exp(g.values[k] * dt[k - 1])))
        err = quat.angle_between(np.array(q), g.q_earth_sensor)
        assert err.max() < np.deg2rad(0.05)


def test_turn_reverses_the_walking_direction_and_the_segments_heading():
    w = gait.walking(12.0, seed=8, turn_at_s=5.0, turn_duration_s=2.0)
    assert w.heading_rad[0] == pytest.approx(0.0) and w.heading_rad[-1] == pytest.approx(np.pi)
    x = quat.rotate(w.right.motion.thigh.q_earth_body, np.array([1.0, 0.0, 0.0]))
    assert x[0, 0] > 0.8 and x[-1, 0] < -0.8                      # anterior axis east, then west
    v = w.right.motion.thigh.velocity([1.0, 11.0])
    assert v[0, 0] > 0.8 and v[1, 0] < -0.8


def test_lateral_mounting_points_the_sensor_z_out_of_the_skin():
    for side, s in (("right", 1.0), ("left", -1.0)):
        q_t, q_s = gait.lateral_mounting(side)
        np.testing.assert_allclose(quat.rotate(q_t, [0.0, 0.0, 1.0]), [0.0, 0.0, s], atol=1e-12)
        np.testing.assert_allclose(quat.rotate(q_s, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("kwargs", [{"duration_s": 0.5}, {"cadence_steps_min": 300.0}, {"shank_wobble_rad": -0.1},
                                    {"wobble_axis": (0.0, 0.0, 0.0)}, {"speed_m_s": float("nan")}])
def test_bad_parameters_say_what_is_wrong(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        gait.walking(**{"duration_s": 5.0, **kwargs})


def test_another_knee_curve_is_followed_and_bad_key_frames_are_refused():
    stiff = [(0.0, 3.0), (13.0, 8.0), (40.0, 2.0), (60.0, 20.0), (76.0, 40.0), (90.0, 16.0)]
    w = gait.walking(8.0, seed=3, knee_keyframes_deg=stiff, amplitude_cv=0.0, offset_sd_rad=0.0, stride_cv=0.0)
    leg = w.right
    a, _, _, b = leg.motion.phases_s[1]
    t = a + np.array([0.13, 0.40, 0.76]) * (b - a)
    np.testing.assert_allclose(np.rad2deg(leg.knee_angles_at(t)[:, 0]), [8.0, 2.0, 40.0], atol=0.2)
    for bad in ([(0.0, 1.0), (50.0, 2.0), (40.0, 3.0), (90.0, 4.0)], [(0.0, 1.0), (50.0, 2.0)],
                [(0.0, 1.0), (30.0, 2.0), (60.0, np.nan), (90.0, 4.0)]):
        with pytest.raises(ValueError, match="knee_keyframes_deg"):
            gait.walking(8.0, knee_keyframes_deg=bad)
