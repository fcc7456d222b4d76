"""``static/metawear/checks.js`` (the recorder's live checks) in Chromium on the simulator's recordings, whose
truth is known: the figure-eight's sphere coverage against the pipeline's own (estimators.magnetometer on the
same samples), stillness on the postures and not during the task, and the step-up's cycle count against the
simulated number of cycles.  Every check runs with the thresholds the server serves (app.choices.live_checks, in
GET /options), whose stillness and coverage values are the pipeline's own."""

from __future__ import annotations

import numpy as np
import pytest

from app.choices import live_checks
from estimators import knee, magnetometer
from estimators.magnetometer import fit_ellipsoid
from metawear_frames import LSB, board_units, counts

LIMITS = live_checks()


@pytest.fixture(scope="module")
def session():
    from app.pipeline.demo import simulate_session

    return simulate_session(seed=9, side="right", n_cycles=6)


def _board(session, segment, role, kind):
    """The samples as the recorder decodes them (quantised, in g, °/s, µT)."""
    _, values = session.recordings[(segment, role)][kind]
    return (counts(kind, values) / LSB[kind]).tolist()


def _coverage(page, mag):
    return page.evaluate("""async ([mag, limits]) => { const c = await import('/metawear/checks.js');
        const s = new c.SphereCoverage(limits); for (const m of mag) s.push(m); return s.coverage(); }""",
                         [mag, LIMITS["coverage"]])


def test_served_thresholds_are_the_pipelines(static_page):
    """The stillness and coverage values served are the pipeline's (its still window, its limits, its cells)."""
    params = knee.CalibrationParams()
    assert LIMITS["stillness"] == {"window_s": params.window_s, "max_gyr_sd_rad_s": knee.STILL_MAX_GYR_SD_RAD_S,
                                   "max_acc_sd_m_s2": knee.STILL_MAX_ACC_SD_M_S2}
    assert LIMITS["stillness"]["window_s"] == 5.0
    assert LIMITS["coverage"]["min_cell_samples"] == magnetometer.MIN_CELL_SAMPLES
    assert LIMITS["coverage"]["complete_fraction"] == magnetometer.COVERAGE_WARN
    # the browser's cells are the pipeline's 20: the fitted quality's cells / fraction
    d = np.random.default_rng(0).normal(size=(600, 3))
    q = fit_ellipsoid(45.0 * d / np.linalg.norm(d, axis=1, keepdims=True) + [10.0, -5.0, 3.0]).quality
    cells = static_page.evaluate("async () => (await import('/metawear/checks.js')).CELL_COUNT")
    assert cells == round(q.coverage_cells / q.coverage_fraction) == 20


def test_checks_refuse_to_run_without_served_thresholds(static_page):
    """The recorder takes no default: without GET /options' live_checks it refuses to start (nothing is guessed)."""
    msg = static_page.evaluate("""async () => { const r = await import('/metawear/recorder.js');
        try { new r.Recorder(1, null, null, undefined); return 'made'; } catch (e) { return e.message; } }""")
    assert "live_checks" in msg


def test_the_stillness_window_is_the_pipelines_judgement(static_page, session):
    """Live "still" on the last window is the pipeline's condition (estimators.knee.stillest_window's SD over its
    window, ddof 1): on the task's samples, the live SD-based flag equals the pipeline's per-window verdict."""
    acc = _board(session, "thigh", "task", "acc")
    gyr = _board(session, "thigh", "task", "gyr")
    n = min(len(acc), len(gyr), 1500)
    flags = np.asarray(_stillness(static_page, acc[:n], gyr[:n]))
    w = int(round(LIMITS["stillness"]["window_s"] * 100))
    a = np.asarray(acc[:n]) * 9.80665
    g = np.deg2rad(np.asarray(gyr[:n]))
    for end in range(w, n, 37):
        sd_a = np.sqrt(a[end - w:end].var(axis=0, ddof=1).sum())
        sd_g = np.sqrt(g[end - w:end].var(axis=0, ddof=1).sum())
        assert flags[end - 1] == (sd_g <= knee.STILL_MAX_GYR_SD_RAD_S and sd_a <= knee.STILL_MAX_ACC_SD_M_S2), end


@pytest.mark.parametrize("segment", ["thigh", "shank"])
def test_figure_eight_coverage_is_near_the_pipelines(static_page, session, segment):
    mag = _board(session, segment, "mag_calibration", "mag")
    live = _coverage(static_page, mag)
    fitted = fit_ellipsoid(np.asarray(mag)).quality.coverage_cells
    assert abs(live["cells"] - fitted) <= 2, (live, fitted)
    assert live["fraction"] >= 0.75                      # a full figure-eight reads as complete
    still = _coverage(static_page, _board(session, segment, "standing", "mag"))
    assert still["cells"] == 0                           # standing still covers nothing


def _stillness(page, acc, gyr):
    return page.evaluate("""async ([acc, gyr, limits]) => { const c = await import('/metawear/checks.js');
        const s = new c.Stillness(100, limits); const flags = [];
        for (let i = 0; i < Math.min(acc.length, gyr.length); i++) {
            s.pushAcc(acc[i]); s.pushGyr(gyr[i]); flags.push(s.still()); }
        return flags; }""", [acc, gyr, LIMITS["stillness"]])


@pytest.mark.parametrize("segment", ["thigh", "shank"])
def test_postures_are_still_and_the_task_is_not(static_page, session, segment):
    for role in ("standing", "lying"):
        flags = np.asarray(_stillness(static_page, _board(session, segment, role, "acc"), _board(session, segment, role, "gyr")))
        assert flags[500:].mean() > 0.95, (role, flags[500:].mean())      # after the first 5 s window
    task = np.asarray(_stillness(static_page, _board(session, segment, "task", "acc"), _board(session, segment, "task", "gyr")))
    assert task[500:].mean() < 0.6


@pytest.mark.parametrize("seed, n_cycles", [(9, 6), (4, 10)])
def test_the_task_cycle_count(static_page, session, seed, n_cycles):
    if (seed, n_cycles) != (9, 6):
        from app.pipeline.demo import simulate_session

        session = simulate_session(seed=seed, side="left", n_cycles=n_cycles)
    for segment in ("thigh", "shank"):
        gyr = _board(session, segment, "task", "gyr")
        n = static_page.evaluate("""async ([gyr, limits]) => { const c = await import('/metawear/checks.js');
            const k = new c.CycleCounter(100, limits); for (const g of gyr) k.push(g); return k.cycles; }""",
                                 [gyr, LIMITS["cycles"]])
        assert n == len(session.motion.cycles_s), (segment, n, len(session.motion.cycles_s))


def test_board_units_of_the_twin_are_the_decoders():
    """The twin's conversion is the one the checks assume: 1 g of specific force reads 1.0."""
    assert np.allclose(board_units("acc", np.array([[0.0, 0.0, 9.80665]])), [[0.0, 0.0, 1.0]])


@pytest.mark.parametrize("seed", [9, 4])
def test_the_knee_flexion_preview_against_the_simulated_truth(static_page, seed):
    """preview.js on the simulator's decoded samples: axes from the standing and supine recordings, flexion over the
    task against the true knee flexion (the simulator's Grood & Suntay angle) at each gyroscope sample; the filter's
    time constant was fixed before this test (1 s), on no data."""
    from app.pipeline.demo import simulate_session

    session = simulate_session(seed=seed, side="right" if seed == 9 else "left", n_cycles=5)
    data = {seg: {role: {k: _board(session, seg, role, k) for k in ("acc", "gyr")}
                  for role in ("standing", "lying", "task")} for seg in ("thigh", "shank")}
    t_gyr = {seg: session.recordings[(seg, "task")]["gyr"][0] for seg in ("thigh", "shank")}
    flex = np.asarray(static_page.evaluate("""async (data) => { const p = await import('/metawear/preview.js');
        const axes = {}, tilts = {};
        for (const seg of ['thigh', 'shank']) {
            const stand = new p.MeanForce(), lie = new p.MeanForce();
            data[seg].standing.acc.forEach((g) => stand.push(g));
            data[seg].lying.acc.forEach((g) => lie.push(g));
            axes[seg] = p.segmentAxes(stand.mean(), lie.mean());
            tilts[seg] = new p.Tilt(100);
        }
        const n = Math.min(data.thigh.task.gyr.length, data.shank.task.gyr.length);
        const out = [];
        for (let k = 0; k < n; k++) {
            for (const seg of ['thigh', 'shank']) {
                if (k < data[seg].task.acc.length) tilts[seg].pushAcc(data[seg].task.acc[k]);
                tilts[seg].pushGyr(data[seg].task.gyr[k]);
            }
            out.push(p.flexionDeg(tilts, axes));
        }
        return out; }""", data), dtype=float)
    # the truth at the thigh's gyroscope times (the simulator's phone clock: task time from the role's start)
    t = t_gyr["thigh"][:len(flex)] - session.role_epoch_s["task"]
    motion = session.motion
    truth = np.rad2deg(motion.knee_angles_at(np.clip(t, motion.t_s[0], motion.t_s[-1]))[:, 0])
    settled = slice(200, None)                       # the filter's first 2 s
    rmse = float(np.sqrt(np.mean((flex[settled] - truth[settled]) ** 2)))
    print(f"seed {seed}: preview flexion RMSE {rmse:.2f} deg over {len(flex)} samples, truth range {np.ptp(truth):.1f} deg")
    assert rmse < 6.0
    assert np.corrcoef(flex[settled], truth[settled])[0, 1] > 0.98
