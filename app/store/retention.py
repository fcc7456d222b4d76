"""The retention policy: sessions with no activity for ``CHAKAMO_RETENTION_DAYS`` days are erased with their
recordings, jobs, analyses, reports and the stored files no other row names (off by default: 0).

A session's last activity is the latest of its creation, its last correction, its recordings' uploads and its
jobs' creation and end::

    last(s) = max(created_at(s), updated_at(s), max uploaded_at(r in s), max created_at(j in s), max finished_at(j in s))

and it is due when ``now − last(s) ≥ days`` (a whole number of days of 24 h, UTC).  A session with a job queued
or running is never due (it is active by definition).  The patient rows stay: their identity and history of
erasures are the clinic's record; erasing a patient is an explicit act (``DELETE /patients/{id}``, ``chakamo
patients erase``).

:func:`apply_retention` erases each due session in a transaction of its own, recording one ``delete`` event per
session through the ``record`` callable it is given (the web layer's :func:`app.web.audit.record_operator`:
this module does not import the web) and marking its blobs (:mod:`app.store.erasure`, reason ``retention``),
then erases them.  ``now`` is a parameter so that tests fix the clock.  Applied by ``chakamo retention
--apply`` and by the API server's housekeeping, whatever the job backend (:mod:`app.web.housekeeping`, hourly).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass, field

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.store.blobs import Storage
from app.store.database import Database
from app.store.erasure import erase_pending, mark, session_blobs
from app.store.models import Job, KneeSession, Recording
from app.store.errors import NotFound
from app.store.sessions import ACTIVE, clinic_session, delete_sessions

#: ``record(db, clinic_id=, patient_id=, session_id=, resource=)`` -> the audit event (``.id``, ``.actor``)
Recorder = Callable[..., object]


@dataclass
class DueSession:
    session_id: int
    clinic_id: int
    patient_id: int
    last_activity: dt.datetime


@dataclass
class RetentionReport:
    days: int
    now: dt.datetime
    due: list[DueSession] = field(default_factory=list)
    erased_sessions: int = 0
    erased_files: int = 0
    kept_files: int = 0
    #: files the erasure sweep removed after the policy (``chakamo retention --apply``)
    swept_files: int = 0


def _latest(*values: dt.datetime | None) -> dt.datetime:
    return max(v for v in values if v is not None)


def due_sessions(db: Session, days: int, now: dt.datetime) -> list[DueSession]:
    """The sessions whose last activity is ``days`` or more before ``now`` (module docstring), oldest first."""
    if days <= 0:
        return []
    cutoff = now - dt.timedelta(days=days)
    candidates = list(db.scalars(select(KneeSession).where(KneeSession.created_at <= cutoff)))
    if not candidates:
        return []
    ids = [s.id for s in candidates]
    uploads = dict(db.execute(select(Recording.session_id, func.max(Recording.uploaded_at))
                              .where(Recording.session_id.in_(ids)).group_by(Recording.session_id)).all())
    jobs = {sid: (c, f) for sid, c, f in db.execute(
        select(Job.session_id, func.max(Job.created_at), func.max(Job.finished_at))
        .where(Job.session_id.in_(ids)).group_by(Job.session_id))}
    active = set(db.scalars(select(Job.session_id).where(Job.session_id.in_(ids), Job.status.in_(ACTIVE))))
    due = []
    for s in candidates:
        if s.id in active:
            continue
        created, finished = jobs.get(s.id, (None, None))
        # the aggregates come back naive on SQLite (no type on max()): they are UTC
        extra = [v if v is None or v.tzinfo else v.replace(tzinfo=dt.timezone.utc)
                 for v in (uploads.get(s.id), created, finished)]
        last = _latest(s.created_at, s.updated_at, *extra)
        if last <= cutoff:
            due.append(DueSession(s.id, s.clinic_id, s.patient_id, last))
    return sorted(due, key=lambda d: (d.last_activity, d.session_id))


def apply_retention(database: Database, store: Storage, days: int, *, now: dt.datetime, record: Recorder,
                    dry_run: bool = True) -> RetentionReport:
    """The due sessions (``dry_run``) or their erasure (module docstring)."""
    report = RetentionReport(days=days, now=now)
    with database.session() as db:
        report.due = due_sessions(db, days, now)
    if dry_run:
        return report
    ids: list[int] = []
    for d in report.due:
        with database.session() as db:
            # locked before the re-check (as a patient's erasure does): an upload to the session, which takes
            # the same lock, then either committed before (and the session is no longer due) or waits for this
            # transaction and finds the session gone — never acknowledged, then deleted (PostgreSQL READ COMMITTED)
            try:
                clinic_session(db, d.clinic_id, d.session_id, lock=True)
            except NotFound:  # erased meanwhile
                continue
            again = [x for x in due_sessions(db, days, now) if x.session_id == d.session_id]
            if not again:  # touched (or erased) since the list was read
                continue
            shas = session_blobs(db, [d.session_id])
            delete_sessions(db, [d.session_id])
            event = record(db, clinic_id=d.clinic_id, patient_id=d.patient_id, session_id=d.session_id,
                           resource=f"retention policy: session {d.session_id}, no activity for {days} days")
            ids += mark(db, shas, reason="retention", actor=getattr(event, "actor", "retention policy"),
                        clinic_id=d.clinic_id, patient_id=d.patient_id, session_id=d.session_id,
                        audit_event_id=getattr(event, "id", None))
            report.erased_sessions += 1
    counts = erase_pending(database, store, ids)
    report.erased_files, report.kept_files = counts.erased, counts.kept
    return report


__all__ = ["DueSession", "RetentionReport", "apply_retention", "due_sessions"]
