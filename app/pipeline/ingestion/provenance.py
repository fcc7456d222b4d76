"""Provenance: what the files say about where a recording came from, and pure checks against the patient.

Facts (:func:`recording_facts`, :func:`session_facts`), per recording, each with how it was found:

* ``side`` — a side word in the file name / MetaBase label / APDM sensor label, or ``session.json``;
* ``started`` — the recording's start: UTC from the first epoch stamp (MetaBase, Shimmer Unix time, APDM,
  Xsens UTC, generic ``epoch``), else the MetaBase name's local time, else ``None``; ``date`` its day
  (or the thesis name's ``ddmmyyyy``);
* ``patient_id`` — the thesis name's ID field, or ``session.json``;
* ``sensor_id`` — MetaBase MAC, Xsens DeviceId, Shimmer device, APDM sensor id (``None`` for the thesis
  workbook and the generic CSV); ``device`` the user-chosen MetaBase name, ``firmware``.

Checks (pure: data in, :class:`Finding` list out; the app decides what refuses):

* :func:`check_side` — a side in the files other than the patient's (``severity="refuse"``: left-leg
  recordings on a right-knee patient flip adduction and rotation);
* :func:`check_dates` — a recording more than ``tolerance_days`` (1) from the session date, or recordings
  spread over more than that among themselves (``"warning"``);
* :func:`check_patient` — a patient id in the files other than the patient's (``"warning"``);
* :func:`check_sensors` — one sensor id recorded as the thigh in one recording and the shank in another
  (swapped straps, ``"warning"``); :func:`check_stored_sensors` the same on the server's stored devices, whose
  serial :func:`sensor_of_file_name` reads from a file's name at upload.

Each :class:`Finding` has a stable ``code`` (``check.*`` of :data:`.messages.CATALOGUE`) and ``params``,
rendered in es/en/pt by :meth:`Finding.message`.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

from app.pipeline.ingestion.labels import fold, recognise_side
from app.pipeline.ingestion.messages import render
from app.pipeline.ingestion.model import RawRecording, Recognition, Session


@dataclass(frozen=True)
class RecordingFacts:
    """What one recording's files say (each a :class:`Recognition` or ``None``), plus its identity.

    segment, role : canonical names.   files : names.   fmt : the format.
    side, patient_id, started (ISO date-time; UTC with ``+00:00``, else local), date (ISO day) :
    :class:`Recognition` or ``None``.   sensor_id, device, firmware : strings or ``None``.
    """

    segment: str
    role: str
    files: tuple[str, ...]
    fmt: str
    side: Recognition | None = None
    patient_id: Recognition | None = None
    started: Recognition | None = None
    date: Recognition | None = None
    sensor_id: str | None = None
    device: str | None = None
    firmware: str | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: Recognitions as ``{"value", "method", "evidence"}``."""
        out: dict[str, Any] = {}
        for k, v in self.__dict__.items():
            out[k] = {"value": v.value, "method": v.method, "evidence": v.evidence} if isinstance(v, Recognition) \
                else list(v) if isinstance(v, tuple) else v
        return out


@dataclass(frozen=True)
class Finding:
    """One check's result: ``code`` (``check.*``), ``params``, ``severity`` (``"refuse"`` or ``"warning"``)."""

    code: str
    params: Mapping[str, Any] = field(default_factory=dict)
    severity: str = "warning"

    def message(self, lang: str = "en") -> str:
        return render(self.code, self.params, lang)

    def as_dict(self) -> dict[str, Any]:
        return {"code": self.code, "params": dict(self.params), "severity": self.severity,
                "message": self.message("en")}


def recording_facts(raw: RawRecording, segment: str | None = None, role: str | None = None) -> RecordingFacts:
    """The facts of one recording as read (see the module docstring)."""
    ex = raw.extras
    started = None
    if raw.acc.time_base == "epoch" and raw.acc.t_s.size:
        when = dt.datetime.fromtimestamp(float(raw.acc.t_s[0]), tz=dt.timezone.utc)
        started = Recognition(when.isoformat(timespec="seconds"), "time stamps", f"{raw.acc.file.name} first stamp")
    elif "started" in ex:
        started = ex["started"]
    date = Recognition(started.value[:10], started.method, started.evidence) if started else ex.get("date")
    return RecordingFacts(
        segment=segment or (raw.segment.value if raw.segment else ""), role=role or (raw.role.value if raw.role else ""),
        files=tuple(p.name for p in raw.files), fmt=raw.fmt, side=ex.get("side"), patient_id=ex.get("patient_id"),
        started=started, date=date, sensor_id=raw.sensor_id,
        device=ex["device"].value if "device" in ex else None,
        firmware=ex["firmware"].value if "firmware" in ex else None)


def session_facts(session: Session) -> dict[tuple[str, str], RecordingFacts]:
    """``{(segment, role): RecordingFacts}`` of every recording of a loaded session; the manifest's side and
    patient id (``session.json``) apply to recordings whose files say none."""
    out = {}
    meta = session.metadata
    for key, raw in session.raw.items():
        f = recording_facts(raw, *key)
        if f.side is None and meta.side is not None and meta.side.method == "session.json":
            f = RecordingFacts(**{**f.__dict__, "side": meta.side})
        if f.patient_id is None and meta.patient_id is not None and meta.patient_id.method == "session.json":
            f = RecordingFacts(**{**f.__dict__, "patient_id": meta.patient_id})
        out[key] = f
    return out


def _name(f: RecordingFacts) -> str:
    return f.files[0] if f.files else f"{f.segment} {f.role}"


def check_side(facts: Iterable[RecordingFacts], patient_side: str) -> list[Finding]:
    """Recordings whose side (file name, label or ``session.json``) is not ``patient_side`` (right/left)."""
    want = recognise_side(patient_side, "argument")
    want_value = want.value if want else patient_side
    out = []
    for f in facts:
        if f.side is not None and f.side.value != want_value:
            out.append(Finding("check.side_mismatch", {"file": _name(f), "side": f.side.value,
                                                       "found": {"code": f"word.{f.side.value}"},
                                                       "method": f.side.method,
                                                       "patient_side": {"code": f"word.{want_value}"}},
                               "refuse"))
    return out


def _as_date(value: Any) -> dt.date | None:
    if isinstance(value, dt.datetime):
        return value.date()
    if isinstance(value, dt.date):
        return value
    try:
        return dt.date.fromisoformat(str(value)[:10])
    except ValueError:
        return None


def check_dates(facts: Iterable[RecordingFacts], session_date: Any = None,
                tolerance_days: float = 1.0) -> list[Finding]:
    """Recording dates vs ``session_date`` (ISO string, date or datetime; ``None``: only among themselves):
    a warning for each recording more than ``tolerance_days`` away, and one when the recordings themselves
    spread over more than that (the one made 48 days before the others)."""
    facts = [f for f in facts if f.date is not None and _as_date(f.date.value) is not None]
    out = []
    day = _as_date(session_date) if session_date is not None else None
    if day is not None:
        for f in facts:
            gap = abs((_as_date(f.date.value) - day).days)
            if gap > tolerance_days:
                out.append(Finding("check.date_far", {"file": _name(f), "date": f.date.value, "days": gap,
                                                      "session_date": day.isoformat()}))
    if len(facts) > 1:
        dates = sorted(facts, key=lambda f: _as_date(f.date.value))
        first, last = dates[0], dates[-1]
        spread = (_as_date(last.date.value) - _as_date(first.date.value)).days
        if spread > tolerance_days:
            out.append(Finding("check.dates_spread", {"first_file": _name(first), "first": first.date.value,
                                                      "last_file": _name(last), "last": last.date.value,
                                                      "days": spread}))
    return out


def _same_id(a: Any, b: Any) -> bool:
    return fold(str(a)).replace(" ", "").replace("-", "") == fold(str(b)).replace(" ", "").replace("-", "")


def check_patient(facts: Iterable[RecordingFacts], patient_id: Any) -> list[Finding]:
    """Patient ids in the files (or ``session.json``) that are not ``patient_id`` (case, accents, spaces and
    ``-`` ignored)."""
    return [Finding("check.patient_mismatch", {"file": _name(f), "found": str(f.patient_id.value),
                                               "method": f.patient_id.method, "patient_id": str(patient_id)})
            for f in facts if f.patient_id is not None and not _same_id(f.patient_id.value, patient_id)]


def sensor_of_file_name(name: str) -> str | None:
    """The sensor serial a file's *name* carries, without reading it: a MetaBase stream file's MAC (12 upper-case
    hex digits, any device name, :func:`.metabase.parse_file_name`), else ``None``.  What the server stores with an
    upload (``Recording.device``) and tells the browser, so the wizard keeps no copy of the naming rule."""
    from pathlib import Path

    from app.pipeline.ingestion.metabase import parse_file_name

    parsed = parse_file_name(Path(name)) if str(name).lower().endswith(".csv") else None
    return parsed["mac"] if parsed else None


def check_stored_sensors(rows: Iterable[tuple[str, str | None, str | None]]) -> list[Finding]:
    """:func:`check_sensors` on what the server stored: ``(file name, segment declared at upload, device)`` rows;
    a device declared on both segments is one sensor recording both (swapped straps or files)."""
    facts = [RecordingFacts(segment=seg, role="", files=(name,), fmt="", sensor_id=dev)
             for name, seg, dev in rows if seg and dev]
    return check_sensors(facts)


def check_sensors(facts: Iterable[RecordingFacts]) -> list[Finding]:
    """A sensor id used as the thigh in one recording and as the shank in another (straps swapped between
    recordings); also, both segments of one role recorded by one sensor."""
    seen: dict[str, dict[str, RecordingFacts]] = {}
    for f in facts:
        if f.sensor_id:
            seen.setdefault(f.sensor_id, {}).setdefault(f.segment, f)
    return [Finding("check.sensor_both_segments", {"sensor": sid, "thigh_file": _name(by["thigh"]),
                                                   "shank_file": _name(by["shank"])})
            for sid, by in seen.items() if "thigh" in by and "shank" in by]


def check_all(session: Session, *, patient_side: str | None = None, patient_id: Any = None,
              session_date: Any = None) -> list[Finding]:
    """Every check above on a loaded session (those whose patient value is ``None`` are skipped)."""
    facts = list(session_facts(session).values())
    out = []
    if patient_side:
        out += check_side(facts, patient_side)
    out += check_dates(facts, session_date)
    if patient_id not in (None, ""):
        out += check_patient(facts, patient_id)
    out += check_sensors(facts)
    return out
