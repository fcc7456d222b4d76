"""Splitting one continuous recording of the protocol, against the simulator's known part boundaries.

The truth: :func:`estimators.simulation.protocol.join` places each part (figure-eight, standing, supine, step-up)
at known times; the figure-eight's motion is its trajectory without the 1 s rests at each end (the sensor lies
still in the hand there, indistinguishable from the transition's start)."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators import simulation as sim
from estimators.protocol_split import PARTS, SplitError, split_protocol
from estimators.simulation.protocol import leg_protocol


def continuous_sensor(seed: int, segment: str = "thigh", *, figure_eight: bool = True, n_cycles: int = 4):
    """One sensor's continuous protocol on a 100 Hz grid and its truth ``{part: (start_s, end_s)}``."""
    motion = sim.step_up(n_cycles, 0.17, "right", seed=seed)
    mount = sim.random_rotation(np.deg2rad(15.0), seed * 10 + 1)
    traj, truth = leg_protocol(motion, segment, mount, figure_eight_seed=seed if figure_eight else None)
    grid = sim.simulate(traj, sim.ImuSpec.random(seed * 10 + 1), seed=seed).on_grid()
    return grid, truth


@pytest.mark.parametrize("seed,segment", [(0, "thigh"), (1, "shank")])
def test_parts_found_within_a_second_of_the_truth(seed, segment):
    grid, truth = continuous_sensor(seed, segment)
    found = split_protocol(grid.acc, grid.gyr, grid.mag, fs_hz=grid.fs_hz)
    spans = found.spans_s()
    assert list(spans) == list(PARTS)
    for part, (a, b) in truth.items():
        end = len(grid.t_s) / grid.fs_hz if part == "task" else b
        assert abs(spans[part][0] - a) < 1.0 and abs(spans[part][1] - end) < 1.0, (part, spans[part], (a, b))
    assert found.octants == 8
    assert found.gravity_angle_rad["standing"] < np.deg2rad(20) < np.deg2rad(70) < found.gravity_angle_rad["lying"]


def test_the_postures_chosen_are_still_and_upright_or_lying():
    """The windows handed to the calibration hold the sensor still in the pose the truth gives."""
    grid, truth = continuous_sensor(2)
    found = split_protocol(grid.acc, grid.gyr, grid.mag, fs_hz=grid.fs_hz)
    for part in ("standing", "lying"):
        a, b = found.windows[part]
        q = grid.q_earth_sensor[a:b]
        assert np.max(quat.angle_between(q[0], q)) < np.deg2rad(0.5), part


def test_without_a_figure_eight_the_split_has_none():
    grid, truth = continuous_sensor(3, figure_eight=False)
    found = split_protocol(grid.acc, grid.gyr, grid.mag, fs_hz=grid.fs_hz)
    assert "mag_calibration" not in found.windows and found.octants == 0
    assert abs(found.spans_s()["lying"][0] - truth["lying"][0]) < 1.0


def test_a_recording_without_the_supine_posture_is_refused():
    grid, truth = continuous_sensor(4)
    cut = int(truth["lying"][0] * grid.fs_hz)
    with pytest.raises(SplitError, match="no still lying posture") as err:
        split_protocol(grid.acc[:cut], grid.gyr[:cut], grid.mag[:cut], fs_hz=grid.fs_hz)
    assert err.value.what == "lying"


def test_gaps_in_the_streams_are_survived():
    grid, truth = continuous_sensor(5)
    acc, gyr = grid.acc.copy(), grid.gyr.copy()
    i = int(truth["standing"][0] * grid.fs_hz) + 1000
    acc[i:i + 30] = np.nan
    gyr[i:i + 30] = np.nan
    found = split_protocol(acc, gyr, grid.mag, fs_hz=grid.fs_hz)
    assert abs(found.spans_s()["lying"][0] - truth["lying"][0]) < 1.0
