"""One continuous recording per sensor → the protocol's four recordings (issue 14 §3a).

A session may hold, per sensor, one recording of the whole protocol instead of four: its role is
``continuous`` (the word ``continuous`` / ``continuo`` / ``contínuo`` / ``protocol`` in its name or
``"role": "continuous"`` in ``session.json``), or it has no role at all and each sensor has exactly one
recording.  :func:`split_session` aligns each such recording on its own grid, finds where the figure-eight,
standing, supine and task lie (:func:`estimators.protocol_split.split_protocol`, per sensor), and cuts the
streams *as read* (their own stamps) at those instants, so what follows — rate checks, alignment, the task
pair on the phones' clock — runs exactly as for four separate recordings.  Each part's role is a
:class:`Recognition` with method ``"split"`` and the span as evidence; a :class:`Note` per sensor
(``recording_split``) says where it was cut, in the reports' languages; :class:`Split` keeps the spans for
``results.json`` ``split``.

A continuous recording without a figure-eight (factory-calibrated sensors) splits into standing, supine and
task; the pipeline then uses the factory calibration.  No standing or no supine posture: refused
(``split.no_posture``), saying what was found.  A clinician moves a cut with ``session.json``
``"split": {"thigh": {"standing": [65.0, 95.0], ...}}`` (seconds from the recording's start, as
``results.json`` ``session.split`` shows them); given spans replace the automatic ones of their roles.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from estimators.protocol_split import PARTS, ProtocolSplit, SplitError, split_protocol

from app.pipeline.ingestion.align import align_recording, check_rates
from app.pipeline.ingestion.model import IngestionError, Note, RawRecording, Recognition, Stream

#: the role of a recording that holds the whole protocol
CONTINUOUS = "continuous"
#: samples per second of the motion trace the wizard draws under the cuts (:func:`motion_trace`)
TRACE_HZ = 4.0

__all__ = ["CONTINUOUS", "TRACE_HZ", "Split", "check_split", "left_unsplit", "motion_trace", "split_recording", "split_session"]


@dataclass(frozen=True)
class Split:
    """Where one sensor's continuous recording was cut.

    segment : ``"thigh"`` / ``"shank"``.   file : the recording's first file.
    spans_s : ``{role: (start_s, end_s)}``, seconds from the recording's first common sample.
    t0_s : that sample on the file's time base.   how : ``"role"`` (named continuous) or ``"only recording"``.
    octants : octants of magnetometer directions the figure-eight reached (0 without one).
    duration_s : the recording's length on its grid.   trace : :func:`motion_trace` of it, at ``trace_hz``: what the
    wizard draws under the cuts for the clinician to confirm or move them.
    """

    segment: str
    file: str
    spans_s: dict[str, tuple[float, float]]
    t0_s: float
    how: str
    octants: int
    duration_s: float = 0.0
    trace: tuple[float, ...] = ()
    trace_hz: float = TRACE_HZ

    def to_dict(self, trace: bool = False) -> dict:
        """``results.json`` ``session.split[segment]``; ``trace=True`` adds ``duration_s``, ``trace_hz`` and ``trace``
        (the session check's, for the wizard)."""
        out = {"file": self.file, "how": self.how, "octants": self.octants,
               "spans_s": {k: [round(a, 3), round(b, 3)] for k, (a, b) in self.spans_s.items()}}
        if trace:
            out |= {"duration_s": round(self.duration_s, 3), "trace_hz": self.trace_hz,
                    "trace": [round(x, 3) for x in self.trace]}
        return out


def motion_trace(gyr, fs_hz: float, trace_hz: float = TRACE_HZ):
    """The angular speed ``|ω|`` (rad/s) of ``gyr`` ``(N, 3)`` at ``fs_hz``, as its RMS over bins of ``1/trace_hz``
    s: still postures are near 0, the figure-eight and the task well above (what the split itself looks for,
    :mod:`estimators.protocol_split`).  NaN samples are ignored; an empty bin is 0."""
    step = max(1, int(round(fs_hz / trace_hz)))
    speed2 = np.nansum(np.asarray(gyr, float) ** 2, axis=1)
    n = len(speed2) // step * step
    bins = speed2[:n].reshape(-1, step) if n else np.zeros((0, step))
    return tuple(float(x) for x in np.sqrt(bins.mean(axis=1)))


def _cut(stream: Stream, t0: float, t1: float) -> Stream:
    keep = (stream.t_s >= t0) & (stream.t_s < t1)
    return replace(stream, t_s=stream.t_s[keep], values=stream.values[keep])


def given_spans(value, manifest: Path | None, segment: str) -> dict[str, tuple[float, float]]:
    """``session.json`` ``split[segment]`` checked: ``{role: [start_s, end_s]}`` with roles of the protocol and
    ``0 <= start_s < end_s`` (seconds from the recording's start); :class:`IngestionError` otherwise."""
    ok = isinstance(value, dict) and value and all(
        k in PARTS and isinstance(v, list) and len(v) == 2
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v) and 0 <= v[0] < v[1]
        for k, v in value.items())
    if not ok:
        raise IngestionError("manifest.bad_split", file=manifest, segment=segment, value=repr(value)[:80],
                             roles=", ".join(PARTS))
    return {k: (float(v[0]), float(v[1])) for k, v in value.items()}


#: the keys of a four-sensor session's ``split``: each knee's sensor (``left_thigh`` …, what its check shows)
KNEE_SPLIT_KEYS = tuple(f"{side}_{seg}" for side in ("left", "right") for seg in ("thigh", "shank"))


def check_split(given, manifest: Path | None = None, *, knees: bool = False) -> dict[str, dict[str, tuple[float, float]]]:
    """``session.json`` ``split`` (``{segment: {role: [start_s, end_s]}}``) checked (:func:`given_spans` per
    segment); :class:`IngestionError` ``manifest.bad_split`` otherwise.  ``knees=True`` also takes a four-sensor
    session's knee-prefixed keys (:data:`KNEE_SPLIT_KEYS`; not mixed with plain ones), which
    :func:`app.pipeline.ingestion.session.load_knees` hands to each knee without their prefix."""
    plain = {"thigh", "shank"}
    ok = isinstance(given, dict) and (set(given) <= plain or (knees and set(given) <= set(KNEE_SPLIT_KEYS)))
    if not ok:
        keys = " | ".join(("thigh", "shank") + (KNEE_SPLIT_KEYS if knees else ()))
        raise IngestionError("manifest.bad_split", file=manifest, segment=keys, value=repr(given)[:80],
                             roles=", ".join(PARTS))
    return {seg: given_spans(v, manifest, seg) for seg, v in given.items()}


def knee_split(given, side: str, manifest: Path | None = None) -> dict | None:
    """The ``split`` of one knee of a four-sensor session: its ``{side}_{segment}`` entries without the prefix
    (checked, :func:`check_split`); None when the clinician moved no cut of that knee.  Plain keys cannot say
    which knee's sensor they cut: refused (``manifest.bad_split``)."""
    if not given:
        return None
    check_split(given, manifest, knees=True)
    if set(given) - set(KNEE_SPLIT_KEYS):
        raise IngestionError("manifest.bad_split", file=manifest, segment=" | ".join(KNEE_SPLIT_KEYS),
                             value=repr(given)[:80], roles=", ".join(PARTS))
    mine = {k.removeprefix(f"{side}_"): v for k, v in given.items() if k.startswith(f"{side}_")}
    return mine or None


def split_recording(rec: RawRecording, segment: str, expected_fs_hz: float | None, how: str,
                    given: dict[str, tuple[float, float]] | None = None
                    ) -> tuple[dict[str, RawRecording], Split, Note]:
    """``rec`` cut into its protocol parts: ``({role: RawRecording}, Split, note)`` (module docstring).

    ``given`` (``session.json`` ``split``): spans the clinician set, s from the recording's start; they replace the
    automatic ones of those roles (``how`` becomes ``"session.json"``); with standing, supine and task all given
    the automatic split is not needed."""
    fs = check_rates(rec, expected_fs_hz)
    grid = align_recording(rec, fs, segment, CONTINUOUS)
    given = given or {}
    try:
        found: ProtocolSplit | None = split_protocol(grid.acc, grid.gyr, grid.mag, fs_hz=grid.fs_hz)
    except SplitError as exc:
        if not {"standing", "lying", "task"} <= set(given):
            raise IngestionError("split.no_posture", file=rec.files[0],
                                 posture={"code": "word.lying" if exc.what == "lying" else "word.standing"},
                                 found=str(exc).split("; still postures found: ")[-1]) from None
        found = None
    spans = found.spans_s() if found is not None else {}
    if given:
        spans = {k: given.get(k, spans.get(k)) for k in PARTS if k in given or k in spans}
        how = "session.json"
    parts: dict[str, RawRecording] = {}
    for i, (role, (a, b)) in enumerate(spans.items()):
        t0, t1 = grid.t0_s + a, grid.t0_s + b
        streams = [_cut(s, t0, t1) for s in rec.streams]
        parts[role] = replace(rec, acc=streams[0], gyr=streams[1], mag=streams[2],
                              role=Recognition(role, "split", f"{a:.1f}–{b:.1f} s of {rec.files[0].name}"),
                              notes=rec.notes if i == 0 else ())
    split = Split(segment, rec.files[0].name, spans, grid.t0_s, how, found.octants if found is not None else 0,
                  duration_s=len(grid.t_s) / grid.fs_hz, trace=motion_trace(grid.gyr, grid.fs_hz))
    span = {f"{k}_from_s": spans[k][0] for k in spans} | {f"{k}_to_s": spans[k][1] for k in spans}
    variant = "recording_split" if "mag_calibration" in spans else "recording_split_no_fig8"
    return parts, split, Note.of(variant, file=rec.files[0].name, segment=segment, **span)


def split_session(continuous: dict[str, list[tuple[RawRecording, str]]], recs: dict, expected_fs_hz: float | None,
                  given: dict | None = None, manifest: Path | None = None) -> tuple[dict, list[Split], list[Note]]:
    """Split the continuous recordings of a session (``{segment: [(rec, how)]}``) into ``recs``.

    A recording named continuous is always split; one without a role only when each of the two sensors has
    exactly one such recording and nothing else was recognised (``how == "only recording"``).  ``given``:
    ``session.json`` ``split`` (``{segment: {role: [start_s, end_s]}}``, :func:`given_spans`).  Returns the
    recordings with the parts added, the splits and their notes."""
    spans_of = check_split(given or {}, manifest)
    named = {seg: [r for r, how in items if how == "role"] for seg, items in continuous.items()}
    unnamed = {seg: [r for r, how in items if how != "role"] for seg, items in continuous.items()}
    chosen = {seg: [(r, "role") for r in rs] for seg, rs in named.items() if rs}
    if not recs and not chosen and len(unnamed) == 2 and all(len(rs) == 1 for rs in unnamed.values()):
        chosen = {seg: [(rs[0], "only recording")] for seg, rs in unnamed.items()}
    out, splits, notes = dict(recs), [], []
    for seg in sorted(chosen):
        for rec, how in chosen[seg]:
            spans = spans_of.get(seg)
            parts, split, note = split_recording(rec, seg, expected_fs_hz, how, spans)
            for role, part in parts.items():
                if (seg, role) in out:
                    raise IngestionError("session.recording_twice", file=part.files[0], other=out[seg, role].files[0],
                                         role=role, segment=seg)
                out[seg, role] = part
            splits.append(split)
            notes.append(note)
    return out, splits, notes


def left_unsplit(continuous: dict[str, list[tuple[RawRecording, str]]], splits: list[Split]) -> list[RawRecording]:
    """The recordings without a role that were not split (they stay unrecognised)."""
    done = {s.file for s in splits}
    return [r for items in continuous.values() for r, how in items if how != "role" and r.files[0].name not in done]
