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

from app.choices import live_checks
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


#: time zones of the browser, with their UTC offset in November 2026 (h) and the local day of the simulated
#: session's start (2026-11-22 10:00 UTC, app.pipeline.demo.EPOCH0_S) there
ZONES = [("Pacific/Kiritimati", 14.0, "2026-11-23"), ("America/St_Johns", -3.5, "2026-11-22"),
         ("Pacific/Pago_Pago", -11.0, "2026-11-21"), ("UTC", 0.0, "2026-11-22")]


@pytest.mark.parametrize("zoned_page, offset_h, local_day", ZONES, indirect=["zoned_page"])
def test_files_carry_the_browsers_local_time_as_metabase_does(zoned_page, session, tmp_path, offset_h, local_day):
    """files.js writes a step's three files with the browser's local time in their names and time column (MetaBase
    writes the phone's): the files the project's writer makes at that UTC offset, and the server's reader dates
    the recording by that local day (the report's "recordings' date")."""
    from app.pipeline.ingestion import read_recording

    streams = session.recordings[("thigh", "standing")]
    rates = {"acc": 100.0, "gyr": 100.0, "mag": 20.0}
    board = {"acc": "g", "gyr": "deg/s", "mag": "uT"}
    ms = {k: np.round(t[:300] * 1e3).astype(np.int64) for k, (t, _) in streams.items()}
    si = {k: (ms[k] / 1e3, counts(k, v[:300]) / LSB[k] * unit_factor(k, board[k])) for k, (_, v) in streams.items()}
    # the floats the Python writer formats, handed to files.js in the board's units (µT for the magnetometer)
    quantised = {k: v / unit_factor(k, FILE_UNIT[k]) * (1e6 if k == "mag" else 1) for k, (_, v) in si.items()}
    files = zoned_page.evaluate("""async ([ms, values, rates]) => { const f = await import('/metawear/files.js');
        const streams = {};
        for (const k of ['acc', 'gyr', 'mag']) streams[k] = {epochMs: ms[k], values: values[k], rateHz: rates[k]};
        return f.filesOf(streams, 'standing-thigh', {serial: 'D4F1A2B3C4E5', firmware: '1.7.3'}); }""",
                                [{k: m.tolist() for k, m in ms.items()}, {k: v.tolist() for k, v in quantised.items()}, rates])
    (tmp_path / "py").mkdir()
    expected = write_recording_metabase(tmp_path / "py", "standing-thigh", "D4F1A2B3C4E5", si, firmware="1.7.3",
                                        utc_offset_h=offset_h)
    assert sorted(f["name"] for f in files) == sorted(p.name for p in expected)
    for p in expected:
        browser = next(f for f in files if f["name"] == p.name)
        assert browser["text"] == p.read_text(encoding="utf-8"), p.name
    assert all(f["name"].split("_")[2].startswith(local_day) for f in files)
    folder = tmp_path / "browser"
    folder.mkdir()
    for f in files:
        (folder / f["name"]).write_text(f["text"], encoding="utf-8")
    raw = read_recording(sorted(folder.iterdir()))
    assert raw.extras["started"].value[:10] == local_day
    # the epoch column stays UTC whatever the zone: the samples' times are the same instants
    np.testing.assert_array_equal(np.round(raw.acc.t_s * 1e3).astype(np.int64), ms["acc"])


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


@pytest.mark.parametrize("segment", ["thigh", "shank"])
@pytest.mark.parametrize("stall_s", [0.6, 1.0, 2.0])
@pytest.mark.parametrize("with_loss", [False, True])
def test_a_stalled_link_is_not_a_loss(static_page, session, segment, stall_s, with_loss):
    """A link that stalls without losing anything (the radio held the notifications and hands them over at once
    when it recovers: a burst after a gap) loses no sample and shifts none: every notification at its true
    index, stamps on the simulator's clock (thigh 40 ppm, shank 0.8 % fast) within 12 ms.  With three
    notifications lost besides (one of them inside the stall), exactly those are counted (before the time
    window of (T4) reached past the burst, a 0.6 s stall read as ~15 samples lost and shifted the run)."""
    rng = np.random.default_rng(21)
    t_s, values = session.recordings[(segment, "task")]["gyr"]
    frames = notifications("gyr", t_s, values)
    true_ms = np.array([f.arrival_s for f in frames]) * 1e3
    arrival = true_ms + rng.uniform(2.0, 8.0, len(frames))
    t0 = true_ms[0] + 0.4 * (true_ms[-1] - true_ms[0])
    held = (true_ms >= t0) & (true_ms < t0 + stall_s * 1e3)
    # the held notifications arrive together once the link recovers, 0.3 ms apart (one connection event)
    arrival[held] = t0 + stall_s * 1e3 + 4.0 + 0.3 * np.arange(held.sum())
    lost = np.zeros(len(frames), bool)
    if with_loss:
        inside = np.flatnonzero(held)
        lost[[inside[len(inside) // 2], len(frames) // 5, 3 * len(frames) // 4]] = True
    out = _stream_run(static_page, [None if gone else float(a) for a, gone in zip(arrival, lost)], 3, 100.0,
                      [1e18, 1e18])
    kept = np.flatnonzero(~lost)
    placed = np.array([p[1] for p in out["placed"]])
    assert out["lost"] == 3 * int(lost.sum()), (np.flatnonzero(lost), np.flatnonzero(held)[[0, -1]],
                                                np.flatnonzero(placed != 3 * kept)[:5], out["lost"])
    # outside the stall every notification at its true index; inside it, the arrivals (all at once) cannot say
    # where the lost one was (the protocol has no counter): it is placed at the stall's start, so the held
    # notifications before it sit one packet late
    off = placed - 3 * kept
    np.testing.assert_array_equal(off[~held[kept]], 0)
    assert set(off[held[kept]]) <= ({0, 3} if with_loss else {0})
    err = np.asarray(out["stamps"]) - true_ms[kept]
    err -= np.median(err)
    assert np.max(np.abs(err[off == 0])) < 12.0, np.max(np.abs(err[off == 0]))
    assert np.max(np.abs(err)) < 12.0 + 30.0


@pytest.mark.parametrize("missing", [None, ("shank", "mag", 1.0), ("thigh", "gyr", 0.5)])
def test_an_incomplete_step_is_not_uploaded(static_page, session, missing):
    """Recorder.upload refuses a step one of whose six streams is missing (or holds half of span × rate samples):
    nothing is sent, the buffer stays; a complete step is sent whole.  The records are the twin's notifications
    of a simulated lying step in the real IndexedDB buffer; ``send`` stands for the server and answers each file's
    SHA-256 (its acknowledgement)."""
    records = []
    for segment in ("thigh", "shank"):
        for kind, (t_s, values) in session.recordings[(segment, "lying")].items():
            frames = notifications(kind, t_s, values)
            if missing and missing[:2] == (segment, kind):
                frames = frames[:int(len(frames) * (1 - missing[2]))]
            records += [{"segment": segment, "stream": kind, "run": 0, "arrivalMs": f.arrival_s * 1e3 + 5.0,
                         "bytes": list(f.payload)} for f in frames]
    out = static_page.evaluate("""async ([records, limits]) => {
        const s = await import('/metawear/store.js');
        const { Recorder } = await import('/metawear/recorder.js');
        const db = await s.PacketStore.open('chakamo-incomplete');
        await db.clear(9, 'lying');
        for (const r of records) db.add({...r, session: 9, step: 'lying', bytes: Uint8Array.from(r.bytes).buffer});
        await db.flush();
        const sent = [];
        const send = async (segment, role, files) => {
            sent.push(segment);
            return {recordings: files.map((f, id) => ({id, file_name: f.name, sha256: f.sha256}))}; };
        const rec = new Recorder(9, db, send, limits);
        rec.sensors = {thigh: {info: {serial: 'D4F1A2B3C4E5', firmware: '1.7.3'}},
                       shank: {info: {serial: 'C1D2E3F4A5B6', firmware: '1.7.3'}}};
        let code = null;
        try { await rec.upload('lying'); } catch (e) { code = e.code; }
        return {code, sent, left: (await db.step(9, 'lying')).length}; }""", [records, live_checks()])
    if missing is None:
        assert out == {"code": None, "sent": ["thigh", "shank"], "left": 0}
    else:
        assert out == {"code": "incomplete", "sent": [], "left": len(records)}


@pytest.mark.parametrize("zoned_page", ["Europe/Madrid"], indirect=True)
def test_a_recording_across_a_daylight_saving_change_keeps_its_starts_offset(zoned_page, tmp_path):
    """Madrid leaves summer time (UTC+2) for UTC+1 at 2026-10-25 01:00 UTC: a stream recorded from 00:59:58 to
    01:00:02 UTC is named and written at its start's +02:00 for every row (the project's writer at that offset),
    while its epoch column stays UTC; what the browser itself says after the change is +01:00."""
    from app.pipeline.ingestion.metabase import write_metabase_csv

    change_ms = 1792890000000                      # 2026-10-25T01:00:00Z
    ms = [change_ms - 2000, change_ms - 1000, change_ms, change_ms + 1000, change_ms + 2000]
    values = [[0.0, 0.0, 1.0]] * len(ms)
    out = zoned_page.evaluate("""async ([ms, values]) => { const c = await import('/metawear/csv.js');
        return { text: c.csvText('acc', ms, values), name: c.fileName('standing-thigh', ms[0], 'D4F1A2B3C4E5', 'acc',
                 100, '1.7.3'), before: c.utcOffsetMin(ms[0]), after: c.utcOffsetMin(ms[4]) }; }""", [ms, values])
    assert (out["before"], out["after"]) == (120, 60)
    lines = out["text"].splitlines()
    assert lines[0].startswith("epoch (ms),time (+02:00),")
    assert [r.split(",")[1] for r in lines[1:]] == ["2026-10-25T02:59:58.000", "2026-10-25T02:59:59.000",
                                                      "2026-10-25T03:00:00.000", "2026-10-25T03:00:01.000",
                                                      "2026-10-25T03:00:02.000"]
    assert [int(r.split(",")[0]) for r in lines[1:]] == ms
    assert out["name"] == "standing-thigh_MetaWear_2026-10-25T02.59.58.000_D4F1A2B3C4E5_Accelerometer_100.000Hz_1.7.3.csv"
    python = write_metabase_csv(tmp_path / "a.csv", "acc", np.asarray(ms), np.asarray(values) * 9.80665,
                                utc_offset_h=2.0).read_text(encoding="utf-8")
    assert out["text"] == python
