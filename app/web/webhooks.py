"""The webhook sender: signs and posts the deliveries :mod:`app.store.webhooks` plans, retrying with back-off.

Each request is ``POST <url>`` with the JSON body ``{"id": <delivery id>, "event": "job.done"|"job.failed",
"job": {...ids and status...}, "links": {...}}`` and the headers

* ``X-ChakaMo-Event``: the event, ``X-ChakaMo-Delivery``: the delivery id (the same on every retry: a receiver
  drops a repeat by it);
* ``X-ChakaMo-Signature: t=<unix seconds>,v1=<hex>``, where ``hex`` is HMAC-SHA256 (RFC 2104, FIPS 198-1) under
  the subscription's secret of the bytes ``"<t>." + body``.  A receiver recomputes it over the raw body,
  compares in constant time, and rejects a ``t`` older than a few minutes (a replayed request).

A 2xx answer delivers it; anything else (another status, a timeout, a refused connection) is retried after
``CHAKAMO_WEBHOOK_RETRY_S · 2^(n−1)`` seconds (at most an hour apart, 8 attempts).  :class:`WebhookSender` runs
in a daemon thread of every server (started and stopped with the app, on a database engine of its own), every :attr:`WebhookSender.EVERY_S`
seconds: plan the new deliveries, then send the due ones.  Several servers share the work through the
database (:func:`app.store.webhooks.claim_due`).  Redirects are not followed (a receiver's address is what the
admin registered).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import threading
import time
import urllib.error
import urllib.request

from app.store import webhooks

log = logging.getLogger("chakamo.webhooks")
TIMEOUT_S = 10.0


def signature(secret: str, timestamp: int, body: bytes) -> str:
    """The ``X-ChakaMo-Signature`` value of ``body`` sent at ``timestamp`` (module docstring)."""
    mac = hmac.new(secret.encode(), f"{timestamp}.".encode() + body, hashlib.sha256).hexdigest()
    return f"t={timestamp},v1={mac}"


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args, **kwargs):  # noqa: ANN002 — urllib's signature
        return None


_OPENER = urllib.request.build_opener(_NoRedirect)


def send(due: webhooks.Due) -> tuple[int | None, str]:
    """POST one delivery; ``(status or None, error sentence or "")``."""
    body = json.dumps({"id": due.id, **due.payload}, separators=(",", ":")).encode()
    req = urllib.request.Request(due.url, data=body, method="POST", headers={
        "Content-Type": "application/json", "User-Agent": "ChakaMo-Webhooks",
        "X-ChakaMo-Event": due.event, "X-ChakaMo-Delivery": str(due.id),
        "X-ChakaMo-Signature": signature(due.secret, int(time.time()), body)})
    try:
        with _OPENER.open(req, timeout=TIMEOUT_S) as resp:
            return resp.status, ""
    except urllib.error.HTTPError as exc:
        return exc.code, f"HTTP {exc.code}"
    except (urllib.error.URLError, OSError, ValueError) as exc:
        return None, f"{type(exc).__name__}: {getattr(exc, 'reason', exc)}"


class WebhookSender:
    """The sender thread (module docstring)."""

    EVERY_S = 1.0

    def __init__(self, db, retry_base_s: float) -> None:
        self.db, self.retry_base_s = db, retry_base_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="chakamo-webhooks", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread after its current round, then close its database engine."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=TIMEOUT_S + 5)
            if not self._thread.is_alive():
                self.db.dispose()

    def run_once(self) -> int:
        """Plan, then send what is due; how many attempts were made."""
        with self.db.sessions() as s:
            webhooks.plan_deliveries(s)
            due = webhooks.claim_due(s)
        for d in due:
            status, error = send(d)
            with self.db.sessions() as s:
                state = webhooks.record_attempt(s, d.id, status=status, error=error, base_s=self.retry_base_s)
            if state != "delivered":
                log.warning("webhook delivery %s (%s) attempt %d to %s: %s -> %s", d.id, d.event, d.attempt, d.url,
                            error or status, state)
        return len(due)

    def _loop(self) -> None:
        while not self._stop.wait(self.EVERY_S):
            try:
                self.run_once()
            except Exception:  # noqa: BLE001 — the database away, say: try again next round
                log.warning("webhook round failed; retrying", exc_info=True)


__all__ = ["TIMEOUT_S", "WebhookSender", "send", "signature"]
