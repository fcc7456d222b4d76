"""``/sessions/{id}``: one session with its recordings, ingestion check, analyses and jobs.

A session whose stored ingestion check is stale (its files changed after the check, or the request that
should have stored it died) is checked again here before it is answered
(:func:`app.api.recordings.refresh_ingestion`), so the check shown always belongs to the files shown.
"""

from fastapi import APIRouter, Request

from app.api.deps import DbDep, Reader, scoped_session
from app.api.recordings import refresh_ingestion
from app.api.schemas import SessionOut, ingestion_fresh, session_out

router = APIRouter(prefix="/sessions", tags=["sessions"])


@router.get("/{session_id}", response_model=SessionOut)
def get_session(session_id: int, principal: Reader, db: DbDep, request: Request):
    session = scoped_session(db, principal, session_id)
    if not ingestion_fresh(session) and session.recordings:
        state = request.app.state
        refresh_ingestion(state.db, state.store, state.settings.tmp_dir, session.id)
        db.refresh(session)
    return session_out(db, session)
