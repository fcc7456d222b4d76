"""``static/metawear/checks.js`` (the recorder's live checks) in Chromium on the simulator's recordings, whose
truth is known: the figure-eight's sphere coverage against the pipeline's own (estimators.magnetometer on the
same samples), stillness on the postures and not during the task, and the step-up's cycle count against the
simulated number of cycles.  The stillness thresholds are estimators.knee's."""

from __future__ import annotations

import numpy as np
import pytest

from estimators import knee
from estimators.magnetometer import fit_ellipsoid
from metawear_frames import LSB, board_units, counts


@pytest.fixture(scope="module")
def session():
    from app.pipeline.demo import simulate_session

    return simulate_session(seed=9, side="right", n_cycles=6)


def _board(session, segment, role, kind):
    """The samples as the recorder decodes them (quantised, in g, °/s, µT)."""
    _, values = session.recordings[(segment, role)][kind]
    return (counts(kind, values) / LSB[kind]).tolist()


def _coverage(page, mag):
    return page.evaluate("""async (mag) => { const c = await import('/metawear/checks.js');
        const s = new c.SphereCoverage(); for (const m of mag) s.push(m); return s.coverage(); }""", mag)


def test_thresholds_are_the_pipelines(static_page):
    js = static_page.evaluate("""async () => { const c = await import('/metawear/checks.js');
        return [c.STILL_MAX_GYR_SD_RAD_S, c.STILL_MAX_ACC_SD_M_S2]; }""")
    assert js == [knee.STILL_MAX_GYR_SD_RAD_S, knee.STILL_MAX_ACC_SD_M_S2]


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
    return page.evaluate("""async ([acc, gyr]) => { const c = await import('/metawear/checks.js');
        const s = new c.Stillness(100); const flags = [];
        for (let i = 0; i < Math.min(acc.length, gyr.length); i++) {
            s.pushAcc(acc[i]); s.pushGyr(gyr[i]); flags.push(s.still()); }
        return flags; }""", [acc, gyr])


@pytest.mark.parametrize("segment", ["thigh", "shank"])
def test_postures_are_still_and_the_task_is_not(static_page, session, segment):
    for role in ("standing", "lying"):
        flags = np.asarray(_stillness(static_page, _board(session, segment, role, "acc"), _board(session, segment, role, "gyr")))
        assert flags[50:].mean() > 0.95, (role, flags[50:].mean())
    task = np.asarray(_stillness(static_page, _board(session, segment, "task", "acc"), _board(session, segment, "task", "gyr")))
    assert task[50:].mean() < 0.6


@pytest.mark.parametrize("seed, n_cycles", [(9, 6), (4, 10)])
def test_the_task_cycle_count(static_page, session, seed, n_cycles):
    if (seed, n_cycles) != (9, 6):
        from app.pipeline.demo import simulate_session

        session = simulate_session(seed=seed, side="left", n_cycles=n_cycles)
    for segment in ("thigh", "shank"):
        gyr = _board(session, segment, "task", "gyr")
        n = static_page.evaluate("""async (gyr) => { const c = await import('/metawear/checks.js');
            const k = new c.CycleCounter(100); for (const g of gyr) k.push(g); return k.cycles; }""", gyr)
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
