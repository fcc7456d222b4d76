"""The 22.1 m lane walked as feet land (estimators.simulation.footpath): geometry, and what PDR reads on it."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.pdr import lane_stance_error
from estimators.pdr import reconstruct
from estimators.simulation.footpath import lane_centre_length_m, lane_footprints
from estimators.simulation.imu import simulate_on_grid
from estimators.simulation.motions import walking_foot
from estimators.simulation.spec import ImuSpec


def _length(xy: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))


@pytest.mark.parametrize("radius_m", [0.0, 0.5])
def test_dense_footprints_follow_the_centre_line(radius_m):
    xy, heads = lane_footprints(stride_length_m=0.005, corner_radius_m=radius_m, lateral_offset_m=0.0)
    assert _length(xy) == pytest.approx(lane_centre_length_m(corner_radius_m=radius_m), abs=0.01)
    assert lane_centre_length_m() == pytest.approx(22.1)
    np.testing.assert_allclose(xy[-1], xy[0])                    # the loop closes
    assert heads[-1] == pytest.approx(heads[0] - 2 * np.pi)     # four right turns (clockwise)
    assert xy[:, 1].min() == pytest.approx(-2.1, abs=1e-3) and xy[:, 0].max() == pytest.approx(8.95, abs=1e-3)


def test_outer_foot_walks_a_longer_loop_than_the_inner_one():
    outer, _ = lane_footprints(stride_length_m=0.005, corner_radius_m=0.5, lateral_offset_m=0.1)
    inner, _ = lane_footprints(stride_length_m=0.005, corner_radius_m=0.5, lateral_offset_m=-0.1)
    # three turned corners of a quarter circle each, radii r ± 0.1 m
    assert _length(outer) - _length(inner) == pytest.approx(3 * np.pi / 2 * 0.2, rel=0.02)


def test_true_stance_to_stance_length_falls_short_of_the_centre_line():
    """With 1.2 m strides a perfect estimate cannot read within 2 % of 22.1 m unless the corners are
    sharp and the foot is the outer one: the polygon of placements cuts every corner."""
    for r in (0.3, 0.5, 0.7):
        for off in (-0.1, -0.05, 0.0, 0.05):
            for f in (0.5, 0.75, 1.0):
                assert lane_stance_error(r, off, f) < -0.02, (r, off, f)
    assert lane_stance_error(0.0, 0.0, 1.0, stride_length_m=0.005) == pytest.approx(0.0, abs=1e-3)


def test_default_method_measures_the_true_placements_of_a_lane_walk():
    xy, heads = lane_footprints(corner_radius_m=0.5, lateral_offset_m=-0.05)
    walk = walking_foot(placements=(xy, heads), seed=4)
    assert walk.closed_loop and len(walk.placements_m) == len(xy)
    g = simulate_on_grid(walk.trajectory, ImuSpec.noise_only(), fs_hz=100.0, seed=4)
    m = reconstruct(g.t_s, g.acc, g.gyr).metrics(22.1)
    true_ed = walk.distance_m / 22.1 - 1.0
    assert true_ed < -0.05
    assert m.ed_stance == pytest.approx(true_ed, abs=0.003)     # the estimate is right, the reference is not
    assert m.ep < 0.005


def test_footprint_and_placement_validation():
    with pytest.raises(ValueError, match="corner_radius_m"):
        lane_footprints(corner_radius_m=2.0)
    with pytest.raises(ValueError, match="first_stride_fraction"):
        lane_footprints(first_stride_fraction=0.0)
    with pytest.raises(ValueError, match="placements"):
        walking_foot(placements=(np.zeros((3, 2)), np.zeros(2)))
