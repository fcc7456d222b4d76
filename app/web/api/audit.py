"""``GET /audit``: the clinic's audit log (:mod:`app.web.audit`), for its admins only.

Newest first; filters ``patient_id``, ``user_id``, ``action``, ``since`` (an ISO date-time: events at or
after it; without a time zone it is read as UTC) and ``limit`` (default :data:`DEFAULT_LIMIT`, at most
:data:`MAX_LIMIT`; page back with ``before_id``, the smallest id of the previous page).  Scoped to the
caller's clinic like every other route: another clinic's events never appear, whatever the filters.  The
log is append-only from the API: this router has no route that changes or deletes an event.
"""

from __future__ import annotations

import datetime as dt

from fastapi import APIRouter, Query
from sqlalchemy import select

from app.web.api.deps import Admin, DbDep
from app.web.api.schemas import AuditEventOut, audit_out
from app.web.audit import ACTIONS
from app.store.models import AuditEvent

router = APIRouter(prefix="/audit", tags=["audit"])
DEFAULT_LIMIT, MAX_LIMIT = 100, 1000


@router.get("", response_model=list[AuditEventOut])
def list_events(principal: Admin, db: DbDep, patient_id: int | None = None, user_id: int | None = None,
                action: str | None = Query(None, pattern="^(" + "|".join(ACTIONS) + ")$"),
                since: dt.datetime | None = None, before_id: int | None = None,
                limit: int = Query(DEFAULT_LIMIT, ge=1, le=MAX_LIMIT)):
    """The clinic's audit events, newest first (module docstring for the filters)."""
    stmt = select(AuditEvent).where(AuditEvent.clinic_id == principal.clinic_id)
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
    rows = db.scalars(stmt.order_by(AuditEvent.id.desc()).limit(limit))
    return [audit_out(e) for e in rows]
