"""Patients: clinic-scoped lookup and search, creation (external ids unique per clinic), correction, erasure,
the ROM trend.

A correction (:func:`correct_patient`) bumps the patient's ``version``; one that changes what the processing
reads or the reports print (:data:`PROCESSED_FIELDS`) supersedes the analyses of every session of the patient
and makes their ingestion checks stale (``files_version``), as a session's own correction does
(:mod:`app.store.sessions`).  Erasing a patient (:func:`delete_patient`) cascades: patient → sessions →
recordings, jobs, analyses, artefacts; it returns the blobs they named for :func:`app.store.erasure.mark`.  Both
refuse while a job of one of the patient's sessions is queued or running, and check the caller's ``If-Match``
version when one is given.
"""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import delete, func, or_, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.choices import MEASURE_RANGES, SEX_NAMES, SIDE_NAMES
from app.store.analyses import SERIES, find_artefact, supersede
from app.store.blobs import BlobStore
from app.store.erasure import session_blobs
from app.store.errors import Conflict, Invalid, NotFound
from app.store.models import Analysis, KneeSession, Patient, utcnow
from app.store.sessions import Page, check_version, delete_sessions, patient_sessions, refuse_while_processing

#: the patient's columns a correction may change
CORRECTABLE_FIELDS = ("external_id", "side", "name", "birth_date", "sex", "height_cm", "mass_kg", "notes",
                      "fhir_reference")
#: those the processing reads or the reports print (a change supersedes the patient's analyses)
PROCESSED_FIELDS = ("external_id", "side", "name", "birth_date", "sex", "height_cm", "mass_kg")
#: open ranges a corrected number must fall in (the API's schema enforces the same at the edge; the operator's
#: CLI reaches the store directly)
RANGES = MEASURE_RANGES


def check_values(values: dict[str, Any], ranges: dict[str, tuple[float, float]],
                 choices: dict[str, tuple[str, ...]]) -> None:
    """:class:`Invalid` for a number outside its open range or a value outside its choices (None passes)."""
    for key, (lo, hi) in ranges.items():
        v = values.get(key)
        if v is not None and not lo < float(v) < hi:
            raise Invalid(code="store.out_of_range", field=key, value=v, low=f"{lo:g}", high=f"{hi:g}")
    for key, allowed in choices.items():
        v = values.get(key)
        if v is not None and v not in allowed:
            raise Invalid(code="store.unknown_value", field=key, value=str(v), allowed=", ".join(allowed))


def clinic_patient(db: Session, clinic_id: int, patient_id: int) -> Patient:
    """Patient ``patient_id`` of clinic ``clinic_id``, else :class:`NotFound`."""
    row = db.get(Patient, patient_id)
    if row is None or row.clinic_id != clinic_id:
        raise NotFound(None, row.clinic_id if row else None, code="store.no_patient", patient_id=patient_id)
    return row


def search_patients(db: Session, clinic_id: int, q: str | None = None) -> list[Patient]:
    """The clinic's patients, newest first; ``q`` filters on external_id or name (case-insensitive
    substring, LIKE wildcards typed by the user taken literally)."""
    return list_patients(db, clinic_id, q=q).rows


def list_patients(db: Session, clinic_id: int, *, q: str | None = None, external_id: str | None = None,
                  after_id: int | None = None, limit: int | None = None) -> Page:
    """The clinic's patients, newest first (by id: ids grow with creation), as a :class:`Page`.

    ``q``: case-insensitive substring of external_id or name (LIKE wildcards taken literally), for people
    typing in a search box.  ``external_id``: exactly this record number (case and every character count: a
    program looking a patient up must never get a near miss — "MRN-77" does not find "MRN-778899").
    ``after_id``: continue after this id (keyset pagination: rows added or erased meanwhile neither repeat nor
    skip a row); ``limit``: at most this many rows (None: all).  ``total`` counts the filtered list, every page."""
    stmt = select(Patient).where(Patient.clinic_id == clinic_id)
    if q and q.strip():
        text = q.strip().lower()
        for ch in ("\\", "%", "_"):
            text = text.replace(ch, "\\" + ch)
        like = f"%{text}%"
        stmt = stmt.where(or_(func.lower(Patient.external_id).like(like, escape="\\"),
                              func.lower(Patient.name).like(like, escape="\\")))
    if external_id is not None:
        stmt = stmt.where(Patient.external_id == external_id)
    total = db.scalar(select(func.count()).select_from(stmt.subquery()))
    if after_id is not None:
        stmt = stmt.where(Patient.id < after_id)
    stmt = stmt.order_by(Patient.id.desc())
    if limit is not None:
        stmt = stmt.limit(limit + 1)
    rows = list(db.scalars(stmt))
    more = limit is not None and len(rows) > limit
    rows = rows[:limit] if limit is not None else rows
    return Page(rows, int(total or 0), rows[-1].id if more else None)


def add_patient(db: Session, clinic_id: int, values: dict[str, Any]) -> Patient:
    """A new patient of the clinic; :class:`Conflict` when its external id exists there — also when two
    requests race (the database's unique constraint decides; the loser gets the same refusal)."""
    external_id = values["external_id"]
    exists = db.scalar(select(Patient.id).where(Patient.clinic_id == clinic_id, Patient.external_id == external_id))
    if exists is not None:
        raise Conflict(code="store.patient_exists", external_id=external_id, with_id=f" (id {exists})")
    patient = Patient(clinic_id=clinic_id, **values)
    db.add(patient)
    try:
        db.flush()
    except IntegrityError:  # created by a concurrent request between the check and the insert
        raise Conflict(code="store.patient_exists", external_id=external_id, with_id="") from None
    return patient


def _lock_patient(db: Session, clinic_id: int, patient_id: int) -> Patient:
    """The patient's row, locked (PostgreSQL ``FOR UPDATE``) and read afresh, else :class:`NotFound`."""
    db.execute(select(Patient.id).where(Patient.id == patient_id).with_for_update())
    row = db.get(Patient, patient_id, populate_existing=True)
    if row is None or row.clinic_id != clinic_id:
        raise NotFound(code="store.no_patient", patient_id=patient_id)
    return row


def _refuse_while_any_processing(db: Session, patient_id: int, what: str) -> list[int]:
    """The patient's session ids, their rows locked (PostgreSQL: an upload or a processing request to one of them
    waits, as for :func:`app.store.sessions.clinic_session`); :class:`app.store.sessions.Busy` if a job of one is active."""
    ids = list(db.scalars(select(KneeSession.id).where(KneeSession.patient_id == patient_id)
                          .order_by(KneeSession.id).with_for_update()))
    for sid in ids:
        refuse_while_processing(db, sid, what)
    return ids


def correct_patient(db: Session, clinic_id: int, patient_id: int, values: dict[str, Any],
                    expected_version: int | None = None) -> tuple[Patient, list[str], int]:
    """Correct the patient's ``values`` (columns of :data:`CORRECTABLE_FIELDS`); returns ``(patient, the fields
    that changed, analyses superseded)`` (module docstring).  :class:`Invalid` for another column or an empty
    external id or side; :class:`Conflict` for an external id another patient of the clinic has."""
    unknown = sorted(set(values) - set(CORRECTABLE_FIELDS))
    if unknown:
        raise Invalid(code="store.not_correctable", fields=", ".join(unknown), allowed=", ".join(CORRECTABLE_FIELDS))
    for required in ("external_id", "side"):
        if required in values and values[required] is None:
            raise Invalid(code="store.empty_value", field=required)
    check_values(values, RANGES, {"side": SIDE_NAMES, "sex": SEX_NAMES})
    patient = _lock_patient(db, clinic_id, patient_id)
    check_version("Patient", patient.id, patient.version, expected_version)
    changed = [k for k, v in values.items() if getattr(patient, k) != v]
    if not changed:
        return patient, [], 0
    session_ids = _refuse_while_any_processing(db, patient.id, "correct_patient")
    if "external_id" in changed:
        other = db.scalar(select(Patient.id).where(Patient.clinic_id == clinic_id,
                                                   Patient.external_id == values["external_id"],
                                                   Patient.id != patient.id))
        if other is not None:
            raise Conflict(code="store.patient_id_taken", external_id=values["external_id"], with_id=f" (id {other})")
    for k in changed:
        setattr(patient, k, values[k])
    patient.version = patient.version + 1
    patient.updated_at = utcnow()
    n_superseded = 0
    if set(changed) & set(PROCESSED_FIELDS):
        n_superseded = supersede(db, session_ids)
        for s in db.scalars(select(KneeSession).where(KneeSession.id.in_(session_ids))):
            s.files_version = s.files_version + 1  # the manifest changed: the checks are redone
    try:
        db.flush()
    except IntegrityError:  # the same identifier taken by a concurrent request
        raise Conflict(code="store.patient_id_taken", external_id=values["external_id"], with_id="") from None
    return patient, changed, n_superseded


def delete_patient(db: Session, clinic_id: int, patient_id: int,
                   expected_version: int | None = None) -> tuple[list[int], set[str]]:
    """Delete the patient and everything under it (module docstring); returns ``(the deleted sessions' ids, the
    blobs they named)``."""
    patient = _lock_patient(db, clinic_id, patient_id)
    check_version("Patient", patient.id, patient.version, expected_version)
    session_ids = _refuse_while_any_processing(db, patient.id, "delete_patient")
    shas = session_blobs(db, session_ids)
    delete_sessions(db, session_ids)
    db.execute(delete(Patient).where(Patient.id == patient.id))
    db.expire_all()
    return session_ids, shas


def rom_trend(db: Session, store: BlobStore, patient_id: int, filter_name: str | None = None,
              pipeline_version: str | None = None, calibration: str | None = None,
              angle_method: str | None = None) -> dict[str, Any]:
    """The ROM per session, oldest first, from analyses of **one series**: the same orientation filter, pipeline
    version, sensor-to-segment calibration and knee-angle convention (numbers from two methods differ by the method,
    not the patient: one session run once with Madgwick read +1.7° of flexion against its default-filter
    neighbours; the thesis' ZYX angles read adduction 10.1° higher and rotation 19.8° lower than Grood & Suntay's at
    90/5/15°, :mod:`app.pipeline.comparison`).

    The series is the one matching every key given (``filter_name``, ``pipeline_version``, ``calibration``,
    ``angle_method``; None: any), of those the one that covers the most sessions (ties: the one of the newest
    analysis).  Each session's point is its latest current (not superseded) analysis of that
    series, named by ``analysis_id``; sessions without one are listed in ``left_out`` with the series they do have.
    Returns ``{"filter", "pipeline_version", "calibration", "angle_method", "points", "left_out", "series"}``
    (``series``: every ``{"filter", "pipeline_version", "calibration", "angle_method", "sessions"}`` the patient's
    analyses offer, to choose another).
    A point's ``rom_deg`` is the patient's knee's (``side``): in a session of both knees ``knees[patient side]``,
    whichever knee was chosen as involved for that analysis (the top level), so one series never sets one knee
    against the other."""
    patient_side = db.get(Patient, patient_id).side
    sessions = patient_sessions(db, patient_id, newest_first=False)
    rows = list(db.execute(select(Analysis.id, Analysis.session_id, *(getattr(Analysis, k) for k in SERIES))
                           .join(KneeSession, KneeSession.id == Analysis.session_id)
                           .where(KneeSession.patient_id == patient_id, Analysis.superseded_at.is_(None))
                           .order_by(Analysis.id)))
    latest: dict[tuple[str, ...], dict[int, int]] = {}  # series → session → its latest analysis there
    for aid, sid, *key in rows:
        latest.setdefault(tuple(key), {})[sid] = aid
    series = sorted(latest, key=lambda k: (len(latest[k]), max(latest[k].values())), reverse=True)
    asked = (filter_name, pipeline_version, calibration, angle_method)
    chosen = next((k for k in series if all(want is None or have == want for have, want in zip(k, asked))), asked)
    named = dict(zip(SERIES, chosen))
    picked = latest.get(chosen, {})
    points, left_out = [], []
    for s in sessions:
        if s.id in picked:
            aid = picked[s.id]
            results = json.loads(store.read(find_artefact(db, aid, "results.json").sha256))
            knee = (results.get("knees") or {}).get(patient_side) or results
            points.append({"session_id": s.id, "date": s.date, "analysis_id": aid, **named,
                           "side": knee.get("side"), "rom_deg": knee.get("rom_deg", {})})
        else:
            have = [{**dict(zip(SERIES, k)), "analysis_id": latest[k][s.id]} for k in series if s.id in latest[k]]
            if have:
                left_out.append({"session_id": s.id, "date": s.date, "analyses": have})
    return {**named, "points": points, "left_out": left_out,
            "series": [{**dict(zip(SERIES, k)), "sessions": len(latest[k])} for k in series]}


__all__ = ["CORRECTABLE_FIELDS", "PROCESSED_FIELDS", "RANGES", "check_values", "add_patient", "clinic_patient", "correct_patient",
           "Page", "delete_patient", "list_patients", "rom_trend", "search_patients"]
