"""Passwords, API tokens, browser sessions and CSRF tokens.

* Passwords: ``hashlib.scrypt`` (n=2**14, r=8, p=1, 32 bytes) with a random 16-byte salt per password,
  stored as ``scrypt$n$r$p$salt$hash`` (base64) so the cost can rise later; verified with
  ``hmac.compare_digest``.  Minimum length 10 characters; no default passwords anywhere.
* API tokens: ``chk_`` + ``secrets.token_urlsafe(32)`` (256 bits), shown once; only their sha256 is stored
  (a fast hash is right for 256-bit random secrets: there is nothing to brute-force).
* Browser sessions: a random id in the ``chakamo_session`` cookie, stored as its sha256.
* Login throttling (:class:`LoginThrottle`): after 10 failed logins for one email within 15 minutes, that
  email's logins are refused (429) until the window passes — online password guessing stays slow; the
  price is that someone who knows an email can delay its owner's login by 15 minutes.  The same counter
  runs per client address (30 failures in 15 minutes), so one machine cannot guess across many emails;
  keys whose failures have all expired are pruned, so the table cannot grow without bound.
* CPU and memory of scrypt: at most :data:`SCRYPT_CONCURRENCY` hashes run at once (each takes ≈16 MB and
  tens of ms of one core); a request that waits longer than :data:`SCRYPT_WAIT_S` for a slot gets
  :class:`Busy` (the API answers 503), so a flood of logins cannot exhaust the machine.
* Roles: :data:`ROLES` (highest first) and :data:`ROLE_RANK` are the one definition the database, the API
  and the CLI use.
* CSRF: ``HMAC-SHA256(secret key, session id)`` — tied to the session, nothing extra to store, checked
  in constant time against the ``X-CSRF-Token`` header of every cookie-authenticated unsafe request.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import secrets
import threading
import time
from collections import deque

MIN_PASSWORD_LENGTH = 10
TOKEN_PREFIX = "chk_"
_N, _R, _P, _LEN = 2 ** 14, 8, 1, 32
#: the roles of users and API tokens, highest first (admin > clinician > read_only)
ROLES: tuple[str, ...] = ("admin", "clinician", "read_only")
#: role → rank (higher may do more)
ROLE_RANK: dict[str, int] = {role: len(ROLES) - 1 - i for i, role in enumerate(ROLES)}
#: scrypt hashes computed at the same time, at most; and how long a caller waits for a slot
SCRYPT_CONCURRENCY = 2
SCRYPT_WAIT_S = 10.0
_scrypt_slots = threading.BoundedSemaphore(SCRYPT_CONCURRENCY)


class Busy(RuntimeError):
    """Too many password checks at once; the caller should try again shortly."""


def _scrypt(password: str, salt: bytes, n: int, r: int, p: int, dklen: int) -> bytes:
    if not _scrypt_slots.acquire(timeout=SCRYPT_WAIT_S):
        raise Busy("the server is busy checking passwords; try again in a moment")
    try:
        return hashlib.scrypt(password.encode("utf-8"), salt=salt, n=n, r=r, p=p, dklen=dklen, maxmem=64 << 20)
    finally:
        _scrypt_slots.release()


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def check_password_strength(password: str) -> None:
    """Raise ``ValueError`` when ``password`` is shorter than :data:`MIN_PASSWORD_LENGTH`."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise ValueError(f"the password must have at least {MIN_PASSWORD_LENGTH} characters; choose a longer one")


def hash_password(password: str) -> str:
    """A salted scrypt hash of ``password`` (module docstring for the format)."""
    salt = secrets.token_bytes(16)
    digest = _scrypt(password, salt, _N, _R, _P, _LEN)
    return f"scrypt${_N}${_R}${_P}${_b64(salt)}${_b64(digest)}"


def verify_password(password: str, stored: str) -> bool:
    """True when ``password`` matches ``stored`` (constant-time comparison; False for a malformed hash).
    Raises :class:`Busy` when no scrypt slot frees up within :data:`SCRYPT_WAIT_S`."""
    try:
        scheme, n, r, p, salt, digest = stored.split("$")
        if scheme != "scrypt":
            return False
        expected = base64.b64decode(digest)
        n_, r_, p_, salt_ = int(n), int(r), int(p), base64.b64decode(salt)
    except (ValueError, TypeError):
        return False
    try:
        got = _scrypt(password, salt_, n_, r_, p_, len(expected))
    except (ValueError, TypeError):
        return False
    return hmac.compare_digest(got, expected)


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


__all__ = ["MIN_PASSWORD_LENGTH", "ROLES", "ROLE_RANK", "Busy", "LoginThrottle", "check_password_strength", "csrf_ok",
           "csrf_token", "hash_password", "new_session_id", "new_token", "sha256_hex", "verify_password"]
