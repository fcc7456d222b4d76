"""Cycles the clinician excludes (:func:`estimators.motor_task.reject_cycles`' ``exclude``): one mechanism with the
pipeline's own rejection.

Truth: the analysis without exclusions.  Detection does not depend on the choice, so every cycle keeps its events,
its normalised curve and its ranges of motion; the statistics with cycle k excluded must equal the statistics of
the first analysis' per-cycle values over the cycles that stay (computed here with numpy, not by the analysis).
Simulated step-ups (:func:`estimators.simulation.step_up`) and a simulated walk (:mod:`estimators.simulation.gait`).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_gait_task import _analyse as _analyse_gait
from test_gait_task import _leg
from test_motor_task import FS_HZ, _noise_drift, _step_up

from estimators.motor_task import (EXCLUDED, MotorTaskParams, NotCandidateError, UnknownCycleError, analyse_task,
                                   reject_cycles)

DEG = np.pi / 180.0


@pytest.fixture(scope="module")
def step_up():
    a, _, _, t = _step_up(8, seed=3)
    a = _noise_drift(a, t, seed=3)
    return a, analyse_task(a, FS_HZ)


def test_excluded_cycles_leave_the_statistics_and_say_so(step_up):
    a, full = step_up
    assert full.n_accepted == full.n_detected == 8
    r = analyse_task(a, FS_HZ, exclude=[2, 5])
    np.testing.assert_array_equal(r.events_s, full.events_s)  # detection is untouched by the choice
    np.testing.assert_array_equal(r.curves_rad, full.curves_rad)
    assert r.accepted.tolist() == [i not in (2, 5) for i in range(8)]
    assert [(x.index, x.code, x.iteration) for x in r.rejected] == [(2, EXCLUDED, 0), (5, EXCLUDED, 0)]
    keep = [i for i in range(8) if i not in (2, 5)]
    np.testing.assert_allclose(r.mean_rad, full.curves_rad[keep].mean(axis=0))
    np.testing.assert_allclose(r.sd_rad, full.curves_rad[keep].std(axis=0, ddof=1))
    rng = full.rom_rad[keep, 0, 2]  # flexion range per kept cycle
    stats = r.rom_stats()["flexion"]["range"]
    assert stats["mean"] == pytest.approx(rng.mean()) and stats["sd"] == pytest.approx(rng.std(ddof=1))
    pct = full.phase_pct[keep, 0]
    assert r.phase_stats()["impulse"]["mean_pct"] == pytest.approx(pct.mean())
    assert r.to_dict()["cycles"]["accepted_indices"] == keep


def test_an_unknown_cycle_is_refused_with_the_count(step_up):
    a, _ = step_up
    with pytest.raises(UnknownCycleError) as err:
        analyse_task(a, FS_HZ, exclude=[8])
    assert (err.value.index, err.value.detected) == (8, 8) and "cycle 9" in str(err.value)


def test_the_rmse_rejection_runs_on_the_cycles_the_clinician_kept():
    # offsets 0 ×6, 30°, 12°: alone the 30° cycle goes first, then the 12° one (test_rejection_is_iterative).  With the
    # 30° cycle excluded by the clinician the 12° one is rejected in round 1 (the mean of the kept ones is 12/7°)
    x = np.linspace(0.0, 1.0, 101)
    base = np.column_stack([60 * DEG * np.cos(np.pi * x) ** 2, 0 * x, 0 * x])
    curves = np.array([base + np.array([o * DEG, 0.0, 0.0]) for o in (0, 0, 0, 0, 0, 0, 30, 12)])
    acc, rej, _ = reject_cycles(curves, np.ones(8, bool), MotorTaskParams(), exclude=[6])
    assert [(r.index, r.code, r.iteration) for r in rej] == [(6, EXCLUDED, 0), (7, "rmse", 1)]
    assert rej[1].rmse_rad[0] == pytest.approx((12 - 12 / 7) * DEG)
    # a cycle that was no candidate keeps the pipeline's reason: excluding it is refused (one reason per cycle)
    candidates = np.array([True] * 7 + [False])
    with pytest.raises(NotCandidateError) as err:
        reject_cycles(curves[:, :, :], candidates, MotorTaskParams(), exclude=[7])
    assert err.value.index == 7


def test_a_stride_is_excluded_from_the_gait_parameters():
    c = _leg(21, "right")
    full = _analyse_gait(c)
    k = int(np.flatnonzero(full.accepted)[1])
    r = _analyse_gait(c, exclude=[k])
    assert not r.accepted[k] and any(x.index == k and x.code == EXCLUDED for x in r.rejected)
    keep = full.accepted.copy()
    keep[k] = False
    # the shared rejection may drop another stride once k is gone; compare over what the second analysis kept
    per = full.gait["per_stride"]["stride_time_s"]
    assert r.gait["parameters"]["stride_time_s"]["mean"] == pytest.approx(per[r.accepted].mean())
    assert r.n_accepted <= full.n_accepted - 1
