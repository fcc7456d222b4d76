"""The ingestion check of a session's stored files: run it, store it if the files did not change meanwhile,
and redo it when the stored one is stale.

Every change of a session's files bumps its ``files_version`` in the same transaction; a check is stored with
the version it was computed from and only if that is still the current one (:func:`save_ingestion`: one
conditional UPDATE), so a slower, older check can never overwrite a newer one.  A session whose stored check
is stale (:func:`app.store.sessions.ingestion_fresh`) is checked again when it is read or processed
(:meth:`IngestionChecker.ensure_fresh`).  The check itself (:func:`app.store.workspace.check_ingestion`)
runs the pipeline's ingestion over the stored files; it is CPU-bound and holds no database connection.

Fairness (issue 16, finding 4: one clinic's crafted files delayed every clinic's checks, which ran one at a
time server-wide): :data:`CHECK_GATE` lets one clinic run at most :data:`CHECKS_PER_CLINIC` check at a time
and the server :data:`CHECK_CONCURRENCY`; a clinic's further checks wait for its own slot, never holding one
of the others'.  With helper processes (:class:`CheckPool`, ``CHAKAMO_CHECK_PROCESSES`` of them when
``CHAKAMO_RENDER_PROCESSES`` > 0) the server's share is the number of helpers (the pool's own gate,
:attr:`CheckPool.gate`) and each check runs in a free one, off this process' GIL, so two clinics'
checks run side by side.  A check that takes longer than :data:`CHECK_TIMEOUT_S` has its helper replaced
(the only case a helper is restarted: a check that raises leaves its helper as it is) and is answered
``session.check_too_slow``, stored for those files: it is never run again in this process (which is what it
would stall) nor again for the same files.  A helper that died under a check is replaced the same way and
that check answered ``session.check_stopped``.

With helpers, no check runs in this process, ever: a check whose helper is still starting (the server's
start, or the replacement after a time-out) or is found dead while idle (replaced then) waits for it within
its :data:`CHECK_WAIT_S` (:meth:`app.pipeline.render.RenderPool.submit`).  Before, such a check ran in the
request thread with no time limit, so the next crafted upload right after a time-out stalled the API
process itself (issue 16, finding 4, from the audit).  A check runs in the calling thread, without a time
limit, only where there is no helper by design: a server configured without them (``CHAKAMO_RENDER_PROCESSES``
or ``CHAKAMO_CHECK_PROCESSES`` 0, the operator's choice) and the operator's command line (``chakamo
reprocess``, :mod:`app.jobs.reprocess`: no request, no pool).  No check waits for a slot or a helper longer
than :data:`CHECK_WAIT_S` (the checks ahead of it finish, or are stopped, within :data:`CHECK_TIMEOUT_S`; a
helper starts in seconds): past that it is answered ``session.check_busy``, not stored, and runs again when
the session is opened or processed.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

from sqlalchemy import bindparam, update
from sqlalchemy.orm import Session

from app.pipeline.service_messages import item, item_texts, render
from app.store.blobs import BlobStore
from app.store.database import Database
from app.store.models import KneeSession, Recording
from app.store.sessions import ingestion_fresh
from app.store.pairing import partner_files
from app.store.workspace import check_ingestion

log = logging.getLogger("chakamo.uploads")

#: longest a check waits for its clinic's and the server's slots; then it is answered ``session.check_busy``
CHECK_WAIT_S = 75.0
#: the upload's answer when its files are stored but their check could not run (it runs again later)
CHECK_DEFERRED = render("session.check_deferred", {})
#: ingestion checks running at once in one server process, over all clinics, when they run in the request
#: threads (no helper processes); with helpers, their number (``CHAKAMO_CHECK_PROCESSES``: :attr:`CheckPool.gate`)
CHECK_CONCURRENCY = 2
#: of which one clinic may run at most this many: its other checks wait for it, not for the others
CHECKS_PER_CLINIC = 1
#: longest a check may take in a helper process; then it is stopped and answered ``session.check_too_slow``
CHECK_TIMEOUT_S = 60.0


def _failed(code: str, **params: Any) -> dict[str, Any]:
    text = render(code, params, "en")
    return {"ok": False, "messages": [], "error": text, "error_item": item(code, params, text)}


def ingestion_view(stored: dict[str, Any]) -> dict[str, Any]:
    """A stored check as the API answers it: as stored, plus ``message_texts`` and ``error_message`` (every
    language, :func:`app.pipeline.service_messages.item_texts`, from the codes stored in ``items`` and
    ``error_item``; a check stored before them shows its English text in every language) and ``splits``."""
    items = stored.get("items")
    if items is None:
        items = list(stored.get("messages") or [])
    error = stored.get("error_item") or stored.get("error")
    return {"ok": bool(stored.get("ok")), "messages": list(stored.get("messages") or []), "error": stored.get("error"),
            "message_texts": [item_texts(i) for i in items], "error_message": item_texts(error) if error else None,
            "splits": stored.get("splits") or {}}


class CheckBusy(Exception):
    """No slot became free, or no helper warm, within the wait's bound (module docstring)."""


class CheckGate:
    """At most ``per_clinic`` checks of one clinic and ``total`` of all clinics at once (module docstring)."""

    def __init__(self, total: int, per_clinic: int) -> None:
        self.total, self.per_clinic = total, per_clinic
        self._all = threading.BoundedSemaphore(total)
        self._clinics: dict[Any, threading.BoundedSemaphore] = {}
        self._lock = threading.Lock()

    @contextmanager
    def slot(self, clinic_id: Any, wait_s: float = CHECK_WAIT_S) -> Iterator[None]:
        """Hold one of ``clinic_id``'s slots, then one of the server's, for the block; :class:`CheckBusy` when
        both were not had within ``wait_s`` in all."""
        deadline = time.monotonic() + wait_s
        with self._lock:
            own = self._clinics.setdefault(clinic_id, threading.BoundedSemaphore(self.per_clinic))
        if not own.acquire(timeout=max(0.0, deadline - time.monotonic())):
            raise CheckBusy
        try:
            if not self._all.acquire(timeout=max(0.0, deadline - time.monotonic())):
                raise CheckBusy
            try:
                yield
            finally:
                self._all.release()
        finally:
            own.release()


#: the process' gate (one per server process: the request threads share it)
CHECK_GATE = CheckGate(CHECK_CONCURRENCY, CHECKS_PER_CLINIC)


def warm_checks() -> None:
    """In a helper process: import the ingestion and its readers before the first check needs them."""
    import app.store.workspace  # noqa: F401 — the import is the warm-up


class CheckTimedOut(Exception):
    """The check took longer than its limit; its helper process was replaced."""


class CheckStopped(Exception):
    """The server's shutdown stopped the check's helper (:meth:`RenderPool.shutdown`): no verdict on the files,
    nothing stored, and not run in the request's thread either (it would hold up the server's exit)."""


class CheckPool:
    """``processes`` single-process helpers (:class:`app.pipeline.render.RenderPool` ``(1)`` each), so that one
    hung check is stopped without stopping another clinic's, which runs in another helper."""

    def __init__(self, processes: int) -> None:
        from app.pipeline.render import RenderPool

        self.processes = processes
        #: admits as many checks at once as there are helpers (module docstring)
        self.gate = CheckGate(processes, CHECKS_PER_CLINIC)
        self.helpers = [RenderPool(1, warm=warm_checks) for _ in range(processes)]
        self._free: queue.Queue = queue.Queue()
        for helper in self.helpers:
            self._free.put(helper)

    def wait_warm(self, timeout_s: float = 120.0) -> bool:
        """Block until every helper is warm (benchmarks, tests); True if all are usable."""
        return all(h.wait_warm(timeout_s) for h in self.helpers)

    def run(self, fn, *args, timeout_s: float = CHECK_TIMEOUT_S, wait_s: float = CHECK_WAIT_S):
        """``fn(*args)`` from a free helper, never from this process (module docstring).
        :class:`CheckTimedOut` past ``timeout_s``, and :class:`BrokenProcessPool` when the helper died under
        it: either way that helper is replaced; :class:`CheckStopped` when the server's shutdown stopped it (or
        had already begun).  An exception ``fn`` raised is raised here, its helper kept; :class:`CheckBusy`
        when no helper was free and warm within ``wait_s`` (:attr:`gate` admits at most as many checks as
        there are helpers: a bound only; a helper may still be starting after a time-out)."""
        deadline = time.monotonic() + wait_s
        try:
            helper = self._free.get(timeout=wait_s)
        except queue.Empty:
            raise CheckBusy from None
        try:
            if helper.stopping:  # the server is stopping: neither a helper nor this thread runs the check
                raise CheckStopped
            future = helper.submit(fn, *args, wait_s=max(0.0, deadline - time.monotonic()))
            if future is None:
                if helper.stopping:
                    raise CheckStopped
                raise CheckBusy  # not started (or replaced) within the wait: this thread does not run it
            try:
                return future.result(timeout_s)
            except FutureTimeout:
                future.cancel()
                helper.restart()
                raise CheckTimedOut from None
            except BrokenProcessPool:
                if helper.stopping:  # shutdown() terminated it under the check: the files are not at fault
                    raise CheckStopped from None
                helper.restart()
                raise
        finally:
            self._free.put(helper)

    def shutdown(self) -> None:
        for helper in self.helpers:
            helper.shutdown()


def save_ingestion(db_: Database, session_id: int, version: int, ingestion: dict) -> bool:
    """Store ``ingestion`` (computed from the files of ``version``) unless the files changed since; True if
    stored.  One conditional UPDATE: a check of older files never overwrites a newer one.  In the same
    transaction each recording gets the sensor serial the reading found in its file (``ingestion["devices"]``,
    every format that carries one: :func:`app.store.workspace.file_facts`), over the one its name gave at upload."""
    with db_.session() as db:
        res = db.execute(update(KneeSession).where(KneeSession.id == session_id, KneeSession.files_version == version)
                         .values(ingestion=ingestion, ingestion_version=version))
        if res.rowcount != 1:
            return False
        devices = [{"b_name": name, "b_device": device} for name, device in (ingestion.get("devices") or {}).items()]
        if devices:  # one statement for every file (executemany), under the write lock no longer than that
            table = Recording.__table__
            db.connection().execute(update(table).where(table.c.session_id == session_id,
                                                        table.c.file_name == bindparam("b_name"))
                                    .values(device=bindparam("b_device")), devices)
        return True


def refresh_ingestion(db_: Database, store: BlobStore, tmp_dir: Path, session_id: int, pool=None,
                      gate: CheckGate | None = None, timeout_s: float = CHECK_TIMEOUT_S,
                      wait_s: float = CHECK_WAIT_S) -> dict[str, Any]:
    """Run the ingestion over the session's stored files (no database connection held meanwhile; within the
    clinic's and the server's slots of ``gate``), store the result if the files did not change meanwhile
    (:func:`save_ingestion`) and return it.  With ``pool`` (a :class:`CheckPool`) the check runs in a helper
    process, off this process' GIL, for at most ``timeout_s``, and never here (module docstring); only
    without one (none by design) does it run here.  ``gate``: the pool's (None), else :data:`CHECK_GATE`; no
    slot or warm helper within ``wait_s``: answered ``session.check_busy`` and not stored (module docstring)."""
    if gate is None:
        gate = getattr(pool, "gate", None) or CHECK_GATE
    with db_.session() as db:
        session = db.get(KneeSession, session_id)
        version = session.files_version
        patient, recordings = session.patient, list(session.recordings)
        paired = partner_files(db, session)  # a paired session's check reads both knees (app.store.pairing)
        db.expunge_all()
    try:
        ingestion = _check_in_slot(gate, pool, store, tmp_dir, session, patient, recordings, timeout_s, wait_s,
                                   paired)
    except CheckBusy:
        log.warning("ingestion check of session %s not run: no check slot or helper free within %.0f s",
                    session_id, wait_s)
        return _failed("session.check_busy", seconds=round(wait_s))  # not stored: checked again later
    except CheckStopped:
        log.info("ingestion check of session %s stopped by the server's shutdown; it runs again later", session_id)
        return _failed("session.check_deferred")  # not stored: a stale check is redone at the next read
    save_ingestion(db_, session_id, version, ingestion)
    return ingestion


def _check_in_slot(gate: CheckGate, pool, store: BlobStore, tmp_dir: Path, session: KneeSession, patient,
                   recordings, timeout_s: float, wait_s: float, paired=None) -> dict[str, Any]:
    session_id = session.id
    deadline = time.monotonic() + wait_s  # one bound for the slot and the helper together (module docstring)
    with gate.slot(session.clinic_id, wait_s):
        if pool is None:  # no helper by design (module docstring): here, with no time limit
            return check_ingestion(store, tmp_dir, session, patient, recordings, paired)
        try:  # in a helper or not at all: never in this thread (CheckBusy, CheckStopped go to the caller)
            return pool.run(check_ingestion, store, tmp_dir, session, patient, recordings, paired,
                            timeout_s=timeout_s, wait_s=max(0.0, deadline - time.monotonic()))
        except CheckTimedOut:
            log.warning("ingestion check of session %s stopped after %.0f s; its helper process was replaced",
                        session_id, timeout_s)
            return _failed("session.check_too_slow", seconds=round(timeout_s))
        except BrokenProcessPool:
            log.error("the helper process died checking session %s; it was replaced", session_id)
            return _failed("session.check_stopped")


@dataclass(frozen=True)
class IngestionChecker:
    """What a check needs: the database, the blob store, the temporary folder and the helper pool (None: the
    checks run in the calling thread; only where there is no pool by design, module docstring)."""

    database: Database
    store: BlobStore
    tmp_dir: Path
    pool: Any = None

    def refresh(self, session_id: int) -> dict[str, Any]:
        """:func:`refresh_ingestion` of session ``session_id``."""
        return refresh_ingestion(self.database, self.store, self.tmp_dir, session_id, self.pool)

    def refresh_or_defer(self, session_id: int, what: str) -> dict[str, Any]:
        """:meth:`refresh`, after a committed change of the files (``what`` happened, for the log, e.g.
        "upload to session 3 stored"): if the check fails
        (e.g. no database connection free) the change stands and :data:`CHECK_DEFERRED` is answered; the
        stale check is redone later."""
        try:
            return self.refresh(session_id)
        except Exception:  # noqa: BLE001
            log.warning("%s; its ingestion check failed and runs again later", what, exc_info=True)
            return _failed("session.check_deferred")

    def ensure_fresh(self, db: Session, session: KneeSession) -> None:
        """When the stored check of ``session`` (a row of ``db``) is stale, check its files again with no
        transaction of ``db`` held meanwhile (``db`` is rolled back first), then reload ``session``."""
        if ingestion_fresh(session) or not session.recordings:
            return
        db.rollback()  # the check may take seconds: no open transaction (nor row lock) while it runs
        self.refresh(session.id)
        db.refresh(session)


__all__ = ["CHECK_CONCURRENCY", "CHECK_DEFERRED", "CHECK_GATE", "CHECK_TIMEOUT_S", "CHECK_WAIT_S", "CHECKS_PER_CLINIC",
           "CheckBusy", "CheckGate",
           "CheckPool", "CheckStopped", "CheckTimedOut", "IngestionChecker", "ingestion_view", "refresh_ingestion", "save_ingestion", "warm_checks"]
