"""``/sessions/{id}``: one session with its recordings, ingestion check, analyses and jobs.

A session whose stored ingestion check is stale (its files changed after the check, or the request that
should have stored it died) is checked again here before it is answered
(:meth:`app.store.checks.IngestionChecker.ensure_fresh`), so the check shown always belongs to the files shown.
Each read is audited (``view``, :mod:`app.web.audit`): the answer lists the session's recordings, so this is
also the audit of the recordings list.
"""

from fastapi import APIRouter, Request

from app.store.sessions import session_analyses, session_jobs
from app.web import audit
from app.web.api.deps import CheckerDep, DbDep, Reader, scoped_session
from app.web.api.schemas import SessionOut, session_out

router = APIRouter(prefix="/sessions", tags=["sessions"])


@router.get("/{session_id}", response_model=SessionOut)
def get_session(session_id: int, principal: Reader, db: DbDep, checker: CheckerDep, request: Request):
    session = scoped_session(db, principal, session_id)
    checker.ensure_fresh(db, session)  # may roll db back: the event is recorded after it
    audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id)
    return session_out(session, session_jobs(db, session.id), session_analyses(db, session.id))
