"""Sessions: clinic-scoped lookup, creation, the facts their status is derived from, and the rule that a
session's files do not change while one of its jobs is queued or running.

Status and freshness (the answer of ``GET /sessions/{id}`` and of the session lists): a session's stored
ingestion check is *fresh* when it was computed from the current files (``ingestion_version ==
files_version``, :func:`ingestion_fresh`); a stale one is shown as "being checked" (:func:`stored_ingestion`)
until :mod:`app.store.checks` has run it again.  The status (:func:`session_status`) is ``empty`` (no files),
``processing`` / ``done`` / ``failed`` (its latest job), else ``ready`` or ``incomplete`` (the check); a
session whose latest job's analysis was superseded (:mod:`app.store.analyses`) is ``superseded``.

Correction and erasure (:func:`correct_session`, :func:`delete_session`): both refuse while a job of the
session is queued or running, and both check the caller's ``If-Match`` version when one is given (a stale one
is :class:`~app.store.errors.PreconditionFailed`).  A correction bumps ``version``; one that changes a fact the
processing reads or the reports print (:data:`PROCESSED_FIELDS`: all of them go into the session's manifest)
also bumps ``files_version`` (the ingestion check is redone, ``chakamo reprocess`` no longer skips the session)
and supersedes the session's analyses.  Erasing a session deletes it with its recordings, jobs, analyses and
artefacts (the database's cascades) and returns the blobs they named, which the caller marks for erasure
(:mod:`app.store.erasure`) in the same transaction.

A paired session (:mod:`app.store.pairing`) reads its partner's files and facts too, so every change that makes
one session's check stale and its analyses superseded does the same to its partner (:func:`files_changed`), and
refuses while a job of either is active.  Erasing a session unpairs its partner the same way (the partner's id has
no foreign key and SQLite reuses ids: a pairing left behind would pair it with a new, unrelated session).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

from sqlalchemy import delete, func, select, update
from sqlalchemy.orm import Session

from app.choices import TASK_NAMES
from app.store.analyses import supersede
from app.store.erasure import session_blobs
from app.store.errors import Conflict, Invalid, NotFound, PreconditionFailed
from app.store.models import Analysis, Artefact, Job, KneeSession, Recording, utcnow
from app.pipeline.service_messages import CATALOGUE, item, render
from app.store.workspace import NO_RECORDINGS

#: the job states during which a session's files must not change
ACTIVE = ("queued", "running")
#: the stored check shown while a stale one is being redone
BEING_CHECKED = {"ok": False, "messages": [], "error": render("session.being_checked", {}),
                 "error_item": item("session.being_checked", {}, render("session.being_checked", {}))}


class Busy(Conflict):
    """A job of the session is queued or running (``job_id``): its files must not change under it."""

    def __init__(self, session_id: int, job_id: int, what: str) -> None:
        super().__init__(code="store.busy", session_id=session_id, job_id=job_id, what={"code": _then(what)})
        self.session_id, self.job_id = session_id, job_id


def _then(what: str) -> str:
    """The catalogue key of ``what`` (``store.then.<what>``); a key the catalogue lacks is a programming error,
    raised here and at every call of :func:`refuse_while_processing` (busy or not) rather than as a 500 when the
    refusal is rendered (a 409 become a 500)."""
    key = f"store.then.{what}"
    if key not in CATALOGUE:
        raise ValueError(f"{key!r} is not an entry of app.pipeline.service_messages.CATALOGUE")
    return key


def clinic_session(db: Session, clinic_id: int, session_id: int, lock: bool = False) -> KneeSession:
    """Session ``session_id`` of clinic ``clinic_id``, else :class:`NotFound`.  ``lock``: ``SELECT … FOR
    UPDATE`` of the row (PostgreSQL; SQLite serialises writers anyway), so that changes of one session's files
    and jobs happen one at a time; the row is then read afresh (what was committed before the lock)."""
    if lock:  # the row alone (the ORM's joined patient cannot be locked on PostgreSQL's outer join)
        db.execute(select(KneeSession.id).where(KneeSession.id == session_id).with_for_update())
    # once locked, read the row again even if this session loaded it before (a change committed meanwhile)
    row = db.get(KneeSession, session_id, populate_existing=lock)
    if row is None or row.clinic_id != clinic_id:
        raise NotFound(None, row.clinic_id if row else None, code="store.no_session", session_id=session_id)
    return row


def active_job_id(db: Session, session_id: int, other_than: int | None = None) -> int | None:
    """The oldest queued or running job of the session (other than job ``other_than``), or None."""
    stmt = select(Job.id).where(Job.session_id == session_id, Job.status.in_(ACTIVE))
    if other_than is not None:
        stmt = stmt.where(Job.id != other_than)
    return db.scalar(stmt.order_by(Job.id))


def refuse_while_processing(db: Session, session_id: int, what: str) -> None:
    """:class:`Busy` when a job of session ``session_id`` is queued or running; ``what`` completes its
    sentence ("… ; upload the files when that job has finished"): the key of a ``store.then.*`` entry of
    :data:`app.pipeline.service_messages.CATALOGUE` (``"upload"``), rendered in the reader's language."""
    _then(what)
    job_id = active_job_id(db, session_id)
    if job_id is not None:
        raise Busy(session_id, job_id, what)


def clinic_job(db: Session, clinic_id: int, job_id: int) -> Job:
    row = db.get(Job, job_id)
    if row is None or row.clinic_id != clinic_id:
        raise NotFound(None, row.clinic_id if row else None, code="store.no_job", job_id=job_id)
    return row


def patient_sessions(db: Session, patient_id: int, newest_first: bool = True) -> list[KneeSession]:
    """The patient's sessions by clinical date, then creation (newest first, or oldest first)."""
    order = (KneeSession.date.desc(), KneeSession.id.desc()) if newest_first else (KneeSession.date, KneeSession.id)
    return list(db.scalars(select(KneeSession).where(KneeSession.patient_id == patient_id).order_by(*order)))


@dataclass(frozen=True)
class Page:
    """One page of a list: its ``rows``, how many rows the whole filtered list has (``total``), and the key to
    continue after (``next_after``: the last row's sort key; None on the last page)."""

    rows: list
    total: int
    next_after: Any


def list_patient_sessions(db: Session, patient_id: int, *, after: tuple[dt.date, int] | None = None,
                          limit: int | None = None) -> Page:
    """:func:`patient_sessions` (newest first) as a :class:`Page`; ``after``: continue after this
    ``(date, id)`` (keyset pagination), ``limit``: at most this many rows (None: all)."""
    base = select(KneeSession).where(KneeSession.patient_id == patient_id)
    total = db.scalar(select(func.count()).select_from(base.subquery()))
    stmt = base
    if after is not None:
        day, sid = after
        stmt = stmt.where((KneeSession.date < day) | ((KneeSession.date == day) & (KneeSession.id < sid)))
    stmt = stmt.order_by(KneeSession.date.desc(), KneeSession.id.desc())
    if limit is not None:
        stmt = stmt.limit(limit + 1)
    rows = list(db.scalars(stmt))
    more = limit is not None and len(rows) > limit
    rows = rows[:limit] if limit is not None else rows
    return Page(rows, int(total or 0), (rows[-1].date, rows[-1].id) if more else None)


def add_session(db: Session, clinic_id: int, patient_id: int, values: dict[str, Any]) -> KneeSession:
    """A new, empty session of the patient (``values``: the columns; date defaults to today, UTC)."""
    values = dict(values)
    values["date"] = values.get("date") or dt.datetime.now(dt.timezone.utc).date()
    session = KneeSession(clinic_id=clinic_id, patient_id=patient_id, **values)
    db.add(session)
    db.flush()
    db.refresh(session)
    return session


def summary_facts(db: Session, sessions: list[KneeSession]) -> tuple[dict[int, int], dict[int, Job], set[int]]:
    """``(recordings per session id, latest job per session id, ids of the sessions whose latest job's analysis
    is superseded)`` of ``sessions``, in three queries whatever their number."""
    ids = [s.id for s in sessions]
    if not ids:
        return {}, {}, set()
    counts = dict(db.execute(select(Recording.session_id, func.count()).where(Recording.session_id.in_(ids))
                             .group_by(Recording.session_id)).all())
    last_ids = select(func.max(Job.id)).where(Job.session_id.in_(ids)).group_by(Job.session_id)
    latest = {j.session_id: j for j in db.scalars(select(Job).where(Job.id.in_(last_ids)))}
    analysis_ids = [j.analysis_id for j in latest.values() if j.analysis_id is not None]
    superseded = set(db.scalars(select(Analysis.session_id).where(Analysis.id.in_(analysis_ids),
                                                                  Analysis.superseded_at.is_not(None)))) \
        if analysis_ids else set()
    return counts, latest, superseded


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


def session_status(n_recordings: int, ingestion_ok: bool, latest_job: Job | None, superseded: bool = False) -> str:
    """empty (no files) · incomplete (ingestion not ok) · processing / done / failed (the latest job) ·
    superseded (the latest job's analysis is) · ready."""
    if n_recordings == 0:
        return "empty"
    if superseded and latest_job is not None and latest_job.status == "done":
        return "superseded"
    if latest_job is not None:
        return {"queued": "processing", "running": "processing"}.get(latest_job.status, latest_job.status)
    return "ready" if ingestion_ok else "incomplete"


#: the session's columns a correction may change; every one goes into its manifest (the processing and the reports)
PROCESSED_FIELDS = ("date", "task", "step_height_m", "professional", "notes")
#: the hospital's order and visit (FHIR export only): correctable without superseding anything
ORDER_FIELDS = ("service_request", "encounter", "accession")


def partner_of(db: Session, session: KneeSession) -> KneeSession | None:
    """The session ``session`` is paired with: one of the same clinic and patient whose pairing points back at
    ``session``; else None (a pairing broken on one side is no pairing)."""
    if session.paired_session_id is None:
        return None
    other = db.get(KneeSession, session.paired_session_id)
    if other is None or (other.clinic_id, other.patient_id, other.paired_session_id) != (
            session.clinic_id, session.patient_id, session.id):
        return None
    return other


def bump(db: Session, session_ids: list[int], *, files: bool = True) -> int:
    """Mark ``session_ids`` changed in SQL (``version`` and, with ``files``, ``files_version`` incremented by the
    database, not from values read earlier) and supersede their analyses; returns how many were superseded."""
    if not session_ids:
        return 0
    values: dict[str, Any] = {"version": KneeSession.version + 1, "updated_at": utcnow()}
    if files:
        values["files_version"] = KneeSession.files_version + 1
    db.execute(update(KneeSession).where(KneeSession.id.in_(session_ids)).values(**values)
               .execution_options(synchronize_session=False))
    n = supersede(db, session_ids)
    for s in db.identity_map.values():  # read again on next access
        if isinstance(s, KneeSession) and s.id in session_ids:
            db.expire(s, ["version", "files_version", "updated_at"])
    return n


def files_changed(db: Session, session: KneeSession, what: str) -> int:
    """``session``'s files or facts changed: its partner's too (module docstring).  Refuses (:class:`Busy`, ``what``
    as for :func:`refuse_while_processing`) while the partner is being processed; bumps the partner's
    ``files_version`` and supersedes its analyses; returns how many of the partner's were superseded (the caller
    bumps ``session`` itself)."""
    other = partner_of(db, session)
    if other is None:
        return 0
    refuse_while_processing(db, other.id, what)
    return bump(db, [other.id], files=True)


def check_version(kind: str, row_id: int, version: int, expected: int | None) -> None:
    """:class:`PreconditionFailed` when the caller's ``If-Match`` version ``expected`` is not ``version``."""
    if expected is not None and expected != version:
        raise PreconditionFailed(code="store.changed_meanwhile", kind=kind, row_id=row_id, version=version,
                                 expected=expected)


def correct_session(db: Session, clinic_id: int, session_id: int, values: dict[str, Any],
                    expected_version: int | None = None) -> tuple[KneeSession, list[str], int]:
    """Correct the session's ``values`` (columns of :data:`PROCESSED_FIELDS`); returns ``(session, the fields
    that changed, analyses superseded)`` (module docstring).  :class:`Invalid` for another column or a null
    date or task."""
    unknown = sorted(set(values) - set(PROCESSED_FIELDS) - set(ORDER_FIELDS))
    if unknown:
        raise Invalid(code="store.not_correctable", fields=", ".join(unknown),
                      allowed=", ".join(PROCESSED_FIELDS + ORDER_FIELDS))
    for required in ("date", "task"):
        if required in values and values[required] is None:
            raise Invalid(code="store.empty_value", field=required)
    step = values.get("step_height_m")
    if step is not None and not 0 < float(step) < 1:
        raise Invalid(code="store.step_out_of_range", value=step)
    if values.get("task") is not None and values["task"] not in TASK_NAMES:
        raise Invalid(code="store.unknown_task", task=str(values["task"]), allowed=", ".join(TASK_NAMES))
    session = clinic_session(db, clinic_id, session_id, lock=True)
    check_version("Session", session.id, session.version, expected_version)
    refuse_while_processing(db, session.id, "correct")
    changed = [k for k, v in values.items() if getattr(session, k) != v]
    n_superseded = 0
    if changed:
        for k in changed:
            setattr(session, k, values[k])
        session.version = session.version + 1
        session.updated_at = utcnow()
        if set(changed) & set(PROCESSED_FIELDS):
            session.files_version = session.files_version + 1  # the manifest changed: the check is redone
            n_superseded = supersede(db, [session.id]) + files_changed(db, session, "correct")
        db.flush()
    return session, changed, n_superseded


def delete_session(db: Session, clinic_id: int, session_id: int,
                   expected_version: int | None = None) -> tuple[int, set[str]]:
    """Delete the session with its recordings, jobs, analyses and artefacts; returns ``(its patient's id, the
    blobs they named)`` for :func:`app.store.erasure.mark` (module docstring)."""
    session = clinic_session(db, clinic_id, session_id, lock=True)
    check_version("Session", session.id, session.version, expected_version)
    refuse_while_processing(db, session.id, "delete")
    patient_id = session.patient_id
    other = partner_of(db, session)
    if other is not None:
        refuse_while_processing(db, other.id, "delete")
    shas = session_blobs(db, [session.id])
    delete_sessions(db, [session.id])
    return patient_id, shas


def delete_sessions(db: Session, session_ids: list[int]) -> None:
    """Delete ``session_ids`` and everything under them (the caller has checked them and read their blobs)."""
    if not session_ids:
        return
    # their partners are unpaired (module docstring): checks redone, analyses superseded
    partners = list(db.scalars(select(KneeSession.id).where(KneeSession.paired_session_id.in_(session_ids),
                                                            KneeSession.id.not_in(session_ids))
                               .order_by(KneeSession.id).with_for_update()))
    if partners:
        db.execute(update(KneeSession).where(KneeSession.id.in_(partners))
                   .values(paired_session_id=None, knee=None).execution_options(synchronize_session=False))
        bump(db, partners, files=True)
    # jobs first (analyses point at them), then the sessions: the cascades take recordings, analyses, artefacts
    db.execute(delete(Job).where(Job.session_id.in_(session_ids)))
    db.execute(delete(Recording).where(Recording.session_id.in_(session_ids)))
    analysis_ids = select(Analysis.id).where(Analysis.session_id.in_(session_ids))
    db.execute(delete(Artefact).where(Artefact.analysis_id.in_(analysis_ids)))
    db.execute(delete(Analysis).where(Analysis.session_id.in_(session_ids)))
    db.execute(delete(KneeSession).where(KneeSession.id.in_(session_ids)))
    db.expire_all()


__all__ = ["ACTIVE", "ORDER_FIELDS", "Page", "list_patient_sessions", "PROCESSED_FIELDS", "check_version", "correct_session", "delete_session", "delete_sessions", "BEING_CHECKED", "Busy", "active_job_id", "add_session", "bump", "files_changed", "partner_of", "clinic_job", "clinic_session",
           "ingestion_fresh", "patient_sessions", "ready", "refuse_while_processing", "session_analyses",
           "session_jobs", "session_status", "stored_ingestion", "summary_facts"]
