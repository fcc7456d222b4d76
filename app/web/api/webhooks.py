"""``/webhooks`` (admin): signed notifications when a job finishes or fails, with their delivery trail; and
``GET /events``: the same news as a server-sent event stream for the browser.

``POST /webhooks {"url", "events": ["job.done", "job.failed"], "label"}`` answers the subscription with its
``secret`` — the only time it is shown — with which every delivery is signed (:mod:`app.web.webhooks` says how
to verify it).  The URL must be ``https`` outside development.  ``GET /webhooks`` lists them (no secrets),
``DELETE /webhooks/{id}`` ends one, ``GET /webhooks/{id}/deliveries`` is its audit trail: every delivery with its
attempts, the last status and error.  Creating and deleting are recorded in the audit log.

``GET /events`` (``text/event-stream``, any role): ``event: job`` with ``{"id", "session_id", "status",
"progress", "stage", "analysis_id"}`` whenever one of the clinic's jobs changes, checked every second; a comment
line every 15 s keeps proxies from closing it; the stream ends after :data:`STREAM_S` seconds and the browser's
``EventSource`` reconnects by itself.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import json
import re
import secrets

from fastapi import APIRouter, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, Field

from app.store import idempotency, webhooks
from app.store.errors import Invalid
from app.store.models import utcnow
from app.web import audit
from app.web.api.deps import Admin, DbDep, Reader
from app.web.idempotency import KEY_PARAMETER, LOCATION, answer, key_of, request_sha256

router = APIRouter(tags=["webhooks"])
#: how long one event stream stays open (the browser reconnects)
STREAM_S = 600.0
_URL = re.compile(r"https?://[^\s/?#]+[^\s]*", re.IGNORECASE)


class WebhookIn(BaseModel):
    url: str = Field(max_length=2000, description="where to POST the events (https outside development)")
    events: list[str] = Field(default=list(webhooks.EVENTS), description="job.done and/or job.failed",
                              json_schema_extra={"items": {"enum": list(webhooks.EVENTS)}})
    label: str = Field("", max_length=200)


class WebhookOut(BaseModel):
    id: int
    url: str
    events: list[str]
    label: str
    created_at: dt.datetime
    secret: str | None = Field(None, description="only in the answer of the POST: sign-checking key, keep it")


class DeliveryOut(BaseModel):
    id: int
    event: str
    job_id: int
    state: str
    attempts: int
    last_status: int | None
    last_error: str
    created_at: dt.datetime
    delivered_at: dt.datetime | None
    next_attempt_at: dt.datetime | None


def _out(row, secret: str | None = None) -> dict:
    return {"id": row.id, "url": row.url, "events": row.events.split(), "label": row.label,
            "created_at": row.created_at, "secret": secret}


@router.post("/webhooks", response_model=WebhookOut, status_code=201, openapi_extra={"parameters": [KEY_PARAMETER]},
             responses={201: {"headers": LOCATION},
                        400: {"description": "the URL is not http(s), or not https outside development"}})
def create_webhook(body: WebhookIn, principal: Admin, db: DbDep, request: Request):
    """Subscribe ``url`` to the events; the answer's ``secret`` is shown only now (and to a repeat of this
    request with its ``Idempotency-Key``)."""
    key = key_of(request)
    claimed = idempotency.claim(db, principal.clinic_id, key, request_sha256(request, body), "webhook") if key else None
    if isinstance(claimed, idempotency.Replay):
        row = webhooks.clinic_subscription(db, principal.clinic_id, claimed.resource_ids[0])
        return answer(_out(row, row.secret), claimed.status, f"/api/v1/webhooks/{row.id}", replayed=True)
    url = body.url.strip()
    development = request.app.state.settings.development
    if not _URL.fullmatch(url) or (not development and not url.lower().startswith("https://")):
        raise Invalid(code="store.webhook_url", url=url[:80])
    secret = secrets.token_urlsafe(32)
    row = webhooks.add_subscription(db, principal.clinic_id, url=url, events=body.events, secret=secret,
                                    label=body.label)
    if claimed is not None:
        idempotency.complete(claimed, [row.id], 201)
    audit.record(db, request, principal, "create", detail=f"webhook {row.id} to {url[:200]}")
    return answer(_out(row, secret), 201, f"/api/v1/webhooks/{row.id}")


@router.get("/webhooks", response_model=list[WebhookOut])
def list_webhooks(principal: Admin, db: DbDep):
    return [_out(r) for r in webhooks.subscriptions(db, principal.clinic_id)]


@router.delete("/webhooks/{webhook_id}", status_code=204)
def delete_webhook(webhook_id: int, principal: Admin, db: DbDep, request: Request) -> Response:
    webhooks.delete_subscription(db, principal.clinic_id, webhook_id)
    audit.record(db, request, principal, "delete", detail=f"webhook {webhook_id}")
    return Response(status_code=204)


@router.get("/webhooks/{webhook_id}/deliveries", response_model=list[DeliveryOut])
def webhook_deliveries(webhook_id: int, principal: Admin, db: DbDep):
    """Every delivery of the subscription, newest first, with its attempts (the audit trail)."""
    rows = webhooks.deliveries(db, principal.clinic_id, webhook_id)
    return [{"id": d.id, "event": d.event, "job_id": d.job_id, "state": d.state, "attempts": d.attempts,
             "last_status": d.last_status, "last_error": d.last_error, "created_at": d.created_at,
             "delivered_at": d.delivered_at, "next_attempt_at": d.next_attempt_at if d.state == "pending" else None}
            for d in rows]


def _states(request: Request, clinic_id: int, since: dt.datetime) -> list[dict]:
    with request.app.state.db.session() as db:
        return webhooks.job_states(db, clinic_id, since)


@router.get("/events", response_class=StreamingResponse,
            responses={200: {"content": {"text/event-stream": {}},
                             "description": "server-sent events: `event: job` with the job's state as JSON"}})
async def events(principal: Reader, request: Request):
    """The clinic's job changes as server-sent events (module docstring)."""
    clinic_id = principal.clinic_id

    async def stream():
        start, last, shown = asyncio.get_running_loop().time(), 0.0, {}
        since = utcnow()
        yield "retry: 3000\n\n"
        while asyncio.get_running_loop().time() - start < STREAM_S:
            if await request.is_disconnected():
                return
            for job in await run_in_threadpool(_states, request, clinic_id, since - dt.timedelta(seconds=5)):
                key = (job["status"], job["progress"], job["stage"])
                if shown.get(job["id"]) != key:
                    shown[job["id"]] = key
                    yield f"id: {job['id']}\nevent: job\ndata: {json.dumps(job)}\n\n"
            now = asyncio.get_running_loop().time()
            if now - last > 15:
                last = now
                yield ": keep-alive\n\n"
            await asyncio.sleep(1.0)

    return StreamingResponse(stream(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"})


__all__ = ["router"]
