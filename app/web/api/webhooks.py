"""``/webhooks`` (admin): signed notifications when a job finishes or fails, with their delivery trail; and
``GET /events``: the same news as a server-sent event stream for the browser.

``POST /webhooks {"url", "events": ["job.done", "job.failed"], "label"}`` answers the subscription with its
``secret`` — the only time it is shown — with which every delivery is signed (:mod:`app.web.webhooks` says how
to verify it).  The URL must be ``https`` outside development and name a host of the operator's
``CHAKAMO_WEBHOOK_ALLOWED_HOSTS`` (:mod:`app.web.webhooks` keeps internal addresses out).  ``GET /webhooks`` lists them (no secrets),
``DELETE /webhooks/{id}`` ends one, ``GET /webhooks/{id}/deliveries`` is its audit trail: every delivery with its
attempts, the last status and error.  Creating and deleting are recorded in the audit log.

``GET /events`` (``text/event-stream``, any role): ``event: job`` with ``{"id", "session_id", "status",
"progress", "stage", "analysis_id"}`` whenever one of the clinic's jobs changes, checked every second; a comment
line every 15 s keeps proxies from closing it; the stream ends after :data:`STREAM_S` seconds and the browser's
``EventSource`` reconnects by itself.  The caller is resolved again every :data:`RECHECK_S` seconds: a token
expired or revoked, or a login closed, meanwhile ends the stream with ``event: end`` carrying the refusal
(``{"status", "code", "params", "message"}``), so a revoked credential stops hearing the clinic's news.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import json
import re
import secrets
import urllib.parse

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, Field

from app.store import idempotency, webhooks
from app.store.models import utcnow
from app.web import audit
from app.web.api.deps import Admin, DbDep, Reader, resolve_principal
from app.web.api.schemas import DeliveryOut, delivery_out
from app.web.headers import host_allowed
from app.web.outbound import header_host, plain_host
from app.web.idempotency import KEY_PARAMETER, LOCATION, answer, key_of, request_sha256
from app.web.messages import refusal
from app.web.refusals import Refusal
from app.store.sealed import seal

router = APIRouter(tags=["webhooks"])
#: how long one event stream stays open (the browser reconnects)
STREAM_S = 600.0
#: how often the stream checks that its caller is still let in (a revoked or expired token)
RECHECK_S = 30.0
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
    secret: str | None = Field(None, description="only in the answer of the first POST: sign-checking key, keep "
                                                     "it (a replay of the POST does not show it again)")


def _out(row, secret: str | None = None) -> dict:
    return {"id": row.id, "url": row.url, "events": row.events.split(), "label": row.label,
            "created_at": row.created_at, "secret": secret}


@router.post("/webhooks", response_model=WebhookOut, status_code=201, openapi_extra={"parameters": [KEY_PARAMETER]},
             responses={201: {"headers": LOCATION},
                        400: {"description": "the URL is not http(s), not https outside development, or its host is "
                                              "not in CHAKAMO_WEBHOOK_ALLOWED_HOSTS"}})
def create_webhook(body: WebhookIn, principal: Admin, db: DbDep, request: Request):
    """Subscribe ``url`` to the events; the answer's ``secret`` is shown only now (a repeat of this request with
    its ``Idempotency-Key`` answers the subscription without it); it is stored sealed (:mod:`app.store.sealed`)."""
    key = key_of(request)
    claimed = idempotency.claim(db, principal.clinic_id, key, request_sha256(request, body), "webhook") if key else None
    if isinstance(claimed, idempotency.Replay):
        row = webhooks.clinic_subscription(db, principal.clinic_id, claimed.resource_ids[0])
        return answer(_out(row), claimed.status, f"/api/v1/webhooks/{row.id}", replayed=True)
    url = body.url.strip()
    settings = request.app.state.settings
    if not _URL.fullmatch(url) or (not settings.development and not url.lower().startswith("https://")):
        raise Refusal(400, "webhook.url_invalid", url=repr(url[:80]))
    try:
        host = urllib.parse.urlsplit(url).hostname or ""
    except ValueError:  # a bracketed host that is no IPv6 address
        raise Refusal(400, "webhook.url_invalid", url=repr(url[:80])) from None
    if not plain_host(host):  # "*" or "*.example.org": a pattern, not a host (a resolver may still answer)
        raise Refusal(400, "webhook.host_invalid", url=repr(url[:80]), host=repr(host[:80]))
    if not host_allowed(header_host(host), settings.webhook_host_patterns):  # the sender checks the address again
        raise Refusal(400, "webhook.url_refused", host=repr(host[:80]))
    secret = secrets.token_urlsafe(32)
    row = webhooks.add_subscription(db, principal.clinic_id, url=url, events=body.events,
                                    secret=seal(settings.key, secret), label=body.label)
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
    return [delivery_out(d) for d in webhooks.deliveries(db, principal.clinic_id, webhook_id)]


def _states(request: Request, clinic_id: int, since: dt.datetime) -> list[dict]:
    with request.app.state.db.session() as db:
        return webhooks.job_states(db, clinic_id, since)


def _refused(request: Request, clinic_id: int) -> dict | None:
    """None while the request's credentials still let it in to ``clinic_id``; else the refusal's body (its
    ``detail`` in the request's language, ``code``, ``params``, ``message`` in es/en/pt)."""
    try:
        with request.app.state.db.session() as db:
            again = resolve_principal(request, db, request.app.state.settings)
        if again.clinic_id == clinic_id:
            return None
        raise refusal(request, 403, "request.events_other_clinic")
    except HTTPException as exc:
        body = exc.body() if isinstance(exc, Refusal) else {"detail": exc.detail}
        return {"status": exc.status_code} | {k: body[k] for k in ("code", "params", "message", "detail") if k in body}


@router.get("/events", response_class=StreamingResponse,
            responses={200: {"content": {"text/event-stream": {}},
                             "description": "server-sent events: `event: job` with the job's state as JSON"}})
async def events(principal: Reader, request: Request):
    """The clinic's job changes as server-sent events (module docstring)."""
    clinic_id = principal.clinic_id

    async def stream():
        start, last, shown = asyncio.get_running_loop().time(), 0.0, {}
        checked = start
        since = utcnow()
        yield "retry: 3000\n\n"
        while asyncio.get_running_loop().time() - start < STREAM_S:
            if await request.is_disconnected():
                return
            if asyncio.get_running_loop().time() - checked >= RECHECK_S:
                checked = asyncio.get_running_loop().time()
                refused = await run_in_threadpool(_refused, request, clinic_id)
                if refused is not None:
                    yield f"event: end\ndata: {json.dumps(refused)}\n\n"
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
