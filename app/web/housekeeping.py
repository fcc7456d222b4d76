"""Periodic housekeeping of the stored data, run by every API server whatever the job backend (:class:`Housekeeper`,
started and stopped with the application by :func:`app.web.main.create_app`): at start and hourly.

:func:`housekeeping`: the erasure sweep (:func:`app.store.erasure.sweep`: marks a crash left pending, blob rows
nothing references, files no row names), the expiry of old ``Idempotency-Key`` records and, when ``CHAKAMO_RETENTION_DAYS`` is set, the retention policy
(:mod:`app.store.retention`), whose erasures are audited as the operator (:func:`app.web.audit.record_operator`).
It lives in the web layer because the audit log's writer does; the jobs layer never calls it.

It needs only the database and the blob store, which every API server has, so it runs there and not in the job
engine: with the embedded runner and with Celery alike (issue 16, finding 8: it used to be the embedded runner's,
so a Celery deployment never applied ``CHAKAMO_RETENTION_DAYS`` nor swept).  ``chakamo worker`` runs none; a
deployment with no API server running has none either (``chakamo retention --apply`` does the same by hand).

One server at a time: the :class:`Housekeeper` of each server tries to take the housekeeping lock — a
:class:`app.jobs.inprocess.RunnerLock` of its own key: a session-level ``pg_try_advisory_lock`` on a connection of
its own on PostgreSQL, an ``flock`` on ``<database file>.housekeeping.lock`` on SQLite — and the one that got it
keeps it while it lives and does the housekeeping; the others try again every :attr:`Housekeeper.TRY_EVERY_S`
seconds, so when that server stops or dies (the lock goes with its connection or its process) another one takes
over within that time and housekeeps at once.  The lock is not what makes a run safe (the erasure and the policy
take their own locks against the requests, the jobs and ``chakamo retention --apply``): it keeps N servers from
listing the whole blob store, and recording the same orphan files, N times an hour.
"""

from __future__ import annotations

import logging
import threading
import time

log = logging.getLogger("chakamo.erasure")

#: the PostgreSQL advisory-lock key of the housekeeping ("CHKMhkep"; the job runner's is "CHKMjobs")
HOUSEKEEPING_LOCK_KEY = 0x43484B4D686B6570


def operator_recorder(actor: str):
    """A ``record`` for :func:`app.store.retention.apply_retention`: ``delete`` events of actor ``actor``."""
    from app.web.audit import record_operator

    def record(db, *, clinic_id: int, patient_id: int | None, session_id: int | None, resource: str):
        return record_operator(db, clinic_id=clinic_id, action="delete", actor=actor, resource=resource,
                               patient_id=patient_id, session_id=session_id)

    return record


def housekeeping(settings, database, store, now=None) -> None:
    """The erasure sweep, the expiry of old ``Idempotency-Key`` records, then the retention policy when it is on
    (module docstring); ``now`` fixes the clock."""
    from app.store.erasure import sweep
    from app.store.models import utcnow
    from app.store.retention import apply_retention

    sweep(database, store)
    from app.store.idempotency import forget_old

    with database.session() as db:  # Idempotency-Keys past their keeping time (app.store.idempotency)
        forget_old(db, now)
    if settings.retention_days > 0:
        report = apply_retention(database, store, settings.retention_days, now=now or utcnow(), dry_run=False,
                                 record=operator_recorder(f"retention policy ({settings.retention_days} days)"))
        if report.erased_sessions:
            log.info("retention: %d sessions erased (%d stored files)", report.erased_sessions, report.erased_files)


class Housekeeper:
    """A daemon thread of the API server: :func:`housekeeping` at start and every :attr:`EVERY_S` seconds while
    this server holds the housekeeping lock; without it, try again every :attr:`TRY_EVERY_S` seconds (module
    docstring).  ``runs`` counts the runs this server made.  ``database`` is the housekeeper's own (disposed by
    :meth:`stop`): the application gives it an engine apart from the requests', so that a run never holds one of
    the connections the requests' pool is sized for (a half-sent upload's test found one checked out by the run at
    start-up)."""

    #: seconds between two housekeeping runs (erasure sweep, retention policy)
    EVERY_S = 3600.0
    #: seconds between two attempts to take the lock another server holds (and between two checks that this
    #: server still holds it)
    TRY_EVERY_S = 60.0

    def __init__(self, settings, database, store) -> None:
        # imported here: app.jobs.inprocess brings the pipeline, which `chakamo retention` (operator_recorder) never needs
        from app.jobs.inprocess import RunnerLock

        self.settings, self.database, self.store = settings, database, store
        self.lock = RunnerLock(database, key=HOUSEKEEPING_LOCK_KEY, name="housekeeping")
        self.runs = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="chakamo-housekeeping", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 30.0) -> None:
        """Stop after the current run (if any) and free the lock for another server."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
            if self._thread.is_alive():
                log.warning("housekeeping still running at shutdown; its lock goes with the process")
                return
        self.lock.release()
        self.database.dispose()

    def holds_lock(self) -> bool:
        """Whether this server is the one that housekeeps: the lock held, or taken now."""
        from app.jobs.inprocess import RunnerLocked

        if self.lock.held():
            return True
        try:
            self.lock.acquire()
        except RunnerLocked:
            return False  # another server housekeeps
        log.info("this server now runs the housekeeping (erasure sweep, retention policy)")
        return True

    def _loop(self) -> None:
        last = None  # monotonic time of this server's last run while it held the lock; None: run at once
        while not self._stop.is_set():
            try:
                if not self.holds_lock():
                    last = None
                elif last is None or time.monotonic() - last >= self.EVERY_S:
                    last = time.monotonic()
                    housekeeping(self.settings, self.database, self.store)
                    self.runs += 1
            except Exception:  # noqa: BLE001 — e.g. the database is restarting: next time
                log.warning("housekeeping (erasure sweep, retention) failed; trying again later", exc_info=True)
            self._stop.wait(self.TRY_EVERY_S if last is None else
                            max(0.0, min(self.TRY_EVERY_S, last + self.EVERY_S - time.monotonic())))


__all__ = ["HOUSEKEEPING_LOCK_KEY", "Housekeeper", "housekeeping", "operator_recorder"]
