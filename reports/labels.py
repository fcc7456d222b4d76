"""Labelling shared by every report: translated texts, the task's phases, which cycle and phase each
sample falls in, and the patient-and-session rows.

Reports present; they compute nothing clinical.  The work here is *labelling* only, from ``results``
(:class:`~reports.model.ReportInput`): cycles from ``results["cycles"]["boundaries_s"]`` /
``["events_s"]`` and phases from the session task's definitions (:data:`estimators.motor_task.tasks.TASKS`;
step-up: impulse = onset → countermovement_peak, extension = countermovement_peak → far_left, fall =
far_left → rest_reached).  Sample ranges are half-open ``[start, end)`` (DESIGN §3).  The PDF, Excel and
HTML reports all read phases through :func:`phase_specs`, so a squat or a seated extension shows its own
phases everywhere, not the step-up's.
"""

from __future__ import annotations

import datetime as _dt
import math
from typing import Any

import numpy as np

from reports import i18n
from reports.model import Patient, ReportInput

__all__ = ["get_path", "tr", "code_label", "phase_specs", "phase_names", "phase_spans_pct",
           "cycle_and_phase_per_sample", "session_rows", "age_years", "identity_items", "identity_line",
           "recorded_text", "filter_label", "angle_method_label", "signature_line", "signed_line", "split_rejected",
           "excluded_lines", "all_excluded_lines", "calibration_sentence", "heading_sentence", "reference_sentence",
           "method_items", "EXCLUDED"]

_DEFAULT_PHASES = (("impulse", "onset", "countermovement_peak"),
                   ("extension", "countermovement_peak", "far_left"),
                   ("fall", "far_left", "rest_reached"))


def get_path(d: Any, *keys: str, default: Any = None) -> Any:
    """``d[k1][k2]...``; ``default`` when a level is missing, not a dict, or the value is None."""
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return default
        d = d[k]
    return default if d is None else d


def tr(key: str, lang: str, /, **fields: Any) -> str:
    """Translated text of ``key`` (:func:`reports.i18n.t`; keys of ``reports/translations*.json``)."""
    return i18n.t(key, lang, **fields)


def code_label(prefix: str, code: Any, lang: str) -> str:
    """Translation of a code from the data (``data.phase.impulse``...), the raw code when the table has none."""
    key = f"{prefix}.{code}"
    return i18n.t(key, lang) if i18n.has(key) else str(code)


def reference_sentence(ref: dict[str, Any], lang: str) -> str:
    """``results["reference"]`` in one sentence: its kind, source, population and conditions (the texts of
    :mod:`estimators.motor_task.reference`, translated by the reference's ``id`` where the tables have them)."""
    def text(field: str) -> str:
        key = f"ref.{ref.get('id')}.{field}"
        return i18n.t(key, lang) if i18n.has(key) else str(ref.get(field) or "")

    kind = tr(f"ref.kind_{ref.get('kind')}", lang)
    return f"{kind}: {ref.get('source')}. {text('population')}; {text('conditions')}. {text('transcription')}."


def heading_sentence(results: dict[str, Any], lang: str) -> str | None:
    """Which thigh–shank heading the angles use (``results["quality"]["heading"]``, ``--heading``), as one
    sentence for the report's quality section; None for a results file without it."""
    h = get_path(results, "quality", "heading")
    if not isinstance(h, dict) or h.get("used") not in ("magnetometer", "constraint"):
        return None
    return tr(f"heading.used.{h['used']}", lang, mode=code_label("heading.mode", h.get("mode"), lang),
              disagreement=i18n.fmt_number(h.get("disagreement_deg"), 0, lang),
              bound=i18n.fmt_number(h.get("bound_deg"), 0, lang))


def calibration_sentence(results: dict[str, Any], lang: str) -> str | None:
    """Which calibration the session had (``results["calibration"]["protocol"]``): the sensor-to-segment method,
    the magnetometer's and the accelerometer's, one sentence; None for a results file without it."""
    p = get_path(results, "calibration", "protocol")
    if not isinstance(p, dict):
        return None
    segment = p.get("segment")
    parts = [code_label("calibration.segment", s, lang) for s in ([segment] if isinstance(segment, str) else segment or [])]
    parts += [code_label("calibration.magnetometer", m, lang) for m in p.get("magnetometer") or []]
    parts += [code_label("calibration.accelerometer", m, lang) for m in p.get("accelerometer") or []]
    return "; ".join(parts) + "." if parts else None


def _segment_methods(value: Any, lang: str) -> str:
    """A sensor-to-segment calibration code (or one per segment, a list) by its human name (``method.segment.*``)."""
    codes = [value] if isinstance(value, str) else [v for v in value or [] if isinstance(v, str)]
    return " / ".join(code_label("method.segment", c, lang) for c in codes)


def method_items(results: dict[str, Any], lang: str) -> list[tuple[str, str]]:
    """``(label, text)`` of how the numbers were computed, for the report's method section: the sensor-to-segment
    calibration asked for (``results["calibration_method"]``, static or functional) beside the one the recordings
    allowed and the pipeline used (``results["calibration"]["protocol"]["segment"]``: a session without a supine
    recording is calibrated on the task even when static was asked for), and the knee-angle convention
    (``results["angle_method"]``) with its signs.  Only what results.json says; a line it has nothing for is left
    out."""
    asked = results.get("calibration_method")
    asked_text = _segment_methods(asked, lang) if isinstance(asked, str) and asked else ""
    used = get_path(results, "calibration", "protocol", "segment")
    used_text = _segment_methods(used, lang)
    if asked_text and used_text:
        same = used == asked or (isinstance(used, list) and set(used) == {asked})
        text = (tr("method.calibration_as_asked", lang, used=used_text) if same
                else tr("method.calibration_asked_used", lang, asked=asked_text, used=used_text))
    elif used_text:
        text = tr("method.calibration_used", lang, used=used_text)
    elif asked_text:
        text = tr("method.calibration_asked", lang, asked=asked_text)
    else:
        text = ""
    items = [(tr("protocol_segment_label", lang), text)] if text else []
    convention = results.get("angle_method")
    if isinstance(convention, str) and i18n.has(f"angle_method_{convention}"):
        items.append((tr("protocol_angles_label", lang),
                      tr(f"angle_method_{convention}", lang) + tr("method.angles_mirrored", lang)))
    return items


#: the reason code of a cycle the clinician excluded (estimators.motor_task.EXCLUDED)
EXCLUDED = "excluded_by_clinician"


def split_rejected(cycles: dict[str, Any]) -> tuple[list[dict], list[dict]]:
    """``results["cycles"]["rejected"]`` as (the pipeline's rejections, the clinician's exclusions)."""
    rejected = [r for r in cycles.get("rejected") or [] if isinstance(r, dict)]
    return ([r for r in rejected if r.get("reason") != EXCLUDED], [r for r in rejected if r.get("reason") == EXCLUDED])


def excluded_lines(cycles: dict[str, Any], lang: str) -> list[str]:
    """One sentence per cycle the clinician excluded (``cycles.excluded``): which, by whom, when and why."""
    out = []
    for e in cycles.get("excluded") or []:
        if not isinstance(e, dict):
            continue
        reason = str(e.get("reason") or "").strip() or i18n.t("reason_unknown", lang)
        out.append(i18n.t("cycle_excluded", lang, n=e.get("cycle", i18n.MISSING), by=e.get("by") or i18n.MISSING,
                          date=str(e.get("at") or "")[:10] or i18n.MISSING, reason=reason))
    return out


def all_excluded_lines(results: dict[str, Any], lang: str) -> list[str]:
    """:func:`excluded_lines` of every knee: a two-knee session's (``results["knees"]``) each with its knee first
    (``warning.knee.<side>``, as the warnings), else the only knee's."""
    knees = results.get("knees")
    if not isinstance(knees, dict) or not knees:
        return excluded_lines(results.get("cycles") or {}, lang)
    out = []
    for side in sorted(knees):
        prefix = (i18n.table().get(f"warning.knee.{side}") or {}).get(lang, f"{side}: ")
        out += [prefix + line for line in excluded_lines((knees[side] or {}).get("cycles") or {}, lang)]
    return out


def phase_specs(results: dict[str, Any]) -> tuple[tuple[str, str, str], ...]:
    """``(phase, start event, end event)`` of the session's task (:data:`estimators.motor_task.tasks.TASKS`).

    Falls back to the step-up definitions when the task is unknown to this version.
    """
    try:
        from estimators.motor_task.tasks import get_task

        return tuple((p.name, p.start, p.end) for p in get_task(results.get("task", "step_up")).phases)
    except (ImportError, ValueError):
        return _DEFAULT_PHASES


def phase_names(results: dict[str, Any]) -> tuple[str, ...]:
    """The session task's phase names, in order (:func:`phase_specs`)."""
    return tuple(name for name, _, _ in phase_specs(results))


def phase_spans_pct(results: dict[str, Any]) -> list[tuple[str, float, float]]:
    """``(phase, start %, end %)`` of the mean cycle: the task's phases laid end to end by their mean
    percentage ``results["phases"][phase]["mean_pct"]``; a missing or non-finite percentage ends the list."""
    out, start = [], 0.0
    for name in phase_names(results):
        pct = get_path(results, "phases", name, "mean_pct")
        if pct is None or not math.isfinite(float(pct)):
            break
        out.append((name, start, start + float(pct)))
        start += float(pct)
    return out


def cycle_and_phase_per_sample(ri: ReportInput) -> tuple[list[int | None], list[str]]:
    """Per sample: the detected cycle (1-based; None outside every cycle) and the phase name ("" outside).

    Cycles are ``results["cycles"]["boundaries_s"]`` (half-open); phases are spans between the cycle's
    events (``events_s`` in the order of ``events``); unknown (null) boundaries or events are skipped.
    """
    cycles = ri.results.get("cycles", {})
    t = np.asarray(ri.t_s, dtype=np.float64)
    n = len(t)
    cycle = np.zeros(n, dtype=np.int64)
    phase = np.full(n, -1, dtype=np.int64)
    specs = phase_specs(ri.results)
    events = list(cycles.get("events", ()))
    events_s = cycles.get("events_s") or []
    for k, bounds in enumerate(cycles.get("boundaries_s") or []):
        if bounds is None or None in bounds[:2]:
            continue
        i0, i1 = np.searchsorted(t, bounds[:2], side="left")
        cycle[i0:i1] = k + 1
        ev = events_s[k] if k < len(events_s) and events_s[k] is not None else []
        for j, (_, start, end) in enumerate(specs):
            if start not in events or end not in events:
                continue
            a, b = events.index(start), events.index(end)
            if max(a, b) >= len(ev) or ev[a] is None or ev[b] is None:
                continue
            p0, p1 = np.searchsorted(t, [ev[a], ev[b]], side="left")
            phase[p0:p1] = j
    names = [name for name, _, _ in specs]
    cycle_list = [c if c else None for c in cycle.tolist()]
    return cycle_list, [names[p] if p >= 0 else "" for p in phase.tolist()]


def session_rows(ri: ReportInput, lang: str) -> list[tuple[str, Any]]:
    """``(field, value)`` rows of the patient and session block (Excel sheet, HTML table): the identity every
    page carries (the known parts: :func:`identity_items`), dates in the language's one format, the step height
    in cm (as the PDF), the filter and angle convention by their human names."""
    p, r = ri.patient, ri.results
    side = p.side or r.get("side") or ""
    task = r.get("task", "")
    cycles = r.get("cycles", {})
    step_m = p.step_height_m if p.step_height_m is not None else get_path(r, "session", "step_height_m")
    step_cm = None if step_m is None else round(100.0 * float(step_m), 1)
    if step_cm is not None and step_cm == int(step_cm):
        step_cm = int(step_cm)  # 17, as the PDF prints it (a float would show decimals in the HTML)
    age = age_years(p.birth_date, p.recorded or p.date) if p.birth_date else None
    identity = [
        (tr("data.patient.record", lang), p.record_number),
        (tr("data.patient.record_system", lang), p.record_system),
        (tr("data.patient.birth_date", lang), i18n.fmt_date(p.birth_date, lang)),
        (tr("data.patient.age", lang), age),
        (tr("data.patient.sex", lang), code_label("id.sex", p.sex, lang) if p.sex else ""),
        (tr("data.patient.clinic", lang), p.clinic),
        (tr("data.patient.recorded", lang), recorded_text(p, lang)),
    ]
    return [
        (tr("data.patient.name_or_id", lang), p.name_or_id),
        *[(k, v) for k, v in identity if v not in (None, "")],
        (tr("data.patient.date", lang), i18n.fmt_date(p.date, lang)),
        (tr("data.patient.professional", lang), p.professional),
        (tr("data.patient.side", lang), code_label("data.side", side, lang) if side else ""),
        (tr("data.patient.step_height_cm", lang), step_cm),
        (tr("data.patient.weight_kg", lang), p.weight_kg),
        (tr("data.patient.height_m", lang), p.height_m),
        (tr("data.patient.observations", lang), p.observations),
        (tr("data.session.task", lang), code_label("data.task", task, lang) if task else ""),
        (tr("data.session.filter", lang), filter_label(r, lang)),
        (tr("data.session.angle_method", lang), angle_method_label(r, lang)),
        (tr("data.session.fs_hz", lang), ri.fs_hz),
        (tr("data.session.cycles_detected", lang), cycles.get("detected")),
        (tr("data.session.cycles_accepted", lang), cycles.get("accepted")),
        (tr("data.session.software", lang), get_path(r, "software", "version", default="")),
    ]

def _iso_date(text: str) -> _dt.date | None:
    try:
        return _dt.date.fromisoformat(str(text).strip()[:10])
    except ValueError:
        return None


def age_years(birth_date: str, on: str) -> int | None:
    """Whole years from ``birth_date`` to ``on`` (both ISO), the usual civil age (a birthday not yet reached that
    year does not count; one born on 29 February turns a year older on 1 March in common years); None when either
    is unknown or ``on`` comes before the birth."""
    b, d = _iso_date(birth_date), _iso_date(on)
    if b is None or d is None or d < b:
        return None
    return d.year - b.year - ((d.month, d.day) < (b.month, b.day))


def recorded_text(p: Patient, lang: str) -> str:
    """The recordings' date (or first – last day when they span several), in the language's date format, with
    " UTC" when it is the UTC day (``recorded_zone``: only UTC time stamps said it), not the local one."""
    first, last = i18n.fmt_date(p.recorded, lang), i18n.fmt_date(p.recorded_last, lang)
    text = f"{first} – {last}" if first and last and last != first else first
    return f"{text} {p.recorded_zone}" if text and p.recorded_zone else text


def identity_items(p: Patient, lang: str) -> list[tuple[str, str]]:
    """``(label, value)`` of who the report is about, the known ones only (nothing unknown is printed, nothing
    invented): name or ID, record number with its identifier system, birth date with the age at the recordings'
    date (else at the session's), sex, clinic, and the recordings' date."""
    items: list[tuple[str, str]] = []
    if p.name_or_id and p.name_or_id != p.record_number:
        items.append((tr("id.patient", lang), p.name_or_id))
    if p.record_number:
        items.append((tr("id.record", lang), f"{p.record_number} ({p.record_system})" if p.record_system
                      else p.record_number))
    if p.birth_date:
        age = age_years(p.birth_date, p.recorded or p.date)
        born = i18n.fmt_date(p.birth_date, lang)
        items.append((tr("id.born", lang), born if age is None else tr("id.born_age", lang, date=born, age=age)))
    if p.sex:
        items.append((tr("id.sex", lang), code_label("id.sex", p.sex, lang)))
    if p.clinic:
        items.append((tr("id.clinic", lang), p.clinic))
    recorded = recorded_text(p, lang)
    if recorded:
        items.append((tr("id.recorded", lang), recorded))
    return items


def identity_line(p: Patient, lang: str) -> str:
    """:func:`identity_items` on one line (``label: value · label: value``), for every page's header."""
    return " · ".join(f"{label}: {value}" for label, value in identity_items(p, lang))


def filter_label(results: dict[str, Any], lang: str) -> str:
    """The orientation filter by its human name (``data.filter.<id>``), never the raw id (issue 17 §3)."""
    name = get_path(results, "filter", "name", default="")
    return code_label("data.filter", name, lang) if name else ""


def angle_method_label(results: dict[str, Any], lang: str) -> str:
    """The knee-angle convention by its human name (``data.angle_method.<id>``), never the raw id."""
    name = results.get("angle_method") or ""
    return code_label("data.angle_method", name, lang) if name else ""


def signature_line(lang: str, it) -> str:
    """Who signed the interpretation ``it`` (:class:`reports.model.Interpretation`) and when; once amended, "First
    signed by A …; last amended by B on … (reason)" — the text printed above it is the amended one, so the signer
    is never shown alone under a text they did not sign."""
    first = signed_line(lang, "interp.signed" if not it.amendments else "interp.first_signed", it.signed_by,
                        it.signed_role, it.signed_at)
    if not it.amendments:
        return first
    last = it.amendments[-1]
    return first + "; " + signed_line(lang, "interp.last_amended", last.by, last.role, last.at, reason=last.reason)


def signed_line(lang: str, key: str, by: str, role: str, at: str, **fields: Any) -> str:
    """``interp.signed`` / ``interp.amendment``: who (``by``, their role's name), the date in the language's format
    and the time (UTC) of ``at`` (ISO date-time), and ``fields`` (an amendment's ``reason``)."""
    try:
        when = _dt.datetime.fromisoformat(at) if at else None
    except ValueError:
        when = None
    if when is not None and when.tzinfo is not None:
        when = when.astimezone(_dt.timezone.utc)
    role_text = i18n.t(f"interp.role.{role}", lang) if i18n.has(f"interp.role.{role}") else role
    return i18n.t(key, lang, name=by, role=role_text, date=i18n.fmt_date(when, lang) if when else i18n.MISSING,
                  time=f"{when:%H:%M}" if when else i18n.MISSING, **fields)
