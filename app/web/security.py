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
  No default passwords anywhere; the strength rules (at least 12 characters, no common or patterned
  password) are :mod:`app.web.passwords`.
* API tokens: ``chk_`` + ``secrets.token_urlsafe(32)`` (256 bits), shown once; only their sha256 is stored
  (a fast hash is right for 256-bit random secrets: there is nothing to brute-force).
* Browser sessions: a random id in the ``chakamo_session`` cookie, stored as its sha256.
* Login throttling: :mod:`app.web.throttle` (attempts reserved in the database before the password is checked).
* CPU and memory of password hashing (issue 16 finding 2): every hash (argon2 or legacy scrypt) runs on one of
  :data:`HASH_CONCURRENCY` dedicated threads (half the machine's cores, at least one: each hash takes 64 MiB
  and ≈ 90 ms of one core, and the other half stays for everybody else's requests).  At most
  :data:`HASH_QUEUE` more wait for a thread; one more gets :class:`Busy` *at once* (the API answers 503 with
  ``Retry-After``) — a flood of logins neither exhausts the machine nor piles up.  :func:`verify_password_async`
  and :func:`hash_password_async` await the hash without holding a request thread (the login route is
  ``async``); the plain functions (CLI, user creation) block their caller's thread on the same bounded pool.
  argon2-cffi releases the GIL while it hashes, so the other requests' Python code keeps running.
* Roles: :data:`ROLES` (highest first) and :data:`ROLE_RANK` are the one definition the database, the API
  and the CLI use.
* CSRF: ``HMAC-SHA256(secret key, session id)`` — tied to the session, nothing extra to store, checked
  in constant time against the ``X-CSRF-Token`` header of every cookie-authenticated unsafe request.
"""

from __future__ import annotations

import asyncio
import base64
import functools
import hashlib
import hmac
import os
import secrets
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, TypeVar

from app.choices import USER_ROLE_NAMES
from app.web.messages import render
from app.web.passwords import MIN_PASSWORD_LENGTH, check_password_strength

if TYPE_CHECKING:
    from argon2 import PasswordHasher

TOKEN_PREFIX = "chk_"
#: argon2id cost of new hashes (module docstring): memory in KiB, passes, lanes
ARGON2_MEMORY_KIB, ARGON2_TIME_COST, ARGON2_PARALLELISM = 64 * 1024, 2, 1
#: the legacy scheme's prefix (hashes of earlier versions; verified, never made any more)
_SCRYPT_PREFIX = "scrypt$"
#: the roles of users and API tokens, highest first (admin > clinician > read_only)
ROLES: tuple[str, ...] = USER_ROLE_NAMES  # the one definition: app.choices.USER_ROLES
#: role → rank (higher may do more)
ROLE_RANK: dict[str, int] = {role: len(ROLES) - 1 - i for i, role in enumerate(ROLES)}
#: password hashes computed at the same time (threads of :data:`_hash_pool`), and how many more may wait
HASH_CONCURRENCY = max(1, (os.cpu_count() or 2) // 2)
HASH_QUEUE = 4 * HASH_CONCURRENCY
_hash_pool = ThreadPoolExecutor(HASH_CONCURRENCY, thread_name_prefix="password-hash")
_admitted = 0  # hashes running or waiting in _hash_pool
_admitted_lock = threading.Lock()

_T = TypeVar("_T")


class Busy(RuntimeError):
    """Too many password checks at once; the caller should try again shortly.  ``str()`` is the English of
    :data:`code` (``password.busy`` of :data:`app.web.messages.CATALOGUE`), :meth:`message` any language: the
    routes answer it as that refusal (503, in the request's language)."""

    code = "password.busy"

    def __str__(self) -> str:
        return self.message("en")

    def message(self, lang: str) -> str:
        return render(self.code, lang)


def hashes_admitted() -> int:
    """How many password hashes run or wait right now (at most ``HASH_CONCURRENCY + HASH_QUEUE``)."""
    return _admitted


def hash_capacity() -> int:
    """How many password hashes may run or wait at once: :data:`HASH_CONCURRENCY` + :data:`HASH_QUEUE`."""
    return HASH_CONCURRENCY + HASH_QUEUE


def hash_queue_full() -> bool:
    """True when a new hash would get :class:`Busy` (every thread and queue place taken)."""
    return _admitted >= hash_capacity()


def _submit(work: Callable[..., _T], *args) -> Future:
    """``work(*args)`` on :data:`_hash_pool`, or :class:`Busy` at once when the pool and its queue are full."""
    global _admitted
    with _admitted_lock:
        if _admitted >= hash_capacity():
            raise Busy()
        _admitted += 1

    def run():
        global _admitted
        try:
            return work(*args)
        finally:
            with _admitted_lock:
                _admitted -= 1

    return _hash_pool.submit(run)


def _in_slot(work: Callable[..., _T], *args) -> _T:
    """Run one password hash on the bounded pool, blocking this thread until it is done."""
    return _submit(work, *args).result()


@functools.cache
def _argon2() -> PasswordHasher:
    """The hasher of new passwords (imported at first use: the CLI imports this module for :data:`ROLES`)."""
    from argon2 import PasswordHasher, Type

    return PasswordHasher(time_cost=ARGON2_TIME_COST, memory_cost=ARGON2_MEMORY_KIB, parallelism=ARGON2_PARALLELISM,
                          hash_len=32, salt_len=16, type=Type.ID)


def _scrypt(password: str, salt: bytes, n: int, r: int, p: int, dklen: int) -> bytes:
    return hashlib.scrypt(password.encode("utf-8"), salt=salt, n=n, r=r, p=p, dklen=dklen, maxmem=64 << 20)


def hash_password(password: str) -> str:
    """An argon2id hash of ``password`` in PHC format, salted (module docstring for the parameters).
    Raises :class:`Busy` at once when every hashing thread and queue place is taken."""
    return _in_slot(_argon2().hash, password)


async def hash_password_async(password: str) -> str:
    """:func:`hash_password` awaited: the caller's thread (an event loop) is free while the hash runs."""
    return await asyncio.wrap_future(_submit(_argon2().hash, password))


def _scrypt_params(stored: str) -> tuple[bytes, int, int, int, bytes] | None:
    """``(salt, n, r, p, digest)`` of a legacy ``scrypt$n$r$p$salt$hash`` string, or None when it is damaged."""
    try:
        _, n, r, p, salt, digest = stored.split("$")  # the caller matched the "scrypt$" prefix
        expected = base64.b64decode(digest, validate=True)
        n_, r_, p_, salt_ = int(n), int(r), int(p), base64.b64decode(salt, validate=True)
    except (ValueError, TypeError):
        return None
    return (salt_, n_, r_, p_, expected) if expected else None


def _check_scrypt(password: str, salt: bytes, n: int, r: int, p: int, expected: bytes) -> bool:
    try:
        got = _scrypt(password, salt, n, r, p, len(expected))
    except (ValueError, TypeError, OverflowError):  # parameters hashlib refuses: a damaged hash
        return False
    return hmac.compare_digest(got, expected)


def _check_argon2(password: str, stored: str) -> bool:
    from argon2.exceptions import InvalidHashError, VerificationError

    try:
        return _argon2().verify(stored, password)
    except (VerificationError, InvalidHashError):  # wrong password (VerifyMismatchError) or a damaged hash
        return False


def _verification(password: str, stored: str) -> tuple[Callable[..., bool], tuple] | None:
    """The work that checks ``password`` against ``stored`` (None: a malformed or unknown hash, False at once)."""
    if stored.startswith("$argon2"):
        return _check_argon2, (password, stored)
    if stored.startswith(_SCRYPT_PREFIX):
        params = _scrypt_params(stored)
        return (_check_scrypt, (password, *params)) if params else None
    return None


def verify_password(password: str, stored: str) -> bool:
    """True when ``password`` matches ``stored`` — an argon2 hash, or a legacy ``scrypt$…`` one (constant-time;
    False for a malformed or unknown hash).  Raises :class:`Busy` at once when the hashing pool is full.
    After a True, call :func:`needs_rehash` and store a new hash if it says so."""
    work = _verification(password, stored)
    return _in_slot(work[0], *work[1]) if work else False


async def verify_password_async(password: str, stored: str) -> bool:
    """:func:`verify_password` awaited without holding the caller's thread (module docstring)."""
    work = _verification(password, stored)
    if work is None:
        return False
    return await asyncio.wrap_future(_submit(work[0], *work[1]))


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


__all__ = ["ARGON2_MEMORY_KIB", "ARGON2_PARALLELISM", "ARGON2_TIME_COST", "HASH_CONCURRENCY", "HASH_QUEUE",
           "MIN_PASSWORD_LENGTH", "ROLES", "ROLE_RANK", "Busy", "check_password_strength", "csrf_ok", "csrf_token",
           "hash_capacity", "hash_password", "hash_password_async", "hash_queue_full", "hashes_admitted", "needs_rehash", "new_session_id", "new_token",
           "sha256_hex", "verify_password", "verify_password_async"]
