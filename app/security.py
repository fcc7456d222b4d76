"""Passwords, API tokens, browser sessions and CSRF tokens.

* Passwords: ``hashlib.scrypt`` (n=2**14, r=8, p=1, 32 bytes) with a random 16-byte salt per password,
  stored as ``scrypt$n$r$p$salt$hash`` (base64) so the cost can rise later; verified with
  ``hmac.compare_digest``.  Minimum length 10 characters; no default passwords anywhere.
* API tokens: ``chk_`` + ``secrets.token_urlsafe(32)`` (256 bits), shown once; only their sha256 is stored
  (a fast hash is right for 256-bit random secrets: there is nothing to brute-force).
* Browser sessions: a random id in the ``chakamo_session`` cookie, stored as its sha256.
* Login throttling (:class:`LoginThrottle`): after 10 failed logins for one email within 15 minutes, that
  email's logins are refused (429) until the window passes — online password guessing stays slow; the
  price is that someone who knows an email can delay its owner's login by 15 minutes.
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


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def check_password_strength(password: str) -> None:
    """Raise ``ValueError`` when ``password`` is shorter than :data:`MIN_PASSWORD_LENGTH`."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise ValueError(f"the password must have at least {MIN_PASSWORD_LENGTH} characters; choose a longer one")


def hash_password(password: str) -> str:
    """A salted scrypt hash of ``password`` (module docstring for the format)."""
    salt = secrets.token_bytes(16)
    digest = hashlib.scrypt(password.encode("utf-8"), salt=salt, n=_N, r=_R, p=_P, dklen=_LEN, maxmem=64 << 20)
    return f"scrypt${_N}${_R}${_P}${_b64(salt)}${_b64(digest)}"


def verify_password(password: str, stored: str) -> bool:
    """True when ``password`` matches ``stored`` (constant-time comparison; False for a malformed hash)."""
    try:
        scheme, n, r, p, salt, digest = stored.split("$")
        if scheme != "scrypt":
            return False
        expected = base64.b64decode(digest)
        got = hashlib.scrypt(password.encode("utf-8"), salt=base64.b64decode(salt), n=int(n), r=int(r), p=int(p),
                             dklen=len(expected), maxmem=64 << 20)
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
    """Failed-login counter per key (the email), in memory, thread-safe (module docstring)."""

    def __init__(self, max_failures: int = 10, window_s: float = 900.0) -> None:
        self.max_failures, self.window_s = max_failures, window_s
        self._failures: dict[str, deque[float]] = {}
        self._lock = threading.Lock()

    def _recent(self, key: str, now: float) -> deque[float]:
        q = self._failures.setdefault(key, deque())
        while q and q[0] < now - self.window_s:
            q.popleft()
        return q

    def blocked(self, key: str) -> bool:
        with self._lock:
            return len(self._recent(key, time.monotonic())) >= self.max_failures

    def fail(self, key: str) -> None:
        with self._lock:
            self._recent(key, time.monotonic()).append(time.monotonic())

    def reset(self, key: str) -> None:
        with self._lock:
            self._failures.pop(key, None)


__all__ = ["MIN_PASSWORD_LENGTH", "LoginThrottle", "check_password_strength", "csrf_ok", "csrf_token", "hash_password", "new_session_id",
           "new_token", "sha256_hex", "verify_password"]
