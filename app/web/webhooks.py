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

No internal address is reached (server-side request forgery): a URL's host must match
``CHAKAMO_WEBHOOK_ALLOWED_HOSTS`` (an operator's list; empty: no webhooks), and at send time the name is resolved
and refused when any address is loopback, private, link-local, multicast or reserved — unless the operator named
that host exactly — and the connection goes to the checked address (:func:`resolve`).  The trail a clinic reads
says ``HTTP <status>`` or ``could not connect``, never why (which would map the server's network).
"""

from __future__ import annotations

import hashlib
import hmac
import http.client
import ipaddress
import json
import logging
import socket
import ssl
import threading
import time
import urllib.parse

from cryptography.exceptions import InvalidTag

from app.store import webhooks
from app.web.headers import host_allowed
from app.web.sealed import unseal

log = logging.getLogger("chakamo.webhooks")
TIMEOUT_S = 10.0
#: the error a clinic sees when no HTTP answer came (the cause is only logged)
NO_CONNECTION = "could not connect"
#: the trail's sentence when the secret was sealed under another ``CHAKAMO_SECRET_KEY`` (the key was changed)
SECRET_UNREADABLE = "secret unreadable: subscribe again"


def signature(secret: str, timestamp: int, body: bytes) -> str:
    """The ``X-ChakaMo-Signature`` value of ``body`` sent at ``timestamp`` (module docstring)."""
    mac = hmac.new(secret.encode(), f"{timestamp}.".encode() + body, hashlib.sha256).hexdigest()
    return f"t={timestamp},v1={mac}"


def _public(address: str) -> bool:
    """Whether ``address`` is a public unicast address (not loopback, private, link-local, multicast, reserved
    or unspecified: RFC 1918, RFC 3927, RFC 4193, RFC 6890's special-purpose registries)."""
    ip = ipaddress.ip_address(address)
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_global and not ip.is_multicast


def resolve(host: str, port: int, patterns: tuple[str, ...]) -> str:
    """The address to connect to for ``host``: the first it resolves to, refused (:class:`AddressRefused`) when
    ``host`` matches none of ``patterns`` (``CHAKAMO_WEBHOOK_ALLOWED_HOSTS``) or resolves to a non-public address
    and is not named exactly there.  The connection then goes to this address, so a name that resolves
    differently a moment later (DNS rebinding) cannot send it elsewhere."""
    name = host.lower()
    if not host_allowed(name, patterns):
        raise AddressRefused(f"{host} is not in CHAKAMO_WEBHOOK_ALLOWED_HOSTS")
    infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    if not infos:
        raise AddressRefused(f"{host} resolves to no address")
    address = infos[0][4][0]
    if name not in patterns and not all(_public(i[4][0]) for i in infos):
        raise AddressRefused(f"{host} resolves to the non-public address {address}")
    return address


class AddressRefused(OSError):
    """The receiver's address is not one webhooks may reach (:func:`resolve`)."""


class _PinnedHTTP(http.client.HTTPConnection):
    """An HTTP connection to a checked address, naming the host in ``Host``."""

    def __init__(self, host: str, port: int, address: str, timeout: float) -> None:
        super().__init__(host, port, timeout=timeout)
        self.address = address

    def connect(self) -> None:
        self.sock = socket.create_connection((self.address, self.port), self.timeout)


class _PinnedHTTPS(http.client.HTTPSConnection):
    """An HTTPS connection to a checked address; the certificate is checked against the host name."""

    def __init__(self, host: str, port: int, address: str, timeout: float) -> None:
        super().__init__(host, port, timeout=timeout, context=ssl.create_default_context())
        self.address = address

    def connect(self) -> None:
        sock = socket.create_connection((self.address, self.port), self.timeout)
        self.sock = self._context.wrap_socket(sock, server_hostname=self.host)


def send(due: webhooks.Due, patterns: tuple[str, ...], key: bytes) -> tuple[int | None, str]:
    """POST one delivery to the address :func:`resolve` allows; ``(status or None, error sentence or "")``.
    The error a clinic sees is generic (``HTTP <status>`` or :data:`NO_CONNECTION`); why the connection failed
    is logged for the operator only (it would tell a clinic about the server's network).  ``key``: the
    ``CHAKAMO_SECRET_KEY`` the subscription's secret is sealed under (:mod:`app.web.sealed`)."""
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
    url = urllib.parse.urlsplit(due.url)
    https = url.scheme.lower() == "https"
    try:
        port = url.port or (443 if https else 80)
        address = resolve(url.hostname or "", port, patterns)
        conn = (_PinnedHTTPS if https else _PinnedHTTP)(url.hostname, port, address, TIMEOUT_S)
        try:  # redirects are not followed: http.client never does
            conn.request("POST", (url.path or "/") + (f"?{url.query}" if url.query else ""), body, headers)
            status = conn.getresponse().status
        finally:
            conn.close()
    except (OSError, ValueError, http.client.HTTPException) as exc:
        log.warning("webhook delivery %s to %s: %s: %s", due.id, due.url, type(exc).__name__, exc)
        return None, NO_CONNECTION
    return status, "" if 200 <= status < 300 else f"HTTP {status}"


class WebhookSender:
    """The sender thread (module docstring)."""

    EVERY_S = 1.0

    def __init__(self, db, retry_base_s: float, allowed_hosts: tuple[str, ...], key: bytes) -> None:
        self.db, self.retry_base_s, self.allowed_hosts, self.key = db, retry_base_s, allowed_hosts, key
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
        """Plan, then send what is due, one claimed delivery at a time; a subscription whose attempt failed gets
        no other this round (a dead receiver costs a round one timeout, not one per delivery, so it holds no
        other clinic's deliveries up); how many attempts were made."""
        with self.db.sessions() as s:
            webhooks.plan_deliveries(s)
        failed: set[int] = set()
        made = 0
        while not self._stop.is_set():
            with self.db.sessions() as s:
                d = webhooks.claim_due(s, skip=frozenset(failed))
            if d is None:
                break
            made += 1
            status, error = send(d, self.allowed_hosts, self.key)
            with self.db.sessions() as s:
                state = webhooks.record_attempt(s, d, status=status, error=error, base_s=self.retry_base_s)
            if state != "delivered":
                failed.add(d.subscription_id)
                log.warning("webhook delivery %s (%s) attempt %d to %s: %s -> %s", d.id, d.event, d.attempt, d.url,
                            error or status, state)
        return made

    def _loop(self) -> None:
        while not self._stop.wait(self.EVERY_S):
            try:
                self.run_once()
            except Exception:  # noqa: BLE001 — the database away, say: try again next round
                log.warning("webhook round failed; retrying", exc_info=True)


__all__ = ["NO_CONNECTION", "TIMEOUT_S", "AddressRefused", "WebhookSender", "resolve", "send", "signature"]
