"""Time alignment: different start ms, 20 Hz magnetometer, a stream running on, NaN rows, two drifting sensors."""

from pathlib import Path

import numpy as np
import pytest

from app.pipeline.ingestion import Note, RawRecording, Stream, align_pair, align_recording
from app.pipeline.ingestion.align import resample
from conftest import EPOCH0_S


def _f(t):
    """A smooth test signal (3 axes) of time."""
    return np.column_stack([np.sin(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 0.3 * t), 9.0 + 0.5 * np.sin(t)])


def _stream(kind, t):
    return Stream(kind=kind, t_s=t, values=_f(t - EPOCH0_S), declared_unit="-", file=Path(f"{kind}.csv"))


def _rec(true_fs=100.0, starts=(0.003, 0.0, 0.017), duration=(10.0, 10.0, 12.0), mag_fs_ratio=0.2, label="x"):
    ts = [EPOCH0_S + s + np.arange(int(d * true_fs * (mag_fs_ratio if i == 2 else 1.0)))
          / (true_fs * (mag_fs_ratio if i == 2 else 1.0)) for i, (s, d) in enumerate(zip(starts, duration))]
    return RawRecording(*(_stream(k, t) for k, t in zip(("acc", "gyr", "mag"), ts)), fmt="test", segment=None,
                        role=None, label=label)


def test_streams_with_different_starts_and_a_run_on_magnetometer():
    rec = _rec()
    a = align_recording(rec, 100.0, "thigh", "task")
    assert a.t0_s == pytest.approx(EPOCH0_S + 0.017)                 # latest first stamp
    assert a.t_s[0] == 0.0 and np.allclose(np.diff(a.t_s), 0.01)
    t_abs = a.t0_s + a.t_s
    assert t_abs[-1] <= EPOCH0_S + 9.99 + 1e-9                         # earliest last stamp (acc/gyr), mag cut
    assert a.flags["trimmed_s"]["mag"][1] > 1.9 and any("mag ran on" in n for n in a.flags["notes"])
    (cut,) = [n for n in a.flags["notes"] if "ran on" in n]          # the note carries its values, unrounded
    assert isinstance(cut, Note) and dict(cut.params) == {"variant": "stream_cut_after", "stream": "mag",
                                                          "seconds": rec.mag.t_s[-1] - t_abs[-1]}
    assert f"{cut.params['seconds']:.2f} s" in cut
    truth = _f(t_abs - EPOCH0_S)
    np.testing.assert_allclose(a.acc, truth, atol=1e-3)               # 100 Hz: interpolation error ~ 1e-4
    # 20 Hz mag interpolated (error <= dt²/8 max|f''| ≈ 3e-3), never repeated
    np.testing.assert_allclose(a.mag, truth, atol=4e-3)
    assert np.all(np.abs(np.diff(a.mag[:, 0])) > 0)


def test_nan_rows_and_gaps_become_nan_on_the_grid_only_inside_the_gap():
    rec = _rec()
    v = rec.gyr.values.copy()
    v[500:510] = np.nan                                                 # 0.1 s gap (10 periods)
    v[700] = np.nan                                                     # one missing sample: interpolated over
    gyr = Stream("gyr", rec.gyr.t_s, v, "-", rec.gyr.file)
    out = resample(gyr, rec.gyr.t_s)
    bad = np.isnan(out).any(axis=1)
    assert bad[500:510].all() and bad.sum() == 10
    a = align_recording(RawRecording(rec.acc, gyr, rec.mag, "test", None, None, "x"), 100.0, "thigh", "task")
    assert 8 <= a.flags["nan_rows"]["gyr"] <= 11 and a.flags["nan_rows"]["acc"] == 0
    (gaps,) = [n for n in a.flags["notes"] if "rows missing" in n]
    assert gaps.params == {"variant": "rows_missing", "stream": "gyr", "rows": a.flags["nan_rows"]["gyr"]}


def test_two_sensors_with_one_percent_drift_share_one_grid():
    thigh = _rec(true_fs=100.0, starts=(0.003, 0.0, 0.017), label="thigh")
    shank = _rec(true_fs=101.0, starts=(0.041, 0.052, 0.030), duration=(10.5, 10.5, 10.0), label="shank")
    a, b = align_pair(thigh, shank, 100.0)
    assert np.array_equal(a.t_s, b.t_s) and a.t0_s == b.t0_s
    assert a.flags["pair_rate_ratio"] == pytest.approx(100.0 / 101.0, rel=1e-4)
    (drift,) = [n for n in b.flags["notes"] if "clock drift" in n]
    assert drift.params["variant"] == "clock_drift" and drift.params["pct"] == pytest.approx(-0.99, abs=0.01)
    assert f"{drift.params['pct']:+.2f} %" in drift
    truth = _f(a.t0_s + a.t_s - EPOCH0_S)
    np.testing.assert_allclose(b.gyr, truth, atol=1e-3)                 # on the stamps: drift removed
    # aligning on sample counts instead would be off by ~1 % of 10 s = 0.1 s at the end
    naive = _f(shank.gyr.t_s[: len(a.t_s)] - EPOCH0_S)
    assert np.max(np.abs(naive - truth)) > 0.1


def test_simulated_task_pair_matches_the_truth(sim_session):
    """Simulator: shank clock 0.8 % fast, streams starting at different ms, 20 Hz mag, stamps on the phone clock."""
    streams, imus = sim_session
    recs = {}
    for seg in ("thigh", "shank"):
        s = {k: Stream(k, t, v, "-", Path(f"{seg}-{k}.csv")) for k, (t, v) in streams[(seg, "task")].items()}
        recs[seg] = RawRecording(s["acc"], s["gyr"], s["mag"], "test", None, None, seg)
    a, b = align_pair(recs["thigh"], recs["shank"], 100.0)
    assert abs(recs["shank"].acc.fs_hz - 100.8) < 0.05                  # the drift is visible in the stamps
    for rec, seg in ((a, "thigh"), (b, "shank")):
        imu = imus[(seg, "task")]
        t_true = rec.t0_s + rec.t_s - (EPOCH0_S + 100.0)
        clean = np.stack([np.interp(t_true, imu.gyr.t_true_s, imu.gyr.clean[:, i]) for i in range(3)], axis=1)
        err = np.sqrt(np.mean((rec.gyr - clean) ** 2))
        assert err < 0.01                                                # rad/s: noise level, no time shift
        assert np.max(np.abs(clean)) > 0.5                               # the check sees real motion
        mag_clean = np.stack([np.interp(t_true, imu.mag.t_true_s, imu.mag.clean[:, i]) for i in range(3)], axis=1)
        assert np.sqrt(np.mean((rec.mag - mag_clean) ** 2)) < 1.5         # µT: noise + 20 Hz interpolation


@pytest.mark.parametrize("epoch_ms", [0, 1_767_225_600_000, 1_767_225_600_002, 1_800_000_000_123])
def test_a_span_of_whole_periods_keeps_its_last_sample_at_any_epoch(epoch_ms):
    """The same millisecond stamps 4 ms later gave one grid row fewer (2996 instead of 2997: the browser's
    recordings against the same samples as files, issue 18): near an epoch of 1.8e9 s a float second carries a
    rounding error of 2.4e-7 s, above the grid's former 1e-6-of-a-sample margin, so a span of a whole number of
    periods lost its last instant at some epochs (1_767_225_600_002 ms here), and the edge tests (1e-9 s) would
    have made it NaN.  The grid now has every instant at every epoch, none NaN."""
    ms = epoch_ms + np.arange(3001) * 10                            # 100 Hz in whole milliseconds, as stamped
    ms_mag = epoch_ms + 10 + np.arange(600) * 50                    # 20 Hz, from 10 ms to 29.96 s: the span
    rec = RawRecording(_stream("acc", ms / 1000.0), _stream("gyr", ms / 1000.0), _stream("mag", ms_mag / 1000.0),
                       fmt="test", segment=None, role=None, label="x")
    a = align_recording(rec, 100.0, "shank", "standing")
    assert len(a.t_s) == 2996                                       # 29.95 s at 100 Hz, both ends included
    assert not np.isnan(a.acc).any() and not np.isnan(a.mag).any()
