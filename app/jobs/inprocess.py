"""The embedded job engine: worker threads inside ``chakamo serve`` (``CHAKAMO_JOB_BACKEND=inprocess``).

:class:`ThreadJobRunner` is N worker threads fed by a queue of job ids; each calls :func:`app.jobs.work.run_job`,
which *claims* a job with a conditional UPDATE (``queued`` → ``running``), so two runners sharing one database
never run the same job twice.  On ``start()`` jobs found ``running`` (their process died mid-way) go back to
``queued`` with a log line, and every queued job is submitted again, oldest first: nothing is lost by a
restart; a resumed job starts over from its stored files (processing is deterministic); one interrupted
:data:`~app.jobs.work.MAX_ATTEMPTS` times is failed instead (it may be what brings the server down).  Every
:attr:`ThreadJobRunner.SWEEP_EVERY_S` seconds :func:`app.jobs.work.sweep` requeues a job whose heartbeat stopped and
hands over jobs queued by another process (``chakamo reprocess``).  The embedded runner allows one server
process per database (``chakamo serve``), and enforces it: ``start()`` takes a :class:`RunnerLock` (an
exclusive ``flock`` on ``<database file>.runner.lock`` for SQLite, a session-level ``pg_try_advisory_lock``
for PostgreSQL; the operating system or the server frees both when the process dies) and a second server on
the same database refuses to start with :class:`RunnerLocked`, instead of requeueing — and running a second
time — the first one's jobs.  Several processes or machines need the distributed backend
(``CHAKAMO_JOB_BACKEND=celery``, :mod:`app.jobs.celery_engine`).  Holding the lock, ``start()`` also removes what a
crashed server left behind: its temporary ``session-*`` folders and unfinished uploads
(``blobs/.incoming/up-*``).  The periodic housekeeping (the erasure sweep, the retention policy) is not the
runner's: every API server runs it whatever the job backend (:class:`app.web.housekeeping.Housekeeper`, one server
at a time through a :class:`RunnerLock` of its own).  ``shutdown()`` waits for the
running jobs and says whether they all stopped; the application disposes the database only then.

**Priority** (issue 16 finding 10h): with ``render_processes`` > 0 (``CHAKAMO_RENDER_PROCESSES``, default 1) each
worker thread has a helper process of its own (:class:`app.jobs.compute.JobProcess`) that computes its jobs —
reading, processing, rendering — at the background priority, off this process' interpreter lock; the thread keeps
the database and the blob store (progress, heartbeats, the stored analysis) at the server's priority.  The worker
threads themselves are not lowered: a lowered thread inside the API process would hold the interpreter's lock
while it runs Python and the database's write lock while it stores — every request thread would then wait on the
least favoured thread of the machine (priority inversion).  With ``render_processes`` = 0 the jobs are computed
in the worker threads (tests, a machine that cannot spare the memory).  The workers are at most
``CHAKAMO_WORKERS`` (default 2).

**A database that is away or busy** (:class:`app.jobs.work.TransientJobError`: an outage, or no pooled connection
free within the pool's timeout because the server is starved): the worker waits (:attr:`ThreadJobRunner.RETRY_S`,
doubling, at most :attr:`ThreadJobRunner.RETRY_MAX_S`) and runs the same attempt again (:meth:`ThreadJobRunner.run`)
— the job is never failed for it, and the wait does not count as one of its attempts.
"""

from __future__ import annotations

import logging
import queue
import shutil
import threading
from pathlib import Path

from sqlalchemy import create_engine, text
from sqlalchemy.pool import NullPool

from app.store.database import Database
from app.jobs.work import LEASE_S, Outcome, TransientJobError, mark_dispatched, run_job, sweep
from app.jobs.compute import JobProcess
from app.pipeline.render import warm_up
from app.store.blobs import Storage

log = logging.getLogger("chakamo.jobs")


class RunnerLocked(RuntimeError):
    """Another server already runs the jobs of this database."""


#: the PostgreSQL advisory-lock key of the job runner ("CHKMjobs")
_PG_LOCK_KEY = 0x43484B4D6A6F6273


class RunnerLock:
    """At most one embedded job runner per database (module docstring): :meth:`acquire`, :meth:`held`,
    :meth:`release`.  ``key`` and ``name`` make another lock of the same kind, one holder per database
    (PostgreSQL advisory-lock key, ``<database file>.<name>.lock``): the housekeeping's
    (:class:`app.web.housekeeping.Housekeeper`)."""

    def __init__(self, db: Database, key: int = _PG_LOCK_KEY, name: str = "runner") -> None:
        self.db, self.key, self.name = db, key, name
        self._file = None
        self._conn = None
        self._engine = None
        self._taken = False

    def acquire(self) -> None:
        """Take the lock or raise :class:`RunnerLocked` with a sentence saying what to do."""
        url = self.db.engine.url
        where = None
        if url.get_backend_name() == "sqlite":
            path = url.database
            if not path or path == ":memory:":
                self._taken = True
                return
            where = f"{path}.{self.name}.lock"
            try:
                import fcntl
            except ImportError:  # no flock (Windows): one server per database is then up to the operator
                log.warning("cannot lock %s on this system; run one ChakaMo server per database", where)
                self._taken = True
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
            try:
                self._conn = self._engine.connect()
                got = self._conn.scalar(text("SELECT pg_try_advisory_lock(:k)"), {"k": self.key})
            except Exception:
                self._close()  # the server is away: nothing is held
                raise
            if not got:
                self._close()
                raise RunnerLocked(self._message(url.render_as_string(hide_password=True)))
        else:
            log.warning("no %s lock for %s; run one ChakaMo server per database", self.name, url.get_backend_name())
        self._taken = True

    def held(self) -> bool:
        """Whether this lock is still held: a PostgreSQL session-level lock goes with its connection (the server
        restarted, an idle timeout cut it), which a query on it tells; a lost one is released here (False)."""
        if not self._taken:
            return False
        if self._conn is not None:
            try:
                self._conn.scalar(text("SELECT 1"))
            except Exception:  # noqa: BLE001 — the connection is gone, and the lock with it
                self._taken = False
                self._close()
                return False
        return True

    @staticmethod
    def _message(where: str) -> str:
        return (f"Another ChakaMo server is already running the jobs of this database ({where}); stop it first, or "
                "give this server its own CHAKAMO_DATA_DIR / DATABASE_URL (several servers on one database need "
                "the distributed job backend).")

    def release(self) -> None:
        self._taken = False
        if self._file is not None:
            self._file.close()  # closing the file drops the flock
            self._file = None
        if self._conn is not None:
            try:
                self._conn.scalar(text("SELECT pg_advisory_unlock(:k)"), {"k": self.key})
            except Exception:  # noqa: BLE001 — closing the connection frees it anyway
                log.exception("could not release the %s lock", self.name)
        self._close()

    def _close(self) -> None:
        """Close the lock's PostgreSQL connection and engine (which frees a lock still held)."""
        if self._conn is not None:
            try:
                self._conn.close()
            except Exception:  # noqa: BLE001 — a connection the server already cut
                pass
            self._conn = None
        if self._engine is not None:
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

    #: seconds between two sweeps (requeue lost jobs, pick up jobs queued by another process)
    SWEEP_EVERY_S = 5.0
    #: first wait before a job cut short by the database (away or busy) runs again, doubling up to the most
    RETRY_S, RETRY_MAX_S = 1.0, 30.0

    def __init__(self, db: Database, store: Storage, tmp_root: Path, workers: int = 2,
                 render_processes: int = 0,
                 lease_s: float = LEASE_S) -> None:
        self.db, self.store, self.tmp_root, self.workers = db, store, Path(tmp_root), workers
        self.render_processes = render_processes
        self.lease_s = lease_s
        self.lock = RunnerLock(db)
        #: one helper process per worker thread (module docstring), started by :meth:`start`
        self.helpers: list[JobProcess] = []
        self._queue: queue.Queue[int | None] = queue.Queue()
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()

    def start(self) -> None:
        """Take the :class:`RunnerLock` (:class:`RunnerLocked` if another server has it), clear a crashed
        server's leftovers, requeue jobs left ``running``, start the threads and submit every queued job,
        oldest first; then sweep every :attr:`SWEEP_EVERY_S` seconds."""
        self.lock.acquire()
        n_tmp, n_up = clear_tmp(self.tmp_root), self.store.clear_incoming()
        if n_tmp or n_up:
            log.info("removed %d temporary session folders and %d unfinished uploads left by a crash", n_tmp, n_up)
        self._stop.clear()
        if self.render_processes > 0 and not self.helpers:
            self.helpers = [JobProcess() for _ in range(self.workers)]
        # holding the lock, every job left running was a dead server's: a zero lease requeues them all now
        pending = sweep(self.db, lease_s=0.0, redispatch_s=0.0, why="server stopped")
        for i in range(self.workers):
            t = threading.Thread(target=self._work, args=(self.helpers[i] if self.helpers else None,),
                                 name=f"chakamo-job-{i}", daemon=True)
            t.start()
            self._threads.append(t)
        for job_id in pending:
            self.submit(job_id)
        threading.Thread(target=self._sweep_loop, name="chakamo-sweeper", daemon=True).start()
        if not self.helpers:  # the jobs are computed in this process: import what they need now
            threading.Thread(target=warm_up, name="chakamo-warm-up", daemon=True).start()

    def submit(self, job_id: int) -> None:
        mark_dispatched(self.db, [job_id])
        self._queue.put(job_id)

    def _sweep_loop(self) -> None:
        while not self._stop.wait(self.SWEEP_EVERY_S):
            try:
                # only never-handed jobs: a job handed to this runner's own queue cannot be lost while it lives
                for job_id in sweep(self.db, self.lease_s, None):
                    self.submit(job_id)
            except Exception:  # noqa: BLE001 — e.g. the database is restarting: sweep again next time
                log.warning("job sweep failed; trying again in %g s", self.SWEEP_EVERY_S, exc_info=True)

    def run(self, job_id: int, helper: JobProcess | None = None) -> Outcome | None:
        """Run job ``job_id`` in the calling thread (its computation in ``helper``, if given); while the database is
        away or busy
        (:class:`~app.jobs.work.TransientJobError`), wait and run the same attempt again (module docstring).
        None when the runner stopped before it could run."""
        wait_s, attempt = self.RETRY_S, None
        while not self._stop.is_set():
            try:
                return run_job(job_id, self.db, self.store, self.tmp_root, self.lease_s, resume_attempt=attempt,
                               helper=helper)
            except TransientJobError as exc:
                attempt = exc.attempt if exc.attempt is not None else attempt
                log.warning("job %s: %s; running it again in %g s", job_id, exc, wait_s)
                self._stop.wait(wait_s)
                wait_s = min(2.0 * wait_s, self.RETRY_MAX_S)
        return None

    def _work(self, helper: JobProcess | None) -> None:
        while True:
            job_id = self._queue.get()
            if job_id is None or self._stop.is_set():  # a queued job left here stays queued in the database
                return
            try:
                self.run(job_id, helper)
            except Exception:  # noqa: BLE001 — an unexpected error outside the job's own handling: keep the worker
                log.exception("worker could not run job %s (the sweeper runs it again)", job_id)

    def problem(self) -> str | None:
        if not self._threads or not any(t.is_alive() for t in self._threads):
            return "the job workers are not running"
        return None

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
        for helper in self.helpers:
            helper.shutdown()
        self.helpers = []
        if not alive:  # a thread still running its job keeps the lock: no other runner may take that job over
            self.lock.release()
        return not alive


__all__ = ["RunnerLock", "RunnerLocked", "ThreadJobRunner", "clear_tmp"]
