"""Motor-task analysis against synthetic flexion curves with known cycle and phase boundaries."""

from __future__ import annotations

import json

import numpy as np
import pytest

from estimators import simulation as sim
from estimators.motor_task import (
    EVENTS,
    TASKS,
    MotorTaskParams,
    PhaseSpec,
    TaskSpec,
    analyse_task,
    normalise_cycles,
    reject_cycles,
)
from estimators.simulation.knee import STEP_UP_SHAPES, _thesis_defaults

DEG = np.pi / 180.0
FS_HZ = 100.0
TRUE_EVENTS = [0, 1, 3, 4]  # simulator phases_s columns: onset, peak flexion, leaving full extension, back at rest


def _step_up(n: int = 10, h: float = 0.17, seed: int = 0, shape: str = "thesis", **kwargs):
    leg = sim.step_up(n_cycles=n, step_height_m=h, seed=seed, fs_hz=FS_HZ, shape=shape, **kwargs)
    return leg.knee_angles_rad.copy(), leg.cycles_s, leg.phases_s, leg.t_s


def _noise_drift(a, t, seed=0, noise_deg=0.5, drift_deg=2.0):
    rng = np.random.default_rng(seed)
    out = a + noise_deg * DEG * rng.standard_normal(a.shape)
    out[:, 0] += drift_deg * DEG * (t - t[0]) / (t[-1] - t[0])
    return out


def _keyframes(times, values, fs_hz=FS_HZ):
    """Minimum-jerk ramps between key frames (times on the sample grid)."""
    times, values = np.asarray(times, float), np.asarray(values, float)
    t = np.arange(int(round(times[-1] * fs_hz)) + 1) / fs_hz
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    tau = (t - times[i]) / (times[i + 1] - times[i])
    return t, values[i] + (values[i + 1] - values[i]) * sim.min_jerk(tau)


def _assert_events_match(r, phases_s, cycles_s, tol_frac=0.02):
    """Every true cycle found, accepted, and every boundary within tol_frac of the cycle duration."""
    assert r.n_detected == len(phases_s)
    assert r.n_accepted == len(phases_s), [x.message for x in r.rejected]
    dur = cycles_s[:, 1] - cycles_s[:, 0]
    err = np.abs(r.events_s[:, TRUE_EVENTS] - phases_s) / dur[:, None]
    assert np.all(err < tol_frac), np.round(err.max(axis=0), 4)
    assert np.all(np.abs(r.cycles_s - cycles_s) / dur[:, None] < tol_frac)
    return err


# ------------------------------------------------------------------------------------------ step-up, simulator truth
@pytest.mark.parametrize("shape", STEP_UP_SHAPES)
@pytest.mark.parametrize("h", [0.17, 0.34])
@pytest.mark.parametrize("n", [5, 15])
def test_every_cycle_and_boundary_noise_free(h, n, shape):
    a, cyc, ph, t = _step_up(n, h, seed=n, shape=shape)
    r = analyse_task(a, FS_HZ)
    err = _assert_events_match(r, ph, cyc)
    assert err.max() < 0.005  # noise-free: the minimum-jerk / least-squares fits are essentially exact
    assert not r.warnings


@pytest.mark.parametrize("shape", STEP_UP_SHAPES)
@pytest.mark.parametrize("h", [0.17, 0.34])
@pytest.mark.parametrize("n", [5, 15])
def test_every_cycle_and_boundary_with_noise_and_drift(h, n, shape):
    a, cyc, ph, t = _step_up(n, h, seed=10 + n, shape=shape)
    r = analyse_task(_noise_drift(a, t, seed=n), FS_HZ)
    _assert_events_match(r, ph, cyc)
    # the mean flexion curve starts and ends in the start posture and reaches ~0°
    f0 = _thesis_defaults(h)[1] if shape == "thesis" else (30.0 + 176.5 * h) * DEG
    assert abs(r.mean_rad[0, 0] - f0) < 4 * DEG and abs(r.mean_rad[-1, 0] - f0) < 4 * DEG
    assert r.mean_rad[:, 0].min() < 5 * DEG
    assert r.mean_rad.shape == (101, 3) and r.sd_rad.shape == (101, 3)


@pytest.mark.parametrize("rest_s", [0.05, 0.3])
def test_continuous_cycles_with_little_or_no_rest(rest_s):
    a, cyc, ph, t = _step_up(8, 0.34, seed=21, shape="rest_between", rest_s=rest_s)
    _assert_events_match(analyse_task(_noise_drift(a, t, seed=3), FS_HZ), ph, cyc)


def test_time_offset_and_flexion_only_input():
    a, cyc, ph, t = _step_up(5, seed=3)
    r = analyse_task(a[:, 0], FS_HZ, t0_s=100.0)
    _assert_events_match(r, ph + 100.0, cyc + 100.0)


def test_pause_mid_task():
    a1, c1, p1, t1 = _step_up(4, seed=1, final_rest_s=4.0)
    a2, c2, p2, t2 = _step_up(5, seed=2, initial_rest_s=4.0)
    off = t1[-1] + 1.0 / FS_HZ
    a2 = a2 - a2[0] + a1[-1]  # continuous across the join: an 8 s pause in the start posture
    a = np.vstack([a1, a2])
    t = np.arange(len(a)) / FS_HZ
    ph = np.vstack([p1, p2 + off])
    cyc = np.vstack([c1, c2 + off])
    r = analyse_task(_noise_drift(a, t, seed=5), FS_HZ)
    _assert_events_match(r, ph, cyc)
    assert r.cycles_s[3, 1] < ph[3, 3] + 0.1  # the pause after cycle 4 is in no cycle
    # the pause stretches cycle 4 (onset → onset) but not its normalised movement
    rest = r.phase_stats()
    assert rest["movement"]["sd_s"] < 0.5


@pytest.mark.parametrize("where", ["extension", "impulse", "hold"])
def test_spoiled_first_cycle_is_excluded(where):
    a, cyc, ph, t = _step_up(10, seed=3, shape="rest_between")
    cut_s = {"extension": ph[0, 1] + 0.5, "impulse": ph[0, 0] + 0.2, "hold": ph[0, 2] - 0.3}[where]
    i = int(round(cut_s * FS_HZ))
    r = analyse_task(a[i:], FS_HZ, t0_s=t[i])
    assert r.n_detected == 10 and r.n_accepted == 9
    assert [(x.index, x.code) for x in r.rejected] == [(0, "incomplete_start")]
    assert not r.accepted[0] and np.isnan(r.events_s[0, 0])
    dur = cyc[1:, 1] - cyc[1:, 0]
    assert np.all(np.abs(r.events_s[1:, TRUE_EVENTS] - ph[1:]) / dur[:, None] < 0.02)


@pytest.mark.parametrize("where", ["fall", "fall_late", "hold"])
def test_spoiled_last_cycle_is_excluded(where):
    a, cyc, ph, t = _step_up(10, seed=4)
    cut_s = {"fall": ph[-1, 2] + 0.4, "fall_late": ph[-1, 3] - 0.1, "hold": ph[-1, 2] - 0.3}[where]
    r = analyse_task(a[:int(round(cut_s * FS_HZ))], FS_HZ)
    assert r.n_detected == 10 and r.n_accepted == 9
    assert [(x.index, x.code) for x in r.rejected] == [(9, "incomplete_end")]
    assert "ends" in r.rejected[0].message or "return" in r.rejected[0].message
    dur = cyc[:-1, 1] - cyc[:-1, 0]
    assert np.all(np.abs(r.events_s[:-1, TRUE_EVENTS] - ph[:-1]) / dur[:, None] < 0.02)
    # the cycle before the spoiled one still ends at the spoiled one's onset
    assert abs(r.cycles_s[-2, 1] - cyc[-2, 1]) < 0.05


def test_first_cycle_spoiled_by_filter_convergence_is_rejected_by_rmse():
    a, cyc, ph, t = _step_up(10, seed=4)
    b = a.copy()
    b[:, 0] += 30 * DEG * np.exp(-t / 4.0)  # a slowly decaying offset, as a converging orientation filter gives
    r = analyse_task(b, FS_HZ)
    assert r.n_detected == 10 and r.n_accepted == 9
    (rej,) = r.rejected
    assert rej.index == 0 and rej.code == "rmse" and rej.iteration == 1
    assert rej.rmse_rad[0] > 8 * DEG and "flexion" in rej.message
    assert r.to_dict()["cycles"]["rejected"][0]["reason"] == "rmse"


# ------------------------------------------------------------------------------------------ rejection iteration
def _curves(offsets_deg):
    x = np.linspace(0.0, 1.0, 101)
    base = np.column_stack([60 * DEG * np.cos(np.pi * x) ** 2, 0 * x, 0 * x])
    return np.array([base + np.array([o * DEG, 0.0, 0.0]) for o in offsets_deg])


def test_rejection_is_iterative():
    # mean offset (30 + 12)/8 = 5.25°: cycle B (12°) is 6.75° from it, under 8° in the first round;
    # after A (30°) goes, the mean moves to 12/7 = 1.71° and B is 10.3° away: rejected in round 2
    curves = _curves([0, 0, 0, 0, 0, 0, 30, 12])
    acc, rej, stopped = reject_cycles(curves, np.ones(8, bool), MotorTaskParams())
    assert [(r.index, r.iteration) for r in rej] == [(6, 1), (7, 2)]
    assert rej[0].rmse_rad[0] == pytest.approx(24.75 * DEG)
    assert rej[1].rmse_rad[0] == pytest.approx((12 - 12 / 7) * DEG)
    assert acc.tolist() == [True] * 6 + [False, False] and not stopped


def test_rejection_stops_at_min_cycles_and_other_angles_optional():
    curves = _curves([0, 10, 40])
    acc, rej, stopped = reject_cycles(curves, np.ones(3, bool), MotorTaskParams())
    assert acc.all() and not rej and stopped
    acc, rej, stopped = reject_cycles(curves, np.ones(3, bool), MotorTaskParams(min_accepted_cycles=2))
    assert [r.index for r in rej] == [2] and acc.tolist() == [True, True, False]
    c = _curves([0, 0, 0, 0])
    c[3, :, 2] += 10 * DEG  # internal rotation off by 10°: ignored by default, rejected when checked
    assert reject_cycles(c, np.ones(4, bool), MotorTaskParams())[0].all()
    acc, rej, _ = reject_cycles(c, np.ones(4, bool), MotorTaskParams(rejection_rmse_rad=(8 * DEG, None, 5 * DEG)))
    assert acc.tolist() == [True, True, True, False] and "internal_rotation" in rej[0].message


# ------------------------------------------------------------------------------------------ hand-checkable statistics
def _hand_step_up():
    """Three step-up cycles from key frames: rest 60°, impulse to 70/72/74°, extension to 0/1/2° held, fall."""
    imp, ext, hold, fall, rest = [0.4, 0.5, 0.6], [0.9, 1.0, 1.1], [0.5, 0.6, 0.7], [1.0, 1.2, 1.4], 1.0
    peaks, mins = [70.0, 72.0, 74.0], [0.0, 1.0, 2.0]
    times, values, events = [0.0, 2.0], [60.0, 60.0], []
    t = 2.0
    for k in range(3):
        e = np.cumsum([t, imp[k], ext[k], hold[k], fall[k]])  # onset, peak, far reached, far left, at rest
        times += list(e[1:])
        values += [peaks[k], mins[k], mins[k], 60.0]
        t = e[-1]
        events.append(e)
        times.append(t + rest)
        values.append(60.0)
        t += rest
    tt, flex = _keyframes(times, values)
    a = np.column_stack([flex, 0.1 * flex, -0.05 * flex]) * DEG
    return a, np.array(events), dict(imp=imp, ext=ext, hold=hold, fall=fall)


def test_rom_and_phase_stats_on_a_hand_checkable_example():
    a, ev, d = _hand_step_up()
    r = analyse_task(a, FS_HZ)
    assert r.n_accepted == 3
    assert np.allclose(r.events_s, ev, atol=0.02)
    rom = r.rom_stats()
    # flexion max 70/72/74 → 72 ± 2; min 0/1/2 → 1 ± 1; range 70/71/72 → 71 ± 1 (SD with ddof = 1)
    assert rom["flexion"]["max"]["mean"] == pytest.approx(72 * DEG, abs=1e-9)
    assert rom["flexion"]["max"]["sd"] == pytest.approx(2 * DEG, abs=1e-9)
    assert rom["flexion"]["min"]["mean"] == pytest.approx(1 * DEG, abs=1e-9)
    assert rom["flexion"]["min"]["sd"] == pytest.approx(1 * DEG, abs=1e-9)
    assert rom["flexion"]["range"]["mean"] == pytest.approx(71 * DEG, abs=1e-9)
    assert rom["flexion"]["range"]["sd"] == pytest.approx(1 * DEG, abs=1e-9)
    assert rom["adduction"]["max"]["mean"] == pytest.approx(7.2 * DEG, abs=1e-9)
    assert rom["internal_rotation"]["min"]["mean"] == pytest.approx(-3.6 * DEG, abs=1e-9)
    ps = r.phase_stats()
    imp, ext = np.array(d["imp"]), np.array(d["ext"]) + np.array(d["hold"])
    fall = np.array(d["fall"])
    move = imp + ext + fall
    # impulse 0.4/0.5/0.6 s → 0.5 ± 0.1 s; extension (ramp + hold) 1.4/1.6/1.8 → 1.6 ± 0.2; fall 1.2 ± 0.2
    assert ps["impulse"]["mean_s"] == pytest.approx(0.5, abs=0.01)
    assert ps["impulse"]["sd_s"] == pytest.approx(0.1, abs=0.01)
    assert ps["extension"]["mean_s"] == pytest.approx(1.6, abs=0.01)
    assert ps["extension"]["sd_s"] == pytest.approx(0.2, abs=0.01)
    assert ps["fall"]["mean_s"] == pytest.approx(1.2, abs=0.01)
    assert ps["fall"]["sd_s"] == pytest.approx(0.2, abs=0.01)
    for name, x in (("impulse", imp), ("extension", ext), ("fall", fall)):
        assert ps[name]["mean_pct"] == pytest.approx(np.mean(100 * x / move), abs=0.5)
        assert ps[name]["sd_pct"] == pytest.approx(np.std(100 * x / move, ddof=1), abs=0.3)
    assert sum(ps[n]["mean_pct"] for n in ("impulse", "extension", "fall")) == pytest.approx(100.0)
    assert ps["movement"]["mean_s"] == pytest.approx(np.mean(move), abs=0.01)
    assert ps["cycle"]["mean_s"] == pytest.approx(np.mean(move[:2]) + 1.0, abs=0.01)


def test_cycle_span_normalisation():
    a, ev, d = _hand_step_up()
    r = analyse_task(a, FS_HZ, params=MotorTaskParams(normalise_span="cycle"))
    # the thesis' span: onset → next onset (the rest after the fall included); the last one ends back at rest
    cycle = np.append(np.diff(r.events_s[:, 0]), r.events_s[-1, 4] - r.events_s[-1, 0])
    assert np.allclose(cycle[:2], np.diff(ev[:, 0]), atol=0.02)
    assert np.allclose(r.cycles_s[:, 1], ev[:, 4], atol=0.02)  # the cycle itself ends back at rest
    assert np.allclose(r.phase_pct[:, 0], 100 * r.phase_s[:, 0] / cycle)
    assert r.phase_pct[:2].sum(axis=1).max() < 90  # the rest after the fall is part of the cycle


def test_threshold_boundary_model():
    a, ev, _ = _hand_step_up()
    r = analyse_task(a, FS_HZ, params=MotorTaskParams(boundary_model="threshold", boundary_threshold_rad=2 * DEG))
    assert r.n_accepted == 3
    # threshold instants lie inside each transition: later than its start, earlier than its end
    assert np.all(r.events_s[:, 0] > ev[:, 0]) and np.all(r.events_s[:, 4] < ev[:, 4])
    assert np.all(np.abs(r.events_s - ev) < 0.3)


def test_normalise_cycles_interpolates_linearly():
    a = np.column_stack([np.arange(50.0), 2 * np.arange(50.0), np.zeros(50)])
    c = normalise_cycles(a, np.array([[10.0, 30.0], [np.nan, 20.0]]), 101)
    assert np.allclose(c[0, :, 0], np.linspace(10, 30, 101)) and np.allclose(c[0, :, 1], np.linspace(20, 60, 101))
    assert np.isnan(c[1]).all()


# ------------------------------------------------------------------------------------------ other tasks
def _repetitions(rest_deg, far_deg, n=6, move=(1.0, 1.2), hold=0.5, rest_s=1.5):
    times, values, events, t = [0.0, 2.0], [rest_deg, rest_deg], [], 2.0
    for k in range(n):
        m1, m2 = move[0] * (1 + 0.05 * k), move[1] * (1 - 0.03 * k)
        e = [t, t + m1, t + m1 + hold, t + m1 + hold + m2]
        times += e[1:] + [e[3] + rest_s]
        values += [far_deg, far_deg, rest_deg, rest_deg]
        events.append(e)
        t = e[3] + rest_s
    tt, flex = _keyframes(times, values)
    return np.column_stack([flex, 0 * flex, 0 * flex]) * DEG, np.array(events), tt


@pytest.mark.parametrize("task, rest_deg, far_deg", [("seated_knee_extension", 90.0, 2.0), ("squat", 3.0, 95.0)])
def test_other_tasks_on_synthetic_repetitions(task, rest_deg, far_deg):
    a, ev, t = _repetitions(rest_deg, far_deg)
    r = analyse_task(_noise_drift(a, t, seed=2), FS_HZ, task=task)
    assert r.n_detected == len(ev) and r.n_accepted == len(ev)
    cycle = np.append(np.diff(ev[:, 0]), ev[-1, 3] - ev[-1, 0])
    err = np.abs(r.events_s[:, [0, 2, 3, 4]] - ev) / cycle[:, None]
    assert np.all(err < 0.02)
    assert np.isnan(r.events_s[:, 1]).all()  # no countermovement
    assert set(r.phase_stats()) >= set(TASKS[task].phase_names)


def test_step_up_without_countermovement_gives_zero_impulse():
    a, ev, t = _repetitions(60.0, 1.0, n=4)
    r = analyse_task(a, FS_HZ, task="step_up")
    assert r.n_accepted == 4
    assert np.allclose(r.phase_s[:, 0], 0.0) and np.allclose(r.events_s[:, 0], ev[:, 0], atol=0.05)


# ------------------------------------------------------------------------------------------ contracts and bad input
def test_to_dict_is_json_in_radians():
    a, cyc, ph, t = _step_up(5, seed=7)
    d = analyse_task(a, FS_HZ).to_dict()
    json.dumps(d, allow_nan=False)
    assert d["task"] == "step_up" and d["cycles"]["detected"] == 5 and d["cycles"]["accepted"] == 5
    assert d["cycles"]["events"] == list(EVENTS) and len(d["cycles"]["boundaries_s"]) == 5
    assert set(d["rom_rad"]) == {"flexion", "adduction", "internal_rotation"}
    assert set(d["rom_rad"]["flexion"]) == {"max", "min", "range"}
    assert set(d["phases"]["impulse"]) == {"mean_s", "sd_s", "mean_pct", "sd_pct"}
    assert len(d["curves_rad"]["flexion"]["mean"]) == 101 and len(d["curves_rad"]["adduction"]["sd"]) == 101
    assert 1.3 < d["rom_rad"]["flexion"]["range"]["mean"] < 1.5  # ~80° in rad, not degrees


def test_no_motion_gives_empty_result_and_warning():
    r = analyse_task(np.full((1000, 3), 0.5), FS_HZ)
    assert r.n_detected == 0 and r.n_accepted == 0 and r.task_span_s is None
    assert [w.code for w in r.warnings] == ["MOTOR_TASK_NO_MOTION"]
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["curves_rad"]["flexion"]["mean"][0] is None and d["phases"]["fall"]["mean_s"] is None


def test_single_cycle_warns_few_cycles():
    a, cyc, ph, t = _step_up(1, seed=1)
    r = analyse_task(a, FS_HZ)
    assert r.n_accepted == 1 and "MOTOR_TASK_FEW_CYCLES" in [w.code for w in r.warnings]
    few = next(w for w in r.warnings if w.code == "MOTOR_TASK_FEW_CYCLES")
    assert few.params == {"accepted": 1, "detected": r.n_detected}
    assert r.to_dict()["warnings"] == [w.to_dict() for w in r.warnings]
    assert np.isnan(r.phase_stats()["impulse"]["sd_s"])


@pytest.mark.parametrize("task", ["step_up", "squat"])
def test_motion_without_cycles_and_stopped_rejection_warn_with_their_values(task):
    t = np.arange(3000) / FS_HZ
    wobble = DEG * (30.0 + 5.0 * np.sin(2 * np.pi * 3.0 * t))  # moves, but never a task cycle
    r = analyse_task(np.column_stack([wobble, 0 * t, 0 * t]), FS_HZ, task=task)
    (w,) = r.warnings
    assert w.code == "MOTOR_TASK_NO_CYCLES" and w.params == {"task": task, "far_label": TASKS[task].far_label}
    a, _, _, _ = _step_up(4, seed=1)
    r = analyse_task(a, FS_HZ, params=MotorTaskParams(rejection_rmse_rad=(1e-4, None, None), min_accepted_cycles=2))
    stopped = [w for w in r.warnings if w.code == "MOTOR_TASK_REJECTION_STOPPED"]
    assert len(stopped) == 1 and stopped[0].params == {"min_cycles": 2} and r.n_accepted == 2


@pytest.mark.parametrize("kwargs, match", [
    (dict(lowpass_hz=0.0), "lowpass_hz"), (dict(boundary_model="x"), "boundary_model"),
    (dict(normalise_span="x"), "normalise_span"), (dict(n_points=2), "n_points"),
    (dict(rejection_rmse_rad=(0.1, -1.0, None)), "rejection_rmse_rad"), (dict(min_accepted_cycles=0), "min_accepted"),
    (dict(merge_gap_s=-1.0), "merge_gap_s")])
def test_parameter_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        MotorTaskParams(**kwargs)


@pytest.mark.parametrize("n", [0, 1, 5])
def test_tiny_input_gives_empty_result(n):
    r = analyse_task(np.zeros((n, 3)), np.int64(100))
    assert r.n_detected == 0 and r.mean_rad.shape == (101, 3)


def test_bad_input():
    with pytest.raises(ValueError, match="shape"):
        analyse_task(np.zeros((10, 2)), FS_HZ)
    with pytest.raises(ValueError, match="NaN"):
        analyse_task(np.full((10, 3), np.nan), FS_HZ)
    with pytest.raises(ValueError, match="fs_hz"):
        analyse_task(np.zeros((10, 3)), 0.0)
    with pytest.raises(ValueError, match="unknown task"):
        analyse_task(np.zeros((10, 3)), FS_HZ, task="jump")
    with pytest.raises(ValueError, match="consecutive"):
        TaskSpec("x", "flexion", False, (PhaseSpec("a", "onset", "far_reached"),
                                         PhaseSpec("b", "far_left", "rest_reached")), "top")


def test_the_compiled_split_residuals_equal_the_numpy_reference():
    """detection.split_rss (numba) against detection._split_residuals (numpy) on a noisy fall–rest–impulse."""
    from estimators.motor_task import detection

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 240.0)
    y = np.interp(t, [0, 60, 110, 240], [1.0, 0.1, 0.12, 1.3]) + rng.normal(scale=0.01, size=t.size)
    t1 = rng.uniform(20, 120, 300)
    t0 = t1 + rng.uniform(0, 80, 300)
    ref = detection._split_residuals(t, y, 5.0, 235.0, t1, t0)[0]
    np.testing.assert_allclose(detection.split_rss(t, y, 5.0, 235.0, t1, t0), ref, rtol=1e-9, atol=1e-9)


# ------------------------------------------------------------------------------------------ issue 13 §7 regressions
@pytest.mark.parametrize("shape", STEP_UP_SHAPES)
def test_cycles_with_a_tenth_of_a_second_of_rest_at_the_recording_edges_are_accepted(shape):
    """Seeds 5 and 35 of benchmarks/robustness.py: 0.1 s of rest before the first / after the last cycle (and the
    streams' alignment trims a few samples).  The still run at an edge, which also holds the movement's slow start
    or end, lasts ~0.15–0.19 s: the 0.2 s the detector asked for rejected these complete cycles."""
    a, cyc, ph, t = _step_up(6, 0.17, seed=35, shape=shape, initial_rest_s=0.12, final_rest_s=0.1)
    i0, i1 = 2, len(a) - 3  # the alignment's trim
    r = analyse_task(_noise_drift(a[i0:i1], t[i0:i1], seed=35, noise_deg=0.1, drift_deg=0.5), FS_HZ, t0_s=t[i0])
    _assert_events_match(r, ph, cyc)


def test_a_cycle_cut_by_the_recording_at_its_onset_is_incomplete():
    """The other side of the edge rule: a recording that starts as the impulse starts (0.05 s of it gone) holds no
    rest before the first cycle."""
    a, cyc, ph, t = _step_up(6, 0.17, seed=35, shape="rest_between", initial_rest_s=0.0)
    i = 5
    r = analyse_task(a[i:], FS_HZ, t0_s=t[i])
    assert [(x.index, x.code) for x in r.rejected] == [(0, "incomplete_start")]


def test_gyroscope_flexion_keeps_the_gyroscopes_shape_and_the_angles_level():
    """D7 against the simulator: sensor gyroscopes (noise, bias residual, scale and axis errors) of a step-up, and
    flexion angles spoiled by what an accelerometer bias does through an offline smoother (a 0.3 Hz ripple of 0.5°
    and a 2° offset).  The D7 flexion follows the true flexion's fast part (ripple gone) at the angles' level."""
    from estimators import quaternion as quat
    from estimators.motor_task.detection import gyroscope_flexion

    leg = sim.step_up(6, 0.34, "left", shape="thesis", cycle_s=5.5, seed=34)
    spec = sim.ImuSpec.random(34)
    spec = sim.ImuSpec(sim.AccErrors.noise_only(), spec.gyr, spec.mag)
    gyr = {}
    for i, seg in enumerate(("thigh", "shank")):
        mount = sim.random_rotation(np.deg2rad(12.0), 340 + i)
        imu = sim.simulate(getattr(leg, seg), spec, q_segment_sensor=mount, seed=3400 + i).on_grid(FS_HZ)
        gyr[seg] = imu.gyr - spec.gyr.bias_rad_s  # the calibration removes the constant bias
        if seg == "shank":
            axis = quat.rotate(quat.conjugate(mount), np.array([0.0, 0.0, 1.0]))
            t = imu.t_true_s
    truth = np.interp(t, leg.t_s, leg.knee_angles_rad[:, 0])
    spoiled = truth + 2.0 * DEG + 0.5 * DEG * np.sin(2 * np.pi * 0.3 * t)
    fit = gyroscope_flexion(spoiled, FS_HZ, gyr["thigh"], gyr["shank"], axis, MotorTaskParams().gyro_crossover_hz)
    err = fit - truth
    assert abs(np.median(err) - 2.0 * DEG) < 0.3 * DEG  # the angles' level
    inner = slice(int(5 * FS_HZ), len(t) - int(5 * FS_HZ))  # away from the zero-phase filter's ends
    assert np.std(err[inner]) < 0.1 * DEG < 0.35 * DEG < np.std((spoiled - truth)[inner])
    assert gyroscope_flexion(spoiled, FS_HZ, None, gyr["shank"], axis, 0.05) is None
