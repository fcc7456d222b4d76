"""``/patients``: list (cursor pages with a total), exact lookup by identifier, search, create, read; a patient's sessions, their ROM trend, and new sessions.

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

import datetime as dt

from fastapi import APIRouter, Query, Request, Response

from app.store import comparisons, erasure, idempotency, patients, sessions
from app.store.sessions import session_analyses, session_jobs
from app.web import audit
from app.web.api.deps import (Admin, Clinician, DbDep, Reader, SettingsDep, StoreDep, route_scope, scoped_patient,
                              scoped_session)
from app.web.idempotency import KEY_PARAMETER, LOCATION, answer, key_of, request_sha256
from app.web.paging import MAX_LIMIT, PAGE_HEADERS, decode_cursor, identifier_value, page_headers
from app.web.refusals import Refusal
from app.web.records import DELETE_ERRORS, ERRORS, erase_now, etag, if_match
from app.web.api.schemas import (AngleConventionName, CalibrationName, CompareOut, PatientIn, PatientOut, PatientPatch, SessionIn, SessionOut,
                                 SessionSummaryOut, TrendOut, patient_out, session_out, summaries)

router = APIRouter(prefix="/patients", tags=["patients"])


@router.get("", response_model=list[PatientOut],
            responses={200: {"headers": PAGE_HEADERS}, 400: {"description": "a cursor this server did not give"}})
def list_patients(principal: Reader, db: DbDep, request: Request, response: Response, settings: SettingsDep,
                  q: str | None = Query(None, max_length=200,
                                        description="case-insensitive substring of external_id or name (people "
                                                    "searching; never for a program's lookup)"),
                  identifier: str | None = Query(None, max_length=300,
                                                 description="exact record number: value, system|value or |value "
                                                             "(FHIR token search)"),
                  limit: int | None = Query(None, ge=1, le=MAX_LIMIT, description="page size (absent: all)"),
                  cursor: str | None = Query(None, max_length=200, description="X-Next-Cursor of the previous page")):
    """The clinic's patients, newest first, a page at a time (:mod:`app.web.paging`: ``X-Total-Count``,
    ``X-Next-Cursor``, ``Link``).  ``identifier`` finds exactly one record number or nobody; ``q`` is the
    search box's substring match."""
    after = decode_cursor(cursor)
    if after is not None and not isinstance(after, int):
        raise Refusal(400, "request.cursor_invalid")
    exact = identifier_value(identifier, settings.patient_identifier_system) if identifier is not None else None
    if identifier is not None and exact is None:  # another system's identifier: nobody here
        page = patients.Page([], 0, None)
    else:
        page = patients.list_patients(db, principal.clinic_id, q=q, external_id=exact, after_id=after, limit=limit)
    searched = bool(q and q.strip()) or identifier is not None
    audit.record(db, request, principal, "search" if searched else "list",
                 patient_id=page.rows[0].id if searched and page.total == 1 else None)
    page_headers(request, response, page.total, page.next_after)
    return [patient_out(p) for p in page.rows]


@router.post("", response_model=PatientOut, status_code=201, openapi_extra={"parameters": [KEY_PARAMETER]},
             responses={201: {"headers": LOCATION},
                        409: {"description": "the external id is already a patient of the clinic, or the "
                                             "Idempotency-Key was used for another request"}})
def create_patient(body: PatientIn, principal: Clinician, db: DbDep, request: Request):
    """A new patient (``Location``: its path).  With ``Idempotency-Key`` a repeat answers the same patient."""
    key = key_of(request)
    claimed = idempotency.claim(db, principal.clinic_id, key, request_sha256(request, body), "patient") if key else None
    if isinstance(claimed, idempotency.Replay):
        patient = scoped_patient(db, principal, claimed.resource_ids[0])
        audit.record(db, request, principal, "view", patient_id=patient.id)
        return answer(patient_out(patient), claimed.status, f"/api/v1/patients/{patient.id}", replayed=True)
    patient = patients.add_patient(db, principal.clinic_id, body.model_dump())  # 409 for a taken external id
    if claimed is not None:
        idempotency.complete(claimed, [patient.id], 201)
    audit.record(db, request, principal, "create", patient_id=patient.id)
    return answer(patient_out(patient), 201, f"/api/v1/patients/{patient.id}")


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
        event = audit.record(db, request, principal, "delete", patient_id=patient_id, now=True)
        ids = erasure.mark(db, shas, reason="patient", actor=event.actor, clinic_id=principal.clinic_id,
                           patient_id=patient_id, audit_event_id=event.id)
    erase_now(request, ids)
    return Response(status_code=204)


@router.get("/{patient_id}/sessions", response_model=list[SessionSummaryOut],
            responses={200: {"headers": PAGE_HEADERS}, 400: {"description": "a cursor this server did not give"}})
def patient_sessions(patient_id: int, principal: Reader, db: DbDep, request: Request, response: Response,
                     limit: int | None = Query(None, ge=1, le=MAX_LIMIT, description="page size (absent: all)"),
                     cursor: str | None = Query(None, max_length=200,
                                                description="X-Next-Cursor of the previous page")):
    """The patient's sessions, newest first (by date, then creation), a page at a time (as ``GET /patients``)."""
    after = decode_cursor(cursor)
    try:
        key = None if after is None else (dt.date.fromisoformat(after[0]), int(after[1]))
    except (TypeError, ValueError, IndexError, KeyError):
        raise Refusal(400, "request.cursor_invalid") from None
    scoped_patient(db, principal, patient_id)
    page = sessions.list_patient_sessions(db, patient_id, after=key, limit=limit)
    audit.record(db, request, principal, "view", patient_id=patient_id)
    page_headers(request, response, page.total, page.next_after)
    return summaries(page.rows, *sessions.summary_facts(db, page.rows))


@router.post("/{patient_id}/sessions", response_model=SessionOut, status_code=201,
             openapi_extra=route_scope("sessions:write", parameters=[KEY_PARAMETER]),
             responses={201: {"headers": LOCATION},
                        409: {"description": "the Idempotency-Key was used for another request"}})
def create_session(patient_id: int, body: SessionIn, principal: Clinician, db: DbDep, request: Request):
    """A new, empty session of the patient (date defaults to today, UTC; ``Location``: its path).  With
    ``Idempotency-Key`` a repeat answers the same session."""
    patient = scoped_patient(db, principal, patient_id)
    key = key_of(request)
    claimed = idempotency.claim(db, principal.clinic_id, key, request_sha256(request, body), "session") if key else None
    if isinstance(claimed, idempotency.Replay):
        session = scoped_session(db, principal, claimed.resource_ids[0])
        audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id)
        return answer(session_out(session, session_jobs(db, session.id), session_analyses(db, session.id)),
                      claimed.status, f"/api/v1/sessions/{session.id}", replayed=True)
    session = sessions.add_session(db, principal.clinic_id, patient.id, body.model_dump())
    if claimed is not None:
        idempotency.complete(claimed, [session.id], 201)
    audit.record(db, request, principal, "create", patient_id=patient.id, session_id=session.id)
    return answer(session_out(session, [], []), 201, f"/api/v1/sessions/{session.id}")


@router.get("/{patient_id}/trend", response_model=TrendOut, openapi_extra=route_scope("results:read"))
def patient_trend(patient_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                  filter: str | None = Query(None, max_length=40),
                  pipeline_version: str | None = Query(None, max_length=40),
                  calibration: CalibrationName | None = None, angle_method: AngleConventionName | None = None):
    """ROM per session, oldest first, from analyses of one filter, pipeline version, calibration and angle
    convention (by default the series that covers the most sessions); each point names its analysis, ``left_out``
    the sessions without one."""
    scoped_patient(db, principal, patient_id)
    trend = patients.rom_trend(db, store, patient_id, filter, pipeline_version, calibration, angle_method)
    audit.record(db, request, principal, "view", patient_id=patient_id)
    return trend


@router.get("/{patient_id}/compare", response_model=CompareOut, openapi_extra=route_scope("results:read"))
def compare_sessions(patient_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                     a: int = Query(..., description="the earlier session (e.g. before treatment)"),
                     b: int = Query(..., description="the later session"),
                     a_analysis: int | None = None, b_analysis: int | None = None):
    """Two sessions of the patient side by side: each one's analysis and every number both hold, with the change
    ``b − a``; ``comparable`` is false when the analyses differ in filter, pipeline version, task, knee,
    calibration or angle convention."""
    scoped_patient(db, principal, patient_id)
    out = comparisons.compare_sessions(db, store, principal.clinic_id, patient_id, a, b, a_analysis, b_analysis)
    audit.record(db, request, principal, "view", patient_id=patient_id)
    return out
