"""``/patients``: list/search, create, read; a patient's sessions, their ROM trend, and new sessions.

Every route records who read or created which patient (:func:`app.web.audit.record`; a list or search is one
event per request, with the patient only when a search found exactly one).

Creating a patient whose external id exists in the clinic answers 409 — also when two requests race (the
database's unique constraint decides; the loser gets the same 409, never a 500).

Correction and erasure: ``PATCH /patients/{id}`` (clinician: the people who type a patient's details correct
their typos) changes the fields sent and supersedes the patient's analyses when a field the reports print
changed (:mod:`app.store.patients`); ``DELETE /patients/{id}`` (admin only: it cascades to every session,
recording, analysis and stored file of the patient) needs ``If-Match`` (:mod:`app.web.records`).  Both are audited
(``update`` / ``delete``) in the transaction that makes the change; the deletion's event and the
``blob_erasures`` rows it links to outlive the patient.
"""

from __future__ import annotations

from fastapi import APIRouter, Query, Request, Response

from app.store import erasure, patients, sessions
from app.web import audit
from app.web.api.deps import Admin, Clinician, DbDep, Reader, StoreDep, scoped_patient
from app.web.records import DELETE_ERRORS, ERRORS, erase_now, etag, if_match
from app.web.api.schemas import (PatientIn, PatientOut, PatientPatch, SessionIn, SessionOut, SessionSummaryOut,
                                 TrendOut, patient_out, session_out, summaries)

router = APIRouter(prefix="/patients", tags=["patients"])


@router.get("", response_model=list[PatientOut])
def list_patients(principal: Reader, db: DbDep, request: Request, q: str | None = Query(None, max_length=200)):
    """The clinic's patients, newest first; ``q`` filters on external_id or name (case-insensitive substring)."""
    rows = patients.search_patients(db, principal.clinic_id, q)
    searched = bool(q and q.strip())
    audit.record(db, request, principal, "search" if searched else "list",
                 patient_id=rows[0].id if searched and len(rows) == 1 else None)
    return [patient_out(p) for p in rows]


@router.post("", response_model=PatientOut, status_code=201,
             responses={409: {"description": "the external id is already a patient of the clinic"}})
def create_patient(body: PatientIn, principal: Clinician, db: DbDep, request: Request):
    patient = patients.add_patient(db, principal.clinic_id, body.model_dump())  # 409 for a taken external id
    audit.record(db, request, principal, "create", patient_id=patient.id)
    return patient_out(patient)


@router.get("/{patient_id}", response_model=PatientOut)
def get_patient(patient_id: int, principal: Reader, db: DbDep, request: Request, response: Response):
    """The patient; ``ETag`` is its version (for ``If-Match`` on ``PATCH`` and ``DELETE``)."""
    patient = scoped_patient(db, principal, patient_id)
    audit.record(db, request, principal, "view", patient_id=patient.id)
    response.headers["ETag"] = etag(patient.version)
    return patient_out(patient)


@router.patch("/{patient_id}", response_model=PatientOut, responses=ERRORS)
def correct_patient(patient_id: int, body: PatientPatch, principal: Clinician, db: DbDep, request: Request,
                    response: Response):
    """Correct the fields sent (absent ones stay); ``If-Match`` optional.  A change of what the reports print
    supersedes the patient's analyses (process its sessions again for final reports)."""
    values = body.model_dump(exclude_unset=True)
    patient, changed, _ = patients.correct_patient(db, principal.clinic_id, patient_id, values,
                                                   if_match(request, required=False))
    if changed:
        audit.record(db, request, principal, "update", patient_id=patient.id)
    response.headers["ETag"] = etag(patient.version)
    return patient_out(patient)


@router.delete("/{patient_id}", status_code=204, responses=DELETE_ERRORS)
def erase_patient(patient_id: int, principal: Admin, request: Request) -> Response:
    """Erase the patient with every session, recording, analysis and report (admin; ``If-Match`` required).
    Stored files no other row names are removed from disk before the answer."""
    expected = if_match(request, required=True)
    with request.app.state.db.session() as db:
        scoped_patient(db, principal, patient_id)  # 404 before anything is recorded
        session_ids, shas = patients.delete_patient(db, principal.clinic_id, patient_id, expected)
        event = audit.record(db, request, principal, "delete", patient_id=patient_id)
        ids = erasure.mark(db, shas, reason="patient", actor=event.actor, clinic_id=principal.clinic_id,
                           patient_id=patient_id, audit_event_id=event.id)
    erase_now(request, ids)
    return Response(status_code=204)


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
