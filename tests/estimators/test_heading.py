"""Constraint heading δ(t) and the heading choice, against the simulator's true orientations and knee angles."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import heading, knee
from estimators import quaternion as quat
from estimators import simulation as sim

DEG = np.pi / 180.0
FS_HZ = 100.0


def _truth(side: str = "right", height: float = 0.17, n_cycles: int = 8, seed: int = 0, facing_rad: float = 0.4):
    """True femur and tibia orientations (the segment frames, ENU) and the generator's knee angles."""
    leg = sim.step_up(n_cycles, height, side, shape="rest_between", seed=seed, facing_rad=facing_rad)  # tuned on it
    t = np.arange(leg.t_s[0], leg.t_s[-1], 1.0 / FS_HZ)  # the motion is defined on a 1 kHz grid
    return t, leg.thigh.orientation(t), leg.shank.orientation(t), leg.knee_angles_at(t)


def _turn(q, angle_rad):
    """The earth frame of a filter turned about the vertical by angle_rad (scalar or per sample)."""
    return quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], np.asarray(angle_rad, dtype=float)), q)


def _rmse(a, b):
    return np.sqrt(np.mean(heading.wrap(a - b) ** 2, axis=0))


def test_follows_a_drifting_offset_on_6d_orientations():
    t, qf, qt, truth = _truth()
    t = t - t[0]
    # 6D: each filter has its own arbitrary heading, and the tibia's drifts by 20° over the task
    drift = 20 * DEG * t / t[-1]
    qf6, qt6 = _turn(qf, 1.1), _turn(qt, -2.0 + drift)
    ch = heading.constraint_heading(qf6, qt6, fs_hz=FS_HZ)
    true_offset = heading.wrap(1.1 - (-2.0 + drift))
    # the hinge bias: the window's mean true knee rotation (−2°..8°) and adduction, −6..+2° here
    assert np.max(np.abs(heading.wrap(ch.offset_rad - true_offset))) < 8 * DEG
    # the drift itself is followed: against the same recording without drift the bias cancels, and between the
    # first and last window centres (outside them δ is held, C2) the difference is the drift (to 0.5°: the
    # straight-knee weights, C3, are uneven in time, so a window's estimate sits a little off its centre)
    ch0 = heading.constraint_heading(qf6, _turn(qt, -2.0), fs_hz=FS_HZ)
    c = ch.window_centre_s[ch.window_excited & ch0.window_excited]
    inner = (t >= c[0]) & (t <= c[-1])
    np.testing.assert_allclose(heading.wrap(ch.offset_rad - ch0.offset_rad)[inner], -drift[inner], atol=0.5 * DEG)
    ang = knee.knee_angles(knee.q_femur_tibia(qf6, qt6, ch.offset_rad), "right")
    e = _rmse(ang, truth)
    assert e[0] < 0.5 * DEG and e[1] < 1.5 * DEG and e[2] < 4 * DEG
    # the residual is the knee's own departure from a hinge (adduction 2..5°, rotation −2..8°): below the warning's 10°
    assert ch.excited_fraction == 1.0 and ch.warnings == () and 3 * DEG < ch.residual_rad < 9 * DEG
    # one constant for the whole trial (knee.heading_offset "hinge") cannot follow the 20° drift
    const = knee.heading_offset(qf6, qt6, method="hinge").offset_rad
    e_const = _rmse(knee.knee_angles(knee.q_femur_tibia(qf6, qt6, const), "right"), truth)
    assert e_const[2] > e[2] + 2 * DEG


@pytest.mark.parametrize("side, height", [("left", 0.34), ("right", 0.34)])
def test_both_legs_and_a_constant_offset(side, height):
    _, qf, qt, truth = _truth(side, height, n_cycles=5, seed=3, facing_rad=-2.5)
    ch = heading.constraint_heading(qf, _turn(qt, 170 * DEG), fs_hz=FS_HZ)  # even a near half turn
    assert np.max(np.abs(heading.wrap(ch.offset_rad + 170 * DEG))) < 5 * DEG
    ang = knee.knee_angles(knee.q_femur_tibia(qf, _turn(qt, 170 * DEG), ch.offset_rad), side)
    assert _rmse(ang, truth)[0] < 0.5 * DEG


def test_still_windows_are_held_and_interpolated():
    _, qf, qt, _ = _truth(n_cycles=8)
    n, k0, m = len(qf), len(qf) // 2, 3000  # 30 s with the knee (and both segments) held still at sample k0
    qf = np.concatenate([qf[:k0], np.repeat(qf[k0:k0 + 1], m, axis=0), qf[k0:]])
    qt = np.concatenate([qt[:k0], np.repeat(qt[k0:k0 + 1], m, axis=0), qt[k0:]])
    # while still, the tibia filter's heading creeps by 8° (gyroscope drift): nothing in the data shows it
    ramp = np.concatenate([np.zeros(k0), np.linspace(0, 8 * DEG, m), np.full(n - k0, 8 * DEG)])
    ch = heading.constraint_heading(qf, _turn(qt, ramp), fs_hz=FS_HZ)
    inside = (ch.window_start >= k0) & (ch.window_stop <= k0 + m)
    assert inside.sum() > 30 and not ch.window_excited[inside].any()
    outside = (ch.window_stop <= k0) | (ch.window_start >= k0 + m)
    assert ch.window_excited[outside].mean() > 0.9
    # over the hold δ(t) is the straight line between the neighbouring excited windows' offsets (C2) ...
    ex = ch.window_excited
    c_s = (ch.window_start + ch.window_stop - 1) / 2.0
    k = np.arange(k0, k0 + m)
    expected = np.interp(k, c_s[ex], np.unwrap(ch.window_offset_rad[ex]))
    np.testing.assert_allclose(ch.offset_rad[k], heading.wrap(expected), atol=1e-9)
    # ... which follows the creep to within the hinge bias
    assert np.max(np.abs(heading.wrap(ch.offset_rad + ramp))) < 8 * DEG
    assert 0.5 < ch.excited_fraction < 0.8 and ch.warnings == ()


def test_no_excitation_falls_back_and_warns():
    st = sim.standing(20.0, "right", facing_rad=0.3)
    t = np.arange(st.t_s[0], st.t_s[-1], 1.0 / FS_HZ)
    qf, qt = st.thigh.orientation(t), st.shank.orientation(t)
    ch = heading.constraint_heading(qf, _turn(qt, -12 * DEG), fs_hz=FS_HZ)
    assert not ch.window_excited.any()
    (w,) = ch.warnings
    assert w.code == "constraint_heading_unexcited" and w.params == {"pct": 0.0, "window_s": 10.0,
                                                                     "min_flexion_deg": pytest.approx(10.0)}
    np.testing.assert_allclose(ch.offset_rad, 12 * DEG, atol=1e-6)  # the straight knee is an exact hinge


def test_validation():
    _, qf, qt, _ = _truth(n_cycles=1)
    with pytest.raises(ValueError, match="shape"):
        heading.constraint_heading(qf, qt[:-1], fs_hz=FS_HZ)
    with pytest.raises(ValueError, match="fs_hz"):
        heading.constraint_heading(qf, qt, fs_hz=0.0)
    with pytest.raises(ValueError, match="window_s"):
        heading.ConstraintHeadingParams(window_s=-1.0)
    with pytest.raises(ValueError, match="heading must be one of"):
        heading.choose_heading(qf, qt, fs_hz=FS_HZ, mode="compass")
    with pytest.raises(ValueError, match="both 6D"):
        heading.choose_heading(qf, qt, fs_hz=FS_HZ, q_earth_femur_6d=qf)


def _disturbed(angle_rad: float):
    """9D orientations whose tibia heading is bent by angle_rad during the middle third (1 s ramps)."""
    t, qf, qt, truth = _truth()
    t = t - t[0]
    frac = np.clip(np.minimum((t - t[-1] / 3) / 1.0, (2 * t[-1] / 3 - t) / 1.0), 0.0, 1.0)
    return qf, _turn(qt, angle_rad * frac), truth, (qf, qt)


def test_auto_keeps_a_sound_magnetometer_heading():
    _, qf, qt, _ = _truth()
    ch = heading.choose_heading(qf, qt, fs_hz=FS_HZ)
    assert (ch.mode, ch.used, ch.run) == ("auto", "magnetometer", "9d") and ch.warnings == ()
    assert np.all(ch.offset_rad == 0.0) and np.array_equal(ch.q_earth_tibia, qt)
    assert ch.disagreement_rad < heading.DISAGREEMENT_BOUND_RAD


def test_auto_switches_to_the_constraint_on_a_bent_heading():
    qf, qt9, truth, (qf6, qt6) = _disturbed(30 * DEG)
    qf6, qt6 = _turn(qf6, 0.7), _turn(qt6, -1.9)  # a 6D run with its own headings
    mag = heading.choose_heading(qf, qt9, fs_hz=FS_HZ, mode="magnetometer")
    auto = heading.choose_heading(qf, qt9, fs_hz=FS_HZ, q_earth_femur_6d=qf6, q_earth_tibia_6d=qt6)
    auto9 = heading.choose_heading(qf, qt9, fs_hz=FS_HZ)
    assert (auto.used, auto.run, auto9.used, auto9.run, mag.used) == ("constraint", "6d", "constraint", "9d",
                                                                      "magnetometer")
    (w,) = auto.warnings
    assert w.code == "magnetic_heading_unreliable" and w.params["bound_deg"] == pytest.approx(np.rad2deg(heading.DISTURBED_BOUND_RAD))
    assert 25.0 < w.params["disagreement_deg"] < 40.0  # 30° and the hinge bias
    assert [x.code for x in mag.warnings] == ["magnetic_heading_disagrees"]
    err = {k: _rmse(knee.knee_angles(knee.q_femur_tibia(c.q_earth_femur, c.q_earth_tibia), "right"), truth)
           for k, c in (("mag", mag), ("auto", auto), ("auto9", auto9))}
    assert err["mag"][2] > 8 * DEG  # a third of the task 30° off
    assert err["auto"][2] < 4 * DEG and err["auto"][0] < 0.5 * DEG
    # without a 6D run the 10 s windows smooth the 1 s ramps of the bend: better, not as good
    assert err["auto9"][2] < err["mag"][2] - 2 * DEG
    forced = heading.choose_heading(qf, qt9, fs_hz=FS_HZ, mode="constraint")
    assert forced.used == "constraint" and forced.warnings == ()


def test_default_filter_rejects_a_shank_field_turned_in_the_middle_third():
    """The default filter's offline heading (chakamo (15b)) rejects a field turned 30° about the vertical (norm and
    dip unchanged) during a third of the task: rotation RMSE 0.8° (8.98° before), so auto keeps the magnetometer."""
    from benchmarks.heading import session

    out, truth, side, fs = session(7, "right", 0.17, 30 * DEG, n_cycles=5)
    (f9, f6), (t9, t6) = out["thigh"], out["shank"]
    auto = heading.choose_heading(f9, t9, fs_hz=fs, q_earth_femur_6d=f6, q_earth_tibia_6d=t6)
    e_auto = _rmse(knee.knee_angles(knee.q_femur_tibia(auto.q_earth_femur, auto.q_earth_tibia), side), truth)
    assert auto.used == "magnetometer" and auto.warnings == ()
    assert e_auto[2] < 2 * DEG and e_auto[0] < 0.5 * DEG


def test_default_filter_on_a_disturbed_shank_field():
    """The default filter in 9D and 6D, the shank's field turned 30° for the last two thirds of the task
    (benchmarks/heading.py): the turned field is then the recording's majority, which no magnetometer check can
    tell from the earth's, so the magnetometer heading is 27° off for the first third and auto must switch."""
    from benchmarks.heading import session

    out, truth, side, fs = session(7, "right", 0.17, 30 * DEG, n_cycles=5, disturb_span=(1.0 / 3.0, 1.0))
    (f9, f6), (t9, t6) = out["thigh"], out["shank"]
    mag = heading.choose_heading(f9, t9, fs_hz=fs, mode="magnetometer")
    auto = heading.choose_heading(f9, t9, fs_hz=fs, q_earth_femur_6d=f6, q_earth_tibia_6d=t6)
    e_mag = _rmse(knee.knee_angles(knee.q_femur_tibia(mag.q_earth_femur, mag.q_earth_tibia), side), truth)
    e_auto = _rmse(knee.knee_angles(knee.q_femur_tibia(auto.q_earth_femur, auto.q_earth_tibia), side), truth)
    assert auto.used == "constraint" and e_auto[2] < e_mag[2] - 3 * DEG and e_auto[0] < 0.5 * DEG


def test_missing_rows_are_skipped_and_get_the_interpolated_offset():
    _, qf, qt, truth = _truth(n_cycles=5)
    qt6 = _turn(qt, 40 * DEG)
    gaps = np.zeros(len(qf), dtype=bool)
    gaps[::17] = True
    gaps[1000:1150] = True  # a 1.5 s dropout of one sensor
    qf_gap = np.where(gaps[:, None], np.nan, qf)
    ch = heading.constraint_heading(qf_gap, qt6, fs_hz=FS_HZ)
    ref = heading.constraint_heading(qf, qt6, fs_hz=FS_HZ)
    assert np.all(np.isfinite(ch.offset_rad))
    assert np.max(np.abs(heading.wrap(ch.offset_rad - ref.offset_rad))) < 0.5 * DEG
    ang = knee.knee_angles(knee.q_femur_tibia(qf, qt6, ch.offset_rad), "right")
    assert _rmse(ang, truth)[0] < 0.5 * DEG


def test_a_session_without_magnetometers_uses_the_constraint():
    _, qf, qt, truth = _truth(n_cycles=5)
    qf6, qt6 = _turn(qf, -0.4), _turn(qt, 2.2)
    ch = heading.choose_heading(None, None, fs_hz=FS_HZ, q_earth_femur_6d=qf6, q_earth_tibia_6d=qt6)
    assert (ch.used, ch.run, ch.constraint_9d) == ("constraint", "6d", None) and np.isnan(ch.disagreement_rad)
    ang = knee.knee_angles(knee.q_femur_tibia(ch.q_earth_femur, ch.q_earth_tibia), "right")
    e = _rmse(ang, truth)
    assert e[0] < 0.5 * DEG and e[2] < 2 * DEG
    with pytest.raises(ValueError, match="needs a 9D run"):
        heading.choose_heading(None, None, fs_hz=FS_HZ, mode="magnetometer", q_earth_femur_6d=qf6,
                               q_earth_tibia_6d=qt6)
    with pytest.raises(ValueError, match="9D run's segment orientations, the 6D"):
        heading.choose_heading(None, None, fs_hz=FS_HZ)


def test_summary_for_the_results_file():
    import json

    qf, qt9, _, _ = _disturbed(30 * DEG)
    d = heading.choose_heading(qf, qt9, fs_hz=FS_HZ).to_dict()
    assert json.loads(json.dumps(d)) == d
    assert (d["mode"], d["used"], d["run"], d["bound_deg"]) == ("auto", "constraint", "9d",
                                                               pytest.approx(np.rad2deg(heading.DISAGREEMENT_BOUND_RAD)))
    assert d["disagreement_deg"] > 25.0 and d["offset_deg"]["min"] < -25.0 and abs(d["offset_deg"]["max"]) < 8.0
    assert d["excited_pct"] == 100.0 and 0.0 < d["residual_deg"] < 10.0
    _, qf, qt, _ = _truth(n_cycles=3)
    clean = heading.choose_heading(qf, qt, fs_hz=FS_HZ).to_dict()
    assert clean["used"] == "magnetometer" and clean["offset_deg"] == {"min": 0.0, "max": 0.0}
