"""Outbound HTTP to hosts the operator allows: the address filter (no server-side request forgery) and a POST
pinned to a checked address within a total deadline — the transport of the webhooks (:mod:`app.web.webhooks`) and of
the FHIR push (:mod:`app.web.fhir_push`).

**Addresses.**  A URL's host must match the operator's patterns (``*.domain``, ``*``, exact names); its name is
resolved (the lookup itself bounded) and every answer that is not a public unicast address is skipped — loopback,
private, link-local, shared, multicast, reserved, unspecified, and the IPv6 forms that lead to such an IPv4 address
(NAT64, 6to4, Teredo, ISATAP, IPv4-mapped/-compatible/-translated) or are site-local (:func:`usable`) — unless the
operator named the host exactly (an internal receiver they mean).  The remaining answers are tried in turn and the
connection goes to the one that answered (:class:`PinnedConnection`): a name that resolves differently a moment later
(DNS rebinding) cannot send it elsewhere.

**Time.**  Each step waits at most :data:`TIMEOUT_S`, and the whole POST — lookup, connection, TLS handshake,
request and the answer's status line — at most ``deadline_s`` (:data:`DEADLINE_S` by default): a receiver trickling
its answer a byte at a time resets a per-read timeout with every byte (one held a sender 39 s), so a watchdog shuts
the socket down at the deadline.
"""

from __future__ import annotations

import http.client
import ipaddress
import re
import socket
import ssl
import threading
import time
import urllib.parse

from app.web.headers import host_allowed

#: the longest wait for one step of a send (connecting to one address, one read)
TIMEOUT_S = 10.0
#: the longest one whole send may take, from the name's lookup to the answer's status line: a receiver trickling
#: its answer a byte at a time resets :data:`TIMEOUT_S` with every byte, so this bound is kept by a watchdog that
#: shuts the socket down (:class:`PinnedConnection`); well inside a webhook delivery's lease
#: (:data:`app.store.webhooks.LEASE_S`, 60 s), so an attempt ends before another sender may claim it again
DEADLINE_S = 20.0
#: IPv6 ranges that carry an IPv4 address in their last 32 bits: IPv4-compatible (RFC 4291 §2.5.5.1, deprecated),
#: IPv4-mapped (§2.5.5.2), IPv4-translated (RFC 2765 §2.1) and the NAT64 well-known prefix (RFC 6052 §2.1)
_IPV4_IN_LAST_32 = tuple(ipaddress.ip_network(n) for n in ("::/96", "::ffff:0:0/96", "::ffff:0:0:0/96",
                                                           "64:ff9b::/96"))
#: IPv6 ranges refused outright: site-local (RFC 3879 deprecated it; Python counts it global), the local-use NAT64
#: prefix (RFC 8215: translates into a network's own IPv4 addresses)
_REFUSED_V6 = tuple(ipaddress.ip_network(n) for n in ("fec0::/10", "64:ff9b:1::/48"))
#: ISATAP interface identifiers (RFC 5214 §6.1): ``0000:5efe`` or ``0200:5efe`` followed by the IPv4 address
_ISATAP = (0x00005EFE, 0x02005EFE)


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


#: a DNS name as RFC 1123 §2.1 has it: dot-separated labels of letters, digits and inner hyphens, 1-63 characters
#: each, at most 253 in all (an optional final dot)
_DNS_NAME = re.compile(r"(?=.{1,253}\.?$)[a-z0-9](?:[a-z0-9-]{0,61}[a-z0-9])?(?:\.[a-z0-9](?:[a-z0-9-]{0,61}[a-z0-9])?)*\.?")


def plain_host(host: str) -> bool:
    """Whether ``host`` (a URL's host, IPv6 without brackets) is a DNS name (:data:`_DNS_NAME`) or an IP address
    literal: ``*``, ``*.hospital.example``, an empty name or one with ``%``, ``_`` or spaces is none of these (a
    resolver may still answer for it, so a host pattern must never be taken for a host)."""
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        return _DNS_NAME.fullmatch(host.lower()) is not None


def named_exactly(host: str, patterns: tuple[str, ...]) -> bool:
    """Whether the operator named ``host`` itself among ``patterns`` (a pattern with ``*`` names no host)."""
    name = host.lower()
    return plain_host(name) and any(p == name and "*" not in p for p in patterns)


def usable(host: str, patterns: tuple[str, ...], addresses: list[str]) -> tuple[str, ...]:
    """Of the addresses ``host`` resolved to (in the resolver's order, repeats dropped), those a send may connect
    to: all of them when the operator named ``host`` exactly in ``patterns`` (:func:`named_exactly`), else only the
    public ones (:func:`_public`); :class:`AddressRefused` for a host that is not a DNS name or an IP literal
    (:func:`plain_host`: ``*`` is a pattern, not a host) or when none is left."""
    if not plain_host(host):
        raise AddressRefused(f"{host!r} is not a host name or an IP address")
    unique = list(dict.fromkeys(addresses))
    if not unique:
        raise AddressRefused(f"{host} resolves to no address")
    ok = tuple(unique) if named_exactly(host, patterns) else tuple(a for a in unique if _public(a))
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
    matches none of ``patterns`` (``CHAKAMO_WEBHOOK_ALLOWED_HOSTS``, ``CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS``); else every answer :func:`usable` keeps (the
    non-public ones skipped unless the operator named ``host`` exactly).  The connection then goes to one of these
    checked addresses (:class:`PinnedConnection`), so a name that resolves differently a moment later (DNS
    rebinding) cannot send it elsewhere."""
    if not plain_host(host):  # before any lookup: a resolver may answer for "*"
        raise AddressRefused(f"{host!r} is not a host name or an IP address")
    if not host_allowed(header_host(host), patterns):
        raise AddressRefused(f"{host} is not among the allowed hosts {', '.join(patterns) or '(none)'}")
    return usable(host, patterns, _lookup(host, port, timeout_s))


def header_host(host: str) -> str:
    """``host`` as :func:`app.web.headers.host_allowed` reads it (a ``Host`` header): an IPv6 literal bracketed,
    so that its last group is not taken for a port."""
    return f"[{host}]" if ":" in host else host.lower()


class AddressRefused(OSError):
    """The receiver's address is not one this server may reach (:func:`resolve`)."""


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
        #: whether the watchdog shut the socket (an answer read since is cut short, whatever it seems to say)
        self.cut = False
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
        self.cut = True
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
        status = conn.getresponse().status
        if conn.cut:  # http.client takes an end of stream inside the headers for their end: a cut status line
            raise TimeoutError("the answer was cut at the deadline")  # such as "HTTP/1.1 200 OK" is no answer
        return status
    finally:
        conn.close()


__all__ = ["DEADLINE_S", "TIMEOUT_S", "AddressRefused", "PinnedConnection", "embedded_ipv4", "header_host", "named_exactly", "plain_host",
           "post", "resolve", "usable"]
