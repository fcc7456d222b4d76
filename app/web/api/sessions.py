"""``/sessions/{id}``: one session with its recordings, ingestion check, analyses and jobs.

A session whose stored ingestion check is stale (its files changed after the check, or the request that
should have stored it died) is checked again here before it is answered
(:meth:`app.store.checks.IngestionChecker.ensure_fresh`), so the check shown always belongs to the files shown.
Each read is audited (``view``, :mod:`app.web.audit`): the answer lists the session's recordings, so this is
also the audit of the recordings list.

Correction and erasure, as for patients (:mod:`.patients`, :mod:`app.web.records`): ``PATCH /sessions/{id}``
(clinician) corrects the session's facts — every one goes into its manifest, so a change supersedes its
analyses and redoes its ingestion check; ``DELETE /sessions/{id}`` (admin; ``If-Match`` required) erases the
session with its recordings, jobs, analyses, reports and the stored files no other row names.
``POST /sessions/{id}/pair`` / ``DELETE /sessions/{id}/pair`` (clinician) pair two one-knee sessions of a patient
into one of both knees, or undo it (:mod:`app.store.pairing`; both audited ``update``).  Both answer 409
while a job of the session is queued or running, and are audited (``update`` / ``delete``).
"""

from fastapi import APIRouter, Request, Response

from app.store import erasure
from app.store.pairing import pair, unpair
from app.store.sessions import correct_session, delete_session, session_analyses, session_jobs
from app.web import audit
from app.web.api.deps import Admin, CheckerDep, Clinician, DbDep, Reader, scoped_session
from app.web.records import DELETE_ERRORS, ERRORS, erase_now, etag, if_match
from app.web.api.schemas import PairIn, PairOut, SessionOut, SessionPatch, pair_out, session_out

router = APIRouter(prefix="/sessions", tags=["sessions"])


@router.get("/{session_id}", response_model=SessionOut)
def get_session(session_id: int, principal: Reader, db: DbDep, checker: CheckerDep, request: Request,
                response: Response):
    """The session; ``ETag`` is its version (for ``If-Match`` on ``PATCH`` and ``DELETE``)."""
    session = scoped_session(db, principal, session_id)
    checker.ensure_fresh(db, session)  # may roll db back: the event is recorded after it
    audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id)
    response.headers["ETag"] = etag(session.version)
    return session_out(session, session_jobs(db, session.id), session_analyses(db, session.id))


@router.patch("/{session_id}", response_model=SessionOut, responses=ERRORS)
def correct(session_id: int, body: SessionPatch, principal: Clinician, db: DbDep, request: Request,
            response: Response):
    """Correct the fields sent (absent ones stay); ``If-Match`` optional.  Any change supersedes the session's
    analyses (process it again for a final report)."""
    session, changed, _ = correct_session(db, principal.clinic_id, session_id, body.model_dump(exclude_unset=True),
                                          if_match(request, required=False))
    if changed:
        audit.record(db, request, principal, "update", patient_id=session.patient_id, session_id=session.id)
    response.headers["ETag"] = etag(session.version)
    return session_out(session, session_jobs(db, session.id), session_analyses(db, session.id))


@router.post("/{session_id}/pair", response_model=PairOut, responses=ERRORS)
def pair_sessions(session_id: int, body: PairIn, principal: Clinician, db: DbDep, request: Request,
                  response: Response):
    """Pair this one-knee session (its knee ``knee``, required) with ``session_id`` of the body, another of the
    patient's of the other knee and the same task (:mod:`app.store.pairing`): processing either then gives both
    knees overlaid and the limb symmetry index.  Both sessions' analyses are superseded (process again), and a
    former partner of either is unpaired; 409 for another patient's or task's session, the session itself, one that
    holds both knees already, a knee its file names contradict, or while a job of any of them is queued or running.
    Sessions of different dates are paired with a warning (``warnings``).  Audited (``update``) on every session
    changed."""
    session, other, previous, warnings = pair(db, principal.clinic_id, session_id, body.session_id, body.knee)
    for s in (session, other):
        audit.record(db, request, principal, "update", patient_id=s.patient_id, session_id=s.id,
                     detail=f"paired with session {s.paired_session_id}, {s.knee} knee")
    for s in previous:
        audit.record(db, request, principal, "update", patient_id=s.patient_id, session_id=s.id,
                     detail=f"pairing undone (sessions {session.id} and {other.id} paired instead)")
    response.headers["ETag"] = etag(session.version)
    return pair_out(session, session_jobs(db, session.id), session_analyses(db, session.id), warnings)


@router.delete("/{session_id}/pair", response_model=SessionOut, responses=ERRORS)
def unpair_sessions(session_id: int, principal: Clinician, db: DbDep, request: Request, response: Response):
    """Undo the pairing (both sessions one knee each again; their analyses superseded).  Audited (``update``) on
    both sessions."""
    session, other, n = unpair(db, principal.clinic_id, session_id)
    if other is not None or n:
        audit.record(db, request, principal, "update", patient_id=session.patient_id, session_id=session.id,
                     detail="pairing undone" + (f" (was session {other.id})" if other is not None else ""))
    if other is not None:
        audit.record(db, request, principal, "update", patient_id=other.patient_id, session_id=other.id,
                     detail=f"pairing undone (was session {session.id})")
    response.headers["ETag"] = etag(session.version)
    return session_out(session, session_jobs(db, session.id), session_analyses(db, session.id))


@router.delete("/{session_id}", status_code=204, responses=DELETE_ERRORS)
def erase(session_id: int, principal: Admin, request: Request) -> Response:
    """Erase the session with its recordings, jobs, analyses and reports (admin; ``If-Match`` required).  Stored
    files no other row names are removed from disk before the answer."""
    expected = if_match(request, required=True)
    with request.app.state.db.session() as db:
        patient_id, shas = delete_session(db, principal.clinic_id, session_id, expected)
        event = audit.record(db, request, principal, "delete", patient_id=patient_id, session_id=session_id, now=True)
        ids = erasure.mark(db, shas, reason="session", actor=event.actor, clinic_id=principal.clinic_id,
                           patient_id=patient_id, session_id=session_id, audit_event_id=event.id)
    erase_now(request, ids)
    return Response(status_code=204)
