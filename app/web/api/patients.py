"""``/patients``: list/search, create, read; a patient's sessions, their ROM trend, and new sessions.

Every route records who read or created which patient (:func:`app.web.audit.record`; a list or search is one
event per request, with the patient only when a search found exactly one).

Creating a patient whose external id exists in the clinic answers 409 — also when two requests race (the
database's unique constraint decides; the loser gets the same 409, never a 500).
"""

from __future__ import annotations

from fastapi import APIRouter, Query, Request

from app.store import patients, sessions
from app.web import audit
from app.web.api.deps import Clinician, DbDep, Reader, StoreDep, scoped_patient
from app.web.api.schemas import (PatientIn, PatientOut, SessionIn, SessionOut, SessionSummaryOut, TrendOut, patient_out,
                                 session_out, summaries)

router = APIRouter(prefix="/patients", tags=["patients"])


@router.get("", response_model=list[PatientOut])
def list_patients(principal: Reader, db: DbDep, request: Request, q: str | None = Query(None, max_length=200)):
    """The clinic's patients, newest first; ``q`` filters on external_id or name (case-insensitive substring)."""
    rows = patients.search_patients(db, principal.clinic_id, q)
    searched = bool(q and q.strip())
    audit.record(db, request, principal, "search" if searched else "list",
                 patient_id=rows[0].id if searched and len(rows) == 1 else None)
    return [patient_out(p) for p in rows]


@router.post("", response_model=PatientOut, status_code=201)
def create_patient(body: PatientIn, principal: Clinician, db: DbDep, request: Request):
    patient = patients.add_patient(db, principal.clinic_id, body.model_dump())  # 409 for a taken external id
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
    rows = sessions.patient_sessions(db, patient_id)
    audit.record(db, request, principal, "view", patient_id=patient_id)
    return summaries(rows, *sessions.summary_facts(db, rows))


@router.post("/{patient_id}/sessions", response_model=SessionOut, status_code=201)
def create_session(patient_id: int, body: SessionIn, principal: Clinician, db: DbDep, request: Request):
    """A new, empty session of the patient (date defaults to today, UTC)."""
    patient = scoped_patient(db, principal, patient_id)
    session = sessions.add_session(db, principal.clinic_id, patient.id, body.model_dump())
    audit.record(db, request, principal, "create", patient_id=patient.id, session_id=session.id)
    return session_out(session, [], [])


@router.get("/{patient_id}/trend", response_model=TrendOut)
def patient_trend(patient_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request):
    """ROM per session, oldest first, from each session's latest finished analysis."""
    scoped_patient(db, principal, patient_id)
    points = patients.rom_trend(db, store, patient_id)
    audit.record(db, request, principal, "view", patient_id=patient_id)
    return {"points": points}
