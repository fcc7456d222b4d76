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

from app.store import audit as store_audit
from app.web.api.deps import Admin, DbDep
from app.web.api.schemas import AuditEventOut, audit_out
from app.web.audit import ACTIONS

router = APIRouter(prefix="/audit", tags=["audit"])
DEFAULT_LIMIT, MAX_LIMIT = 100, 1000


@router.get("", response_model=list[AuditEventOut])
def list_events(principal: Admin, db: DbDep, patient_id: int | None = None, user_id: int | None = None,
                action: str | None = Query(None, pattern="^(" + "|".join(ACTIONS) + ")$"),
                since: dt.datetime | None = None, before_id: int | None = None,
                limit: int = Query(DEFAULT_LIMIT, ge=1, le=MAX_LIMIT)):
    """The clinic's audit events, newest first (module docstring for the filters)."""
    rows = store_audit.list_events(db, principal.clinic_id, patient_id=patient_id, user_id=user_id, action=action,
                                   since=since, before_id=before_id, limit=limit)
    return [audit_out(e) for e in rows]
