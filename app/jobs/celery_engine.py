"""The distributed job engine: Celery workers fed through a Redis broker (``CHAKAMO_JOB_BACKEND=celery``).

Who does what:

* The API server (:class:`CeleryJobRunner`, chosen by :func:`app.web.main.create_app`) never runs a job.  The
  process route commits the ``jobs`` row, then ``submit`` hands the id to a dispatcher thread that publishes
  one message per job (task :data:`TASK` on queue :data:`QUEUE`) — off the request path, so a broker that is
  down delays processing but never an upload or a request: the job stays ``queued`` in the database and the
  sweeper (:func:`app.jobs.work.sweep`, every :attr:`CeleryJobRunner.SWEEP_EVERY_S` s) publishes it again once the
  broker answers.  The database, not the broker, is the record of every job.
* ``chakamo worker`` (:func:`run_worker`) runs a Celery worker (prefork pool, ``--concurrency``); each pool
  process opens its own database engine after the fork (:func:`_context`) and calls :func:`app.jobs.work.run_job`.
  The worker's main process sweeps too, so a cohort queued by ``chakamo reprocess`` with no API server
  running still recovers from lost workers and lost messages.

Delivery guarantees (Celery settings in :func:`make_celery`):

* late acknowledgement (``task_acks_late``): a message is acknowledged only after :func:`run_job` returned,
  so a worker killed mid-job leaves it unacknowledged; ``task_reject_on_worker_lost`` requeues it at once
  when only a pool process died, and Redis delivers it again after ``CHAKAMO_BROKER_VISIBILITY_TIMEOUT_S``
  when the whole worker died.  Either way the job's heartbeat stops and the sweeper queues and publishes it
  again after ``CHAKAMO_JOB_LEASE_S`` — whichever comes first runs it; the other finds it claimed or done.
* retries with exponential back-off and jitter (:func:`backoff_s`): when the database is unreachable
  (:class:`app.jobs.work.TransientJobError`) and when the job is still held by a worker whose lease has not yet
  expired (``busy``).
* idempotent: :func:`app.jobs.work.claim` is a conditional UPDATE and an analysis is unique per job, so a message
  delivered twice runs the job once; artefacts are content-addressed blobs written by atomic rename
  (:mod:`app.store.blobs`), so a job cut short leaves nothing half-written, and a retried job yields
  byte-identical artefacts (processing is deterministic).
* one message per worker process at a time (``worker_prefetch_multiplier = 1``): a job waits in Redis, not in
  a busy worker's buffer, while another worker is free.
"""

from __future__ import annotations

import logging
import os
import queue
import random
import shutil
import socket
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from app.store.database import Database
from app.jobs.work import TransientJobError, mark_dispatched, run_job, sweep
from app.settings import Settings
from app.store.blobs import Storage, open_storage

log = logging.getLogger("chakamo.celery")

#: the Celery task name and queue of a processing job
TASK = "chakamo.process_job"
QUEUE = "chakamo"
#: retries of one message (then the sweeper's re-dispatch takes over); back-off cap in seconds
MAX_RETRIES = 20
BACKOFF_MAX_S = 60.0


def backoff_s(retries: int, *, cap_s: float = BACKOFF_MAX_S) -> float:
    """Delay before retry number ``retries + 1``: 1, 2, 4, … s capped at ``cap_s``, with ±25 % jitter (so the
    retries of many jobs after one outage do not arrive together)."""
    base = min(cap_s, 2.0 ** retries)
    return base * random.uniform(0.75, 1.25)


def make_celery(settings: Settings):
    """A Celery application for ``settings`` (broker ``CHAKAMO_BROKER_URL``), with the task registered."""
    from celery import Celery

    celery = Celery("chakamo", broker=settings.broker_url, set_as_current=False)
    celery.conf.update(
        task_acks_late=True,
        task_reject_on_worker_lost=True,
        task_acks_on_failure_or_timeout=True,
        worker_prefetch_multiplier=1,
        task_default_queue=QUEUE,
        task_ignore_result=True,           # the job row in the database is the result
        task_serializer="json",
        accept_content=["json"],
        broker_connection_retry_on_startup=True,
        broker_connection_max_retries=None,  # a worker waits for a restarted broker instead of exiting
        broker_transport_options={"visibility_timeout": settings.broker_visibility_timeout_s,
                                  "socket_connect_timeout": 2, "socket_timeout": 30},
        broker_connection_timeout=2,
        task_time_limit=settings.job_time_limit_s,  # a hung job: its pool process is killed, the lease takes over
        broker_pool_limit=4,
        worker_hijack_root_logger=False,
        worker_send_task_events=False,
        worker_cancel_long_running_tasks_on_connection_loss=False,
    )

    @celery.task(name=TASK, bind=True, acks_late=True, reject_on_worker_lost=True, max_retries=MAX_RETRIES)
    def process_job(task, job_id: int, resume_attempt: int | None = None) -> str:
        ctx = _context()
        try:
            outcome = run_job(int(job_id), ctx.db, ctx.store, ctx.tmp_root, ctx.settings.job_lease_s,
                              resume_attempt=resume_attempt)
        except TransientJobError as exc:  # the retry resumes the same run: an outage is not one of its attempts
            log.warning("%s; retrying", exc)
            raise task.retry(exc=exc, countdown=backoff_s(task.request.retries),
                             args=[int(job_id)], kwargs={"resume_attempt": exc.attempt or resume_attempt}) from exc
        if outcome == "busy":  # another worker holds it; its lease decides (the sweeper requeues a lost one)
            raise task.retry(countdown=max(1.0, ctx.settings.job_lease_s / 2), args=[int(job_id)],
                             kwargs={"resume_attempt": resume_attempt})
        return outcome

    return celery


def _ask_broker(settings: Settings, command: str, *args, timeout_s: float = 2.0):
    """Redis ``command`` on the broker, answered within ``timeout_s``; raises ``redis.RedisError``/``OSError``."""
    import redis

    client = redis.Redis.from_url(settings.broker_url, socket_connect_timeout=timeout_s, socket_timeout=timeout_s)
    try:
        return client.execute_command(command, *args)
    finally:
        client.close()


def broker_problem(settings: Settings) -> str | None:
    """None when the Redis broker answers a PING, else a sentence (``/readyz``)."""
    import redis

    try:
        _ask_broker(settings, "PING")
    except (redis.RedisError, OSError) as exc:
        return f"the job broker is unreachable ({type(exc).__name__})"
    return None


class CeleryJobRunner:
    """:class:`app.jobs.work.JobRunner` of the distributed engine: publishes jobs, sweeps, runs none (module docstring)."""

    SWEEP_EVERY_S = 5.0

    def __init__(self, db: Database, settings: Settings) -> None:
        self.db, self.settings = db, settings
        self.celery = make_celery(settings)
        self._pending: queue.Queue[int | None] = queue.Queue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="chakamo-dispatcher", daemon=True)
        self._thread.start()

    def submit(self, job_id: int) -> None:
        self._pending.put(job_id)

    def publish(self, job_id: int) -> bool:
        """Send job ``job_id`` to the workers now; False (logged) when the broker cannot take it."""
        try:
            self.celery.send_task(TASK, args=[int(job_id)], queue=QUEUE, retry=False)
        except Exception as exc:  # noqa: BLE001 — kombu/redis errors: the sweeper publishes it again later
            log.warning("job %s not handed to the broker (%s); it stays queued and is sent again", job_id, exc)
            return False
        mark_dispatched(self.db, [job_id])
        return True

    def _loop(self) -> None:
        next_sweep = 0.0
        while not self._stop.is_set():
            try:
                job_id = self._pending.get(timeout=self.SWEEP_EVERY_S)
            except queue.Empty:
                job_id = None
            if self._stop.is_set():
                return
            try:
                if job_id is not None:
                    self.publish(job_id)
                now = time.monotonic()
                if now >= next_sweep:
                    next_sweep = now + self.SWEEP_EVERY_S
                    # re-send stale jobs only while the broker's queue is empty: a job still waiting its turn
                    # behind a backlog is not lost, and re-sending it would only multiply messages
                    backlog = self.queue_length()
                    redispatch = self.settings.redispatch_s if backlog == 0 else None
                    for jid in sweep(self.db, self.settings.job_lease_s, redispatch):
                        if not self.publish(jid):
                            break  # the broker is down: try again at the next sweep
            except Exception:  # noqa: BLE001 — e.g. the database is restarting: the next round tries again
                log.warning("job dispatch round failed; trying again", exc_info=True)
                self._stop.wait(1.0)

    def queue_length(self) -> int | None:
        """Messages waiting in the broker's queue (None when the broker does not answer)."""
        import redis

        try:
            return int(_ask_broker(self.settings, "LLEN", QUEUE))
        except (redis.RedisError, OSError):
            return None

    def problem(self) -> str | None:
        return broker_problem(self.settings)

    def shutdown(self, wait: bool = True) -> bool:
        self._stop.set()
        self._pending.put(None)
        if wait and self._thread is not None:
            self._thread.join(10.0)
        return True


# --- the worker side -----------------------------------------------------------------------------------------


@dataclass
class _Context:
    pid: int
    settings: Settings
    db: Database
    store: Storage
    tmp_root: Path


_ctx: _Context | None = None


def _tmp_name(pid: int) -> str:
    return f"worker-{socket.gethostname()}-{pid}"


def _context() -> _Context:
    """This process' database, blob store and temporary folder, made after the fork (one per pool process)."""
    global _ctx
    if _ctx is None or _ctx.pid != os.getpid():
        from app.settings import get_settings

        settings = get_settings()
        tmp_root = settings.tmp_dir / _tmp_name(os.getpid())
        tmp_root.mkdir(parents=True, exist_ok=True)
        _ctx = _Context(os.getpid(), settings, Database(settings.db_url), open_storage(settings), tmp_root)
    return _ctx


def clear_dead_workers_tmp(tmp_dir: Path) -> int:
    """Remove the temporary folders of this host's worker processes that no longer run; returns how many."""
    n = 0
    prefix = f"worker-{socket.gethostname()}-"
    for p in tmp_dir.glob(prefix + "*") if tmp_dir.is_dir() else ():
        try:
            pid = int(p.name[len(prefix):])
        except ValueError:
            continue
        try:
            os.kill(pid, 0)
            continue  # alive (this host's process table)
        except ProcessLookupError:
            pass
        except PermissionError:
            continue
        shutil.rmtree(p, ignore_errors=True)
        n += 1
    return n


def run_worker(settings: Settings, concurrency: int | None = None, loglevel: str = "INFO") -> None:
    """``chakamo worker``: a Celery worker of this deployment until stopped (SIGTERM: warm shutdown, the
    running jobs finish; SIGKILL: their messages are delivered again, module docstring)."""
    if settings.job_backend != "celery":
        raise ValueError("chakamo worker runs the distributed jobs: set CHAKAMO_JOB_BACKEND=celery and "
                         "CHAKAMO_BROKER_URL=redis://HOST:6379/0 (the embedded `chakamo serve` needs no worker)")
    from celery import signals

    settings.tmp_dir.mkdir(parents=True, exist_ok=True)
    n = clear_dead_workers_tmp(settings.tmp_dir)
    if n:
        log.info("removed %d temporary folders of worker processes that died", n)
    celery = make_celery(settings)
    sweeper: dict[str, CeleryJobRunner] = {}

    def on_ready(**_):
        runner = CeleryJobRunner(Database(settings.db_url), settings)
        runner.start()
        sweeper["runner"] = runner

    def on_shutdown(**_):
        runner = sweeper.pop("runner", None)
        if runner is not None:
            runner.shutdown()
            runner.db.dispose()

    def on_child(**_):
        global _ctx
        _ctx = None  # never reuse the parent's engine after the fork

    signals.worker_ready.connect(on_ready, weak=False)
    signals.worker_shutdown.connect(on_shutdown, weak=False)
    signals.worker_process_init.connect(on_child, weak=False)
    argv = ["worker", f"--concurrency={concurrency or settings.workers}", f"--loglevel={loglevel}",
            f"--queues={QUEUE}", f"--hostname=chakamo-{os.getpid()}@%h", "--without-gossip", "--without-mingle",
            "--pool=prefork"]
    celery.worker_main(argv)


__all__ = ["MAX_RETRIES", "QUEUE", "TASK", "CeleryJobRunner", "backoff_s", "broker_problem",
           "clear_dead_workers_tmp", "make_celery", "run_worker"]
