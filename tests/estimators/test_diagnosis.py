"""Each cause of wrong knee angles provoked on a simulated step-up and named by its own code."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import diagnosis, heading, knee
from estimators import quaternion as quat
from estimators import simulation as sim

DEG = np.pi / 180.0
SIDE = "right"


def _turn(q, angle_rad):
    return quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], np.asarray(angle_rad, dtype=float)), q)


@pytest.fixture(scope="module")
def sensors():
    """Thigh and shank sensors (noise-free, 100 Hz) on a 6-cycle step-up, mounted as the protocol says (+y up the
    segment) or, for the thigh, upside down (turned 180° about its z)."""
    leg = sim.step_up(6, 0.17, SIDE, shape="rest_between", seed=4, facing_rad=1.3)  # the shape it was tuned on
    out = {}
    for name, mount in (("thigh", quat.identity()), ("shank", quat.identity()),
                        ("thigh_flipped", quat.from_axis_angle([0, 0, 1], np.pi))):
        seg = name.split("_")[0]
        out[name] = sim.simulate_on_grid(getattr(leg, seg), sim.ImuSpec.perfect(), q_segment_sensor=mount,
                                         lever_arm_m=getattr(leg, f"{seg}_lever_arm_m"))
    out["truth"] = np.column_stack([np.interp(out["thigh"].t_true_s, leg.t_s, leg.knee_angles_rad[:, i])
                                    for i in range(3)])
    return out


def _diagnose(qf, qt, acc, mode="auto"):
    ch = heading.choose_heading(qf, qt, fs_hz=100.0, mode=mode)
    return ch, diagnosis.diagnose(ch.q_earth_femur, ch.q_earth_tibia, SIDE, choice=ch, acc_sensor=acc)


def _codes(d):
    return [f.code for f in d.findings]


def test_a_sound_session_has_no_finding(sensors):
    g_t, g_s = sensors["thigh"], sensors["shank"]
    _, d = _diagnose(g_t.q_earth_sensor, g_s.q_earth_sensor, {"thigh": g_t.acc, "shank": g_s.acc})
    assert d.findings == () and not d.refuse and d.cause is None


def test_swapped_sensors_are_named_and_refused(sensors):
    g_t, g_s = sensors["thigh"], sensors["shank"]
    _, d = _diagnose(g_s.q_earth_sensor, g_t.q_earth_sensor, {"thigh": g_s.acc, "shank": g_t.acc})
    assert d.refuse and d.cause.code == "sensors_swapped" and d.cause.fixable and _codes(d) == ["sensors_swapped"]
    p = d.cause.warning.params
    true_median = np.rad2deg(np.median(sensors["truth"][:, 0]))
    assert p["median_deg"] == pytest.approx(-true_median, abs=1.0)  # a swap reads −flexion
    assert p["swapped_median_deg"] == pytest.approx(true_median, abs=1.0) and p["pct"] > 50.0
    assert "swapped" in d.cause.warning.message and "upside" not in d.cause.warning.message


def test_upside_down_sensor_is_named_and_refused(sensors):
    g_t, g_s = sensors["thigh_flipped"], sensors["shank"]
    # nominal calibration (task-only session: sensor axes taken as the segment's), so the flip reaches the angles
    _, d = _diagnose(g_t.q_earth_sensor, g_s.q_earth_sensor, {"thigh": g_t.acc, "shank": g_s.acc})
    assert d.refuse and d.cause.code == "sensor_upside_down_task" and d.cause.fixable
    assert d.cause.warning.params["segment"] == "thigh" and d.cause.warning.params["angle_deg"] > 150.0
    assert _codes(d) == ["sensor_upside_down_task"]  # not a swap, not a heading problem


def test_upside_down_sensor_undone_by_the_postures_is_no_refusal(sensors):
    g_s = sensors["shank"]
    flip = quat.from_axis_angle([0, 0, 1], np.pi)
    st, su = sim.standing(8.0, SIDE), sim.supine(8.0, SIDE)
    gs = sim.simulate_on_grid(st.thigh, sim.ImuSpec.perfect(), q_segment_sensor=flip)
    gu = sim.simulate_on_grid(su.thigh, sim.ImuSpec.perfect(), q_segment_sensor=flip, seed=1)
    cal = knee.calibrate_segment(gs.acc, gs.gyr, gu.acc, gu.gyr, fs_hz=100.0, label="thigh")
    q_f = knee.segment_orientation(sensors["thigh_flipped"].q_earth_sensor, cal.q_sensor_segment)
    _, d = _diagnose(q_f, g_s.q_earth_sensor, {"thigh": sensors["thigh_flipped"].acc, "shank": g_s.acc})
    assert not d.refuse and d.findings == ()
    assert [w.code for w in knee.mounting_warnings(cal, label="thigh")] == ["sensor_upside_down"]


def test_lost_heading_is_corrected_not_blamed_on_the_sensors(sensors):
    g_t, g_s = sensors["thigh"], sensors["shank"]
    t = g_s.t_s - g_s.t_s[0]
    lost = _turn(g_s.q_earth_sensor, np.where(t > 8.0, 150 * DEG, 0.0))  # the shank filter diverges at 8 s
    acc = {"thigh": g_t.acc, "shank": g_s.acc}
    ch, d = _diagnose(g_t.q_earth_sensor, lost, acc)
    assert ch.used == "constraint" and not d.refuse and _codes(d) == ["heading_lost"]
    f = d.findings[0]
    assert not f.fixable and f.warning.params["angle_deg"] == pytest.approx(150.0, abs=10.0)
    ang = knee.knee_angles(knee.q_femur_tibia(ch.q_earth_femur, ch.q_earth_tibia), SIDE)
    settled = t > 20.0  # away from the windows that straddle the jump
    assert np.sqrt(np.mean((ang[settled, 0] - sensors["truth"][settled, 0]) ** 2)) < 1.0 * DEG
    # forced to keep the magnetometers: named all the same (not refused: nothing for the clinician to fix) ...
    _, d_mag = _diagnose(g_t.q_earth_sensor, lost, acc, mode="magnetometer")
    assert _codes(d_mag) == ["heading_lost"]
    # ... and a half turn, which reverses the flexion axis, is not taken for a swap
    half = _turn(g_s.q_earth_sensor, np.where(t > 8.0, np.pi, 0.0))
    _, d_half = _diagnose(g_t.q_earth_sensor, half, acc, mode="magnetometer")
    assert _codes(d_half) == ["heading_lost"] and (d_half.cause is None or d_half.cause.code == "heading_lost")
    ch_half, d_auto = _diagnose(g_t.q_earth_sensor, half, acc)
    assert ch_half.used == "constraint" and not d_auto.refuse and _codes(d_auto) == ["heading_lost"]


def test_disturbed_field_is_corrected_and_named(sensors):
    g_t, g_s = sensors["thigh"], sensors["shank"]
    t = g_s.t_s - g_s.t_s[0]
    bend = 30 * DEG * np.clip(np.minimum(t - t[-1] / 3, 2 * t[-1] / 3 - t), 0.0, 1.0)
    ch, d = _diagnose(g_t.q_earth_sensor, _turn(g_s.q_earth_sensor, bend), {"thigh": g_t.acc, "shank": g_s.acc})
    assert ch.used == "constraint" and not d.refuse and _codes(d) == ["magnetic_field_disturbed"]
    p = d.findings[0].warning.params
    assert not d.findings[0].fixable and 25.0 < p["angle_deg"] < 40.0 and p["bound_deg"] == pytest.approx(6.0)
    assert 25.0 < p["pct"] < 65.0  # the bend lasts a third of the task; 10 s windows widen it


def test_with_the_magnetometer_heading_kept_the_cause_says_how_to_correct_it(sensors):
    """--heading magnetometer keeps the bent field: the finding must not claim the constraint corrected it."""
    from reports.warning_text import warning_text

    g_t, g_s = sensors["thigh"], sensors["shank"]
    t = g_s.t_s - g_s.t_s[0]
    bend = 30 * DEG * np.clip(np.minimum(t - t[-1] / 3, 2 * t[-1] / 3 - t), 0.0, 1.0)
    ch, d = _diagnose(g_t.q_earth_sensor, _turn(g_s.q_earth_sensor, bend), {"thigh": g_t.acc, "shank": g_s.acc},
                      mode="magnetometer")
    assert ch.used == "magnetometer" and _codes(d) == ["magnetic_field_disturbed"]
    w = d.findings[0].warning
    assert w.params["variant"] == "kept" and "--heading auto" in w.message and "corrects it" not in w.message
    for lang in ("es", "pt"):
        text, translated = warning_text(w.to_dict(), lang, {})
        assert translated and "--heading auto" in text, (lang, text)


def test_task_warnings_name_the_symptom_only(sensors):
    g_t, g_s = sensors["thigh"], sensors["shank"]
    ang = knee.knee_angles(knee.q_femur_tibia(g_s.q_earth_sensor, g_t.q_earth_sensor), SIDE)
    (w,) = knee.task_warnings(ang)
    assert w.code == "flexion_negative" and "swapped" not in w.message and "upside" not in w.message


def test_every_cause_is_listed_with_who_can_fix_it():
    assert diagnosis.CAUSES == {"sensors_swapped": True, "sensor_upside_down_task": True, "heading_lost": False,
                                "magnetic_field_disturbed": False}
