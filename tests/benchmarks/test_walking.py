"""The walking benchmark's scoring and data-only calibration against the simulator's truth."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import walking
from estimators import quaternion as quat


@pytest.fixture(scope="module")
def clips():
    return walking.clip(1)


def test_score_is_zero_on_the_truth_and_sees_an_overestimated_range(clips):
    c = clips[0]
    s = walking.score(c.flexion_true_rad, c)
    assert s["rom_err_deg"] == 0.0 and s["rmse_deg"] == 0.0 and s["r"] == pytest.approx(1.0)
    assert s["strides"] == len(c.strides_s) >= 3
    f = np.rad2deg(c.flexion_true_rad)
    roms = [np.ptp(f[(c.t_s >= a) & (c.t_s < b)]) for a, b in c.strides_s]
    s = walking.score(1.1 * c.flexion_true_rad + 0.2, c)
    assert s["rom_err_deg"] == pytest.approx(0.1 * np.mean(roms), rel=1e-9)
    assert s["rmse_offset_deg"] == pytest.approx(0.1 * np.std(f), rel=1e-9)
    assert s["r"] == pytest.approx(1.0)


def test_true_orientations_with_the_known_mounting_give_the_bones_flexion_but_for_the_wobble(clips):
    for c in clips:
        f = walking.flexion(c.q_true["thigh"], c.q_true["shank"], c.q_sensor_segment, c.side, "9d")
        s = walking.score(f, c)
        wobble_deg = np.rad2deg(max(c.info["shank_wobble_rad"], c.info["thigh_wobble_rad"]))
        assert 0.0 < s["rmse_deg"] < wobble_deg
        assert abs(s["rom_err_deg"]) < wobble_deg
        # 6D: the hinge heading alignment of a correct pair changes next to nothing
        f6 = walking.flexion(c.q_true["thigh"], c.q_true["shank"], c.q_sensor_segment, c.side, "6d")
        assert np.sqrt(np.mean((f6 - f) ** 2)) < np.deg2rad(0.5)


def test_data_only_calibration_finds_the_flexion_and_long_axes(clips):
    for c in clips:
        cal = walking.data_calibration(c)
        for seg in ("thigh", "shank"):
            z_true = quat.rotate(c.q_sensor_segment[seg], [0.0, 0.0, 1.0])
            z_data = quat.rotate(cal[seg], [0.0, 0.0, 1.0])
            assert np.rad2deg(np.arccos(abs(z_true @ z_data))) < 15.0   # non-hinge knee + wobble: a few degrees
            y_true = quat.rotate(c.q_sensor_segment[seg], [0.0, 1.0, 0.0])
            y_data = quat.rotate(cal[seg], [0.0, 1.0, 0.0])
            assert np.rad2deg(np.arccos(y_true @ y_data)) < 20.0        # mean inclination while walking
        f = walking._signed_data_flexion(c.q_true["thigh"], c.q_true["shank"], cal, c.side, "9d")
        s = walking.score(f, c)
        assert s["r"] > 0.99 and abs(s["rom_err_deg"]) < 1.5


def test_params_parse_flags_and_numbers():
    assert walking.parse_params(["chakamo:offline=false,tau_acc_s=5", "madgwick:beta_rad_s=0.1"]) == {
        "chakamo": {"offline": False, "tau_acc_s": 5.0}, "madgwick": {"beta_rad_s": 0.1}}


def test_offline_padding_swap_is_undone_after_the_run():
    import estimators.orientation.chakamo as ck

    before = ck.zero_phase_lowpass
    with walking.offline_padding("even"):
        assert ck.zero_phase_lowpass is not before
    assert ck.zero_phase_lowpass is before
    with walking.offline_padding("odd"):
        assert ck.zero_phase_lowpass is before
