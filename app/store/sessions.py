"""Sessions: clinic-scoped lookup, creation, the facts their status is derived from, and the rule that a
session's files do not change while one of its jobs is queued or running.

Status and freshness (the answer of ``GET /sessions/{id}`` and of the session lists): a session's stored
ingestion check is *fresh* when it was computed from the current files (``ingestion_version ==
files_version``, :func:`ingestion_fresh`); a stale one is shown as "being checked" (:func:`stored_ingestion`)
until :mod:`app.store.checks` has run it again.  The status (:func:`session_status`) is ``empty`` (no files),
``processing`` / ``done`` / ``failed`` (its latest job), else ``ready`` or ``incomplete`` (the check).
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.store.errors import Conflict, NotFound
from app.store.models import Analysis, Job, KneeSession, Recording
from app.store.workspace import NO_RECORDINGS

#: the job states during which a session's files must not change
ACTIVE = ("queued", "running")
#: the stored check shown while a stale one is being redone
BEING_CHECKED = {"ok": False, "messages": [], "error": "The session's files are being checked; reload in a moment."}


class Busy(Conflict):
    """A job of the session is queued or running (``job_id``): its files must not change under it."""

    def __init__(self, session_id: int, job_id: int, what: str) -> None:
        super().__init__(f"Session {session_id} is being processed (job {job_id}); {what} when that job has "
                         "finished.")
        self.session_id, self.job_id = session_id, job_id


def clinic_session(db: Session, clinic_id: int, session_id: int, lock: bool = False) -> KneeSession:
    """Session ``session_id`` of clinic ``clinic_id``, else :class:`NotFound`.  ``lock``: ``SELECT … FOR
    UPDATE`` of the row (PostgreSQL; SQLite serialises writers anyway), so that changes of one session's files
    and jobs happen one at a time; the row is then read afresh (what was committed before the lock)."""
    if lock:  # the row alone (the ORM's joined patient cannot be locked on PostgreSQL's outer join)
        db.execute(select(KneeSession.id).where(KneeSession.id == session_id).with_for_update())
    # once locked, read the row again even if this session loaded it before (a change committed meanwhile)
    row = db.get(KneeSession, session_id, populate_existing=lock)
    if row is None or row.clinic_id != clinic_id:
        raise NotFound(f"No session {session_id} in your clinic; check the id.", row.clinic_id if row else None)
    return row


def active_job_id(db: Session, session_id: int, other_than: int | None = None) -> int | None:
    """The oldest queued or running job of the session (other than job ``other_than``), or None."""
    stmt = select(Job.id).where(Job.session_id == session_id, Job.status.in_(ACTIVE))
    if other_than is not None:
        stmt = stmt.where(Job.id != other_than)
    return db.scalar(stmt.order_by(Job.id))


def refuse_while_processing(db: Session, session_id: int, what: str) -> None:
    """:class:`Busy` when a job of session ``session_id`` is queued or running; ``what`` completes its
    sentence ("… ; upload the files when that job has finished")."""
    job_id = active_job_id(db, session_id)
    if job_id is not None:
        raise Busy(session_id, job_id, what)


def clinic_job(db: Session, clinic_id: int, job_id: int) -> Job:
    row = db.get(Job, job_id)
    if row is None or row.clinic_id != clinic_id:
        raise NotFound(f"No job {job_id} in your clinic; check the id.", row.clinic_id if row else None)
    return row


def patient_sessions(db: Session, patient_id: int, newest_first: bool = True) -> list[KneeSession]:
    """The patient's sessions by clinical date, then creation (newest first, or oldest first)."""
    order = (KneeSession.date.desc(), KneeSession.id.desc()) if newest_first else (KneeSession.date, KneeSession.id)
    return list(db.scalars(select(KneeSession).where(KneeSession.patient_id == patient_id).order_by(*order)))


def add_session(db: Session, clinic_id: int, patient_id: int, values: dict[str, Any]) -> KneeSession:
    """A new, empty session of the patient (``values``: the columns; date defaults to today, UTC)."""
    values = dict(values)
    values["date"] = values.get("date") or dt.datetime.now(dt.timezone.utc).date()
    session = KneeSession(clinic_id=clinic_id, patient_id=patient_id, **values)
    db.add(session)
    db.flush()
    db.refresh(session)
    return session


def summary_facts(db: Session, sessions: list[KneeSession]) -> tuple[dict[int, int], dict[int, Job]]:
    """``(recordings per session id, latest job per session id)`` of ``sessions``, in two queries whatever
    their number."""
    ids = [s.id for s in sessions]
    if not ids:
        return {}, {}
    counts = dict(db.execute(select(Recording.session_id, func.count()).where(Recording.session_id.in_(ids))
                             .group_by(Recording.session_id)).all())
    last_ids = select(func.max(Job.id)).where(Job.session_id.in_(ids)).group_by(Job.session_id)
    latest = {j.session_id: j for j in db.scalars(select(Job).where(Job.id.in_(last_ids)))}
    return counts, latest


def session_jobs(db: Session, session_id: int) -> list[Job]:
    """The session's jobs, newest first."""
    return list(db.scalars(select(Job).where(Job.session_id == session_id).order_by(Job.id.desc())))


def session_analyses(db: Session, session_id: int) -> list[Analysis]:
    """The session's analyses, newest first."""
    return list(db.scalars(select(Analysis).where(Analysis.session_id == session_id).order_by(Analysis.id.desc())))


def ingestion_fresh(s: KneeSession) -> bool:
    """True when the stored ingestion check was computed from the session's current files."""
    return s.ingestion is not None and s.ingestion_version == s.files_version


def stored_ingestion(s: KneeSession, n_recordings: int | None = None) -> dict[str, Any]:
    """The stored check when fresh; "no recordings" for an empty session; else "being checked"."""
    if ingestion_fresh(s):
        return s.ingestion
    n = len(s.recordings) if n_recordings is None else n_recordings
    return dict(NO_RECORDINGS if n == 0 else BEING_CHECKED)


def ready(s: KneeSession) -> bool:
    """The stored check is fresh and passed: the session can be processed."""
    return ingestion_fresh(s) and bool(s.ingestion.get("ok"))


def session_status(n_recordings: int, ingestion_ok: bool, latest_job: Job | None) -> str:
    """empty (no files) · incomplete (ingestion not ok) · processing / done / failed (the latest job) · ready."""
    if n_recordings == 0:
        return "empty"
    if latest_job is not None:
        return {"queued": "processing", "running": "processing"}.get(latest_job.status, latest_job.status)
    return "ready" if ingestion_ok else "incomplete"


__all__ = ["ACTIVE", "BEING_CHECKED", "Busy", "active_job_id", "add_session", "clinic_job", "clinic_session",
           "ingestion_fresh", "patient_sessions", "ready", "refuse_while_processing", "session_analyses",
           "session_jobs", "session_status", "stored_ingestion", "summary_facts"]
