"""Processing jobs: persisted in the database, run off the request path, resumed after a restart.

Interface (ready for a distributed engine): a :class:`JobRunner` has ``start()``, ``submit(job_id)`` and
``shutdown()``.  The API only inserts a ``jobs`` row (status ``queued``) in the same transaction that
checks the session, then calls ``submit``; the runner does the rest.  :func:`run_job` is the unit of
work any engine calls with a job id — a Celery task would call it too.

:class:`ThreadJobRunner`, the embedded default, is N worker threads fed by a queue of job ids.  A worker
*claims* a job with a conditional UPDATE (``queued`` → ``running``), so two runners sharing one database
never run the same job twice.  On ``start()`` jobs found ``running`` (their process died mid-way) go back
to ``queued`` with a log line, and every queued job is submitted again, oldest first: nothing is lost by a
restart; a resumed job starts over from its stored files (processing is deterministic); one interrupted
:data:`MAX_ATTEMPTS` times is failed instead (it may be what brings the server down).  The embedded
runner allows one server process per database (``chakamo serve``), and enforces it: ``start()`` takes a
:class:`RunnerLock` (an exclusive ``flock`` on ``<database file>.runner.lock`` for SQLite, a session-level
``pg_try_advisory_lock`` for PostgreSQL; the operating system or the server frees both when the process
dies) and a second server on the same database refuses to start with :class:`RunnerLocked`, instead of
requeueing — and running a second time — the first one's jobs.  Several processes or machines need the
distributed backend (``CHAKAMO_JOB_BACKEND``, next issue), which calls :func:`run_job` from its workers.
Holding the lock, ``start()`` also removes what a crashed server left behind: its temporary ``session-*``
folders and unfinished uploads (``blobs/.incoming/up-*``).  ``shutdown()`` waits for the running jobs and
says whether they all stopped; the application disposes the database only then.

A job's work (:func:`run_job`): copy the session's stored files into a temporary folder with its
``session.json`` (:mod:`app.workspace`), load and process them (:func:`app.pipeline.process_session`, its
``progress(stage, fraction)`` calls written to the job row), build ``results.json`` once and render every
artefact from one report input (:func:`app.render.render_all`: the PDFs in every language, the Excel files,
report.html, scene.viser, timeseries.npz; part of them in the warm render process), store them as blobs
(:func:`app.db.ensure_blob`: identical artefacts of concurrent jobs never collide) and record a new
:class:`~app.db.models.Analysis` in one transaction.  Earlier analyses stay.  A problem with the data
(ingestion or pipeline error) fails the job with the pipeline's sentence as ``error``; an unexpected
exception fails it with a sentence and a reference id — the traceback goes to the server log only (under that
reference), never to the job row that read-only users and API tokens see.
"""

from __future__ import annotations

import logging
import queue
import secrets
import shutil
import threading
from pathlib import Path
from typing import Protocol

from sqlalchemy import create_engine, select, text, update
from sqlalchemy.pool import NullPool

from app.db import Database, ensure_blob
from app.db.models import Analysis, Artefact, Job, KneeSession, Patient, Recording, utcnow
from app.render import MEDIA, PIPELINE_SHARE, RENDER_TIMEOUT_S, RenderPool, render_all, warm_up
from app.storage import BlobStore

log = logging.getLogger("chakamo.jobs")

#: a job interrupted by this many server stops is failed instead of resumed again
MAX_ATTEMPTS = 3


class JobRunner(Protocol):
    """What the application needs of a job engine."""

    def start(self) -> None: ...

    def submit(self, job_id: int) -> None: ...

    def shutdown(self, wait: bool = True) -> None: ...


class _Progress:
    """Writes ``stage`` / ``progress`` and a log line to the job row (one short transaction each)."""

    def __init__(self, db: Database, job_id: int) -> None:
        self.db, self.job_id = db, job_id

    def __call__(self, stage: str, fraction: float, *, note: str | None = None) -> None:
        with self.db.session() as s:
            job = s.get(Job, self.job_id)
            job.stage, job.progress = stage[:40], float(min(max(fraction, 0.0), 1.0))
            job.log = [*job.log, f"{utcnow().isoformat(timespec='seconds')} {note or stage}"]


def _fail(db: Database, job_id: int, error: str) -> None:
    with db.session() as s:
        job = s.get(Job, job_id)
        job.status, job.error, job.finished_at = "failed", error, utcnow()
        job.log = [*job.log, f"{utcnow().isoformat(timespec='seconds')} failed: {error}"]


def claim(db: Database, job_id: int) -> bool:
    """Mark job ``job_id`` running if it is queued; False when another worker has it (or it is finished)."""
    with db.session() as s:
        res = s.execute(update(Job).where(Job.id == job_id, Job.status == "queued")
                        .values(status="running", started_at=utcnow(), attempts=Job.attempts + 1,
                                stage="start", progress=0.0, error=None))
        return res.rowcount == 1


def _public_results(results: dict, session_id: int) -> dict:
    """results.json without the server's temporary folder in it."""
    sess = results.get("session", {})
    sess["folder"] = f"session {session_id}"
    for src in sess.get("recognised", {}).values():
        if isinstance(src, dict) and "files" in src:
            src["files"] = [Path(f).name for f in src["files"]]
    return results


def run_job(job_id: int, db: Database, store: BlobStore, tmp_root: Path, pool: RenderPool | None = None,
            render_timeout_s: float = RENDER_TIMEOUT_S) -> None:
    """Claim and run job ``job_id`` to ``done`` or ``failed`` (module docstring).  Never raises for bad data."""
    from app.ingestion import IngestionError, load_session
    from app.pipeline import PipelineError, ProcessOptions, process_session
    from app.results import build_results
    from app.workspace import materialise, public_message

    if not claim(db, job_id):
        return
    progress = _Progress(db, job_id)
    folder = None
    try:
        with db.session() as s:
            job = s.get(Job, job_id)
            session = s.get(KneeSession, job.session_id)
            patient = s.get(Patient, session.patient_id)
            recordings = list(s.scalars(select(Recording).where(Recording.session_id == session.id)
                                        .order_by(Recording.id)))
            s.expunge_all()
        progress("read", 0.01, note=f"started (attempt {job.attempts}): filter {job.filter}, language {job.lang}")
        options = ProcessOptions(filter_name=job.filter, language=job.lang)
        with materialise(store, tmp_root, session, patient, recordings) as folder:
            loaded = load_session(folder)
            outcome = process_session(loaded, options,
                                      progress=lambda st, f: progress(st, 0.02 + (PIPELINE_SHARE - 0.02) * f))
        results = _public_results(build_results(outcome), session.id)
        files = render_all(outcome, results, job.lang, progress, pool, render_timeout_s)
        progress("store", 0.99)
        stored = {key: store.put(data) for key, data in files.items()}
        with db.session() as s:
            for sha, size in sorted(set(stored.values())):
                ensure_blob(s, sha, size)
            analysis = Analysis(session_id=session.id, job_id=job_id, filter=job.filter, lang=job.lang,
                                accepted_cycles=int(results["cycles"]["accepted"]),
                                warnings=len(results["quality"]["warnings"]))
            analysis.artefacts = [Artefact(name=name, lang=lang, media_type=MEDIA[name], sha256=sha, size_bytes=size)
                                  for (name, lang), (sha, size) in stored.items()]
            s.add(analysis)
            s.flush()
            row = s.get(Job, job_id)
            row.status, row.stage, row.progress, row.finished_at = "done", "done", 1.0, utcnow()
            row.analysis_id = analysis.id
            row.log = [*row.log, f"{utcnow().isoformat(timespec='seconds')} done: analysis {analysis.id}, "
                                 f"{analysis.accepted_cycles} cycles accepted, {analysis.warnings} warnings"]
    except (IngestionError, PipelineError) as exc:
        _fail(db, job_id, public_message(str(exc), folder))
    except Exception:  # noqa: BLE001 — a job must end failed, never stay running
        ref = secrets.token_hex(4)
        log.exception("job %s failed: internal error, reference %s", job_id, ref)
        _fail(db, job_id, f"An internal error stopped the processing (reference {ref}); try again, and if it "
                          "happens again give the reference to your ChakaMo administrator.")


class RunnerLocked(RuntimeError):
    """Another server already runs the jobs of this database."""


#: the PostgreSQL advisory-lock key of the job runner ("CHKMjobs")
_PG_LOCK_KEY = 0x43484B4D6A6F6273


class RunnerLock:
    """At most one embedded job runner per database (module docstring): :meth:`acquire`, :meth:`release`."""

    def __init__(self, db: Database) -> None:
        self.db = db
        self._file = None
        self._conn = None
        self._engine = None

    def acquire(self) -> None:
        """Take the lock or raise :class:`RunnerLocked` with a sentence saying what to do."""
        url = self.db.engine.url
        where = None
        if url.get_backend_name() == "sqlite":
            path = url.database
            if not path or path == ":memory:":
                return
            where = f"{path}.runner.lock"
            try:
                import fcntl
            except ImportError:  # no flock (Windows): one server per database is then up to the operator
                log.warning("cannot lock %s on this system; run one ChakaMo server per database", where)
                return
            f = open(where, "a+")  # noqa: SIM115 — held open while the runner lives
            try:
                fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                f.close()
                raise RunnerLocked(self._message(path)) from None
            self._file = f
        elif url.get_backend_name() == "postgresql":
            # a connection of its own, outside the request pool, in autocommit (never "idle in transaction")
            self._engine = create_engine(url, poolclass=NullPool, isolation_level="AUTOCOMMIT")
            conn = self._engine.connect()
            if not conn.scalar(text("SELECT pg_try_advisory_lock(:k)"), {"k": _PG_LOCK_KEY}):
                conn.close()
                self._engine.dispose()
                self._engine = None
                raise RunnerLocked(self._message(url.render_as_string(hide_password=True)))
            self._conn = conn
        else:
            log.warning("no job-runner lock for %s; run one ChakaMo server per database", url.get_backend_name())

    @staticmethod
    def _message(where: str) -> str:
        return (f"Another ChakaMo server is already running the jobs of this database ({where}); stop it first, or "
                "give this server its own CHAKAMO_DATA_DIR / DATABASE_URL (several servers on one database need "
                "the distributed job backend).")

    def release(self) -> None:
        if self._file is not None:
            self._file.close()  # closing the file drops the flock
            self._file = None
        if self._conn is not None:
            try:
                self._conn.scalar(text("SELECT pg_advisory_unlock(:k)"), {"k": _PG_LOCK_KEY})
            except Exception:  # noqa: BLE001 — closing the connection frees it anyway
                log.exception("could not release the job-runner lock")
            self._conn.close()
            self._conn = None
            self._engine.dispose()
            self._engine = None


def clear_tmp(tmp_root: Path) -> int:
    """Remove the ``session-*`` folders a crashed server left in ``tmp_root``; returns how many.  Only while
    no job or upload check runs (the runner calls it at start-up, holding the :class:`RunnerLock`)."""
    n = 0
    if tmp_root.is_dir():
        for p in tmp_root.glob("session-*"):
            if p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
                n += 1
    return n


class ThreadJobRunner:
    """The embedded engine: ``workers`` threads taking job ids from a queue (module docstring)."""

    def __init__(self, db: Database, store: BlobStore, tmp_root: Path, workers: int = 2,
                 render_processes: int = 0, render_timeout_s: float = RENDER_TIMEOUT_S) -> None:
        self.db, self.store, self.tmp_root, self.workers = db, store, Path(tmp_root), workers
        self.render_processes, self.render_timeout_s = render_processes, render_timeout_s
        self.lock = RunnerLock(db)
        self.pool: RenderPool | None = None
        self._queue: queue.Queue[int | None] = queue.Queue()
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()

    def start(self) -> None:
        """Take the :class:`RunnerLock` (:class:`RunnerLocked` if another server has it), clear a crashed
        server's leftovers, requeue jobs left ``running``, start the threads and submit every queued job,
        oldest first."""
        self.lock.acquire()
        n_tmp, n_up = clear_tmp(self.tmp_root), self.store.clear_incoming()
        if n_tmp or n_up:
            log.info("removed %d temporary session folders and %d unfinished uploads left by a crash", n_tmp, n_up)
        self._stop.clear()
        if self.render_processes > 0 and self.pool is None:
            self.pool = RenderPool(self.render_processes)
        with self.db.session() as s:
            for job in s.scalars(select(Job).where(Job.status == "running")):
                stamp = utcnow().isoformat(timespec="seconds")
                if job.attempts >= MAX_ATTEMPTS:  # it keeps taking the server down with it: stop trying
                    job.status, job.finished_at = "failed", utcnow()
                    job.error = (f"processing was interrupted {job.attempts} times (the server stopped each time); "
                                 "check the server's memory and logs, then process the session again")
                    job.log = [*job.log, f"{stamp} interrupted again; given up"]
                    continue
                job.status, job.stage = "queued", "queued"
                job.log = [*job.log, f"{stamp} interrupted (server stopped); queued again"]
            pending = list(s.scalars(select(Job.id).where(Job.status == "queued").order_by(Job.id)))
        for i in range(self.workers):
            t = threading.Thread(target=self._work, name=f"chakamo-job-{i}", daemon=True)
            t.start()
            self._threads.append(t)
        for job_id in pending:
            self.submit(job_id)
        threading.Thread(target=warm_up, name="chakamo-warm-up", daemon=True).start()

    def submit(self, job_id: int) -> None:
        self._queue.put(job_id)

    def _work(self) -> None:
        while True:
            job_id = self._queue.get()
            if job_id is None or self._stop.is_set():  # a queued job left here stays queued in the database
                return
            try:
                run_job(job_id, self.db, self.store, self.tmp_root, self.pool, self.render_timeout_s)
            except Exception:  # noqa: BLE001 — e.g. the database went away: keep the worker alive
                log.exception("worker could not run job %s", job_id)

    def shutdown(self, wait: bool = True, timeout_s: float = 60.0) -> bool:
        """Stop the threads after their current job; queued jobs stay queued for the next start (a job cut
        short by the process' exit is resumed then too).  True when every thread has stopped (only then may
        the caller dispose the database: a job thread may still be writing to it)."""
        self._stop.set()
        for _ in self._threads:
            self._queue.put(None)
        if wait:
            for t in self._threads:
                t.join(timeout_s)
        alive = [t for t in self._threads if t.is_alive()]
        if alive:
            log.warning("%d job threads still running at shutdown; their jobs resume at the next start", len(alive))
        self._threads.clear()
        if self.pool is not None:
            self.pool.shutdown()
            self.pool = None
        self.lock.release()
        return not alive


__all__ = ["MAX_ATTEMPTS", "JobRunner", "RunnerLock", "RunnerLocked", "ThreadJobRunner", "claim", "clear_tmp",
           "run_job"]
