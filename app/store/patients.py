"""Patients: clinic-scoped lookup and search, creation (external ids unique per clinic), the ROM trend."""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import func, or_, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.store.analyses import find_artefact, latest_analysis
from app.store.blobs import BlobStore
from app.store.errors import Conflict, NotFound
from app.store.models import Patient
from app.store.sessions import patient_sessions


def clinic_patient(db: Session, clinic_id: int, patient_id: int) -> Patient:
    """Patient ``patient_id`` of clinic ``clinic_id``, else :class:`NotFound`."""
    row = db.get(Patient, patient_id)
    if row is None or row.clinic_id != clinic_id:
        raise NotFound(f"No patient {patient_id} in your clinic; check the id.", row.clinic_id if row else None)
    return row


def search_patients(db: Session, clinic_id: int, q: str | None = None) -> list[Patient]:
    """The clinic's patients, newest first; ``q`` filters on external_id or name (case-insensitive
    substring, LIKE wildcards typed by the user taken literally)."""
    stmt = select(Patient).where(Patient.clinic_id == clinic_id)
    if q and q.strip():
        text = q.strip().lower()
        for ch in ("\\", "%", "_"):
            text = text.replace(ch, "\\" + ch)
        like = f"%{text}%"
        stmt = stmt.where(or_(func.lower(Patient.external_id).like(like, escape="\\"),
                              func.lower(Patient.name).like(like, escape="\\")))
    return list(db.scalars(stmt.order_by(Patient.created_at.desc(), Patient.id.desc())))


def add_patient(db: Session, clinic_id: int, values: dict[str, Any]) -> Patient:
    """A new patient of the clinic; :class:`Conflict` when its external id exists there — also when two
    requests race (the database's unique constraint decides; the loser gets the same refusal)."""
    external_id = values["external_id"]
    exists = db.scalar(select(Patient.id).where(Patient.clinic_id == clinic_id, Patient.external_id == external_id))
    if exists is not None:
        raise Conflict(f"Patient {external_id!r} already exists in your clinic (id {exists}); open that patient "
                       "instead.")
    patient = Patient(clinic_id=clinic_id, **values)
    db.add(patient)
    try:
        db.flush()
    except IntegrityError:  # created by a concurrent request between the check and the insert
        raise Conflict(f"Patient {external_id!r} already exists in your clinic; open that patient instead.") \
            from None
    return patient


def rom_trend(db: Session, store: BlobStore, patient_id: int) -> list[dict[str, Any]]:
    """ROM per session, oldest first, from each session's latest analysis (sessions without one left out)."""
    points = []
    for s in patient_sessions(db, patient_id, newest_first=False):
        analysis = latest_analysis(db, s.id)
        if analysis is None:
            continue
        results = json.loads(store.read(find_artefact(db, analysis.id, "results.json").sha256))
        points.append({"session_id": s.id, "date": s.date, "analysis_id": analysis.id, "filter": analysis.filter,
                       "rom_deg": results.get("rom_deg", {})})
    return points


__all__ = ["add_patient", "clinic_patient", "rom_trend", "search_patients"]
