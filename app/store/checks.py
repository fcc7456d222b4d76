"""The ingestion check of a session's stored files: run it, store it if the files did not change meanwhile,
and redo it when the stored one is stale.

Every change of a session's files bumps its ``files_version`` in the same transaction; a check is stored with
the version it was computed from and only if that is still the current one (:func:`save_ingestion`: one
conditional UPDATE), so a slower, older check can never overwrite a newer one.  A session whose stored check
is stale (:func:`app.store.sessions.ingestion_fresh`) is checked again when it is read or processed
(:meth:`IngestionChecker.ensure_fresh`).  The check itself (:func:`app.store.workspace.check_ingestion`)
runs the pipeline's ingestion over the stored files; it is CPU-bound, so at most :data:`CHECK_CONCURRENCY`
run at once per process, holding no database connection, and with a warm helper process (the server's
:class:`app.pipeline.render.RenderPool`) they run there, off this process' GIL.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import update
from sqlalchemy.orm import Session

from app.store.blobs import BlobStore
from app.store.database import Database
from app.store.models import KneeSession
from app.store.sessions import ingestion_fresh
from app.store.workspace import check_ingestion

log = logging.getLogger("chakamo.uploads")

#: the upload's answer when its files are stored but their check could not run (it runs again later)
CHECK_DEFERRED = ("The files are stored, but the server could not check them now; the check runs again when the "
                  "session is opened or processed.")
#: ingestion checks (CPU-bound, holding the GIL most of the time) running at once in one server process; the
#: others wait their turn, holding no database connection, so that reads keep their share of the processor
CHECK_CONCURRENCY = 1
_check_slots = threading.BoundedSemaphore(CHECK_CONCURRENCY)
#: longest wait for the check in the helper process before it runs here instead
CHECK_TIMEOUT_S = 120.0


def save_ingestion(db_: Database, session_id: int, version: int, ingestion: dict) -> bool:
    """Store ``ingestion`` (computed from the files of ``version``) unless the files changed since; True if
    stored.  One conditional UPDATE: a check of older files never overwrites a newer one."""
    with db_.session() as db:
        res = db.execute(update(KneeSession).where(KneeSession.id == session_id, KneeSession.files_version == version)
                         .values(ingestion=ingestion, ingestion_version=version))
        return res.rowcount == 1


def refresh_ingestion(db_: Database, store: BlobStore, tmp_dir: Path, session_id: int, pool=None) -> dict[str, Any]:
    """Run the ingestion over the session's stored files (no database connection held meanwhile; at most
    :data:`CHECK_CONCURRENCY` at once), store the result if the files did not change meanwhile
    (:func:`save_ingestion`) and return it.  With ``pool`` (a warm helper process,
    :class:`app.pipeline.render.RenderPool`) the check runs there, so its CPU time does not hold this process'
    GIL; without it, or while it is not warm, it runs here."""
    with db_.session() as db:
        session = db.get(KneeSession, session_id)
        version = session.files_version
        patient, recordings = session.patient, list(session.recordings)
        db.expunge_all()
    with _check_slots:
        future = pool.submit(check_ingestion, store, tmp_dir, session, patient, recordings) if pool else None
        try:
            ingestion = future.result(CHECK_TIMEOUT_S) if future is not None else None
        except Exception:  # noqa: BLE001 — a hung or broken helper: replace it, and check here instead
            log.warning("ingestion check of session %s failed in the helper process; checking here", session_id,
                        exc_info=True)
            future.cancel()
            pool.restart()
            ingestion = None
        if ingestion is None:
            ingestion = check_ingestion(store, tmp_dir, session, patient, recordings)
    save_ingestion(db_, session_id, version, ingestion)
    return ingestion


@dataclass(frozen=True)
class IngestionChecker:
    """What a check needs: the database, the blob store, the temporary folder and the helper pool (or None)."""

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
            return {"ok": False, "messages": [], "error": CHECK_DEFERRED}

    def ensure_fresh(self, db: Session, session: KneeSession) -> None:
        """When the stored check of ``session`` (a row of ``db``) is stale, check its files again with no
        transaction of ``db`` held meanwhile (``db`` is rolled back first), then reload ``session``."""
        if ingestion_fresh(session) or not session.recordings:
            return
        db.rollback()  # the check may take seconds: no open transaction (nor row lock) while it runs
        self.refresh(session.id)
        db.refresh(session)


__all__ = ["CHECK_CONCURRENCY", "CHECK_DEFERRED", "CHECK_TIMEOUT_S", "IngestionChecker", "refresh_ingestion",
           "save_ingestion"]
