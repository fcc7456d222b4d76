"""Magnetic disturbance flags against a simulated field with a known perturbation."""

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.disturbance import field_disturbance
from estimators.simulation import ImuSpec, motions, simulate_on_grid


@pytest.fixture(scope="module")
def grid():
    return simulate_on_grid(motions.rotations(20.0, seed=2), ImuSpec.noise_only(), fs_hz=100.0, seed=2)


def test_clean_field_is_not_disturbed(grid):
    check = field_disturbance(grid.mag, grid.q_earth_sensor, float(np.linalg.norm(grid.mag_earth_ut)))
    assert check.fraction < 0.01 and not check.warnings
    assert np.rad2deg(check.dip_ref_rad) == pytest.approx(np.rad2deg(np.arctan2(40.0, 20.0)), abs=0.5)


def test_rotated_field_of_right_norm_is_caught_by_dip(grid):
    mag = grid.mag.copy()
    bad = slice(500, 900)
    # a disturbance that bends the field by 15° about the sensor x axis keeps |m| but changes the dip
    mag[bad] = quat.rotate(quat.from_axis_angle([1.0, 0.0, 0.0], np.deg2rad(15.0)), mag[bad])
    check = field_disturbance(mag, grid.q_earth_sensor, float(np.linalg.norm(grid.mag_earth_ut)), label="thigh")
    assert check.disturbed[bad].mean() > 0.5 and check.disturbed[:400].mean() < 0.02
    assert [w.code for w in check.warnings] == ["magnetic_disturbance"]
    assert "thigh" in check.warnings[0].message
    p = check.warnings[0].params
    assert p == {"segment": "thigh", "pct": 100.0 * check.fraction, "norm_pct": 100.0 * check.max_norm_dev,
                 "dip_deg": np.rad2deg(check.max_dip_dev_rad)}
    assert f"during {p['pct']:.0f} %" in check.warnings[0].message and 10.0 < p["dip_deg"] < 20.0


def test_norm_change_and_missing_rows(grid):
    mag = grid.mag.copy()
    mag[100:200] *= 1.3
    mag[300:310] = np.nan
    check = field_disturbance(mag, grid.q_earth_sensor, float(np.linalg.norm(grid.mag_earth_ut)))
    assert check.disturbed[100:200].all() and not check.disturbed[300:310].any()


@pytest.mark.parametrize("field", [0.0, -1.0, float("nan")])
def test_bad_reference(grid, field):
    with pytest.raises(ValueError, match="field_ut"):
        field_disturbance(grid.mag, grid.q_earth_sensor, field)
