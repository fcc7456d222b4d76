"""``/patients``: list/search, create, read; a patient's sessions, their ROM trend, and new sessions.

Every route records who read or created which patient (:func:`app.web.audit.record`; a list or search is one
event per request, with the patient only when a search found exactly one).

Creating a patient whose external id exists in the clinic answers 409 — also when two requests race (the
database's unique constraint decides; the loser gets the same 409, never a 500).
"""

from __future__ import annotations

import datetime as dt
import json

from fastapi import APIRouter, HTTPException, Query, Request
from sqlalchemy import func, or_, select
from sqlalchemy.exc import IntegrityError

from app.web import audit
from app.web.api.deps import Clinician, DbDep, Reader, StoreDep, scoped_patient
from app.web.api.schemas import (PatientIn, PatientOut, SessionIn, SessionOut, SessionSummaryOut, TrendOut, patient_out,
                             session_out, summaries)
from app.store.models import Analysis, Artefact, KneeSession, Patient

router = APIRouter(prefix="/patients", tags=["patients"])


@router.get("", response_model=list[PatientOut])
def list_patients(principal: Reader, db: DbDep, request: Request, q: str | None = Query(None, max_length=200)):
    """The clinic's patients, newest first; ``q`` filters on external_id or name (case-insensitive substring)."""
    stmt = select(Patient).where(Patient.clinic_id == principal.clinic_id)
    if q and q.strip():
        text = q.strip().lower()
        for ch in ("\\", "%", "_"):  # LIKE wildcards typed by the user are literal
            text = text.replace(ch, "\\" + ch)
        like = f"%{text}%"
        stmt = stmt.where(or_(func.lower(Patient.external_id).like(like, escape="\\"),
                              func.lower(Patient.name).like(like, escape="\\")))
    rows = list(db.scalars(stmt.order_by(Patient.created_at.desc(), Patient.id.desc())))
    searched = bool(q and q.strip())
    audit.record(db, request, principal, "search" if searched else "list",
                 patient_id=rows[0].id if searched and len(rows) == 1 else None)
    return [patient_out(p) for p in rows]


@router.post("", response_model=PatientOut, status_code=201)
def create_patient(body: PatientIn, principal: Clinician, db: DbDep, request: Request):
    exists = db.scalar(select(Patient.id).where(Patient.clinic_id == principal.clinic_id,
                                                Patient.external_id == body.external_id))
    if exists is not None:
        raise HTTPException(409, f"Patient {body.external_id!r} already exists in your clinic (id {exists}); "
                                 "open that patient instead.")
    patient = Patient(clinic_id=principal.clinic_id, **body.model_dump())
    db.add(patient)
    try:
        db.flush()
    except IntegrityError:  # created by a concurrent request between the check and the insert
        raise HTTPException(409, f"Patient {body.external_id!r} already exists in your clinic; open that patient "
                                 "instead.") from None
    audit.record(db, request, principal, "create", patient_id=patient.id)
    return patient_out(patient)


@router.get("/{patient_id}", response_model=PatientOut)
def get_patient(patient_id: int, principal: Reader, db: DbDep, request: Request):
    patient = scoped_patient(db, principal, patient_id)
    audit.record(db, request, principal, "view", patient_id=patient.id)
    return patient_out(patient)


@router.get("/{patient_id}/sessions", response_model=list[SessionSummaryOut])
def patient_sessions(patient_id: int, principal: Reader, db: DbDep, request: Request):
    """The patient's sessions, newest first (by date, then creation)."""
    scoped_patient(db, principal, patient_id)
    rows = list(db.scalars(select(KneeSession).where(KneeSession.patient_id == patient_id)
                           .order_by(KneeSession.date.desc(), KneeSession.id.desc())))
    audit.record(db, request, principal, "view", patient_id=patient_id)
    return summaries(db, rows)


@router.post("/{patient_id}/sessions", response_model=SessionOut, status_code=201)
def create_session(patient_id: int, body: SessionIn, principal: Clinician, db: DbDep, request: Request):
    """A new, empty session of the patient (date defaults to today, UTC)."""
    patient = scoped_patient(db, principal, patient_id)
    values = body.model_dump()
    values["date"] = values["date"] or dt.datetime.now(dt.timezone.utc).date()
    session = KneeSession(clinic_id=principal.clinic_id, patient_id=patient.id, **values)
    db.add(session)
    db.flush()
    db.refresh(session)
    audit.record(db, request, principal, "create", patient_id=patient.id, session_id=session.id)
    return session_out(db, session)


@router.get("/{patient_id}/trend", response_model=TrendOut)
def patient_trend(patient_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request):
    """ROM per session, oldest first, from each session's latest finished analysis."""
    scoped_patient(db, principal, patient_id)
    sessions = list(db.scalars(select(KneeSession).where(KneeSession.patient_id == patient_id)
                               .order_by(KneeSession.date, KneeSession.id)))
    points = []
    for s in sessions:
        analysis = db.scalar(select(Analysis).where(Analysis.session_id == s.id).order_by(Analysis.id.desc()))
        if analysis is None:
            continue
        art = db.scalar(select(Artefact).where(Artefact.analysis_id == analysis.id, Artefact.name == "results.json"))
        results = json.loads(store.read(art.sha256))
        points.append({"session_id": s.id, "date": s.date, "analysis_id": analysis.id, "filter": analysis.filter,
                       "rom_deg": results.get("rom_deg", {})})
    audit.record(db, request, principal, "view", patient_id=patient_id)
    return {"points": points}
