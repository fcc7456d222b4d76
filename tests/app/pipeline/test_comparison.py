"""Two analyses computed with another knee-angle convention or sensor-to-segment calibration are not comparable
(:func:`app.pipeline.comparison.comparison`): the conventions read other numbers of the same knee pose."""

from __future__ import annotations

import numpy as np

from app.pipeline.comparison import comparison
from estimators.knee import knee_angles, knee_quaternion


def _results(**top) -> dict:
    return {"session": {"date": "2026-01-01", "patient_id": "P1"}, "filter": {"name": "vqf"},
            "software": {"version": "1"}, "task": "step_up", "side": "right",
            "rom_deg": {"flexion": {"max": {"mean": 90.0}}}, **top}


def test_zyx_reads_another_knee_than_grood_suntay():
    """The truth: a pose built by Grood & Suntay (K1) at 90° flexion, 5° adduction, 15° internal rotation; the
    thesis' ZYX extraction of the same quaternion differs by degrees, so a change between the two is the method's."""
    q = knee_quaternion(np.deg2rad([90.0, 5.0, 15.0]))
    gs = np.rad2deg(knee_angles(q, method="grood_suntay"))
    zyx = np.rad2deg(knee_angles(q, method="thesis_zyx"))
    np.testing.assert_allclose(gs, [90.0, 5.0, 15.0], atol=1e-9)
    np.testing.assert_allclose(zyx - gs, [-1.3, 10.1, -19.8], atol=0.05)


def test_angle_convention_and_calibration_break_comparability():
    base = _results(angle_method="grood_suntay", calibration_method="static")
    c = comparison(base, _results(angle_method="thesis_zyx", calibration_method="static"))
    assert not c["comparable"] and c["mismatch"] == ["angle_method"]
    c = comparison(base, _results(angle_method="grood_suntay", calibration_method="functional"))
    assert not c["comparable"] and c["mismatch"] == ["calibration"]
    # results.json written before the options were recorded ran with the defaults
    assert comparison(_results(), base)["comparable"]
    assert comparison(_results(), base)["with"]["angle_method"] == "grood_suntay"
