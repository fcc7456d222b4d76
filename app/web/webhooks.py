"""The webhook sender: signs and posts the deliveries :mod:`app.store.webhooks` plans, retrying with back-off.

Each request is ``POST <url>`` with the JSON body ``{"id": <delivery id>, "event": "job.done"|"job.failed",
"job": {...ids and status...}, "links": {...}}`` and the headers

* ``X-ChakaMo-Event``: the event, ``X-ChakaMo-Delivery``: the delivery id (the same on every retry: a receiver
  drops a repeat by it);
* ``X-ChakaMo-Signature: t=<unix seconds>,v1=<hex>``, where ``hex`` is HMAC-SHA256 (RFC 2104, FIPS 198-1) under
  the subscription's secret of the bytes ``"<t>." + body``.  A receiver recomputes it over the raw body,
  compares in constant time, and rejects a ``t`` older than a few minutes (a replayed request).

A 2xx answer delivers it; anything else (another status, no answer within :data:`DEADLINE_S`, a refused
connection) is retried after ``CHAKAMO_WEBHOOK_RETRY_S · 2^(n−1)`` seconds (at most an hour apart, 8 attempts).
One attempt takes at most :data:`DEADLINE_S` (20 s) in all, however slowly a receiver trickles its answer — well
inside the 60 s lease that keeps other servers from sending the same attempt (:mod:`app.web.outbound`).
:class:`WebhookSender` runs in a daemon thread of every server (started and stopped with the app, on a database
engine of its own), every :attr:`WebhookSender.EVERY_S` seconds: plan the new deliveries, then send the due ones.
Several servers share the work through the database (:func:`app.store.webhooks.claim_due`).  Redirects are not
followed (a receiver's address is what the admin registered).  The same machinery pushes reports to a hospital's
FHIR server (:mod:`app.web.fhir_push`): a delivery of that kind gets its body and headers there.

No internal address is reached (server-side request forgery): a URL's host must match
``CHAKAMO_WEBHOOK_ALLOWED_HOSTS`` (an operator's list; empty: no webhooks), and :mod:`app.web.outbound` skips every
answer of the name that is not public (also hidden in IPv6: NAT64, 6to4, Teredo, ...) unless the operator named the
host exactly, and connects to a checked address within the total deadline.  The trail a clinic reads is a code
(:data:`NO_CONNECTION`, :data:`HTTP_STATUS`, :data:`SECRET_UNREADABLE`; in es/en/pt through :func:`trail_error`): the receiver's HTTP status or "no answer", never
why (which would map the server's network).
"""

from __future__ import annotations

import hashlib
import hmac
import http.client
import json
import logging
import threading
import time

from cryptography.exceptions import InvalidTag

from app.store import webhooks
from app.web import messages
from app.store.models import utcnow
from app.store.sealed import unseal
from app.web.outbound import DEADLINE_S, post

log = logging.getLogger("chakamo.webhooks")
#: the trail's codes (``last_error``; rendered in es/en/pt from :mod:`app.web.messages` by :func:`trail_error`):
#: no HTTP answer came in time (the cause is only logged), the receiver answered another status than 2xx, the
#: secret was sealed under another ``CHAKAMO_SECRET_KEY`` (the key was changed: subscribe again; no retry can mend it,
#: so the delivery fails at once)
NO_CONNECTION = "webhook.no_connection"
HTTP_STATUS = "webhook.http_status"
SECRET_UNREADABLE = "webhook.secret_unreadable"
#: the suffix of a code's sentence for a delivery whose last attempt failed for good (state ``failed``: "it is not
#: retried" where the pending one says "it is retried later")
FINAL = ".final"
#: the part of a delivery's lease (:data:`app.store.webhooks.LEASE_S`) an attempt leaves for recording its outcome
#: (and auditing a push): the POST's deadline is what is left of the lease after the body was built, less this
RECORD_MARGIN_S = 10.0


def signature(secret: str, timestamp: int, body: bytes) -> str:
    """The ``X-ChakaMo-Signature`` value of ``body`` sent at ``timestamp`` (module docstring)."""
    mac = hmac.new(secret.encode(), f"{timestamp}.".encode() + body, hashlib.sha256).hexdigest()
    return f"t={timestamp},v1={mac}"


def outcome(status: int | None) -> str:
    """The trail's code of an attempt answered ``status`` (None: no answer): "" for a 2xx."""
    if status is None:
        return NO_CONNECTION
    return "" if 200 <= status < 300 else HTTP_STATUS


def trail_error(code: str, status: int | None, state: str = "pending") -> dict | None:
    """A delivery's ``last_error`` for the API: ``{"code", "params", "message": {es, en, pt}}`` (None: no error);
    for a delivery in ``state`` ``failed`` the code's final sentence (:data:`FINAL`) when it has one; a code this
    version does not know (written by a newer one) is shown as it is in every language."""
    if not code:
        return None
    params = {"status": status} if code == HTTP_STATUS else {"seconds": int(DEADLINE_S)} \
        if code == NO_CONNECTION else {}
    if code not in messages.CATALOGUE:
        return {"code": code, "params": params, "message": {lang: code for lang in messages.LANGUAGES}}
    sentence = code + FINAL if state == "failed" and code + FINAL in messages.CATALOGUE else code
    return {"code": code, "params": params,
            "message": {lang: messages.render(sentence, lang, **params) for lang in messages.LANGUAGES}}


def send(due: webhooks.Due, patterns: tuple[str, ...], key: bytes,
         deadline_s: float = DEADLINE_S) -> tuple[int | None, str]:
    """POST one delivery (:func:`post`); ``(status or None, the trail's code or "")``.  The code a clinic sees is
    generic (:data:`HTTP_STATUS` or :data:`NO_CONNECTION`); why the connection failed is logged for the operator
    only (it would tell a clinic about the server's network).  ``key``: the ``CHAKAMO_SECRET_KEY`` the
    subscription's secret is sealed under (:mod:`app.store.sealed`)."""
    body = json.dumps({"id": due.id, **due.payload}, separators=(",", ":")).encode()
    try:
        secret = unseal(key, due.secret)
    except (InvalidTag, ValueError) as exc:  # sealed under another CHAKAMO_SECRET_KEY: an attempt that failed
        log.warning("webhook delivery %s: its subscription's secret cannot be unsealed (%s); subscribe again",
                    due.id, type(exc).__name__)
        return None, SECRET_UNREADABLE
    headers = {"Content-Type": "application/json", "User-Agent": "ChakaMo-Webhooks",
               "X-ChakaMo-Event": due.event, "X-ChakaMo-Delivery": str(due.id),
               "X-ChakaMo-Signature": signature(secret, int(time.time()), body)}
    return attempt(due, due.url, body, headers, patterns, deadline_s)


def time_left(due: webhooks.Due) -> float:
    """Seconds an attempt of ``due`` may still take: until its lease ends, less :data:`RECORD_MARGIN_S`."""
    return (due.lease - utcnow()).total_seconds() - RECORD_MARGIN_S


def attempt(due: webhooks.Due, url: str, body: bytes, headers: dict[str, str], patterns: tuple[str, ...],
            deadline_s: float = DEADLINE_S) -> tuple[int | None, str]:
    """:func:`post` as one attempt of ``due``, within ``deadline_s`` and what is left of its lease
    (:func:`time_left`: building a FHIR bundle takes some of it; none left, nothing is sent): ``(status or None,
    the trail's code or "")``, the cause of a failed connection logged only."""
    deadline_s = min(deadline_s, time_left(due))
    if deadline_s <= 0:  # another sender may claim it before this attempt could be recorded
        log.warning("delivery %s: its lease has too little time left for an attempt", due.id)
        return None, NO_CONNECTION
    try:
        status = post(url, body, headers, patterns, deadline_s)
    except (OSError, ValueError, http.client.HTTPException) as exc:
        log.warning("delivery %s to %s: %s: %s", due.id, url, type(exc).__name__, exc)
        return None, NO_CONNECTION
    return status, outcome(status)


class WebhookSender:
    """The sender thread (module docstring); ``fhir_push``: the FHIR push (:class:`app.web.fhir_push.FhirPush`) whose
    deliveries it sends too, None when ``CHAKAMO_FHIR_PUSH_URL`` is not set."""

    EVERY_S = 1.0

    def __init__(self, db, retry_base_s: float, allowed_hosts: tuple[str, ...], key: bytes, fhir_push=None) -> None:
        self.db, self.retry_base_s, self.allowed_hosts, self.key = db, retry_base_s, allowed_hosts, key
        self.fhir_push = fhir_push
        self.kinds = ("webhook", "fhir") if fhir_push is not None else ("webhook",)
        self._unknown: tuple[str, ...] = ()
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
            self._thread.join(timeout=DEADLINE_S + 5)
            if not self._thread.is_alive():
                self.db.dispose()

    def run_once(self) -> int:
        """Plan, then send what is due, one claimed delivery at a time; a subscription whose attempt failed gets
        no other this round (a dead receiver costs a round one timeout, not one per delivery, so it holds no
        other clinic's deliveries up); how many attempts were made."""
        with self.db.sessions() as s:
            if self.fhir_push is not None:
                unknown = webhooks.ensure_fhir_push(s, self.fhir_push.url, self.fhir_push.clinics)
                if unknown != self._unknown:  # said once, not every round
                    self._unknown = unknown
                    if unknown:
                        log.warning("CHAKAMO_FHIR_PUSH_CLINICS names no clinic called %s", ", ".join(unknown))
            webhooks.plan_deliveries(s, kinds=self.kinds)
        failed: set[int] = set()
        made = 0
        while not self._stop.is_set():
            with self.db.sessions() as s:
                d = webhooks.claim_due(s, skip=frozenset(failed), kinds=self.kinds)
            if d is None:
                break
            made += 1
            give_up = False
            if d.kind == "fhir":
                status, error, give_up = self.fhir_push.send(self.db, d)
            else:
                status, error = send(d, self.allowed_hosts, self.key)
                give_up = error == SECRET_UNREADABLE  # another key: no retry opens it
            with self.db.sessions() as s:
                state = webhooks.record_attempt(s, d, status=status, error=error, base_s=self.retry_base_s,
                                                give_up=give_up)
            if state != "delivered":
                failed.add(d.subscription_id)
                log.warning("%s delivery %s (%s) attempt %d to %s: %s -> %s", d.kind, d.id, d.event, d.attempt,
                            d.url, error or status, state)
        return made

    def _loop(self) -> None:
        while not self._stop.wait(self.EVERY_S):
            try:
                self.run_once()
            except Exception:  # noqa: BLE001 — the database away, say: try again next round
                log.warning("webhook round failed; retrying", exc_info=True)


__all__ = ["FINAL", "HTTP_STATUS", "NO_CONNECTION", "RECORD_MARGIN_S", "SECRET_UNREADABLE", "WebhookSender", "attempt", "outcome",
           "send", "signature", "time_left", "trail_error"]
