"""Processing jobs: persisted in the database, run off the request path, resumed after a restart.

Interface: a :class:`JobRunner` has ``start()``, ``submit(job_id)``, ``problem()`` and ``shutdown()``.  The
API only inserts a ``jobs`` row (status ``queued``) in the same transaction that checks the session, then
calls ``submit``; the runner does the rest.  :func:`run_job` is the unit of work every engine calls with a
job id.

The embedded engine is :class:`app.jobs.inprocess.ThreadJobRunner` (worker threads inside ``chakamo serve``); the
distributed one is :mod:`app.jobs.celery_engine` (Celery workers fed through Redis).  Both call :func:`run_job`.

Leases and the sweeper (both engines).  While a worker runs a job a heartbeat thread refreshes
``heartbeat_at`` every quarter of the lease (``CHAKAMO_JOB_LEASE_S``).  :func:`sweep` finds what a lost worker
or a lost message left: a ``running`` job whose heartbeat is older than the lease goes back to ``queued`` (or
to ``failed`` after :data:`MAX_ATTEMPTS`), and a ``queued`` job never handed to the engine — or, with Celery
while the broker's queue is empty, handed longer ago than ``CHAKAMO_REDISPATCH_S`` — is handed again.  Every
write of a run carries its attempt number (:func:`claim` returns it): a run the sweeper gave up on (a worker
that only looked lost) can never overwrite the run that replaced it (:class:`Superseded`).  Handing a job
twice is harmless: :func:`claim` is a conditional UPDATE, so only one worker runs it, and the analysis row is
unique per job, so a job never yields two analyses (the work is idempotent, keyed by the job — a session, its
files' version and the pipeline version).  :class:`app.jobs.inprocess.ThreadJobRunner` sweeps every few seconds
(so jobs queued by ``chakamo reprocess`` from another process are found too), and at start-up with a zero
lease (every job left running belonged to a dead server); the Celery engine (:mod:`app.jobs.celery_engine`) sweeps
in the API server and in every worker.  A database outage during a job (``OperationalError``) is not the data's fault:
:func:`run_job` re-raises it as :class:`TransientJobError` (the Celery task retries with back-off; the
embedded runner runs the same attempt again after a back-off, :meth:`app.jobs.inprocess.ThreadJobRunner.run`)
instead of failing the job.  So does a wait for a pooled connection that timed out (SQLAlchemy's pool
``TimeoutError``: every connection busy, e.g. a server starved of CPU): it is the server's state, never the
job's, and the job waits and runs again rather than fail.

A job's work (:func:`run_job`): copy the session's stored files into a temporary folder with its
``session.json`` (:mod:`app.store.workspace`), load and process them (:func:`app.pipeline.session.process_session`, its
``progress(stage, fraction)`` calls written to the job row), build ``results.json`` once and render every
artefact from one report input (:func:`app.pipeline.render.render_all`: the PDFs in every language, the Excel files,
report.html, scene.viser, timeseries.npz) — that computation (:func:`app.jobs.compute.compute`) in a helper
process at background priority when the engine gives one (the embedded engine does), — then store them as blobs
(:func:`app.store.erasure.reserve_blobs`, under the blobs' locks: identical artefacts of concurrent jobs never
collide, nor an erasure of the same bytes) and record a new
:class:`~app.store.models.Analysis` in one transaction.  Earlier analyses stay.  A problem with the data
(ingestion or pipeline error) fails the job with the pipeline's sentence as ``error``; an unexpected
exception fails it with a sentence and a reference id (a full disk — ``ENOSPC`` while storing the
artefacts — with a sentence saying so: nothing half-stored is recorded, and processing again works once there
is space) — the traceback goes to the server log only (under that
reference), never to the job row that read-only users and API tokens see.
"""

from __future__ import annotations

import datetime as dt
import errno
import hashlib
import logging
import secrets
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Literal, Protocol

from sqlalchemy import or_, select, update
from sqlalchemy.exc import DBAPIError, IntegrityError, OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeout

from app.store.database import Database
from app.store.analyses import supersede
from app.store.erasure import reserve_blobs
from app.store.models import Analysis, Artefact, Clinic, Job, KneeSession, Patient, Recording, utcnow
from app.pipeline.messages import render_message
from app.pipeline.render import MEDIA
from app.store.blobs import Storage, commit_all, discarding
from app.settings import get_settings

if TYPE_CHECKING:
    from app.jobs.compute import JobProcess

log = logging.getLogger("chakamo.jobs")

#: a job interrupted this many times (a server stop, a lost worker, an expired lease) is failed instead of run again
MAX_ATTEMPTS = 3
#: default lease of a running job (``CHAKAMO_JOB_LEASE_S``) and re-dispatch delay (``CHAKAMO_REDISPATCH_S``)
LEASE_S = 60.0
REDISPATCH_S = 120.0


class TransientJobError(RuntimeError):
    """The job could not run for a reason outside its data (the database went away); run it again later.
    ``attempt``: the run that was cut short (None if it never claimed the job), to resume with
    :func:`run_job`'s ``resume_attempt`` — so an outage does not count as one of the job's attempts."""

    def __init__(self, message: str, attempt: int | None = None) -> None:
        super().__init__(message)
        self.attempt = attempt


class JobRunner(Protocol):
    """What the application needs of a job engine."""

    def start(self) -> None: ...

    def submit(self, job_id: int) -> None: ...

    def shutdown(self, wait: bool = True) -> bool: ...

    def problem(self) -> str | None:
        """None when the engine can take jobs, else one sentence saying what is wrong (``/readyz``)."""


class Superseded(RuntimeError):
    """This run no longer owns its job (the sweeper gave it to another run, or it ended): stop, write nothing."""


def _owned(s, job_id: int, attempt: int) -> Job:
    """The job row if run ``attempt`` still owns it (``running`` with that attempt number), locked on PostgreSQL;
    else :class:`Superseded`.  Every write of a run goes through it, so a run the sweeper gave up on can never
    overwrite the run that replaced it."""
    job = s.get(Job, job_id, with_for_update=True)
    if job is None or job.status != "running" or job.attempts != attempt:
        raise Superseded(f"job {job_id}: attempt {attempt} no longer owns it")
    return job


class _Progress:
    """Writes ``stage`` / ``progress`` and a log line to the job row (one short transaction each)."""

    def __init__(self, db: Database, job_id: int, attempt: int) -> None:
        self.db, self.job_id, self.attempt = db, job_id, attempt

    def __call__(self, stage: str, fraction: float, *, note: str | None = None) -> None:
        with self.db.session() as s:
            job = _owned(s, self.job_id, self.attempt)
            job.stage, job.progress = stage[:40], float(min(max(fraction, 0.0), 1.0))
            job.log = [*job.log, f"{utcnow().isoformat(timespec='seconds')} {note or stage}"]


def _fail(db: Database, job_id: int, attempt: int, error: str, code: str | None = None,
          params: dict | None = None) -> None:
    """End the run failed with ``error`` (English) and, when it has one, its catalogue ``code`` and ``params``
    (:mod:`app.pipeline.messages`), from which the API renders it in the reader's language."""
    try:
        with db.session() as s:
            job = _owned(s, job_id, attempt)
            job.status, job.error, job.finished_at = "failed", error, utcnow()
            job.error_code, job.error_params = code, params
            job.log = [*job.log, f"{utcnow().isoformat(timespec='seconds')} failed: {error}"]
    except Superseded:
        log.warning("job %s: attempt %s failed (%s) after another run took the job over; left to that run",
                    job_id, attempt, error)


def _public_params(params, folder):
    """A failed job's message parameters without the server's temporary folder (the texts' public form)."""
    from app.store.workspace import public_message

    if isinstance(params, dict):
        return {k: _public_params(v, folder) for k, v in params.items()}
    if isinstance(params, list):
        return [_public_params(v, folder) for v in params]
    return public_message(params, folder) if isinstance(params, str) else params


def claim(db: Database, job_id: int) -> int | None:
    """Mark job ``job_id`` running if it is queued and return this run's attempt number (the run's ownership
    token, :func:`_owned`); None when another worker has it (or it is finished)."""
    now = utcnow()
    with db.session() as s:
        res = s.execute(update(Job).where(Job.id == job_id, Job.status == "queued")
                        .values(status="running", started_at=now, heartbeat_at=now, attempts=Job.attempts + 1,
                                stage="start", progress=0.0, error=None, error_code=None, error_params=None))
        if res.rowcount != 1:
            return None
        return s.scalar(select(Job.attempts).where(Job.id == job_id))


def reclaim(db: Database, job_id: int, attempt: int) -> bool:
    """Resume run ``attempt`` of job ``job_id`` after a database outage cut it short: True when the job is
    still ``running`` under that attempt (its lease has not expired and the sweeper has not requeued it)."""
    with db.session() as s:
        res = s.execute(update(Job).where(Job.id == job_id, Job.status == "running", Job.attempts == attempt)
                        .values(heartbeat_at=utcnow(), stage="start", progress=0.0))
        return res.rowcount == 1


def job_state(db: Database, job_id: int) -> str | None:
    """The job's status (None for an unknown id)."""
    with db.session() as s:
        return s.scalar(select(Job.status).where(Job.id == job_id))


@contextmanager
def heartbeat(db: Database, job_id: int, attempt: int, lease_s: float = LEASE_S):
    """Refresh the job's ``heartbeat_at`` every ``lease_s / 4`` seconds while the block runs and run ``attempt``
    owns the job (module docstring).  A failed beat (database briefly away) is logged and tried again at the
    next tick."""
    stop = threading.Event()

    def beat() -> None:
        while not stop.wait(lease_s / 4):
            try:
                with db.session() as s:
                    s.execute(update(Job).where(Job.id == job_id, Job.status == "running", Job.attempts == attempt)
                              .values(heartbeat_at=utcnow()))
            except Exception:  # noqa: BLE001 — the next beat tries again; the lease is 4 beats long
                log.warning("heartbeat of job %s not written", job_id, exc_info=True)

    t = threading.Thread(target=beat, name=f"chakamo-heartbeat-{job_id}", daemon=True)
    t.start()
    try:
        yield
    finally:
        stop.set()
        t.join(5.0)


def sweep(db: Database, lease_s: float = LEASE_S, redispatch_s: float | None = REDISPATCH_S, *,
          why: str | None = None) -> list[int]:
    """Requeue the ``running`` jobs whose heartbeat is older than ``lease_s`` (fail them after
    :data:`MAX_ATTEMPTS`), and return the ``queued`` jobs to hand to the engine: never handed, or handed
    more than ``redispatch_s`` ago (``None``: only the never handed ones — an engine whose hand-over cannot be
    lost, or a broker whose queue still holds messages).  Each change is a conditional UPDATE on the state
    seen (status, attempt, heartbeat), so a job that finished or beat meanwhile is left alone.  ``why`` is
    the job log's reason (default: the worker lost).  The caller calls :func:`mark_dispatched` for each job
    it could hand over."""
    now = utcnow()
    stale = now - dt.timedelta(seconds=lease_s)
    stamp = now.isoformat(timespec="seconds")
    why = why or f"worker lost: no heartbeat for {lease_s:g} s"
    # no heartbeat yet (a row from before leases existed): judged by its start, or lost if it has none either
    is_lost = (Job.status == "running",
               or_(Job.heartbeat_at < stale,
                   Job.heartbeat_at.is_(None) & or_(Job.started_at.is_(None), Job.started_at < stale)))
    with db.session() as s:
        lost = list(s.execute(select(Job.id, Job.attempts, Job.log).where(*is_lost)))
        for job_id, attempts, job_log in lost:
            if attempts >= MAX_ATTEMPTS:  # it keeps taking its worker down with it: stop trying
                values = dict(status="failed", finished_at=now, log=[*job_log, f"{stamp} interrupted ({why}); given up"],
                              error=render_message("job.interrupted", {"attempts": attempts}),
                              error_code="job.interrupted", error_params={"attempts": attempts})
            else:
                values = dict(status="queued", stage="queued", dispatched_at=None,
                              log=[*job_log, f"{stamp} interrupted ({why}); queued again"])
            if s.execute(update(Job).where(Job.id == job_id, Job.attempts == attempts, *is_lost)
                         .values(**values)).rowcount:
                log.warning("job %s: worker lost, %s", job_id, values["status"])
        due = Job.dispatched_at.is_(None)
        if redispatch_s is not None:
            due = or_(due, Job.dispatched_at < now - dt.timedelta(seconds=redispatch_s))
        return list(s.scalars(select(Job.id).where(Job.status == "queued", due).order_by(Job.id)))


def mark_dispatched(db: Database, job_ids: list[int]) -> None:
    """Record that ``job_ids`` were handed to the engine now."""
    if job_ids:
        with db.session() as s:
            s.execute(update(Job).where(Job.id.in_(job_ids), Job.status == "queued").values(dispatched_at=utcnow()))


def _is_disk_full(exc: BaseException) -> bool:
    return isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def _transient(exc: BaseException) -> bool:
    """A database that went away (connection refused or dropped) or no pooled connection free in time (the
    pool's ``TimeoutError``): the server's state, not a problem of this job (module docstring)."""
    return isinstance(exc, (OperationalError, PoolTimeout)) or (
        isinstance(exc, DBAPIError) and exc.connection_invalidated)


def _identifier_system() -> str | None:
    """``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM`` of this process' settings, for the reports' identity line; None when the
    settings cannot be read here (the reports then print the record number without its system: never a guess)."""
    try:
        return get_settings(require_key=False).patient_identifier_system
    except Exception:  # noqa: BLE001 — a job must not fail for a label
        log.exception("the settings could not be read for the identifier system; reports print the number alone")
        return None


Outcome = Literal["done", "failed", "busy", "finished"]


def run_job(job_id: int, db: Database, store: Storage, tmp_root: Path, lease_s: float = LEASE_S,
            resume_attempt: int | None = None, helper: "JobProcess | None" = None) -> Outcome:
    """Claim and run job ``job_id`` (module docstring).  Returns ``done`` or ``failed`` when this call ran it,
    ``busy`` when another worker holds it (running, lease not expired), ``finished`` when it had already ended
    (or is unknown).  Never raises for bad data; raises :class:`TransientJobError` when the database went away
    (the job is then left to the sweeper or to the engine's retry, which passes the error's ``attempt`` back as
    ``resume_attempt``: the same run goes on, not a new attempt).  ``helper``: the computation runs in that
    process (:class:`app.jobs.compute.JobProcess`), else in this thread."""
    try:
        if resume_attempt is not None and reclaim(db, job_id, resume_attempt):
            attempt = resume_attempt
        else:
            attempt = claim(db, job_id)
        if attempt is None:
            return "busy" if job_state(db, job_id) in ("queued", "running") else "finished"
    except Exception as exc:
        if _transient(exc):  # not claimed (or not known to be): the retry resumes the attempt it was given
            raise TransientJobError(f"job {job_id}: database unreachable", resume_attempt) from exc
        raise
    with heartbeat(db, job_id, attempt, lease_s):
        return _run_claimed(job_id, attempt, db, store, tmp_root, helper)


def _run_claimed(job_id: int, attempt: int, db: Database, store: Storage, tmp_root: Path,
                 helper: "JobProcess | None") -> Outcome:
    from app.jobs.compute import HelperStopped, compute
    from app.pipeline.ingestion import IngestionError
    from app.pipeline.session import PIPELINE_VERSION, PipelineError, ProcessOptions
    from app.pipeline.exclusions import from_records
    from app.store.pairing import partner_files
    from app.store.workspace import materialise, public_message

    progress = _Progress(db, job_id, attempt)
    folder = None
    try:
        with db.session() as s:
            job = s.get(Job, job_id)
            session = s.get(KneeSession, job.session_id)
            patient = s.get(Patient, session.patient_id)
            clinic = s.get(Clinic, session.clinic_id)
            clinic_name = clinic.name if clinic is not None else ""
            recordings = list(s.scalars(select(Recording).where(Recording.session_id == session.id)
                                        .order_by(Recording.id)))
            paired = partner_files(s, session)  # the other knee's session, when paired (app.store.pairing)
            s.expunge_all()
        progress("read", 0.01, note=f"started (attempt {job.attempts}): filter {job.filter}, language {job.lang}")
        # a paired session's involved knee: the request's, else the patient's side (not the session's own knee)
        involved = job.involved or (patient.side if paired is not None else None)
        options = ProcessOptions(filter_name=job.filter, language=job.lang, task=session.task, heading=job.heading,
                                 side=job.side, involved=involved, calibration=job.calibration,
                                 angle_method=job.angle_method, exclusions=from_records(job.cycle_exclusions))
        identifier_system = _identifier_system()
        # the reports' identity line: the clinic's name and the record numbers' system (issue 17 §3)
        with materialise(store, tmp_root, session, patient, recordings, paired, clinic=clinic_name,
                         identifier_system=identifier_system) as folder:
            paired_id = paired[0].id if paired else None
            if helper is not None:  # off this process: app.jobs.compute says why
                results, files = helper.run(progress, folder, options, job.lang, session.id, paired_id)
            else:
                results, files = compute(folder, options, job.lang, session.id, paired_id, progress)
        progress("store", 0.99)
        stored = {key: (hashlib.sha256(data).hexdigest(), len(data)) for key, data in files.items()}
        contents = {stored[key]: data for key, data in files.items()}
        # written and fsynced before the transaction (BlobWriter.seal): under the locks only the renames; what
        # a failure leaves unplaced is discarded
        sealed = {}
        with discarding(sealed.values()):
            for key, data in contents.items():
                sealed[key] = store.sealed(data)
            with db.session() as s:
                row = _owned(s, job_id, attempt)  # checked (and locked) first: a superseded run stores nothing
                # the files are placed under their blobs' locks, as an upload's: the same bytes may be another
                # session's artefact being erased right now (app.store.erasure)
                reserve_blobs(s, list(contents))  # locked in sha256 order by reserve_blobs
                commit_all(list(sealed.values()))
                analysis = Analysis(session_id=session.id, job_id=job_id, filter=job.filter, lang=job.lang,
                                    calibration=job.calibration, angle_method=job.angle_method,
                                    accepted_cycles=int(results["cycles"]["accepted"]),
                                    warnings=len(results["quality"]["warnings"]),
                                    pipeline_version=PIPELINE_VERSION, files_version=session.files_version)
                analysis.artefacts = [Artefact(name=name, lang=lang, media_type=MEDIA[name], sha256=sha, size_bytes=size)
                                      for (name, lang), (sha, size) in stored.items()]
                # a choice of cycles revises the analysis: the earlier ones of its calibration and convention stay,
                # for the record, superseded (another convention's view of the files is left current); a paired
                # session's partner reports the same two knees, so its analyses are superseded too
                revised = supersede(s, [session.id] + ([paired[0].id] if paired else []),
                                    calibration=job.calibration, angle_method=job.angle_method) \
                    if job.cycle_exclusions is not None else 0
                s.add(analysis)
                s.flush()
                row.status, row.stage, row.progress, row.finished_at = "done", "done", 1.0, utcnow()
                row.analysis_id = analysis.id
                row.log = [*row.log, f"{utcnow().isoformat(timespec='seconds')} done: analysis {analysis.id}, "
                                     f"{analysis.accepted_cycles} cycles accepted, {analysis.warnings} warnings"
                                     + (f"; {revised} earlier analyses superseded (cycles chosen by the clinician)"
                                        if revised else "")]
        return "done"
    except HelperStopped:  # the server is stopping: the job stays running and resumes at the next start
        log.warning("job %s: the server stopped its helper process; it resumes at the next start", job_id)
        raise TransientJobError(f"job {job_id}: the server is stopping", attempt) from None
    except Superseded:  # the sweeper gave the job to another run (this one looked lost): that run stands
        log.warning("job %s: attempt %s was taken over by another run; its results are dropped", job_id, attempt)
        return "finished"
    except IntegrityError:  # a second run of this job stored its analysis first: that one stands
        log.warning("job %s: another run stored its analysis first; this run's results are dropped", job_id)
        return "finished"
    except (IngestionError, PipelineError) as exc:
        coded = exc.code != "text"
        _fail(db, job_id, attempt, public_message(str(exc), folder), exc.code if coded else None,
              _public_params(exc.params, folder) if coded else None)
    except Exception as exc:  # noqa: BLE001 — a job must end failed, never stay running
        if _transient(exc):  # not the job's fault: leave it running; the engine runs this attempt again
            log.warning("job %s: database unreachable or busy (%s); it will run again", job_id, type(exc).__name__)
            raise TransientJobError(f"job {job_id}: database unreachable", attempt) from exc
        if _is_disk_full(exc):
            log.error("job %s failed: no space left to store its artefacts (%s)", job_id, exc)
            _fail(db, job_id, attempt, render_message("job.disk_full", {}), "job.disk_full", {})
            return "failed"
        ref = secrets.token_hex(4)
        log.exception("job %s failed: internal error, reference %s", job_id, ref)
        _fail(db, job_id, attempt, render_message("job.internal", {"ref": ref}), "job.internal", {"ref": ref})
    return "failed"


__all__ = ["LEASE_S", "MAX_ATTEMPTS", "REDISPATCH_S", "JobRunner", "Superseded", "TransientJobError", "claim",
           "heartbeat", "job_state", "mark_dispatched", "reclaim", "run_job", "sweep"]
