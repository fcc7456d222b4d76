"""``static/metawear/checks.js`` (the recorder's live checks) in Chromium on the simulator's recordings, whose
truth is known: the figure-eight's sphere coverage against the pipeline's own (estimators.magnetometer on the
same samples), stillness on the postures and not during the task, and the step-up's cycle count against the
simulated number of cycles.  Every check runs with the thresholds the server serves (app.choices.live_checks, in
GET /options), whose stillness and coverage values are the pipeline's own."""

from __future__ import annotations

import numpy as np
import pytest

from app.choices import live_checks
from estimators import knee
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
    """The stillness and coverage values served are the pipeline's, as its docstrings state them: the 5 s still
    window (estimators.knee.CalibrationParams), 0.05 rad/s and 0.3 m/s² (STILL_MAX_GYR_SD_RAD_S,
    STILL_MAX_ACC_SD_M_S2), 3 samples per cell (magnetometer.MIN_CELL_SAMPLES) and the warning below 15 of the 20
    cells (COVERAGE_WARN 0.75); and the browser's cells are the pipeline's 20."""
    assert LIMITS["stillness"] == {"window_s": 5.0, "max_gyr_sd_rad_s": 0.05, "max_acc_sd_m_s2": 0.3}
    assert LIMITS["coverage"]["min_cell_samples"] == 3 and type(LIMITS["coverage"]["min_cell_samples"]) is int
    assert LIMITS["coverage"]["complete_fraction"] == 0.75
    # the browser's cells are the pipeline's 20: the fitted quality's cells / fraction
    d = np.random.default_rng(0).normal(size=(600, 3))
    q = fit_ellipsoid(45.0 * d / np.linalg.norm(d, axis=1, keepdims=True) + [10.0, -5.0, 3.0]).quality
    cells = static_page.evaluate("async () => (await import('/metawear/checks.js')).CELL_COUNT")
    assert cells == round(q.coverage_cells / q.coverage_fraction) == 20


def test_checks_refuse_to_run_without_served_thresholds(static_page):
    """The recorder takes no default: without GET /options' live_checks it refuses to start (nothing is guessed)."""
    msg = static_page.evaluate("""async () => { const r = await import('/metawear/recorder.js');
        try { new r.Recorder(1, null, null, undefined); return 'made'; } catch (e) { return [e.code, e.message]; } }""")
    assert msg[0] == "live_checks_missing" and "live_checks" in msg[1]          # the page says it by its code


#: the pipeline's still limits as its docstring states them (estimators.knee.CalibrationParams: 0.05 rad/s, 0.3 m/s²)
GYR_LIMIT, ACC_LIMIT = 0.05, 0.3
#: (gyroscope SD, accelerometer SD) of each window as multiples of those limits, ddof 1: either just below or just
#: above one limit (0.05 % off), and windows whose ddof-0 SD is below the limit while the ddof-1 SD is above it
#: (the two differ by √(500/499) = 1.001 over 500 samples), so a check with the other ddof or the other side of
#: "≤" gives another verdict
NEAR = [(0.9995, 0.5), (1.0005, 0.5), (0.5, 0.9995), (0.5, 1.0005), (0.9995, 0.9995), (1.0004, 0.5),
        (0.5, 1.0004), (0.9985, 0.5), (0.5, 0.9985), (2.0, 0.5), (0.5, 0.2)]


def _window(rng, gyr_sd, acc_sd, n=500):
    """A window of n samples in the board's units (g, °/s) whose total SD (ddof 1) is exactly ``gyr_sd`` rad/s and
    ``acc_sd`` m/s² (the noise scaled to it), the accelerometer around gravity along a tilted axis."""
    def noise(sd):
        x = rng.normal(size=(n, 3))
        x -= x.mean(axis=0)
        return x * sd / np.sqrt(x.var(axis=0, ddof=1).sum())
    acc = (np.array([0.3, -0.2, 9.7]) + noise(acc_sd)) / 9.80665
    gyr = np.rad2deg(np.array([0.01, -0.02, 0.005]) + noise(gyr_sd))
    return acc, gyr


#: samples pushed before a window in the prefixed runs: not a multiple of the window's 500, so the judged window
#: ends mid-way between two of the running sums' fresh summations and its verdict rests on the O(1) updates (the
#: prefix's samples leaving the sums one by one), not on a summation of exactly the window
PREFIX_N = 237


def _prefix(rng):
    """A still stretch with another mean (the gyroscope 30 °/s off, SD half of each limit): left in the sums, it
    would make every window read as moving."""
    acc, gyr = _window(rng, 0.5 * GYR_LIMIT, 0.5 * ACC_LIMIT, n=PREFIX_N)
    return acc, gyr + 30.0


def test_the_stillness_window_is_the_pipelines_judgement(static_page):
    """Live "still" on the last window is the pipeline's verdict on that window (estimators.knee.stillest_window's
    ``still`` on exactly those samples, its limits and ddof 1), on windows built just inside and just outside each
    limit, and where ddof 0 and ddof 1 disagree: a mix of still and not still.  Each window is judged alone and
    after a prefix (:func:`_prefix`), which the last window no longer holds: the verdict must not change."""
    rng = np.random.default_rng(3)
    windows = [_window(rng, g * GYR_LIMIT, a * ACC_LIMIT) for g, a in NEAR]
    prefix = _prefix(np.random.default_rng(9))
    assert LIMITS["stillness"] == {"window_s": 5.0, "max_gyr_sd_rad_s": GYR_LIMIT, "max_acc_sd_m_s2": ACC_LIMIT}
    pipeline = [knee.stillest_window(a * 9.80665, np.deg2rad(g), fs_hz=100.0).still for a, g in windows]
    for pre in (None, prefix):
        runs = [(a, g) if pre is None else (np.vstack([pre[0], a]), np.vstack([pre[1], g])) for a, g in windows]
        live = static_page.evaluate("""async ([windows, limits]) => { const c = await import('/metawear/checks.js');
            return windows.map(([acc, gyr]) => { const s = new c.Stillness(100, limits); const before = [];
                for (let i = 0; i < acc.length; i++) { s.pushAcc(acc[i]); s.pushGyr(gyr[i]); before.push(s.still()); }
                return [s.still(), before.slice(0, -1).some(Boolean)]; }); }""",
                                    [[[a.tolist(), g.tolist()] for a, g in runs], LIMITS["stillness"]])
        assert [v for v, _ in live] == pipeline, "with the prefix" if pre is not None else "alone"
        if pre is None:
            assert not any(early for _, early in live)      # nothing is still before a whole window arrived
    # the verdicts expected from the windows' construction: below both limits, ddof 1
    assert pipeline == [g <= 1 and a <= 1 for g, a in NEAR]
    assert 3 <= sum(pipeline) <= len(pipeline) - 3


def test_seconds_still_are_the_union_of_still_windows(static_page):
    """stillSeconds over still (8 s), moving (4 s: ±90 °/s, every sample), still again (7 s) at 100 Hz: the still
    windows (5 s) cover the first 8 s and the last 7 s and nothing of the movement, 15 s in all; still() follows."""
    rng = np.random.default_rng(5)
    n1, n2, n3 = 800, 400, 700
    acc = np.array([0.0, 0.0, 1.0]) + rng.normal(scale=0.002, size=(n1 + n2 + n3, 3))
    gyr = rng.normal(scale=0.2, size=(n1 + n2 + n3, 3))
    gyr[n1:n1 + n2, 0] = 90.0 * np.where(np.arange(n2) // 50 % 2 == 0, 1.0, -1.0)
    out = static_page.evaluate("""async ([acc, gyr, limits]) => { const c = await import('/metawear/checks.js');
        const s = new c.Stillness(100, limits); const seconds = [], still = [];
        for (let i = 0; i < acc.length; i++) { s.pushAcc(acc[i]); s.pushGyr(gyr[i]);
            seconds.push(s.stillSeconds()); still.push(s.still()); }
        return { seconds, still }; }""", [acc.tolist(), gyr.tolist(), LIMITS["stillness"]])
    seconds, still = np.asarray(out["seconds"]), np.asarray(out["still"])
    assert seconds[498] == 0.0 and seconds[499] == pytest.approx(5.0)       # the first whole window
    assert seconds[n1 - 1] == pytest.approx(8.0)
    assert seconds[n1 + n2 + 498] == pytest.approx(8.0)                     # every window touching the movement
    assert seconds[-1] == pytest.approx(15.0)
    assert still[499:n1].all() and not still[n1:n1 + n2 + 499].any() and still[n1 + n2 + 499:].all()


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
def test_the_knee_angle_preview_against_the_simulated_truth(static_page, seed):
    """preview.js on the simulator's decoded samples: axes and gyroscope bias from the standing and supine recordings,
    the three angles over the task (seed 9 a right knee, seed 4 a left one: the mirror) against the simulator's Grood
    & Suntay angles at each gyroscope sample.  The filters' time constants were fixed before any test (1 s, 10 s), on
    no data; the bounds (RMS ≤ 1.5° per angle) from six other simulated sessions (test_browser_record_results.py's
    docstring).  The true adduction (2–7°) and rotation (−3–6°) are small: a preview stuck at 0°, a sign not mirrored
    or the gyroscope's bias left in (rotation 12° RMS, measured) fails."""
    from app.pipeline.demo import simulate_session

    session = simulate_session(seed=seed, side="right" if seed == 9 else "left", n_cycles=5)
    data = {seg: {role: {k: _board(session, seg, role, k) for k in ("acc", "gyr")}
                  for role in ("standing", "lying")} for seg in ("thigh", "shank")}
    # the task's samples in time order, as they reach the page (the shank's clock runs 0.8 % fast: index k of the two
    # sensors is not the same instant); the preview read at each shank gyroscope sample
    events = sorted((t, seg, kind, v) for seg in ("thigh", "shank") for kind in ("acc", "gyr")
                    for t, v in zip(session.recordings[(seg, "task")][kind][0], _board(session, seg, "task", kind)))
    task = [[seg, kind, v] for _, seg, kind, v in events]
    t_shank = np.array([t for t, seg, kind, _ in events if seg == "shank" and kind == "gyr"])
    angles = np.asarray(static_page.evaluate("""async ([data, task, side]) => {
        const p = await import('/metawear/preview.js');
        const axes = {}, bias = {};
        for (const seg of ['thigh', 'shank']) {
            const stand = new p.MeanForce(), lie = new p.MeanForce(), gyr = new p.MeanForce();
            data[seg].standing.acc.forEach((g) => stand.push(g));
            data[seg].lying.acc.forEach((g) => lie.push(g));
            for (const role of ['standing', 'lying']) data[seg][role].gyr.forEach((w) => gyr.push(w));
            axes[seg] = p.segmentAxes(stand.mean(), lie.mean());
            bias[seg] = gyr.mean();
        }
        const knee = new p.KneePreview(axes, bias, side);
        const out = [];
        for (const [seg, kind, v] of task) {
            if (kind === 'acc') knee.pushAcc(seg, v);
            else knee.pushGyr(seg, v);
            if (seg === 'shank' && kind === 'gyr') out.push(knee.angles() ?? [NaN, NaN, NaN]);
        }
        return out; }""", [data, task, session.side]), dtype=float)
    # the truth at the shank's gyroscope times (the simulator's phone clock: task time from the role's start)
    t = t_shank - session.role_epoch_s["task"]
    motion = session.motion
    truth = np.rad2deg(motion.knee_angles_at(np.clip(t, motion.t_s[0], motion.t_s[-1])))
    settled = slice(200, None)                       # the filter's first 2 s
    rmse = np.sqrt(np.mean((angles[settled] - truth[settled]) ** 2, axis=0))
    print(f"seed {seed}: preview RMSE flexion {rmse[0]:.2f}, adduction {rmse[1]:.2f}, rotation {rmse[2]:.2f} deg over "
          f"{len(angles)} samples; truth ranges {np.ptp(truth, axis=0).round(1)} deg")
    assert (rmse <= 1.5).all(), rmse
    assert np.corrcoef(angles[settled, 0], truth[settled, 0])[0, 1] > 0.98
