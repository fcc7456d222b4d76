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
inside the 60 s lease that keeps other servers from sending the same attempt (:class:`PinnedConnection`).
:class:`WebhookSender` runs in a daemon thread of every server (started and stopped with the app, on a database
engine of its own), every :attr:`WebhookSender.EVERY_S` seconds: plan the new deliveries, then send the due ones.
Several servers share the work through the database (:func:`app.store.webhooks.claim_due`).  Redirects are not
followed (a receiver's address is what the admin registered).  The same machinery pushes reports to a hospital's
FHIR server (:mod:`app.web.fhir_push`): a delivery of that kind gets its body and headers there.

No internal address is reached (server-side request forgery): a URL's host must match
``CHAKAMO_WEBHOOK_ALLOWED_HOSTS`` (an operator's list; empty: no webhooks), and at send time the name is resolved
and every answer that is loopback, private, link-local, shared, multicast or reserved — or an IPv6 form that
embeds such an IPv4 address (NAT64, 6to4, Teredo, ISATAP, IPv4-mapped/-compatible/-translated) or is site-local —
is skipped, unless the operator named that host exactly; the remaining answers are tried in turn and the
connection goes to a checked address (:func:`resolve`, :func:`usable`).  The trail a clinic reads is a code
(:data:`TRAIL_CODES`, in es/en/pt through :func:`trail_error`): the receiver's HTTP status or "no answer",
never why (which would map the server's network).
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
from app.web import messages
from app.web.headers import host_allowed
from app.store.sealed import unseal

log = logging.getLogger("chakamo.webhooks")
#: the longest wait for one step of a send (connecting to one address, one read)
TIMEOUT_S = 10.0
#: the longest one whole send may take, from the name's lookup to the answer's status line: a receiver trickling
#: its answer a byte at a time resets :data:`TIMEOUT_S` with every byte, so this bound is kept by a watchdog that
#: shuts the socket down (:class:`PinnedConnection`); well inside a delivery's lease
#: (:data:`app.store.webhooks.LEASE_S`, 60 s), so an attempt ends before another sender may claim it again
DEADLINE_S = 20.0
#: the trail's codes (``last_error``; rendered in es/en/pt from :mod:`app.web.messages` by :func:`trail_error`):
#: no HTTP answer came in time (the cause is only logged), the receiver answered another status than 2xx, the
#: secret was sealed under another ``CHAKAMO_SECRET_KEY`` (the key was changed: subscribe again)
NO_CONNECTION = "webhook.no_connection"
HTTP_STATUS = "webhook.http_status"
SECRET_UNREADABLE = "webhook.secret_unreadable"
TRAIL_CODES = (NO_CONNECTION, HTTP_STATUS, SECRET_UNREADABLE)

#: IPv6 ranges that carry an IPv4 address in their last 32 bits: IPv4-compatible (RFC 4291 §2.5.5.1, deprecated),
#: IPv4-mapped (§2.5.5.2), IPv4-translated (RFC 2765 §2.1) and the NAT64 well-known prefix (RFC 6052 §2.1)
_IPV4_IN_LAST_32 = tuple(ipaddress.ip_network(n) for n in ("::/96", "::ffff:0:0/96", "::ffff:0:0:0/96",
                                                           "64:ff9b::/96"))
#: IPv6 ranges refused outright: site-local (RFC 3879 deprecated it; Python counts it global), the local-use NAT64
#: prefix (RFC 8215: translates into a network's own IPv4 addresses)
_REFUSED_V6 = tuple(ipaddress.ip_network(n) for n in ("fec0::/10", "64:ff9b:1::/48"))
#: ISATAP interface identifiers (RFC 5214 §6.1): ``0000:5efe`` or ``0200:5efe`` followed by the IPv4 address
_ISATAP = (0x00005EFE, 0x02005EFE)


def signature(secret: str, timestamp: int, body: bytes) -> str:
    """The ``X-ChakaMo-Signature`` value of ``body`` sent at ``timestamp`` (module docstring)."""
    mac = hmac.new(secret.encode(), f"{timestamp}.".encode() + body, hashlib.sha256).hexdigest()
    return f"t={timestamp},v1={mac}"


def embedded_ipv4(ip: ipaddress.IPv6Address) -> list[ipaddress.IPv4Address]:
    """The IPv4 addresses an IPv6 address leads to: the last 32 bits of the IPv4-compatible, -mapped, -translated
    and NAT64 (``64:ff9b::/96``) forms; 6to4's (RFC 3056 §2: ``2002:V4ADDR::/48``); Teredo's server and client
    (RFC 4380 §4, the client's bits inverted); ISATAP's (RFC 5214 §6.1)."""
    out = []
    if any(ip in net for net in _IPV4_IN_LAST_32):
        out.append(ipaddress.IPv4Address(int(ip) & 0xFFFFFFFF))
    if ip.sixtofour is not None:
        out.append(ip.sixtofour)
    if ip.teredo is not None:
        out.extend(ip.teredo)
    if (int(ip) >> 32) & 0xFFFFFFFF in _ISATAP:
        out.append(ipaddress.IPv4Address(int(ip) & 0xFFFFFFFF))
    return out


def _public(address: str) -> bool:
    """Whether ``address`` is a public unicast address: not loopback, private, link-local, shared, multicast,
    reserved or unspecified (RFC 1918, RFC 3927, RFC 4193, RFC 6598, RFC 6890's special-purpose registries), and,
    for IPv6, not site-local (fec0::/10) nor the local-use NAT64 prefix, and every IPv4 address it embeds
    (:func:`embedded_ipv4`) public too: ``64:ff9b::10.0.0.1`` reaches 10.0.0.1 through a NAT64 gateway, and
    ``2002:0a00:0001::`` through a 6to4 relay, though Python calls both global."""
    ip = ipaddress.ip_address(address.split("%", 1)[0])  # a link-local address' %scope
    if isinstance(ip, ipaddress.IPv4Address):
        return ip.is_global and not ip.is_multicast
    if any(ip in net for net in _REFUSED_V6):
        return False
    inner = embedded_ipv4(ip)
    if any(ip in net for net in _IPV4_IN_LAST_32):  # only the IPv4 address counts (Python: ::ffff:8.8.8.8 private)
        return all(v4.is_global and not v4.is_multicast for v4 in inner)
    return ip.is_global and not ip.is_multicast and all(v4.is_global and not v4.is_multicast for v4 in inner)


def usable(host: str, patterns: tuple[str, ...], addresses: list[str]) -> tuple[str, ...]:
    """Of the addresses ``host`` resolved to (in the resolver's order, repeats dropped), those a send may connect
    to: all of them when the operator named ``host`` exactly in ``patterns``, else only the public ones
    (:func:`_public`); :class:`AddressRefused` when none is left."""
    name = host.lower()
    unique = list(dict.fromkeys(addresses))
    if not unique:
        raise AddressRefused(f"{host} resolves to no address")
    ok = tuple(unique) if name in patterns else tuple(a for a in unique if _public(a))
    if not ok:
        raise AddressRefused(f"{host} resolves only to non-public addresses ({', '.join(unique[:4])})")
    return ok


def _lookup(host: str, port: int, timeout_s: float) -> list[str]:
    """``host``'s addresses (``getaddrinfo``), waited for at most ``timeout_s`` (the resolver's own retries can
    take longer: the lookup runs in a daemon thread, left to finish on its own)."""
    answer: list = []

    def look() -> None:
        try:
            answer.append(socket.getaddrinfo(host, port, type=socket.SOCK_STREAM))
        except OSError as exc:
            answer.append(exc)

    thread = threading.Thread(target=look, name="chakamo-webhook-dns", daemon=True)
    thread.start()
    thread.join(max(0.0, timeout_s))
    if not answer:
        raise TimeoutError(f"looking up {host} took longer than {timeout_s:.1f} s")
    if isinstance(answer[0], OSError):
        raise answer[0]
    return [info[4][0] for info in answer[0]]


def resolve(host: str, port: int, patterns: tuple[str, ...], timeout_s: float = TIMEOUT_S) -> tuple[str, ...]:
    """The addresses to try for ``host``, in the resolver's order: refused (:class:`AddressRefused`) when ``host``
    matches none of ``patterns`` (``CHAKAMO_WEBHOOK_ALLOWED_HOSTS``); else every answer :func:`usable` keeps (the
    non-public ones skipped unless the operator named ``host`` exactly).  The connection then goes to one of these
    checked addresses (:class:`PinnedConnection`), so a name that resolves differently a moment later (DNS
    rebinding) cannot send it elsewhere."""
    if not host_allowed(host.lower(), patterns):
        raise AddressRefused(f"{host} is not in CHAKAMO_WEBHOOK_ALLOWED_HOSTS")
    return usable(host, patterns, _lookup(host, port, timeout_s))


class AddressRefused(OSError):
    """The receiver's address is not one webhooks may reach (:func:`resolve`)."""


def _left(deadline: float) -> float:
    """Seconds until ``deadline`` (``time.monotonic``); ``TimeoutError`` once it has passed."""
    left = deadline - time.monotonic()
    if left <= 0:
        raise TimeoutError("the send's deadline passed")
    return left


class PinnedConnection(http.client.HTTPConnection):
    """An HTTP(S) connection to checked addresses, naming the host in ``Host`` (and, with ``context``, checking the
    certificate against it): each of ``addresses`` is tried in turn until one connects (the one used:
    :attr:`address`); from then on a watchdog shuts the socket down at ``deadline`` (``time.monotonic``), which
    ends any wait for the TLS handshake or the answer, however slowly the receiver trickles bytes."""

    def __init__(self, host: str, port: int, addresses: tuple[str, ...], deadline: float,
                 context: ssl.SSLContext | None = None) -> None:
        super().__init__(host, port, timeout=TIMEOUT_S)
        self.addresses, self.deadline, self.context = addresses, deadline, context
        self.address: str | None = None
        self._watchdog: threading.Timer | None = None

    def connect(self) -> None:
        error: OSError = AddressRefused("no address to connect to")
        for address in self.addresses:
            try:
                sock = socket.create_connection((address, self.port), min(self.timeout, _left(self.deadline)))
            except OSError as exc:  # refused, unreachable, slow: the next answer
                error = exc
                continue
            self.address, self.sock = address, sock
            break
        else:
            raise error
        self._watchdog = threading.Timer(_left(self.deadline), self._cut)
        self._watchdog.daemon = True
        self._watchdog.start()
        if self.context is not None:
            self.sock = self.context.wrap_socket(sock, server_hostname=self.host, do_handshake_on_connect=False)
            self.sock.do_handshake()

    def _cut(self) -> None:
        """The deadline passed: shut the socket down, so a blocked read returns (``socket.socket``'s own
        ``shutdown``, which an ``SSLSocket`` would otherwise take for a TLS close)."""
        sock = self.sock
        if sock is not None:
            try:
                socket.socket.shutdown(sock, socket.SHUT_RDWR)
            except OSError:
                pass

    def close(self) -> None:
        if self._watchdog is not None:
            self._watchdog.cancel()
        super().close()


def post(url: str, body: bytes, headers: dict[str, str], patterns: tuple[str, ...],
         deadline_s: float = DEADLINE_S) -> int:
    """POST ``body`` to ``url`` on an address :func:`resolve` allows, within ``deadline_s`` in all (lookup,
    connection, TLS, request and the answer's status line); the answer's status.  Redirects are not followed
    (http.client never does).  Raises ``OSError`` (refused, unreachable, timed out, cut at the deadline),
    ``ValueError`` (a malformed URL) or ``http.client.HTTPException`` (no valid answer)."""
    deadline = time.monotonic() + deadline_s
    parts = urllib.parse.urlsplit(url)
    https = parts.scheme.lower() == "https"
    port = parts.port or (443 if https else 80)
    addresses = resolve(parts.hostname or "", port, patterns, min(TIMEOUT_S, _left(deadline)))
    conn = PinnedConnection(parts.hostname or "", port, addresses, deadline,
                            ssl.create_default_context() if https else None)
    try:
        conn.request("POST", (parts.path or "/") + (f"?{parts.query}" if parts.query else ""), body, headers)
        return conn.getresponse().status
    finally:
        conn.close()


def outcome(status: int | None) -> str:
    """The trail's code of an attempt answered ``status`` (None: no answer): "" for a 2xx."""
    if status is None:
        return NO_CONNECTION
    return "" if 200 <= status < 300 else HTTP_STATUS


def trail_error(code: str, status: int | None) -> dict | None:
    """A delivery's ``last_error`` for the API: ``{"code", "params", "message": {es, en, pt}}`` (None: no error);
    a code this version does not know (written by a newer one) is shown as it is in every language."""
    if not code:
        return None
    params = {"status": status} if code == HTTP_STATUS else {"seconds": int(DEADLINE_S)} \
        if code == NO_CONNECTION else {}
    if code not in messages.CATALOGUE:
        return {"code": code, "params": params, "message": {lang: code for lang in messages.LANGUAGES}}
    return {"code": code, "params": params,
            "message": {lang: messages.render(code, lang, **params) for lang in messages.LANGUAGES}}


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


def attempt(due: webhooks.Due, url: str, body: bytes, headers: dict[str, str], patterns: tuple[str, ...],
            deadline_s: float = DEADLINE_S) -> tuple[int | None, str]:
    """:func:`post` as one attempt of ``due``: ``(status or None, the trail's code or "")``, the cause of a failed
    connection logged only."""
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
                webhooks.ensure_fhir_push(s, self.fhir_push.url)
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


__all__ = ["DEADLINE_S", "HTTP_STATUS", "NO_CONNECTION", "SECRET_UNREADABLE", "TIMEOUT_S", "TRAIL_CODES",
           "AddressRefused", "PinnedConnection", "WebhookSender", "attempt", "embedded_ipv4", "outcome", "post",
           "resolve", "send", "signature", "trail_error", "usable"]
