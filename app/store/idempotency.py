"""``Idempotency-Key``: a POST that creates something, sent again with the same key, answers what the first one
created instead of creating it twice (a retry after a lost answer, a timeout, a client restart).

The key is claimed in the transaction that creates the resource (:func:`claim`, flushed before the work): two
requests with one key race on the table's unique constraint (``clinic_id``, ``key``); the loser's whole
transaction — the resource it was creating included — rolls back, and it answers the winner's resource
(:func:`replayed`).  After the work, :func:`complete` stores the created ids in the same transaction, so a key
is remembered exactly when its resource exists.  The same key with another request (another path or body:
``request_sha256``) is :class:`KeyReused`.  Only ids are kept, never an answer's body: an erasure leaves no copy
of a patient's data behind, and a replay reads the resource as it is now.  Keys are scoped to the clinic and
kept for :data:`KEEP_DAYS` days (:func:`forget_old`, run by the housekeeping).
"""

from __future__ import annotations

import datetime as dt
import hashlib
from dataclasses import dataclass

from sqlalchemy import delete, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.store.errors import Conflict
from app.store.models import IdempotencyKey, utcnow

#: how long a key is remembered (a client retries within minutes; the IETF draft suggests at least 24 h)
KEEP_DAYS = 7
#: the longest key accepted (UUIDs are 36 characters)
MAX_KEY_LENGTH = 200


class KeyReused(Conflict):
    """The key was used for another request (another path or body)."""

    def __init__(self, key: str) -> None:
        super().__init__(code="store.key_reused", key=key)
        self.key = key


class KeyInFlight(Conflict):
    """The first request with this key has not finished yet."""

    def __init__(self, key: str) -> None:
        super().__init__(code="store.key_in_flight", key=key)


@dataclass(frozen=True)
class Replay:
    """What the first request with the key created: ``kind``, its ``resource_ids`` and the ``status`` answered."""

    kind: str
    resource_ids: list
    status: int


def fingerprint(method: str, path: str, body: bytes) -> str:
    """sha256 of the request's method, path and body (the identity a key is bound to)."""
    h = hashlib.sha256(f"{method.upper()} {path}\n".encode())
    h.update(body)
    return h.hexdigest()


def replayed(db: Session, clinic_id: int, key: str, request_sha256: str) -> Replay | None:
    """The resource key ``key`` already created (None: a new key); :class:`KeyReused` for another request,
    :class:`KeyInFlight` while the first request is still running (claimed, not completed)."""
    row = db.scalar(select(IdempotencyKey).where(IdempotencyKey.clinic_id == clinic_id, IdempotencyKey.key == key))
    if row is None:
        return None
    if row.request_sha256 != request_sha256:
        raise KeyReused(key)
    if not row.status:
        raise KeyInFlight(key)
    return Replay(row.kind, list(row.resource_ids), row.status)


def claim(db: Session, clinic_id: int, key: str, request_sha256: str, kind: str) -> IdempotencyKey | Replay:
    """Claim ``key`` in the caller's transaction before the work (module docstring): the new row, or the
    :class:`Replay` of the request that holds it (the caller's transaction is then rolled back)."""
    found = replayed(db, clinic_id, key, request_sha256)
    if found is not None:
        return found
    row = IdempotencyKey(clinic_id=clinic_id, key=key, request_sha256=request_sha256, kind=kind, resource_ids=[],
                         status=0)
    db.add(row)
    try:
        db.flush()  # on PostgreSQL a concurrent claim of the same key waits here until the first one commits
    except IntegrityError:
        db.rollback()
        found = replayed(db, clinic_id, key, request_sha256)
        if found is None:  # the holder rolled back meanwhile: the client may simply retry
            raise KeyInFlight(key) from None
        return found
    return row


def complete(row: IdempotencyKey, resource_ids: list, status: int) -> None:
    """Record what the request created (in its transaction: the key is remembered iff the resource exists)."""
    row.resource_ids, row.status = list(resource_ids), status


def forget_old(db: Session, now: dt.datetime | None = None) -> int:
    """Delete keys older than :data:`KEEP_DAYS`; how many."""
    cutoff = (now or utcnow()) - dt.timedelta(days=KEEP_DAYS)
    return db.execute(delete(IdempotencyKey).where(IdempotencyKey.created_at < cutoff)).rowcount or 0


__all__ = ["KEEP_DAYS", "MAX_KEY_LENGTH", "KeyInFlight", "KeyReused", "Replay", "claim", "complete", "fingerprint",
           "forget_old", "replayed"]
