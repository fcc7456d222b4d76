"""``results.json`` of one knee session (``../shared/DESIGN.md`` §4), and writing outputs safely.

The estimators work in radians; this is where clinical numbers become degrees.  Every NaN becomes
``null`` (JSON has no NaN).  :func:`write_outputs` writes all files into a temporary folder next to the
destination and moves them in only when every file is complete, so a failure leaves nothing half-written.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from estimators import __version__
from estimators.jsonable import json_ready
from estimators.motor_task import ANGLES
from estimators.motor_task.analysis import ROM_STATS

from reports.model import Interpretation, Patient, ReportInput
from reports.warning_text import is_technical

from app.pipeline.ingestion.provenance import session_facts
from app.pipeline.knees import KneesOutcome, limb_symmetry
from app.pipeline.session import SessionOutcome


#: segment calibrations made without the supine posture (estimators.functional)
NO_SUPINE_METHODS = ("standing_functional", "task_functional")


def _deg(x: Any) -> Any:
    """Degrees of a number, an array or a nested mapping of them (None stays None)."""
    if isinstance(x, Mapping):
        return {k: _deg(v) for k, v in x.items()}
    if x is None:
        return None
    return np.rad2deg(np.asarray(x, dtype=np.float64))


def build_results(outcome: SessionOutcome) -> dict[str, Any]:
    """The ``results.json`` dictionary (DESIGN §4 keys, plus session facts and per-cycle detail)."""
    a = outcome.analysis
    task = a.to_dict()
    opts = outcome.options
    warnings = [w.to_dict() for w in outcome.warnings]
    session = outcome.session
    meta = session.metadata
    results = {
        "side": outcome.side,
        "task": task["task"],
        "filter": {"name": opts.filter_name, "params": dataclasses.asdict(outcome.filter_params),
                   "overrides": dict(opts.filter_params)},
        "angles": list(ANGLES),
        "angle_method": opts.angle_method,
        # the sensor-to-segment calibration asked for (ProcessOptions.calibration); "calibration" holds what it made
        "calibration_method": opts.calibration,
        "cycles": {
            "detected": task["cycles"]["detected"],
            "accepted": task["cycles"]["accepted"],
            "rejected": task["cycles"]["rejected"],
            "boundaries_s": task["cycles"]["boundaries_s"],
            "accepted_indices": task["cycles"]["accepted_indices"],
            "events": task["cycles"]["events"],
            "events_s": task["cycles"]["events_s"],
            "task_span_s": task["task_span_s"],
            "per_cycle": _per_cycle(outcome),
            # who excluded which cycle and why (their reason in rejected is excluded_by_clinician)
            "excluded": [e.to_dict() for e in opts.exclusions],
        },
        "rom_deg": _deg(task["rom_rad"]),
        **({"gait": _gait(task["gait"])} if "gait" in task else {}),
        "phases": task["phases"],
        "curves": {name: _deg(c) for name, c in task["curves_rad"].items()},
        "calibration": {
            "magnetometer": {seg: cal.to_dict() for seg, cal in outcome.mag.items()},
            # the accelerometer bias (and gain) from the still poses, applied before everything else
            "accelerometer": None if outcome.acc is None else {seg: c.to_dict() for seg, c in outcome.acc.items()},
            "segment": {
                seg: {
                    "q_sensor_segment": cal.q_sensor_segment,
                    "method": cal.method,
                    "axis_change_deg": None if cal.axis_change_rad is None else np.rad2deg(cal.axis_change_rad),
                    "angle_between_postures_deg": np.rad2deg(cal.angle_between_postures_rad),
                    "gyr_bias_deg_s": np.rad2deg(cal.gyr_bias_rad_s),
                    "standing_window_s": [cal.standing.start_s, cal.standing.start_s + cal.standing.duration_s],
                    # without a supine recording (standing/task functional) there is no supine window: the
                    # standing field then holds the straight window used (of the standing or the task recording)
                    "supine_window_s": None if cal.method in NO_SUPINE_METHODS else
                    [cal.supine.start_s, cal.supine.start_s + cal.supine.duration_s],
                }
                for seg, cal in outcome.segments.items()
            },
            "heading_offset_standing_deg": None if outcome.heading is None else np.rad2deg(outcome.heading.offset_rad),
            # which recordings the calibration had: postures (standing + supine), standing_task, or task alone
            "protocol": _protocol_facts(outcome),
        },
        "quality": {
            # clinical warnings apart from the technical notes on reading the files (reports.warning_text.is_technical)
            "warnings": [w for w in warnings if not is_technical(w)],
            "technical_notes": [w for w in warnings if is_technical(w)],
            "magnetic_disturbance_fraction": {seg: f.fraction for seg, f in outcome.field.items()},
            "heading_task": _heading_task(outcome),
            # which thigh–shank heading the knee angles use (--heading), and the figures it was chosen by
            "heading": None if outcome.heading_choice is None else outcome.heading_choice.to_dict(),
        },
        "session": {
            "folder": str(session.folder),
            "patient_id": meta.value("patient_id"),
            "date": meta.value("date"),
            # the recordings' own first and last day (local, else UTC: "zone"; None when no recording says it)
            "recorded": dict(zip(("first", "last", "zone"), (d or None for d in recorded_dates(session)))),
            "step_height_m": outcome.step_height_m,
            "language": opts.language,
            "task_recording": {"fs_hz": outcome.fs_hz, "duration_s": len(outcome.t_s) / outcome.fs_hz,
                               "t0_s": outcome.t0_s},
            "recognised": {f"{seg}/{role}": rec.source for (seg, role), rec in session.recordings.items()},
            # one continuous recording per sensor split into the protocol's parts: where (s from its start)
            "split": {s.segment: s.to_dict() for s in session.splits} or None,
        },
        "software": {"version": __version__},
    }
    out = json_ready(results)
    reference = _reference(out)
    if reference is not None:
        out["reference"] = reference
    return out


def _reference(r: dict[str, Any]) -> dict[str, Any] | None:
    """The task's reference block (:func:`estimators.motor_task.reference.compare`): the session's means in the
    reference's units (degrees, % of the cycle, s), or None for a task without a reference."""
    from estimators.motor_task.reference import compare, reference_for

    ref = reference_for(r["task"], (r.get("session") or {}).get("step_height_m"))
    if ref is None:
        return None
    if r["task"] == "gait":
        values = {k: v.get("mean") for k, v in ((r.get("gait") or {}).get("parameters") or {}).items()}
    else:
        phases = r.get("phases") or {}
        flexion = (r.get("rom_deg") or {}).get("flexion") or {}
        values = {f"{name}_pct": p.get("mean_pct") for name, p in phases.items()}
        # the cycle's own mean: ``phases`` holds the task's phases *and* "movement" and "cycle", so their sum is
        # not the cycle time (it was ~3x it)
        values["cycle_s"] = (phases.get("cycle") or {}).get("mean_s")
        values.update({f"flexion_{k}_deg": (flexion.get(stat) or {}).get("mean")
                       for k, stat in (("rom", "range"), ("max", "max"), ("min", "min"))})
    return json_ready(compare(ref, values))


def build_knees_results(knees: KneesOutcome) -> dict[str, Any]:
    """``results.json`` of a session of one or both knees.

    One knee: :func:`build_results` unchanged.  Both knees: the top level is still one knee's results (DESIGN §4,
    so every reader of the one-knee contract keeps working): the involved knee's, else the right's; beside it
    ``involved_side`` (or None), ``knees`` (``{"left": ..., "right": ...}``: each knee's own one-knee results) and
    ``symmetry`` (:func:`app.pipeline.knees.limb_symmetry`: the LSI per parameter, None without an involved side).
    The top level's ``quality.warnings`` are both knees' (:func:`knees_warnings`), so the other knee's reach the
    reports, the web and FHIR too.
    """
    primary = build_results(knees.primary)
    if not knees.bilateral:
        return primary
    per = {side: primary if outcome is knees.primary else build_results(outcome)
           for side, outcome in sorted(knees.knees.items())}
    top = next(side for side, outcome in knees.knees.items() if outcome is knees.primary)
    quality = {**primary["quality"], "warnings": knees_warnings(per, top),
               "technical_notes": knees_warnings(per, top, "technical_notes")}
    return {**primary, "quality": quality, "involved_side": knees.involved, "knees": per,
            "symmetry": json_ready(limb_symmetry(per, knees.involved))}


def knees_warnings(per: Mapping[str, Mapping[str, Any]], first: str, key: str = "warnings") -> list[dict[str, Any]]:
    """Both knees' ``quality.warnings`` as one list, knee ``first`` (the top level's) first: a warning both knees
    raise alike (a session-wide one, as a recording missing from the folder, or the same on both legs) once and as
    it is; every other with ``params["knee"]`` = its knee's side, which the reports, the web and FHIR print as a
    translated prefix (:func:`reports.warning_text.warning_text`).  ``knee``, not ``side``: a warning's ``side``
    is already the recording's side in ``check.side_mismatch``.  ``key``: ``warnings`` or ``technical_notes``."""
    order = [first, *sorted(side for side in per if side != first)]
    lists = [list(per[side]["quality"].get(key) or []) for side in order]
    shared = [w for w in lists[0] if all(w in other for other in lists[1:])]

    def of(w: Mapping[str, Any], side: str) -> dict[str, Any]:
        return {**w, "params": {**(w.get("params") or {}), "knee": side}}

    out = [dict(w) if w in shared else of(w, first) for w in lists[0]]
    for side, warnings in zip(order[1:], lists[1:]):
        out += [of(w, side) for w in warnings if w not in shared]
    return out


def _gait(gait: dict[str, Any]) -> dict[str, Any]:
    """The gait task's parameters for ``results.json``: each ``*_rad`` value in degrees as ``*_deg``, the rest as
    analysed (stride time and cadence with their CV, stance/swing and peak-timing percentages, bouts, turns)."""
    def deg_keys(d: Any) -> Any:
        if isinstance(d, dict):
            return {(k[:-4] + "_deg" if k.endswith("_rad") else k): (_deg(v) if k.endswith("_rad") else deg_keys(v))
                    for k, v in d.items()}
        return d

    return deg_keys(gait)


def _protocol_facts(outcome: SessionOutcome) -> dict[str, Any]:
    """What the calibration was made from: the segment method (static, functional, standing_functional,
    task_functional) and the magnetometer's (ellipsoid, sphere, or factory: no figure-eight)."""
    methods = {cal.method for cal in outcome.segments.values()}
    return {"segment": methods.pop() if len(methods) == 1 else sorted(methods),
            "magnetometer": sorted({m.model for m in outcome.mag.values()}),
            "accelerometer": None if outcome.acc is None else sorted({c.model for c in outcome.acc.values()}),
            "recordings": sorted({role for _, role in outcome.session.recordings})}


def _heading_task(outcome: SessionOutcome) -> dict[str, Any] | None:
    """The heading check over the task's straight-knee holds (degrees), or None when there was no hold."""
    h = outcome.heading_task
    if h is None:
        return None
    return {"spans_s": h.spans_s, "offsets_deg": _deg(h.offsets_rad), "change_deg": _deg(h.change_rad),
            "mean_offset_deg": _deg(h.mean_offset_rad)}


def _per_cycle(outcome: SessionOutcome) -> list[dict[str, Any]]:
    """One entry per detected cycle: accepted or the reason it is not (the pipeline's or ``excluded_by_clinician``),
    ROM (deg), phase durations and its normalised flexion curve (``flexion_deg``, 0..100 %, None when incomplete),
    which the results page draws per cycle."""
    a = outcome.analysis
    reasons = {r.index: r.code for r in a.rejected}
    flexion = np.rad2deg(a.curves_rad[:, :, 0])  # each cycle's normalised flexion (NaN for the incomplete)
    phases = a.task.phase_names
    out = []
    for k in range(a.n_detected):
        out.append({
            "index": k,
            "accepted": bool(a.accepted[k]),
            "reason": reasons.get(k),
            "start_s": a.cycles_s[k, 0],
            "end_s": a.cycles_s[k, 1],
            "rom_deg": {angle: dict(zip(ROM_STATS, np.rad2deg(a.rom_rad[k, i]))) for i, angle in enumerate(ANGLES)},
            "phases": {name: {"s": a.phase_s[k, j], "pct": a.phase_pct[k, j]} for j, name in enumerate(phases)},
            "flexion_deg": None if not np.all(np.isfinite(flexion[k])) else np.round(flexion[k], 2),
        })
    return out


def timeseries_npz(outcome: SessionOutcome, knees: KneesOutcome | None = None) -> bytes:
    """The task's series (``timeseries.npz``): t_s, angles_deg, and sensor and segment quaternions (of the knee
    :func:`build_knees_results` puts at the top level); with both knees also ``t_s_left``, ``angles_deg_left``,
    ``t_s_right``, ``angles_deg_right`` (each knee's own task grid)."""
    return _series_npz(outcome.t_s, np.rad2deg(outcome.angles_rad), outcome.q_earth_sensor,
                       {"femur": outcome.q_earth_segment["thigh"], "tibia": outcome.q_earth_segment["shank"]},
                       {seg: cal.q_sensor_segment for seg, cal in outcome.segments.items()}, _knees_series(knees))


def timeseries_npz_of(ri: ReportInput) -> bytes:
    """:func:`timeseries_npz` from the report input :func:`report_input` made of the outcome (the same arrays:
    its angles are the outcome's in degrees, as here), for a render process that has only the report input."""
    return _series_npz(ri.t_s, ri.angles_deg, ri.q_earth_sensor, ri.q_earth_segment, ri.q_sensor_segment,
                       ri.knees_series)


def report_input_of_files(results: dict[str, Any], npz: bytes, patient: Patient, language: str,
                          interpretation: Interpretation | None = None) -> ReportInput:
    """The report input again from an analysis' stored ``results.json`` and ``timeseries.npz`` (the arrays
    :func:`timeseries_npz` wrote, bit for bit), with ``patient`` and the clinician's signed ``interpretation``:
    the reports of a stored analysis rendered again with what was added since (issue 17 §3)."""
    with np.load(io.BytesIO(npz), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    knees_series = {side: {"t_s": arrays[f"t_s_{side}"], "angles_deg": arrays[f"angles_deg_{side}"]}
                    for side in ("left", "right") if f"t_s_{side}" in arrays}
    return ReportInput(
        results=results, t_s=arrays["t_s"], angles_deg=arrays["angles_deg"],
        q_earth_sensor={seg: arrays[f"q_earth_sensor_{seg}"] for seg in ("thigh", "shank")},
        q_earth_segment={seg: arrays[f"q_earth_segment_{seg}"] for seg in ("femur", "tibia")},
        q_sensor_segment={seg: arrays[f"q_sensor_segment_{seg}"] for seg in ("thigh", "shank")},
        patient=patient, language=language, knees_series=knees_series, interpretation=interpretation)


def _knees_series(knees: KneesOutcome | None) -> dict[str, dict[str, np.ndarray]]:
    """``{side: {"t_s", "angles_deg"}}`` of both knees (``{}`` for one knee)."""
    if knees is None or not knees.bilateral:
        return {}
    return {side: {"t_s": o.t_s, "angles_deg": np.rad2deg(o.angles_rad)} for side, o in sorted(knees.knees.items())}


def _series_npz(t_s, angles_deg, q_earth_sensor, q_earth_segment, q_sensor_segment, knees_series) -> bytes:
    buf = io.BytesIO()
    per_knee = {f"{name}_{side}": v for side, series in knees_series.items() for name, v in series.items()}
    np.savez_compressed(
        buf, t_s=t_s, angles_deg=angles_deg, **per_knee,
        q_earth_sensor_thigh=q_earth_sensor["thigh"], q_earth_sensor_shank=q_earth_sensor["shank"],
        q_earth_segment_femur=q_earth_segment["femur"], q_earth_segment_tibia=q_earth_segment["tibia"],
        q_sensor_segment_thigh=q_sensor_segment["thigh"], q_sensor_segment_shank=q_sensor_segment["shank"],
    )
    return buf.getvalue()


def write_outputs(out_dir: str | os.PathLike, files: Mapping[str, Any]) -> list[Path]:
    """Write ``{name: content}`` into ``out_dir`` all-or-nothing; returns the paths written.

    ``content`` is bytes, text, or a callable that writes the file at the path it is given (for writers
    such as openpyxl's).  Everything is first written into a temporary folder beside ``out_dir`` (same
    file system), then moved in with ``os.replace``; if anything fails before the moves, ``out_dir`` is
    untouched.
    """
    out = Path(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for name, content in files.items():
            target = staging / name
            if callable(content):
                content(target)
                if not target.is_file():
                    raise OSError(f"the writer of {name} produced no file")
            else:
                target.write_bytes(content.encode() if isinstance(content, str) else content)
        out.mkdir(parents=True, exist_ok=True)
        written = []
        for name in files:
            os.replace(staging / name, out / name)
            written.append(out / name)
        return written
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def results_json(results: dict[str, Any]) -> str:
    """``results.json`` text of :func:`build_results`' dictionary (UTF-8, indented, no NaN)."""
    return json.dumps(results, indent=2, ensure_ascii=False, allow_nan=False)


def session_patient(outcome: SessionOutcome) -> Patient:
    """The patient block: what the names and ``session.json`` said (:func:`patient_of`), and the recordings' own
    date (:func:`recorded_dates`)."""
    meta = outcome.session.metadata
    return patient_of(outcome.session.manifest_data, record=meta.value("patient_id"), date=meta.value("date"),
                      side=outcome.side, step_height_m=outcome.step_height_m,
                      recorded=recorded_dates(outcome.session))


def patient_of(manifest: Mapping[str, Any], *, record: Any, date: Any, side: str, step_height_m: float | None,
               recorded: tuple[str, ...]) -> Patient:
    """The reports' :class:`Patient` from a ``session.json``'s optional keys ``name``, ``professional``,
    ``weight_kg``, ``height_m``, ``observations``, ``identifier_system``, ``birth_date``, ``sex``, ``clinic`` (shown as
    typed; the server writes them from its patient and clinic, :func:`app.store.workspace.build_manifest`), the
    record number ``record`` and session ``date`` the ingestion found, and the recordings' ``(first, last[, zone])``
    day (:func:`recorded_dates`).
    What nothing said stays empty: the reports omit it."""
    def number(key: str) -> float | None:
        try:
            value = float(manifest[key])
        except (KeyError, TypeError, ValueError):
            return None
        return value if math.isfinite(value) else None

    def typed(key: str) -> str:
        return str(manifest.get(key) or "")

    first, last, zone = (*recorded, "")[:3]
    return Patient(
        name_or_id=str(manifest.get("name") or record or ""),
        date=str(date or ""),
        professional=typed("professional"),
        side=side,
        step_height_m=step_height_m,
        weight_kg=number("weight_kg"),
        height_m=number("height_m"),
        observations=typed("observations"),
        record_number="" if record is None else str(record),
        record_system=typed("identifier_system") if record is not None else "",
        birth_date=typed("birth_date"),
        sex=typed("sex"),
        clinic=typed("clinic"),
        recorded=first or "",
        recorded_last="" if last == first else (last or ""),
        recorded_zone=(zone or "") if first else "",
    )


def recorded_dates(session) -> tuple[str, str, str]:
    """``(first, last, zone)``: the ISO days of the session's recordings, from their own clocks.  A format that gives
    the local date-time (MetaBase's file name, the thesis name's date) gives the recording's local day, ``zone``
    ``""``; when only epoch time stamps say it (UTC by definition: :func:`app.pipeline.ingestion.provenance.
    recording_facts`), the UTC day, ``zone`` ``"UTC"`` (printed beside it: a recording made at 00:30 local time
    east of Greenwich has the previous UTC day).  Local days win when some recordings give one.
    ``("", "", "")`` when no recording says it (then no date is printed as the recordings')."""
    local, utc = set(), set()
    for key, f in session_facts(session).items():
        given = session.raw[key].extras.get("started")  # the format's local start (MetaBase's file name)
        if given is not None:
            local.add(str(given.value)[:10])
        elif f.started is not None and f.started.method == "time stamps":
            utc.add(str(f.started.value)[:10])
        elif f.date is not None:
            local.add(str(f.date.value)[:10])
    days, zone = (sorted(local), "") if local else (sorted(utc), "UTC" if utc else "")
    return (days[0], days[-1], zone) if days else ("", "", "")


def report_input(outcome: SessionOutcome, results: dict[str, Any], patient: Patient | None = None,
                 knees: KneesOutcome | None = None) -> ReportInput:
    """What the reports read (``reports.model``): results.json, the task's series in degrees, orientations (of
    ``outcome``, the top-level knee), and with ``knees`` of two knees each knee's angles."""
    if patient is None:
        patient = session_patient(outcome)
    return ReportInput(
        results=results,
        t_s=outcome.t_s,
        angles_deg=np.rad2deg(outcome.angles_rad),
        q_earth_sensor=dict(outcome.q_earth_sensor),
        q_earth_segment={"femur": outcome.q_earth_segment["thigh"], "tibia": outcome.q_earth_segment["shank"]},
        q_sensor_segment={seg: cal.q_sensor_segment for seg, cal in outcome.segments.items()},
        patient=patient,
        language=outcome.options.language,
        knees_series=_knees_series(knees),
    )
