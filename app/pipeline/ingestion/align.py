r"""Time alignment: three streams of one sensor, and two sensors of one task, onto one uniform grid.

Assumptions about the stamps
----------------------------
* MetaBase's ``epoch (ms)`` stamps of every stream and every sensor of a session are on one clock (the
  phone's), so they are directly comparable: a sensor whose crystal runs 1 % slow delivers 99 samples
  per stamped second, and aligning *on the stamps* (never on sample counts) removes that drift.
  Whatever error the phone makes when it stamps a sensor's samples is not corrected here.
* Files with only elapsed seconds (thesis Excel, generic CSV without epoch) have no common clock: every
  stream is taken to start at its file's time zero, i.e. streams and sensors started together.  The
  result says so (``time_base="elapsed"``).

Method
------
The grid runs over the span common to all streams, :math:`[t_0, t_1] = [\max_s t_s^{first}, \min_s
t_s^{last}]`, at ``fs_hz``: :math:`t_k = t_0 + k/f_s`, :math:`k = 0..\lfloor (t_1-t_0+\epsilon) f_s\rfloor`
(:math:`\epsilon` = :data:`SAME_INSTANT_S`: the float rounding of epoch seconds must not drop the last sample).  Each
stream is linearly interpolated on its own stamps (the 20 Hz magnetometer is interpolated, never
repeated).  Rows with NaN are dropped from their stream before interpolation; a grid instant strictly
inside an interval without valid samples longer than 2.5 periods of that stream (a gap) is NaN in that
stream, which the orientation filters treat as a missing measurement.  Whatever a stream
records outside the common span (started early, ran on after the others stopped) is cut and reported
in ``flags["trimmed_s"]``.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from app.pipeline.ingestion.model import (AlignedRecording, FloatArray, IngestionError, Note, RawRecording, Stream,
                                          rows_all, rows_any)

GAP_PERIODS = 2.5
#: Two stamps closer than this are the same instant (the grid's last sample, the edges of a stream).  Stamps are
#: whole milliseconds (MetaBase, the browser's recordings) or finer; as float seconds near an epoch of 1.8e9 s
#: they carry a rounding error of one ulp, 2.4e-7 s, so an exact test (the earlier 1e-9 s, or 1e-6 of a sample
#: at 100 Hz) could drop a span's last sample when the span is a whole number of periods: the same samples
#: stamped 4 ms later gave 2996 grid rows instead of 2997.  10 µs is 40 ulps there and a hundredth of a
#: millisecond stamp.
SAME_INSTANT_S = 1e-5
#: Relative tolerance between a stream's measured rate and the expected one.
RATE_TOLERANCE = 0.03
MAG_MIN_FS_HZ = 5.0


def common_span(streams: Sequence[Stream]) -> tuple[float, float]:
    """``(t0, t1)``: the latest first stamp and the earliest last stamp (valid rows only)."""
    firsts, lasts = [], []
    for s in streams:
        ok = rows_all(np.isfinite(s.values))
        if not ok.any():
            raise IngestionError("stream.no_valid_sample", file=s.file, stream=s.kind)
        firsts.append(s.t_s[ok][0])
        lasts.append(s.t_s[ok][-1])
    return float(max(firsts)), float(min(lasts))


def resample(stream: Stream, t_grid: FloatArray) -> FloatArray:
    """Linear interpolation of ``stream`` at ``t_grid`` (same time base), NaN inside gaps (module docstring)."""
    ok = rows_all(np.isfinite(stream.values))
    t, v = stream.t_s[ok], stream.values[ok]
    out = np.stack([np.interp(t_grid, t, v[:, i]) for i in range(3)], axis=1)
    period = float(np.median(np.diff(stream.t_s)))
    j = np.clip(np.searchsorted(t, t_grid, side="right"), 1, len(t) - 1)
    inside = (t_grid - t[j - 1] > SAME_INSTANT_S) & (t[j] - t_grid > SAME_INSTANT_S)
    gap = ((t[j] - t[j - 1]) > GAP_PERIODS * period) & inside
    gap |= (t_grid < t[0] - SAME_INSTANT_S) | (t_grid > t[-1] + SAME_INSTANT_S)
    out[gap] = np.nan
    return out


def check_rates(rec: RawRecording, expected_fs_hz: float | None) -> float:
    """Check the measured rates; return the grid rate (expected, or the acc stream's nominal rate)."""
    acc, gyr, mag = rec.streams
    fs_acc, fs_gyr, fs_mag = acc.fs_hz, gyr.fs_hz, mag.fs_hz
    same = abs(fs_gyr / fs_acc - 1.0) <= RATE_TOLERANCE
    if expected_fs_hz is not None:
        for s, fs in ((acc, fs_acc), (gyr, fs_gyr)):
            if abs(fs / expected_fs_hz - 1.0) > RATE_TOLERANCE:
                # --any-rate helps only when it would then load: acc and gyr at one rate, mag within range
                helps = same and MAG_MIN_FS_HZ <= fs_mag <= fs_acc * (1 + RATE_TOLERANCE)
                raise IngestionError("rate.unexpected_any_rate" if helps else "rate.unexpected", file=s.file,
                                     stream=s.kind, fs_hz=fs, expected_hz=expected_fs_hz)
        fs_grid = float(expected_fs_hz)
    else:
        if not same:
            raise IngestionError("rate.acc_gyr_differ", file=gyr.file, gyr_hz=fs_gyr, acc_hz=fs_acc,
                                 label=rec.label)
        nominal = acc.nominal_fs_hz
        fs_grid = float(nominal if nominal and abs(fs_acc / nominal - 1.0) <= RATE_TOLERANCE else round(fs_acc))
    if not MAG_MIN_FS_HZ <= fs_mag <= fs_grid * (1 + RATE_TOLERANCE):
        raise IngestionError("rate.mag", file=mag.file, fs_hz=fs_mag, min_hz=MAG_MIN_FS_HZ, max_hz=fs_grid)
    return fs_grid


def _grid(t0: float, t1: float, fs_hz: float, what: str, files: str) -> FloatArray:
    if t1 - t0 < 1.0:
        raise IngestionError("align.no_overlap_pair" if what == "pair" else "align.no_overlap", file=files,
                             seconds=max(t1 - t0, 0.0))
    n = int(np.floor((t1 - t0 + SAME_INSTANT_S) * fs_hz)) + 1
    return t0 + np.arange(n) / fs_hz


def _aligned(rec: RawRecording, t: FloatArray, fs_hz: float, segment: str, role: str) -> AlignedRecording:
    arrays = {s.kind: resample(s, t) for s in rec.streams}
    cut = {s.kind: (float(t[0] - s.t_s[0]), float(s.t_s[-1] - t[-1])) for s in rec.streams}
    trimmed = {k: (round(before, 4), round(after, 4)) for k, (before, after) in cut.items()}
    notes = [Note(f"{k} ran on {after:.2f} s after the common span (cut)",
                  {"variant": "stream_cut_after", "stream": k, "seconds": after})
             for k, (_, after) in cut.items() if after > 0.5]
    notes += [Note(f"{k} started {before:.2f} s before the common span (cut)",
                   {"variant": "stream_cut_before", "stream": k, "seconds": before})
              for k, (before, _) in cut.items() if before > 0.5]
    nan_rows = {k: int(rows_any(np.isnan(v)).sum()) for k, v in arrays.items()}
    notes += [Note(f"{k}: {n} grid rows missing (gaps in the stream)",
                   {"variant": "rows_missing", "stream": k, "rows": n}) for k, n in nan_rows.items() if n]
    if rec.acc.time_base != "epoch":
        notes.append(Note("no epoch time stamps: streams assumed to start together", {"variant": "no_epoch"}))
    if rec.mag.mag_unit == "normalised":
        notes.append(Note.of("mag_normalised", file=rec.mag.file.name,
                             field=f"{rec.mag.field_ut:g} µT" if rec.mag.field_ut else "-"))
    source = {"files": [str(f) for f in rec.files], "format": rec.fmt, "label": rec.label,
              "sensor_id": rec.sensor_id,
              "segment": rec.segment.describe() if rec.segment else segment,
              "role": rec.role.describe() if rec.role else role, "notes": list(rec.notes),
              # how segment and role were found ([method, evidence]), for the session check's translated lines
              "found_by": {k: [r.method, str(r.evidence)] for k, r in (("segment", rec.segment), ("role", rec.role)) if r}}
    flags = {"stream_fs_hz": {s.kind: round(s.fs_hz, 4) for s in rec.streams},
             "declared_units": {s.kind: s.declared_unit for s in rec.streams},
             "trimmed_s": trimmed, "nan_rows": nan_rows, "notes": notes,
             "mag_unit": rec.mag.mag_unit, "mag_field_ut": rec.mag.field_ut}
    return AlignedRecording(t_s=np.arange(len(t)) / fs_hz, acc=arrays["acc"], gyr=arrays["gyr"], mag=arrays["mag"],
                            fs_hz=fs_hz,
                            t0_s=float(t[0]), time_base=rec.acc.time_base, segment=segment, role=role,
                            source=source, flags=flags)


def align_recording(rec: RawRecording, fs_hz: float, segment: str, role: str) -> AlignedRecording:
    """Acc, gyr, mag of one recording on one grid at ``fs_hz`` over their common span.

    The three streams must share a time base: a stream file without its ``epoch (ms)`` column counts from
    its own start while the others count from 1970, so no span would be common (refused, naming it)."""
    if len({s.time_base for s in rec.streams}) > 1:
        odd = [s for s in rec.streams if s.time_base != "epoch"]
        raise IngestionError("align.time_base_mixed", file=odd[0].file, label=rec.label)
    t0, t1 = common_span(rec.streams)
    return _aligned(rec, _grid(t0, t1, fs_hz, "recording", rec.files[0].name), fs_hz, segment, role)


def align_pair(thigh: RawRecording, shank: RawRecording, fs_hz: float,
               role: str = "task") -> tuple[AlignedRecording, AlignedRecording]:
    """Both sensors' recordings on one grid over the span common to all six streams (clock-drift note above)."""
    if thigh.acc.time_base != shank.acc.time_base:
        raise IngestionError("align.pair_time_base", file=thigh.files[0], other=shank.files[0])
    t0, t1 = common_span(thigh.streams + shank.streams)
    t = _grid(t0, t1, fs_hz, "pair", f"{thigh.files[0].name}, {shank.files[0].name}")
    a, b = _aligned(thigh, t, fs_hz, "thigh", role), _aligned(shank, t, fs_hz, "shank", role)
    ratio = thigh.acc.fs_hz / shank.acc.fs_hz
    for r in (a, b):
        r.flags["pair_rate_ratio"] = round(ratio, 6)
    if abs(ratio - 1.0) > 0.002:  # noted once, on the shank (a session's notes list every recording's)
        pct = 100.0 * (ratio - 1.0)
        b.flags["notes"].append(Note(f"the sensors' rates differ by {pct:+.2f} % (clock drift), aligned on the "
                                     "time stamps", {"variant": "clock_drift", "pct": pct}))
    return a, b
