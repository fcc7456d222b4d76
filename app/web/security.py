"""Passwords, API tokens, browser sessions and CSRF tokens.

* Passwords: argon2id through ``argon2-cffi`` (a maintained binding of the reference implementation), in
  its PHC string format ``$argon2id$v=19$m=65536,t=2,p=1$<salt>$<hash>``, which carries its own
  parameters and random 16-byte salt.  The parameters (:data:`ARGON2_MEMORY_KIB`, :data:`ARGON2_TIME_COST`,
  :data:`ARGON2_PARALLELISM`): 64 MiB of memory and 2 passes (OWASP's password-storage minimum is 19 MiB
  and 2 passes; RFC 9106's low-memory profile is 64 MiB and 3 passes over 4 lanes), one lane so that one
  hash occupies one core (≈ 90 ms on this project's 2-core test machine) — memory-hardness is what makes
  a stolen database expensive to crack on GPUs, and one lane keeps the concurrency bound below honest.
  Hashes made by earlier versions (``scrypt$n$r$p$salt$hash``, base64; n=2**14, r=8, p=1) still verify,
  in constant time; :func:`needs_rehash` is true for them and for argon2 hashes with weaker parameters than
  today's, and the login stores a fresh hash after the next successful password check, so the parameters
  can rise later without a migration.  (Until an old account logs in once, a wrong password for it costs
  scrypt's ≈ 30 ms instead of argon2's ≈ 90 ms: that timing tells only that the account is old.)
  Minimum length 10 characters; no default passwords anywhere.
* API tokens: ``chk_`` + ``secrets.token_urlsafe(32)`` (256 bits), shown once; only their sha256 is stored
  (a fast hash is right for 256-bit random secrets: there is nothing to brute-force).
* Browser sessions: a random id in the ``chakamo_session`` cookie, stored as its sha256.
* Login throttling (:class:`LoginThrottle`): after 10 failed logins for one email within 15 minutes, that
  email's logins are refused (429) until the window passes — online password guessing stays slow; the
  price is that someone who knows an email can delay its owner's login by 15 minutes.  The same counter
  runs per client address (30 failures in 15 minutes), so one machine cannot guess across many emails;
  keys whose failures have all expired are pruned, so the table cannot grow without bound.
* CPU and memory of password hashing: at most :data:`HASH_CONCURRENCY` hashes (argon2 or legacy scrypt) run
  at once (each takes 64 MiB and ≈ 90 ms of one core); a request that waits longer than :data:`HASH_WAIT_S`
  for a slot gets :class:`Busy` (the API answers 503), so a flood of logins cannot exhaust the machine.
* Roles: :data:`ROLES` (highest first) and :data:`ROLE_RANK` are the one definition the database, the API
  and the CLI use.
* CSRF: ``HMAC-SHA256(secret key, session id)`` — tied to the session, nothing extra to store, checked
  in constant time against the ``X-CSRF-Token`` header of every cookie-authenticated unsafe request.
"""

from __future__ import annotations

import base64
import functools
import hashlib
import hmac
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar
from app.choices import USER_ROLE_NAMES

if TYPE_CHECKING:
    from argon2 import PasswordHasher

MIN_PASSWORD_LENGTH = 10
TOKEN_PREFIX = "chk_"
#: argon2id cost of new hashes (module docstring): memory in KiB, passes, lanes
ARGON2_MEMORY_KIB, ARGON2_TIME_COST, ARGON2_PARALLELISM = 64 * 1024, 2, 1
#: the legacy scheme's prefix (hashes of earlier versions; verified, never made any more)
_SCRYPT_PREFIX = "scrypt$"
#: the roles of users and API tokens, highest first (admin > clinician > read_only)
ROLES: tuple[str, ...] = USER_ROLE_NAMES  # the one definition: app.choices.USER_ROLES
#: role → rank (higher may do more)
ROLE_RANK: dict[str, int] = {role: len(ROLES) - 1 - i for i, role in enumerate(ROLES)}
#: password hashes computed at the same time, at most; and how long a caller waits for a slot
HASH_CONCURRENCY = 2
HASH_WAIT_S = 10.0
_hash_slots = threading.BoundedSemaphore(HASH_CONCURRENCY)

_T = TypeVar("_T")


class Busy(RuntimeError):
    """Too many password checks at once; the caller should try again shortly."""


def _in_slot(work: Callable[..., _T], *args) -> _T:
    """Run one password hash in a slot of :data:`_hash_slots` (:class:`Busy` after :data:`HASH_WAIT_S`)."""
    if not _hash_slots.acquire(timeout=HASH_WAIT_S):
        raise Busy("the server is busy checking passwords; try again in a moment")
    try:
        return work(*args)
    finally:
        _hash_slots.release()


@functools.cache
def _argon2() -> PasswordHasher:
    """The hasher of new passwords (imported at first use: the CLI imports this module for :data:`ROLES`)."""
    from argon2 import PasswordHasher, Type

    return PasswordHasher(time_cost=ARGON2_TIME_COST, memory_cost=ARGON2_MEMORY_KIB, parallelism=ARGON2_PARALLELISM,
                          hash_len=32, salt_len=16, type=Type.ID)


def _scrypt(password: str, salt: bytes, n: int, r: int, p: int, dklen: int) -> bytes:
    return hashlib.scrypt(password.encode("utf-8"), salt=salt, n=n, r=r, p=p, dklen=dklen, maxmem=64 << 20)


def check_password_strength(password: str) -> None:
    """Raise ``ValueError`` when ``password`` is shorter than :data:`MIN_PASSWORD_LENGTH`."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise ValueError(f"the password must have at least {MIN_PASSWORD_LENGTH} characters; choose a longer one")


def hash_password(password: str) -> str:
    """An argon2id hash of ``password`` in PHC format, salted (module docstring for the parameters).
    Raises :class:`Busy` when no hashing slot frees up within :data:`HASH_WAIT_S`."""
    return _in_slot(_argon2().hash, password)


def _verify_scrypt(password: str, stored: str) -> bool:
    try:
        _, n, r, p, salt, digest = stored.split("$")  # the caller matched the "scrypt$" prefix
        expected = base64.b64decode(digest, validate=True)
        n_, r_, p_, salt_ = int(n), int(r), int(p), base64.b64decode(salt, validate=True)
    except (ValueError, TypeError):
        return False
    if not expected:
        return False
    try:
        got = _in_slot(_scrypt, password, salt_, n_, r_, p_, len(expected))
    except (ValueError, TypeError, OverflowError):  # parameters hashlib refuses: a damaged hash
        return False
    return hmac.compare_digest(got, expected)


def _verify_argon2(password: str, stored: str) -> bool:
    from argon2.exceptions import InvalidHashError, VerificationError

    try:
        return _in_slot(_argon2().verify, stored, password)
    except (VerificationError, InvalidHashError):  # wrong password (VerifyMismatchError) or a damaged hash
        return False


def verify_password(password: str, stored: str) -> bool:
    """True when ``password`` matches ``stored`` — an argon2 hash, or a legacy ``scrypt$…`` one (constant-time;
    False for a malformed or unknown hash).  Raises :class:`Busy` when no slot frees up within
    :data:`HASH_WAIT_S`.  After a True, call :func:`needs_rehash` and store a new hash if it says so."""
    if stored.startswith("$argon2"):
        return _verify_argon2(password, stored)
    if stored.startswith(_SCRYPT_PREFIX):
        return _verify_scrypt(password, stored)
    return False


def needs_rehash(stored: str) -> bool:
    """True when ``stored`` should be replaced by :func:`hash_password` at the next successful login: a
    legacy scrypt hash, or an argon2 hash whose type or parameters differ from today's."""
    from argon2.exceptions import InvalidHashError

    if not stored.startswith("$argon2"):
        return True
    try:
        return _argon2().check_needs_rehash(stored)
    except (InvalidHashError, ValueError):
        return True


def new_token() -> str:
    """A new API token (shown once to the person who creates it)."""
    return TOKEN_PREFIX + secrets.token_urlsafe(32)


def new_session_id() -> str:
    return secrets.token_urlsafe(32)


def sha256_hex(secret: str) -> str:
    """What is stored of a token or session id."""
    return hashlib.sha256(secret.encode("utf-8")).hexdigest()


def csrf_token(key: bytes, session_id: str) -> str:
    """The CSRF token of browser session ``session_id``."""
    return hmac.new(key, b"csrf:" + session_id.encode("utf-8"), hashlib.sha256).hexdigest()


def csrf_ok(key: bytes, session_id: str, header_value: str | None) -> bool:
    """True when ``header_value`` is the CSRF token of ``session_id`` (constant time)."""
    return bool(header_value) and hmac.compare_digest(csrf_token(key, session_id), header_value)


class LoginThrottle:
    """Failed-login counters per key (``email:<address>`` and ``ip:<address>``), in memory, thread-safe.

    ``max_failures`` within ``window_s`` blocks a key; :meth:`blocked` / :meth:`fail` / :meth:`reset` take the
    email and the client address together (per-IP limit ``max_ip_failures``).  Expired entries are pruned
    at most once per ``window_s / 10`` (and whenever the table passes ``max_keys``)."""

    def __init__(self, max_failures: int = 10, window_s: float = 900.0, max_ip_failures: int = 30,
                 max_keys: int = 10_000) -> None:
        self.max_failures, self.window_s, self.max_ip_failures = max_failures, window_s, max_ip_failures
        self.max_keys = max_keys
        self._failures: dict[str, deque[float]] = {}
        self._lock = threading.Lock()
        self._pruned = time.monotonic()

    def __len__(self) -> int:
        return len(self._failures)

    def _recent(self, key: str, now: float) -> deque[float]:
        q = self._failures.setdefault(key, deque())
        while q and q[0] < now - self.window_s:
            q.popleft()
        return q

    def _count(self, key: str, now: float) -> int:
        q = self._failures.get(key)
        if q is None:
            return 0
        while q and q[0] < now - self.window_s:
            q.popleft()
        return len(q)

    def _prune(self, now: float) -> None:
        if now - self._pruned < self.window_s / 10 and len(self._failures) <= self.max_keys:
            return
        self._pruned = now
        for key in [k for k, q in self._failures.items() if not q or q[-1] < now - self.window_s]:
            del self._failures[key]

    def blocked(self, email: str, ip: str | None = None) -> bool:
        """True when ``email`` (or the client address ``ip``) has too many recent failures."""
        with self._lock:
            now = time.monotonic()
            if self._count(f"email:{email}", now) >= self.max_failures:
                return True
            return ip is not None and self._count(f"ip:{ip}", now) >= self.max_ip_failures

    def fail(self, email: str, ip: str | None = None) -> None:
        """Count one failed login of ``email`` from ``ip``."""
        with self._lock:
            now = time.monotonic()
            self._prune(now)
            self._recent(f"email:{email}", now).append(now)
            if ip is not None:
                self._recent(f"ip:{ip}", now).append(now)

    def reset(self, email: str) -> None:
        """Forget ``email``'s failures (after a successful login; the address keeps its count)."""
        with self._lock:
            self._failures.pop(f"email:{email}", None)


__all__ = ["ARGON2_MEMORY_KIB", "ARGON2_PARALLELISM", "ARGON2_TIME_COST", "HASH_CONCURRENCY", "HASH_WAIT_S",
           "MIN_PASSWORD_LENGTH", "ROLES", "ROLE_RANK", "Busy", "LoginThrottle", "check_password_strength", "csrf_ok",
           "csrf_token", "hash_password", "needs_rehash", "new_session_id", "new_token", "sha256_hex",
           "verify_password"]
