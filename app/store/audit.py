"""The audit log's rows: append one event, list a clinic's events (``app.web.audit`` says who and why)."""

from __future__ import annotations

import datetime as dt

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.store.database import add_at_commit
from app.store.models import AuditEvent, utcnow


def add_event(db: Session, *, at_commit: bool = False, **columns) -> AuditEvent:
    """Add one :class:`AuditEvent` to ``db``'s transaction: flushed now (a failing insert raises here), or with
    ``at_commit`` written by the commit (:func:`app.store.database.add_at_commit`: a failing insert fails the
    commit; the event has no id before it)."""
    event = AuditEvent(**columns)
    if at_commit:
        event.at = utcnow()  # when it happened, not when the commit (or the group commit) writes it
        add_at_commit(db, event)
        return event
    db.add(event)
    db.flush()
    return event


def list_events(db: Session, clinic_id: int, *, patient_id: int | None = None, user_id: int | None = None,
                action: str | None = None, since: dt.datetime | None = None, before_id: int | None = None,
                limit: int = 100) -> list[AuditEvent]:
    """The clinic's events, newest first, filtered; ``since`` without a time zone is read as UTC; page back
    with ``before_id`` (the smallest id of the previous page)."""
    stmt = select(AuditEvent).where(AuditEvent.clinic_id == clinic_id)
    if patient_id is not None:
        stmt = stmt.where(AuditEvent.patient_id == patient_id)
    if user_id is not None:
        stmt = stmt.where(AuditEvent.user_id == user_id)
    if action is not None:
        stmt = stmt.where(AuditEvent.action == action)
    if since is not None:
        if since.tzinfo is None:
            since = since.replace(tzinfo=dt.timezone.utc)
        stmt = stmt.where(AuditEvent.at >= since)
    if before_id is not None:
        stmt = stmt.where(AuditEvent.id < before_id)
    # newest first by id, the key ``before_id`` pages on (``at`` is taken before the insert, so two requests'
    # events may interleave differently by time and by id: ordering by both could skip or repeat on a page)
    return list(db.scalars(stmt.order_by(AuditEvent.id.desc()).limit(limit)))


__all__ = ["add_event", "list_events"]
