"""``static/metawear/csv.js`` and ``timeline.js`` in Chromium, against the project's own MetaBase writer and the
simulator's clocks.

* csv.js writes a stream character for character as :func:`app.pipeline.ingestion.metabase.write_metabase_csv`
  (the ingestion's documented format) does for the same floats, file name included, and its number formatting
  is Python's ``f"{x:.nf}"`` (ties to even) on every value tried, ties included.
* timeline.js stamps the samples of a simulated task (:func:`app.pipeline.demo.simulate_session`: the shank's clock
  0.8 % fast, the thigh's 40 ppm) from arrival times alone — BLE latency of 0–60 ms in bursts, 3 % of the
  notifications lost, a 5 s disconnection in the middle — within 12 ms of the simulator's true times (35 ms for
  the few held back right before a loss); it counts exactly the samples lost inside each run, places all but
  3 % of the notifications at their true index, recovers each sensor's drift within 300 ppm, and reads no
  loss where there is none.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.pipeline.ingestion.metabase import file_name, write_metabase_csv, write_recording_metabase
from app.pipeline.ingestion.units import unit_factor
from metawear_frames import LSB, counts, notifications

FILE_UNIT = {"acc": "g", "gyr": "deg/s", "mag": "T"}


@pytest.fixture(scope="module")
def session():
    from app.pipeline.demo import simulate_session

    return simulate_session(seed=5, side="left", n_cycles=3)


def test_number_formatting_is_pythons(static_page):
    rng = np.random.default_rng(1)
    ties = [k / 16 for k in range(-41, 42, 2)] + [k / 1024 for k in (1, 3, -5, 977)]
    values = ties + list(rng.normal(0, 3, 300)) + list(rng.normal(0, 1e-4, 50)) + [0.0, 1e-12, -1e-12, 2047.9995]
    digits = [3, 9]
    got = static_page.evaluate("""async ([values, digits]) => { const c = await import('/metawear/csv.js');
        return digits.map((d) => values.map((x) => c.pyFixed(x, d))); }""", [values, digits])
    for d, row in zip(digits, got):
        assert row == [f"{x:.{d}f}" for x in values]


@pytest.mark.parametrize("kind", ["acc", "gyr", "mag"])
def test_a_stream_is_the_file_metabase_writes(static_page, session, tmp_path, kind):
    t_s, values = session.recordings[("thigh", "standing")][kind]
    epoch_ms = np.round(t_s[:400] * 1e3).astype(np.int64)
    quantised_si = counts(kind, values[:400]) / LSB[kind] * unit_factor(kind, {"acc": "g", "gyr": "deg/s", "mag": "uT"}[kind])
    file_unit = unit_factor(kind, FILE_UNIT[kind])
    # the floats the Python writer formats, handed to csv.js in the board's units (µT for the magnetometer)
    board = quantised_si / file_unit * (1e6 if kind == "mag" else 1)
    path = write_metabase_csv(tmp_path / "x.csv", kind, epoch_ms, quantised_si)
    rate = {"acc": 100.0, "gyr": 100.0, "mag": 20.0}[kind]
    out = static_page.evaluate("""async ([kind, ms, values, rate]) => { const c = await import('/metawear/csv.js');
        return {text: c.csvText(kind, ms, values), name: c.fileName('task-thigh', ms[0], 'd4:f1:a2:b3:c4:e5', kind, rate, '1.7.3')}; }""",
                               [kind, epoch_ms.tolist(), board.tolist(), rate])
    assert out["text"] == path.read_text(encoding="utf-8")
    assert out["name"] == file_name("task-thigh", int(epoch_ms[0]), "D4F1A2B3C4E5", kind, rate, firmware="1.7.3")


def _arrivals(rng, n: int) -> np.ndarray:
    """BLE-like latency: a few ms mostly, every ~25th notification held back 20–60 ms with those after it."""
    latency = rng.uniform(2.0, 8.0, n)
    for start in np.flatnonzero(rng.random(n) < 0.04):
        latency[start:start + 4] += rng.uniform(20.0, 60.0)
    return latency


def _stream_run(static_page, arrivals_ms, per, fs_hz, blackout):
    return static_page.evaluate("""async ([arrivals, per, fs, blackout]) => {
        const tl = await import('/metawear/timeline.js');
        const s = new tl.StreamTimeline(fs, per);
        const pushed = [];
        let reconnected = false;
        for (const a of arrivals) {
            if (a === null) continue;                         // lost in the air
            if (!reconnected && a > blackout[1]) { s.newRun(); reconnected = true; }
            pushed.push(s.push(a));
        }
        const placed = s.placement();
        return {placed: pushed.map(([run, k]) => [run, placed[run].first[k]]),
                stamps: pushed.map(([run, k]) => tl.stampMs(placed[run].line, placed[run].first[k] + per - 1)),
                lost: s.lost(placed), drift: s.driftPpm(placed)};
    }""", [arrivals_ms, per, fs_hz, blackout])


@pytest.mark.parametrize("segment, drift_ppm", [("thigh", 40.0), ("shank", 8000.0)])
@pytest.mark.parametrize("kind", ["acc", "mag"])
def test_stamps_losses_and_drift_from_arrivals(static_page, session, segment, drift_ppm, kind):
    rng = np.random.default_rng(11 if segment == "thigh" else 12)
    t_s, values = session.recordings[(segment, "task")][kind]
    frames = notifications(kind, t_s, values)
    per = 1 if kind == "mag" else 3
    fs = 20.0 if kind == "mag" else 100.0
    true_ms = np.array([f.arrival_s for f in frames]) * 1e3
    arrival = true_ms + _arrivals(rng, len(frames))
    mid = true_ms[0] + 0.5 * (true_ms[-1] - true_ms[0])
    blackout = (mid, mid + 5000.0)
    lost = (rng.random(len(frames)) < 0.03) | ((true_ms >= blackout[0]) & (true_ms <= blackout[1]))
    # the first notification of each run, and the last W = 16 (a loss needs 16 after it to be told from a burst)
    last_before = np.flatnonzero(true_ms < blackout[0])[-1]
    lost[[0, *range(last_before - 15, last_before + 1), *range(len(lost) - 16, len(lost))]] = False
    lost[np.flatnonzero(true_ms > blackout[1])[0]] = False
    out = _stream_run(static_page, [None if gone else float(a) for a, gone in zip(arrival, lost)], per, fs, blackout)

    kept = np.flatnonzero(~lost)
    after = true_ms[kept] > blackout[1]
    run = np.array([p[0] for p in out["placed"]])
    np.testing.assert_array_equal(run, after.astype(int))
    # the notifications sit at their true place in their run (the first run counts from the stream's start, the
    # second from the first notification after the reconnection); a notification held back in a burst right
    # before a loss cannot be told from one sent after it (no counter in the protocol): such few are placed a
    # lost packet or two late
    first = np.array([p[1] for p in out["placed"]])
    true_first = np.where(after, (kept - kept[after][0]) * per, kept * per)
    off = first - true_first
    assert np.count_nonzero(off) <= 0.03 * len(off), np.count_nonzero(off)
    assert off.min() >= 0 and off.max() <= 2 * per
    in_run_losses = int(lost[kept[0]:kept[~after][-1]].sum() + lost[kept[after][0]:kept[-1]].sum())
    assert out["lost"] == in_run_losses * per
    # stamps on the true clock (the simulator's phone time) within 12 ms; the run's latency mean is in them
    err = np.asarray(out["stamps"]) - true_ms[kept]
    err -= np.median(err)
    assert np.max(np.abs(err[off == 0])) < 12.0, np.max(np.abs(err[off == 0]))
    assert np.max(np.abs(err)) < (35.0 if per == 3 else 65.0)
    assert abs(out["drift"] - drift_ppm) < 300.0, out["drift"]


def test_no_loss_is_read_where_there_is_none(static_page, session):
    rng = np.random.default_rng(3)
    t_s, values = session.recordings[("shank", "task")]["gyr"]
    frames = notifications("gyr", t_s, values)
    arrival = np.array([f.arrival_s for f in frames]) * 1e3 + _arrivals(rng, len(frames))
    out = _stream_run(static_page, arrival.tolist(), 3, 100.0, [1e18, 1e18])
    assert out["lost"] == 0
    assert [p[1] for p in out["placed"]] == list(range(0, 3 * len(frames), 3))


def test_a_recordings_three_files_are_the_ones_metabase_writes(static_page, session, tmp_path):
    """filesOf: the three files of one sensor's step, names (one shared start: the ingestion groups a recording's
    files by it) and texts as the project's writer of a whole recording makes them; their SHA-256 is that of the
    text (what the upload route answers)."""
    import hashlib

    streams = session.recordings[("shank", "lying")]
    board, ms = {}, {}
    for kind, (t_s, values) in streams.items():
        ms[kind] = np.round(t_s[:300] * 1e3).astype(np.int64)
        si = counts(kind, values[:300]) / LSB[kind] * unit_factor(kind, {"acc": "g", "gyr": "deg/s", "mag": "uT"}[kind])
        board[kind] = (si, si / unit_factor(kind, FILE_UNIT[kind]) * (1e6 if kind == "mag" else 1))
    paths = write_recording_metabase(tmp_path, "lying-shank", "C1D2E3F4A5B6",
                                     {k: (ms[k] / 1e3, board[k][0]) for k in streams}, firmware="1.7.3")
    files = static_page.evaluate("""async (streams) => { const f = await import('/metawear/files.js');
        return f.filesOf(streams, 'lying-shank', {serial: 'C1D2E3F4A5B6', firmware: '1.7.3'}); }""",
                                 {k: {"epochMs": ms[k].tolist(), "values": board[k][1].tolist(),
                                      "rateHz": 20.0 if k == "mag" else 100.0} for k in streams})
    assert sorted(f["name"] for f in files) == sorted(p.name for p in paths)
    for f in files:
        text = (tmp_path / f["name"]).read_text(encoding="utf-8")
        assert f["text"] == text and f["sha256"] == hashlib.sha256(text.encode()).hexdigest()


def test_the_buffer_outlives_a_reload_and_clears_per_step(static_page):
    """store.js: records flushed to IndexedDB are there after the page is loaded again (nothing lost before the
    server acknowledged them); clearing one step leaves the others."""
    static_page.evaluate("""async () => { const s = await import('/metawear/store.js');
        const db = await s.PacketStore.open('chakamo-test');
        for (const step of ['standing', 'task']) for (let k = 0; k < 5; k++)
            db.add({session: 7, step, segment: 'thigh', stream: 'acc', run: 0, arrivalMs: k,
                    bytes: Uint8Array.of(3, 0x1c, k).buffer});
        db.add({session: 8, step: 'task', segment: 'shank', stream: 'mag', run: 0, arrivalMs: 0, bytes: new ArrayBuffer(8)});
        await db.flush(); }""")
    static_page.reload()
    out = static_page.evaluate("""async () => { const s = await import('/metawear/store.js');
        const db = await s.PacketStore.open('chakamo-test');
        const before = (await db.steps(7)).sort();
        const task = await db.step(7, 'task');
        const cleared = await db.clear(7, 'standing');
        return {before, task: task.map((r) => [r.arrivalMs, Array.from(new Uint8Array(r.bytes))]), cleared,
                after: await db.steps(7), other: await db.steps(8)}; }""")
    assert out["before"] == ["standing", "task"]
    assert out["task"] == [[k, [3, 0x1C, k]] for k in range(5)]
    assert out["cleared"] == 5 and out["after"] == ["task"] and out["other"] == ["task"]
