"""Login throttling (OWASP ASVS 2.2.1; issue 16 findings 1, 2 and 10a): progressive delays, reserved before the
password is checked, counted in the database so that every API server sees the same counts.

**Reserve, then verify.**  A login first reserves an attempt on three counters — ``pair:<email> <address>``,
``email:<email>`` and ``ip:<address>`` — in one transaction (:func:`app.store.accounts.reserve_attempt`: one
atomic conditional ``UPDATE`` per counter), and only a login whose reservation succeeded reaches the slow argon2
check.  The reservation counts the attempt as failed until the check says otherwise, so a burst of parallel
logins cannot run more password checks than the rule allows, and the right password sent inside a burst that
has used up the allowance is refused (429) like the wrong ones.  A successful login resets its pair and email
counters and gives its reservation on the address counter back (a clinic behind one NAT address logs in all
morning without being slowed).

**Accounts per clinic** (issue 16 finding 10b: an email may have an account in several clinics; a login
names the clinic when it has, :func:`app.store.accounts.login_account`).  The ``email:`` and ``pair:`` counters
are the email's — the person's, whichever of their accounts is tried, so naming a clinic or not never gives a
guesser a second allowance.  A login that names a clinic also reserves on ``account:<email>|<clinic>`` (free as
``email:``), a counter of that clinic's account that only that clinic's admin clears: an unlock clears the
email's counters and the account counter of the admin's own clinic, so an admin of one clinic can never lift the
limit on guesses at the same email's account in another clinic.  The keys depend only on what the login typed,
never on whether an account exists: the counters answer alike for known and unknown accounts.

**Progressive delay, not lock-out** (:class:`ThrottlePolicy`).  Per counter, the first ``free`` attempts are
immediate; after that each attempt makes the next wait ``d(n) = min(cap_s, base_s · 2^(n − free))`` seconds
(``n`` the attempts so far: 1 s, 2 s, 4 s … 15 min).  The counters differ only in ``free``: 5 for one email
from one address (a person mistyping is never slowed; one guesser gets 5 + ~10 guesses in the first 20 minutes,
then 4 an hour), 20 for one email from anywhere (a guesser using many addresses), 30 for one address across
emails (one machine guessing many accounts).  Someone who knows an email therefore delays only their own
address — the owner, elsewhere, is slowed only after 20 failures on the email and only for as long as the
delay — and a clinic admin can clear an account's counters at once (``POST /users/{id}/unlock``).  A counter
idle for ``forget_s`` (1 h) starts again from zero; idle rows are pruned now and then.

Why not the ``limits`` library: its storages are memory, Redis, Memcached, MongoDB and etcd — none is the SQL
database the embedded default (SQLite) and the scaled-out deployment (PostgreSQL) already share, and its
moving/fixed windows count hits but do not express "the next attempt waits ``d(n)``".  The counter is one
``UPDATE … WHERE next_s <= now`` per key, which both databases run atomically.

**Concurrent logins per address and per server** (:class:`InFlight`): at most ``max_in_flight`` logins of one
client address are inside the server at once (in memory, per server process); one more is answered 429 at once,
before any database work — one machine cannot fill the hashing queue (:mod:`app.web.security`) that everybody
shares.  And at most as many logins as that queue holds (:func:`app.web.security.hash_capacity`: 5 on two cores)
are inside the server at once from all addresses together; one more is answered 503 at once, also before any
database work.  A login's reservation is a database write, and it runs on one of the ~40 request threads: when
only the hashes were counted, a flood from many addresses (each under its own cap) sent every login in, each held
a request thread while it waited for SQLite's one write lock — whose busy-wait is unfair: with 40 writers a few
wait seconds while newcomers pass — and a clinician's reads queued behind them for a thread (issue 16 finding 2:
reads timed out at 30 s under 120 parallel logins from 120 addresses; py-spy showed ~38 request threads waiting
in the reservation's ``INSERT``).  More logins inside than the hashing queue holds would only wait there or get
503 after their write, so the bound costs an honest login nothing.

**Without a client address** (uvicorn on a unix socket, behind a proxy that does not pass the browser's
address): clients cannot be told apart, so nothing is kept per address — no ``ip:`` or ``pair:`` counter and no
per-address in-flight cap (the server's cap holds).  Keying them all under one shared "address" would let any one client hold every login of the
server (4 in flight) and push every email's ``pair:`` counter into its delay for everybody (the lock-out of
finding 10a again).  What still holds: the ``email:``/``account:`` counters, the server's in-flight cap and the
hashing queue's bound (503 when full).  Deployments behind a proxy should pass the address (``chakamo serve --proxy-headers``).
:class:`LoginGate`, an ASGI middleware, gives these refusals (429 per address, 503 per server) before the
request reaches the framework — no routing, no body parsing, no dependency: a flood of them costs the event
loop that also answers everybody's reads as little as an answer can.
"""

from __future__ import annotations

import hashlib
import ipaddress
import math
import threading
import time
from dataclasses import dataclass

from sqlalchemy.orm import Session

from app.store import accounts
from app.store.database import Database
from app.web.security import hash_capacity, hash_queue_full


@dataclass(frozen=True)
class ThrottlePolicy:
    """The numbers of the module docstring: free attempts per counter, the delay's base and cap, the idle time
    after which a counter starts from zero, and the concurrent logins allowed per address."""

    free_per_pair: int = 5
    free_per_email: int = 20
    free_per_address: int = 30
    base_s: float = 1.0
    cap_s: float = 900.0
    forget_s: float = 3600.0
    max_in_flight: int = 4


def client_key(ip: str | None) -> str | None:
    """The address a client's counters are kept under: an IPv4 address as it is, an IPv6 address as its /64
    network (one host is routinely given a whole /64, so its full addresses would be unlimited counters and
    in-flight slots); None or anything unparsable as given."""
    if not ip:
        return ip
    try:
        addr = ipaddress.ip_address(ip)
    except ValueError:
        return ip
    if isinstance(addr, ipaddress.IPv6Address):
        if addr.ipv4_mapped is not None:  # ::ffff:a.b.c.d is the IPv4 client a.b.c.d
            return str(addr.ipv4_mapped)
        return str(ipaddress.ip_network(f"{addr}/64", strict=False))
    return str(addr)


def account_key(email: str, clinic: str) -> str:
    """The ``account:`` counter of ``email``'s account in the clinic named ``clinic`` (the name as a short
    digest: the key fits its column whatever the name's length)."""
    return f"account:{email}|{hashlib.sha256(clinic.encode()).hexdigest()[:16]}"


def _keys(email: str, ip: str | None, clinic: str | None = None) -> list[tuple[str, str | None, str]]:
    """``(key, email, kind)`` of the counters of one login, in the order they are locked (always the same order,
    so two transactions never wait on each other's rows crosswise); the address as :func:`client_key`, none of
    its counters without one (module docstring).  ``email`` is set on the rows an unlock clears by email; the
    ``account:`` row has none (only its own clinic's unlock clears it, by key)."""
    ip = client_key(ip)
    out = [(f"pair:{email} {ip}", email, "pair")] if ip else []
    out.append((f"email:{email}", email, "email"))
    if clinic is not None:
        out.append((account_key(email, clinic), None, "account"))
    if ip:
        out.append((f"ip:{ip}", None, "ip"))
    return out


class LoginThrottle:
    """The database-backed counters of the module docstring (one per app; the state is in ``db``)."""

    #: prune idle counters about once per this many reservations
    PRUNE_EVERY = 500

    def __init__(self, db: Database, policy: ThrottlePolicy | None = None) -> None:
        self.db, self.policy = db, policy or ThrottlePolicy()
        self._count = 0

    def _free(self, kind: str) -> int:
        p = self.policy
        return {"pair": p.free_per_pair, "email": p.free_per_email, "account": p.free_per_email,
                "ip": p.free_per_address}[kind]

    def reserve(self, email: str, ip: str | None, clinic: str | None = None) -> float:
        """Reserve one attempt of ``email`` (of the account in the clinic named ``clinic`` when given) from ``ip``
        on every counter, committed at once; returns 0.0 when reserved, else the seconds to wait (nothing
        reserved).  Blocking (database): call it from a thread."""
        p, now = self.policy, time.time()
        keys = [k for k, _, _ in _keys(email, ip, clinic)]
        with self.db.sessions() as s:  # a plain read first: a key still waiting refuses without a write lock
            wait = accounts.attempt_wait_s(s, keys, now)
        if wait > 0:
            return max(1.0, math.ceil(wait))
        with self.db.sessions() as s:  # the atomic reservation (the authority; the read above only saves writes)
            for key, key_email, kind in _keys(email, ip, clinic):
                if not accounts.reserve_attempt(s, key, key_email, now, free=self._free(kind), base_s=p.base_s,
                                                cap_s=p.cap_s, forget_s=p.forget_s):
                    s.rollback()
                    return max(1.0, math.ceil(accounts.attempt_wait_s(s, keys, now)))
            s.commit()
        self._count += 1
        if self._count % self.PRUNE_EVERY == 0:
            with self.db.session() as s:
                accounts.prune_attempts(s, now - p.forget_s)
        return 0.0

    def succeeded(self, db: Session, email: str, ip: str | None, clinic: str | None = None) -> None:
        """After a right password: reset the pair, email and account counters, give the address its attempt back
        (in the login's transaction ``db``)."""
        keys = _keys(email, ip, clinic)
        accounts.reset_attempts(db, [k for k, _, kind in keys if kind != "ip"])
        for key, _, kind in keys:
            if kind == "ip":
                accounts.refund_attempt(db, key, free=self._free(kind), base_s=self.policy.base_s)

    @staticmethod
    def unlock(db: Session, email: str, clinic: str) -> int:
        """Clear the counters of ``email`` and of its account in the clinic named ``clinic`` — never another
        clinic's account counter (module docstring); an admin's unlock.  Returns how many were cleared."""
        return accounts.delete_attempts_of_email(db, email, also_key=account_key(email, clinic))


class InFlight:
    """Logins inside this server right now: of each client address at most ``throttle.policy.max_in_flight``, of
    all together at most :func:`app.web.security.hash_capacity` (both read at each login, so a changed policy
    applies at once; thread-safe)."""

    #: the refusal codes of :meth:`enter`
    PER_ADDRESS, SERVER = "login.too_many_at_once", "login.busy"

    def __init__(self, throttle: LoginThrottle) -> None:
        self.throttle = throttle
        self._counts: dict[str, int] = {}
        self._total = 0
        self._lock = threading.Lock()

    @property
    def total(self) -> int:
        """Logins inside this server now, from all addresses."""
        return self._total

    def enter(self, ip: str | None) -> str | None:
        """Count one more login of ``ip`` (None: no address, counted only in the total); None when counted, else
        why not (nothing counted): :attr:`PER_ADDRESS` when ``ip`` has the most allowed, :attr:`SERVER` when the
        server has."""
        with self._lock:
            n = self._counts.get(ip, 0) if ip else 0
            if ip and n >= self.throttle.policy.max_in_flight:
                return self.PER_ADDRESS
            if self._total >= hash_capacity():
                return self.SERVER
            if ip:
                self._counts[ip] = n + 1
            self._total += 1
            return None

    def leave(self, ip: str | None) -> None:
        with self._lock:
            self._total -= 1
            if not ip:
                return
            n = self._counts.get(ip, 0) - 1
            if n > 0:
                self._counts[ip] = n
            else:
                self._counts.pop(ip, None)




async def receive_nothing() -> dict:
    """The ``receive`` of a refusal answered before the request's body is read (the answer never reads it)."""
    return {"type": "http.disconnect"}


class LoginGate:
    """ASGI middleware in front of ``POST /api/v1/auth/login`` (module docstring): counts the request in ``InFlight``
    for as long as it is inside the app, and answers 429 (too many at once from this address) or 503 (as many
    logins inside the server as the hashing queue holds, or that queue full) itself, in the request's language, with ``Retry-After`` and the code header."""

    PATH = "/api/v1/auth/login"

    def __init__(self, app, *, in_flight: InFlight) -> None:
        self.app, self.in_flight = app, in_flight

    @staticmethod
    async def _refuse(scope, send, status: int, code: str, retry_s: int) -> None:
        from starlette.requests import Request

        from app.web.messages import refusal

        response = refusal(Request(scope), status, code, headers={"Retry-After": str(retry_s)}).response()
        await response(scope, receive_nothing, send)

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http" or scope["path"] != self.PATH or scope["method"] != "POST":
            await self.app(scope, receive, send)
            return
        ip = client_key((scope.get("client") or (None,))[0])  # None: no address, no per-address cap (docstring)
        refused = self.in_flight.enter(ip)
        if refused == InFlight.PER_ADDRESS:
            await self._refuse(scope, send, 429, refused, 1)
            return
        if refused == InFlight.SERVER:
            await self._refuse(scope, send, 503, refused, 2)
            return
        try:
            if hash_queue_full():  # taken by other hashes (password changes, new users)
                await self._refuse(scope, send, 503, "login.busy", 2)
                return
            await self.app(scope, receive, send)
        finally:
            self.in_flight.leave(ip)


__all__ = ["InFlight", "LoginGate", "LoginThrottle", "ThrottlePolicy", "account_key", "client_key"]
