"""Reprocessing a cohort: ``chakamo reprocess --filter NAME --since DATE`` queues one job per session.

Which sessions: those whose clinical date is on or after ``since`` (of one clinic, or of all), that have
recordings.  Each gets one of these outcomes (:class:`Outcome`), printed as a table by the CLI:

* ``queued`` — a new job (``jobs`` row, ``queued``, carrying :data:`app.pipeline.session.PIPELINE_VERSION`), handed to
  the engine, with the choices the session was last processed with (heading, side, involved knee, calibration,
  angle convention: :func:`app.jobs.queue.previous_choices`), so ``--force`` never resets a clinician's choice;
* ``current`` — an analysis with the same filter, language and those choices already exists for this pipeline
  version and these files (``files_version``): nothing to do.  This is what makes a cohort run idempotent — running the
  same command twice queues nothing the second time — the work being keyed by session, files and pipeline
  version (``--force`` queues it anyway);
* ``busy`` — a job of the session is queued or running (it is not queued twice);
* ``not ready`` — the stored files do not pass the ingestion check (its sentence is shown).

The rules are those of the API's ``POST /sessions/{id}/process`` (:func:`app.jobs.queue.enqueue`, which both
call), plus ``current``.

Handing the jobs over: with ``CHAKAMO_JOB_BACKEND=celery`` each job is published to the broker at once (a broker
that does not answer leaves the jobs queued: the API server's and the workers' sweepers publish them when it
answers again); with the embedded engine the running ``chakamo serve`` finds them at its next sweep (or at its
next start).  Nothing is lost either way: the database holds every job.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

from sqlalchemy import select

from app.choices import FILTER_NAMES
from app.jobs.queue import NotReady, UpToDate, enqueue, previous_choices
from app.pipeline.service_messages import item
from app.settings import Settings
from app.store.accounts import clinic_named
from app.store.blobs import open_storage
from app.store.checks import IngestionChecker
from app.store.database import Database
from app.store.models import KneeSession, utcnow
from app.store.sessions import Busy


#: the outcomes, in the order ``chakamo reprocess`` counts them
STATUSES = ("queued", "current", "busy", "not ready")


@dataclass(frozen=True)
class Outcome:
    """What happened to one session: ``status`` (module docstring, one of :data:`STATUSES`), the job id when
    queued, a note: a message as stored (``{"code", "params"}``: :func:`app.pipeline.service_messages.render_item`
    says it in any language) or None."""

    session_id: int
    patient: str
    date: dt.date
    status: str
    job_id: int | None = None
    note: dict | str | None = None


def _candidates(db: Database, since: dt.date, clinic: str | None) -> list[int]:
    with db.session() as s:
        query = select(KneeSession.id).where(KneeSession.date >= since, KneeSession.recordings.any())
        if clinic is not None:
            query = query.where(KneeSession.clinic_id == clinic_named(s, clinic).id)
        return list(s.scalars(query.order_by(KneeSession.date, KneeSession.id)))


def _queue_one(db: Database, checker: IngestionChecker, session_id: int, filter_name: str, lang: str,
               force: bool) -> Outcome:
    """One session's outcome: :func:`app.jobs.queue.enqueue`'s refusals become ``busy`` / ``not ready`` /
    ``current`` (its transaction rolled back), a queued job ``queued``."""
    with db.session() as s:
        session = s.get(KneeSession, session_id)
        clinic_id = session.clinic_id
        base = dict(session_id=session.id, patient=session.patient.external_id, date=session.date)
        choices = previous_choices(s, session_id)
    try:
        with db.session() as s:
            job = enqueue(s, clinic_id, session_id, filter_name=filter_name, lang=lang, checker=checker,
                          log_lines=[f"{utcnow().isoformat(timespec='seconds')} queued by chakamo reprocess"],
                          unless_current=not force, **choices)
            return Outcome(**base, status="queued", job_id=job.id)
    except Busy as busy:  # also one queued by the API at the same moment: that one stands
        return Outcome(**base, status="busy", job_id=busy.job_id, note=_item(busy))
    except NotReady as not_ready:
        return Outcome(**base, status="not ready", note=not_ready.params["reason"])
    except UpToDate as current:
        return Outcome(**base, status="current", note=_item(current))


def _item(error) -> dict:
    """A domain error as a stored message (:func:`app.pipeline.service_messages.item`)."""
    return item(error.code, error.params, str(error))


def reprocess(settings: Settings, *, filter_name: str, since: dt.date, clinic: str | None = None,
              lang: str = "es", force: bool = False) -> tuple[list[Outcome], dict]:
    """Queue the cohort's jobs (module docstring); returns the outcomes and one sentence on the hand-over (a stored
    message: :func:`app.pipeline.service_messages.render_item`).  :class:`~app.store.errors.NotFound` for an
    unknown ``clinic``."""
    if filter_name not in FILTER_NAMES:
        raise ValueError(f"unknown filter {filter_name!r}; use one of {', '.join(FILTER_NAMES)}")
    db = Database(settings.db_url)
    try:
        db.migrate(settings.sealing_key)
        checker = IngestionChecker(db, open_storage(settings), settings.tmp_dir)
        outcomes = [_queue_one(db, checker, sid, filter_name, lang, force) for sid in _candidates(db, since, clinic)]
        job_ids = [o.job_id for o in outcomes if o.status == "queued"]
        if not job_ids:
            return outcomes, {"code": "jobs.reprocess_none", "params": {}}
        if settings.job_backend == "celery":
            from app.jobs.celery_engine import CeleryJobRunner

            runner = CeleryJobRunner(db, settings)
            sent = 0
            for j in job_ids:  # stop at the first refusal: the broker is down, the sweepers send the rest later
                if not runner.publish(j):
                    break
                sent += 1
            if sent < len(job_ids):
                return outcomes, {"code": "jobs.reprocess_celery_partly", "params": {"n": len(job_ids), "sent": sent}}
            return outcomes, {"code": "jobs.reprocess_celery", "params": {"n": len(job_ids)}}
        return outcomes, {"code": "jobs.reprocess_embedded", "params": {"n": len(job_ids)}}
    finally:
        db.dispose()


__all__ = ["STATUSES", "Outcome", "reprocess"]
