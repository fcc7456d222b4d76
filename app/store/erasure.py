"""Reference-counted erasure of stored files, crash-safe, with a record that survives it.

A blob (:mod:`app.store.blobs`) is named by the rows that use its content: recordings and artefacts, of any
clinic (equal content is stored once).  Its *reference count* is the number of those rows,
``n(sha) = |{recording: sha256 = sha}| + |{artefact: sha256 = sha}|``, counted from the rows themselves under a
lock at the moment of erasure — never a stored counter, which every writer (uploads, jobs) would have to keep
right and which a crash could leave wrong.  When a deletion (a recording, a session, a patient, the retention
policy) removes rows, the blobs they named are candidates; a blob is erased only when ``n(sha) = 0``, so a
recording uploaded twice (two sessions, or two clinics, with the same bytes) keeps its file while either remains.

Order (each step a transaction; a crash between any two leaves a state the next step or the sweep completes):

1. **mark** (:func:`mark`), in the deleting request's own transaction: the rows go and one ``pending``
   :class:`~app.store.models.BlobErasure` per candidate blob is added, linked to the request's audit event
   (``delete``: who, when, which patient and session).  Commit.  From here the deletion stands.
2. **erase** (:func:`erase_pending`), right after the commit, one blob per transaction: claim the pending row
   (an UPDATE — on SQLite the first write takes the database's write lock), lock the blob's row (``SELECT … FOR
   UPDATE`` on PostgreSQL), count the references again; if any (the same content uploaded again meanwhile)
   the mark becomes ``kept``; else the blob row is deleted, the file unlinked (:meth:`BlobStore.remove`, the
   folder fsynced) and the mark becomes ``erased``.  Commit.  The unlink happens *inside* the transaction that
   holds the lock on purpose: an upload of the same bytes takes the same lock before it places its file
   (:func:`app.store.recordings.store_upload`), so the two cannot interleave as "uploader finds the file, eraser
   unlinks it, uploader commits a row naming a missing file".  A crash after the unlink and before the commit
   leaves the mark ``pending`` and the blob row in place with no file: the next :func:`erase_pending` finds no
   reference, deletes the row, finds the file already gone, and records ``erased``.
3. **sweep** (:func:`sweep`: the API server's housekeeping at start and hourly, ``chakamo retention --apply``):
   pending marks (a crash between 1 and 2), blob rows no row references (deletions made before this module
   existed), and files on disk that no blob row names and that are older than ``grace_s`` (a writer places
   its file, under the blob's lock, a moment before its row commits: :func:`reserve_blobs`) are erased, each
   with a mark of reason ``orphan``.

Every writer places its file only under the blob's lock (:func:`reserve_blobs`): an upload
(:func:`app.store.recordings.store_upload`) and a job storing its artefacts (:func:`app.jobs.work.run_job`,
whose bytes may equal another session's artefact that is being erased), and :meth:`BlobWriter.commit` refreshes the modification time of a file it finds already stored, which the eraser
reads: a file touched after its mark was made is left for the next sweep instead of being unlinked (for
:data:`ORPHAN_GRACE_S` at most: a writer that never committed its row leaves a file that is erased after it).

The record: the audit event says who erased which patient's or session's data and when (``app.web.audit``;
the CLI and the retention policy add theirs with actor kind ``operator``); the ``blob_erasures`` rows say which
contents went (sha256, size, state, when) — never the content, nor the file names, which are patient data.
Neither has a foreign key to the rows erased, so both outlive them.
"""

from __future__ import annotations

import datetime as dt
import logging
import time
from collections.abc import Iterable
from dataclasses import dataclass, field

from sqlalchemy import func, select, update
from sqlalchemy.orm import Session

from app.store.blobs import Storage
from app.store.database import Database
from app.store.models import Artefact, Blob, BlobErasure, Recording, utcnow

log = logging.getLogger("chakamo.erasure")

#: why a blob lost its last reference (``BlobErasure.reason``)
REASONS = ("recording", "session", "patient", "retention", "orphan")
#: a file on disk no blob row names is left alone this long (its writer may not have committed its row yet)
ORPHAN_GRACE_S = 3600.0


@dataclass
class ErasureCounts:
    """What one :func:`erase_pending` or :func:`sweep` did."""

    erased: int = 0
    kept: int = 0
    deferred: int = 0
    bytes_erased: int = 0
    ids: list[int] = field(default_factory=list)

    def add(self, other: "ErasureCounts") -> "ErasureCounts":
        self.erased += other.erased
        self.kept += other.kept
        self.deferred += other.deferred
        self.bytes_erased += other.bytes_erased
        self.ids += other.ids
        return self


def references(db: Session, sha256: str) -> int:
    """``n(sha)``: the recordings and artefacts naming blob ``sha256`` (module docstring)."""
    n_rec = db.scalar(select(func.count()).select_from(Recording).where(Recording.sha256 == sha256))
    n_art = db.scalar(select(func.count()).select_from(Artefact).where(Artefact.sha256 == sha256))
    return int(n_rec) + int(n_art)


def session_blobs(db: Session, session_ids: Iterable[int]) -> set[str]:
    """The blobs the recordings and artefacts of ``session_ids`` name (read before deleting them)."""
    from app.store.models import Analysis

    ids = list(session_ids)
    if not ids:
        return set()
    recs = db.scalars(select(Recording.sha256).where(Recording.session_id.in_(ids)))
    arts = db.scalars(select(Artefact.sha256).join(Analysis, Analysis.id == Artefact.analysis_id)
                      .where(Analysis.session_id.in_(ids)))
    return set(recs) | set(arts)


def mark(db: Session, shas: Iterable[str], *, reason: str, actor: str, clinic_id: int | None = None,
         patient_id: int | None = None, session_id: int | None = None,
         audit_event_id: int | None = None) -> list[int]:
    """Step 1: a ``pending`` erasure per blob of ``shas`` in ``db``'s transaction (the one deleting the rows);
    returns their ids for :func:`erase_pending`.  ValueError for a reason outside :data:`REASONS`."""
    if reason not in REASONS:
        raise ValueError(f"unknown erasure reason {reason!r}; use one of {', '.join(REASONS)}")
    shas = sorted(set(shas))
    if not shas:
        return []
    sizes = dict(db.execute(select(Blob.sha256, Blob.size_bytes).where(Blob.sha256.in_(shas))).all())
    rows = [BlobErasure(sha256=sha, size_bytes=sizes.get(sha), state="pending", reason=reason, actor=actor[:320],
                        clinic_id=clinic_id, patient_id=patient_id, session_id=session_id,
                        audit_event_id=audit_event_id, requested_at=utcnow()) for sha in shas]
    db.add_all(rows)
    db.flush()
    return [r.id for r in rows]


def lock_blob(db: Session, sha256: str) -> Blob | None:
    """The blob's row (None if there is none), locked until ``db``'s transaction ends (PostgreSQL ``SELECT …
    FOR UPDATE``; SQLite holds the database's write lock from the transaction's first write): writers placing a
    file take it after reserving the row, the eraser before counting references (module docstring)."""
    return _lock_blobs(db, [sha256]).get(sha256)


def _lock_blobs(db: Session, shas: list[str]) -> dict[str, Blob]:
    """:func:`lock_blob` of each of ``shas`` in one statement, locked in sha256 order (two writers locking
    overlapping sets on PostgreSQL take them in the same order: no deadlock)."""
    stmt = select(Blob).where(Blob.sha256.in_(shas)).order_by(Blob.sha256)
    if db.get_bind().dialect.name == "postgresql":
        stmt = stmt.with_for_update()
    return {b.sha256: b for b in db.scalars(stmt.execution_options(populate_existing=True))}


def reserve_blobs(db: Session, blobs: list[tuple[str, int]]) -> dict[str, Blob]:
    """The row of each ``(sha256, size_bytes)`` of ``blobs``, added if missing and locked until ``db``'s transaction
    ends (``{sha256: row}``): what a writer holds before it places the files (an upload, a job's artefacts, a signed
    report).  When an eraser deleted a row while this waited for its lock (PostgreSQL: the row existed when it was
    ensured, was gone once the lock was granted), it is added again and locked again, so each file placed next is
    named by a row this transaction holds.  Two statements for all the rows (two more per such retry): on SQLite
    every statement here is made holding the database's one write lock, which every other writer — the reads'
    audit batches among them — waits for (issue 16: an upload's 24 files, one reservation and placement each, held
    it for 260–850 ms during the 20-clinician burst)."""
    from app.store.database import ensure_blobs

    sizes = dict(blobs)
    held: dict[str, Blob] = {}
    missing = sorted(sizes)
    for _ in range(5):  # twice at most in practice: a row this transaction added is seen by no eraser
        if not missing:
            return held
        ensure_blobs(db, [(sha, sizes[sha]) for sha in missing])
        held |= _lock_blobs(db, missing)
        missing = sorted(set(sizes) - set(held))
    if missing:
        raise RuntimeError(f"the row of stored file {missing[0][:12]}… could not be reserved")
    return held


def _erase_one(database: Database, store: Storage, erasure_id: int) -> str:
    """Step 2 for one mark: ``erased``, ``kept``, ``deferred`` (file touched after the mark) or ``gone`` (done
    by another process)."""
    with database.session() as db:
        now = utcnow()
        claimed = db.execute(update(BlobErasure).where(BlobErasure.id == erasure_id, BlobErasure.state == "pending")
                             .values(done_at=now)).rowcount  # the first write: takes the lock (SQLite)
        if not claimed:
            return "gone"
        row = db.get(BlobErasure, erasure_id, populate_existing=True)
        blob = lock_blob(db, row.sha256)
        if references(db, row.sha256):
            row.state = "kept"
            return "kept"
        if blob is not None:
            mtime = _mtime(store, row.sha256)
            if mtime is not None and mtime > row.requested_at.timestamp() and time.time() - mtime < ORPHAN_GRACE_S:
                row.done_at = None  # rewritten after the mark (module docstring): the next sweep decides
                return "deferred"
            db.delete(blob)
            db.flush()
            store.remove(row.sha256)  # inside the locked transaction (module docstring)
        row.state = "erased"
        return "erased"


def _mtime(store: Storage, sha256: str) -> float | None:
    path = getattr(store, "path", None)
    if path is None:
        return None
    try:
        return path(sha256).stat().st_mtime
    except FileNotFoundError:
        return None


def erase_pending(database: Database, store: Storage, ids: Iterable[int] | None = None) -> ErasureCounts:
    """Step 2 for the marks ``ids`` (None: every pending one, oldest first).  A mark that fails (an I/O error)
    stays pending for the next sweep and is logged; the others go on."""
    if ids is None:
        with database.session() as db:
            ids = list(db.scalars(select(BlobErasure.id).where(BlobErasure.state == "pending")
                                  .order_by(BlobErasure.id)))
    counts = ErasureCounts()
    for erasure_id in ids:
        try:
            outcome = _erase_one(database, store, erasure_id)
        except OSError:
            log.exception("erasure %s failed; the sweep tries again", erasure_id)
            counts.deferred += 1
            continue
        if outcome == "erased":
            counts.erased += 1
            counts.ids.append(erasure_id)
            with database.session() as db:
                counts.bytes_erased += db.get(BlobErasure, erasure_id).size_bytes or 0
        elif outcome == "kept":
            counts.kept += 1
        elif outcome == "deferred":
            counts.deferred += 1
    return counts


def sweep(database: Database, store: Storage, *, grace_s: float = ORPHAN_GRACE_S,
          now: dt.datetime | None = None) -> ErasureCounts:
    """Step 3 (module docstring): pending marks, unreferenced blob rows and unnamed files older than ``grace_s``."""
    now = now or utcnow()
    counts = erase_pending(database, store)
    cutoff = now - dt.timedelta(seconds=grace_s)
    with database.session() as db:
        unreferenced = list(db.scalars(
            select(Blob.sha256).where(Blob.created_at < cutoff,
                                      ~select(Recording.id).where(Recording.sha256 == Blob.sha256).exists(),
                                      ~select(Artefact.id).where(Artefact.sha256 == Blob.sha256).exists())))
        ids = mark(db, unreferenced, reason="orphan", actor="erasure sweep")
    counts.add(erase_pending(database, store, ids))
    # files without a row: read the rows after listing the files, so a row committed meanwhile is seen
    on_disk = [(sha, mtime) for sha, mtime in store.stored() if mtime < time.time() - grace_s]
    if on_disk:
        with database.session() as db:
            named = set(db.scalars(select(Blob.sha256).where(Blob.sha256.in_([sha for sha, _ in on_disk]))))
        for sha, _ in on_disk:
            if sha in named:
                continue
            with database.session() as db:
                row = BlobErasure(sha256=sha, size_bytes=_size(store, sha), state="erased", reason="orphan",
                                  actor="erasure sweep", requested_at=now, done_at=utcnow())
                db.add(row)
                db.flush()  # the first write: takes the lock (SQLite) before looking again
                mtime = _mtime(store, sha)
                if lock_blob(db, sha) is not None or mtime is None or mtime > time.time() - grace_s:
                    db.rollback()  # its writer committed, or touched it, meanwhile
                    continue
                store.remove(sha)
                counts.erased += 1
                counts.bytes_erased += row.size_bytes or 0
    if counts.erased or counts.kept:
        log.info("erasure: %d stored files erased (%d bytes), %d kept (still referenced)", counts.erased,
                 counts.bytes_erased, counts.kept)
    return counts


def _size(store: Storage, sha256: str) -> int | None:
    try:
        return store.path(sha256).stat().st_size
    except (AttributeError, OSError):
        return None


def erasure_log(db: Session, clinic_id: int, limit: int = 100) -> list[BlobErasure]:
    """The clinic's erasure records, newest first (the orphan sweep's carry no clinic)."""
    return list(db.scalars(select(BlobErasure).where(BlobErasure.clinic_id == clinic_id)
                           .order_by(BlobErasure.id.desc()).limit(limit)))


__all__ = ["ORPHAN_GRACE_S", "REASONS", "ErasureCounts", "erase_pending", "erasure_log", "lock_blob", "mark", "references",
           "reserve_blobs", "session_blobs", "sweep"]
