"""``/sessions/{id}``: one session with its recordings, ingestion check, analyses and jobs."""

from fastapi import APIRouter

from app.api.deps import DbDep, Reader, scoped_session
from app.api.schemas import SessionOut, session_out

router = APIRouter(prefix="/sessions", tags=["sessions"])


@router.get("/{session_id}", response_model=SessionOut)
def get_session(session_id: int, principal: Reader, db: DbDep):
    return session_out(db, scoped_session(db, principal, session_id))
