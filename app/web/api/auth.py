"""``/auth``: browser login (session cookie + CSRF token), logout, who am I, and the user's own account:
password change and the list of their open sessions.

The cookie ``chakamo_session`` is HttpOnly, SameSite=Strict, ``Secure`` outside development, and lives
``CHAKAMO_SESSION_HOURS``; only its sha256 is stored.  A wrong email and a wrong password get the same 401
after the same argon2 work, so login does not reveal which emails exist.  The client address is the
connection's peer: behind a reverse proxy run uvicorn with ``--proxy-headers`` so that it is the browser's.

Login, in order (issue 16 findings 1, 2, 10a; :mod:`app.web.throttle`, :mod:`app.web.security`):

1. more than :attr:`~app.web.throttle.ThrottlePolicy.max_in_flight` logins of this address inside the server →
   429 at once; as many logins inside the server as the hashing queue holds, or that queue full → 503 at once
   (both with ``Retry-After``, no database work and no request thread taken; answered by the ASGI middleware
   :class:`app.web.throttle.LoginGate` before the request reaches this route);
2. an attempt is reserved on the email's and the address's counters, atomically in the database, *before*
   the password is checked; a counter still in its progressive delay → 429 with ``Retry-After``, no check,
   recorded as ``login_refused`` — for an unknown email too (in no clinic), so that a refusal costs the same
   work (one read, one audit write) whether the email has an account or not and its timing tells nothing;
3. the password is checked on the bounded hashing pool, awaited: this ``async`` route holds no request thread
   while it waits (the database steps run on the thread pool, a few milliseconds each);
4. success resets the counters, opens the session and records ``login``; failure records ``login_failed``
   (the same statements for an unknown email as for a wrong password: the account row is looked up either way).

Accounts are per clinic (issue 16 finding 10b): an email may have an account in several clinics.  The login
body's optional ``clinic`` (the clinic's name) picks one; without it the email's only account is used, and an
email with several accounts is refused like an unknown one (:func:`app.store.accounts.login_account`; the 401
sentence says to name the clinic), so nobody learns from a login how many clinics know an email.  The throttle's
counters stay keyed by the email (the person behind it), whichever of their accounts is tried.

A successful login whose stored hash is of an older scheme or weaker parameters
(:func:`app.web.security.needs_rehash`: the scrypt hashes of earlier versions) stores a new argon2id hash of the
password just checked; when the hashing queue is full at that moment the upgrade waits for the next login.

Account (cookie callers only; an API token has neither password nor sessions: 400):

* ``POST /auth/password`` ``{"current_password", "new_password"}`` — the current password is checked (and
  throttled like a login), the new one must pass :mod:`app.web.passwords`; every *other* session of the user
  ends (ASVS 3.3.3), this one stays.
* ``GET /auth/sessions`` — the user's open sessions (opened, expires, address, browser, ``current``);
  ``DELETE /auth/sessions/{id}`` ends one of the others, ``POST /auth/end-other-sessions`` all of them.

Refusals speak the request's language (:mod:`app.web.messages`).
"""

from __future__ import annotations

import base64
import functools
import secrets
from typing import Annotated

from fastapi import APIRouter, Depends, Request, Response
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool

from app.store import accounts
from app.web.api.deps import COOKIE, DbDep, Principal, PrincipalDep, SettingsDep
from app.web.api.schemas import LoginIn, MeOut, _In, user_out
from app.web.audit import record, record_login
from app.web.messages import refusal
from app.web.passwords import WeakPassword, check_password_strength
from app.web.security import (ARGON2_MEMORY_KIB, ARGON2_PARALLELISM, ARGON2_TIME_COST, Busy, csrf_token,
                              hash_password_async, needs_rehash, new_session_id, sha256_hex,
                              verify_password_async)

router = APIRouter(prefix="/auth", tags=["auth"])


@functools.cache
def _dummy_hash() -> str:
    """A hash to check unknown emails against: today's argon2id parameters with a random salt and digest, so
    checking it costs exactly what checking a real one costs (it matches no password).  Built, not hashed: no
    hashing slot is spent on it, whatever the load."""
    def b64(n: int) -> str:
        return base64.b64encode(secrets.token_bytes(n)).decode().rstrip("=")

    return (f"$argon2id$v=19$m={ARGON2_MEMORY_KIB},t={ARGON2_TIME_COST},p={ARGON2_PARALLELISM}"
            f"${b64(16)}${b64(32)}")


def _address(request: Request) -> str | None:
    return request.client.host if request.client else None


def _begin(request: Request, email: str, clinic: str | None, ip: str | None) -> tuple[float, tuple | None]:
    """Reserve the attempt (:meth:`app.web.throttle.LoginThrottle.reserve`) and find the account; a refused
    reservation is recorded (``login_refused``), whether the email has an account or not (module docstring,
    step 2).  Returns ``(wait_s, (id, hash, active) or None)``."""
    state = request.app.state
    wait_s = state.login_throttle.reserve(email, ip, clinic)
    with state.db.session() as s:
        user = accounts.login_account(s, email, clinic)
        if wait_s:
            record_login(s, request, "login_refused", email=email, user=user, status=429,
                         detail=f"throttled: wait {wait_s:g} s")
        return wait_s, (user.id, user.password_hash, user.active) if user else None


def _finish(request: Request, response: Response, email: str, clinic: str | None, ip: str | None,
            user_id: int | None, ok: bool, verified: str | None, new_hash: str | None) -> dict:
    """Record the outcome; on success reset the counters, store ``new_hash`` if any, open the session.

    The user's row is locked and its hash must still be ``verified``, the one the password was checked against:
    a password changed or reset while this login was being checked (an operator locking out a leaked password)
    wins, and the login is refused rather than opening a session with the old password or writing the old
    password's rehash over the new one."""
    state = request.app.state
    settings = state.settings
    with state.db.session() as s:
        # looked up (and locked) for an unknown email too, as id 0 that no row has: the same statements either way
        user = accounts.user_by_id(s, user_id if user_id is not None else 0, lock=True)
        changed = ok and user is not None and user.password_hash != verified
        if not ok or user is None or not user.active or changed:
            reason = ("unknown email" if user is None else "account deactivated" if not user.active
                      else "password changed during the login" if changed else "wrong password")
            record_login(s, request, "login_failed", email=email, user=user, status=401, detail=reason)
            return {}
        state.login_throttle.succeeded(s, email, ip, clinic)
        if new_hash:
            user.password_hash = new_hash
        sid = new_session_id()
        accounts.open_browser_session(s, user.id, sha256_hex(sid), settings.session_hours, client=ip or "",
                                      user_agent=request.headers.get("user-agent", ""))
        record_login(s, request, "login", email=email, user=user, status=200)
        out = {"user": user_out(user), "csrf_token": csrf_token(settings.key, sid)}
    response.set_cookie(COOKIE, sid, max_age=int(settings.session_hours * 3600), httponly=True, samesite="strict",
                        secure=not settings.development, path="/")
    return out


@router.post("/login", response_model=MeOut)
async def login(body: LoginIn, request: Request, response: Response):
    """Check email and password; set the session cookie; return the user and the CSRF token (module docstring)."""
    email, ip = body.email.lower(), _address(request)
    # step 1 (the per-address and per-server caps, a full hashing queue) is app.web.throttle.LoginGate
    wait_s, found = await run_in_threadpool(_begin, request, email, body.clinic, ip)
    if wait_s:
        raise refusal(request, 429, "login.throttled", headers={"Retry-After": f"{wait_s:.0f}"},
                      seconds=f"{wait_s:.0f}")
    user_id, stored, _active = found if found else (None, None, False)
    try:
        stored = stored or _dummy_hash()
        ok = await verify_password_async(body.password, stored)
    except Busy:  # the queue filled between the check above and now: the attempt stays counted
        raise refusal(request, 503, "login.busy", headers={"Retry-After": "2"}) from None
    new_hash = None
    if ok and found and needs_rehash(stored):
        try:
            new_hash = await hash_password_async(body.password)
        except Busy:  # the old hash still works; it is upgraded at a later login
            pass
    out = await run_in_threadpool(_finish, request, response, email, body.clinic, ip, user_id,
                                  ok and found is not None, stored, new_hash)
    if not out:
        raise refusal(request, 401, "login.wrong")
    return out


@router.post("/logout", status_code=204)
def logout(request: Request, principal: PrincipalDep, db: DbDep, settings: SettingsDep) -> Response:
    """Close the browser session (a bearer caller has none: nothing to do) and clear the cookie."""
    if principal.session_id:
        accounts.close_browser_session(db, sha256_hex(principal.session_id))
        record(db, request, principal, "logout", status=204)
    response = Response(status_code=204)
    response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict", secure=not settings.development)
    return response


@router.get("/me", response_model=MeOut)
def me(principal: PrincipalDep):
    """The logged-in user and CSRF token; for a bearer token, ``user`` is null and so is ``csrf_token``."""
    return {"user": user_out(principal.user) if principal.user else None, "csrf_token": principal.csrf_token}


# ---------------------------------------------------------------------------------------------- account
def _browser_user(request: Request, principal: PrincipalDep) -> Principal:
    if principal.user is None or not principal.session_id:
        raise refusal(request, 400, "account.browser_only")
    return principal


BrowserUser = Annotated[Principal, Depends(_browser_user)]


class PasswordChangeIn(_In):
    current_password: str = Field(min_length=1, max_length=1000)
    new_password: str = Field(min_length=1, max_length=1000)


class SessionInfoOut(BaseModel):
    id: int
    created_at: str
    expires_at: str
    client: str
    user_agent: str
    current: bool


def _weak(request: Request, error: WeakPassword):
    return refusal(request, 422, error.code, **error.params)


@router.post("/password")
async def change_password(body: PasswordChangeIn, request: Request, principal: BrowserUser):
    """Change the caller's password; every other session of theirs ends (module docstring)."""
    user, ip = principal.user, _address(request)
    try:
        check_password_strength(body.new_password, email=user.email, name=user.name)
    except WeakPassword as error:
        raise _weak(request, error) from None
    wait_s = await run_in_threadpool(request.app.state.login_throttle.reserve, user.email, ip, user.clinic.name)
    if wait_s:
        raise refusal(request, 429, "login.throttled", headers={"Retry-After": f"{wait_s:.0f}"},
                      seconds=f"{wait_s:.0f}")
    try:
        ok = await verify_password_async(body.current_password, user.password_hash)
        new_hash = await hash_password_async(body.new_password) if ok else None
    except Busy:
        raise refusal(request, 503, "password.busy", headers={"Retry-After": "2"}) from None

    def store() -> int | None:
        with request.app.state.db.session() as s:
            if not ok:
                record(s, request, principal, "password_change", status=400, detail="wrong current password")
                return None
            row = accounts.user_by_id(s, user.id)
            row.password_hash = new_hash
            request.app.state.login_throttle.succeeded(s, user.email, ip, user.clinic.name)
            ended = accounts.close_user_browser_sessions(s, user.id, keep_sha256=sha256_hex(principal.session_id))
            record(s, request, principal, "password_change", status=200,
                   detail=f"self-service; {ended} other session(s) ended")
            return ended

    ended = await run_in_threadpool(store)
    if ended is None:
        raise refusal(request, 400, "password.wrong_current")
    return {"ended_sessions": ended}


@router.get("/sessions", response_model=list[SessionInfoOut])
def list_sessions(principal: BrowserUser, db: DbDep):
    """The caller's open browser sessions, newest first; ``current`` marks the one of this request."""
    mine = sha256_hex(principal.session_id)
    return [{"id": r.id, "created_at": r.created_at.isoformat(), "expires_at": r.expires_at.isoformat(),
             "client": r.client or "", "user_agent": r.user_agent or "", "current": r.session_sha256 == mine}
            for r in accounts.user_browser_sessions(db, principal.user.id)]


@router.delete("/sessions/{session_id}", status_code=204)
def end_session(session_id: int, request: Request, principal: BrowserUser, db: DbDep) -> Response:
    """End one of the caller's other sessions (the current one ends with logout)."""
    rows = {r.id: r for r in accounts.user_browser_sessions(db, principal.user.id)}
    if session_id not in rows:
        raise refusal(request, 404, "account.no_session", id=session_id)
    if rows[session_id].session_sha256 == sha256_hex(principal.session_id):
        raise refusal(request, 400, "account.this_session")
    accounts.close_user_browser_sessions(db, principal.user.id, only_id=session_id)
    record(db, request, principal, "session_end", status=204, detail=f"browser session {session_id}")
    return Response(status_code=204)


@router.post("/end-other-sessions")
def end_other_sessions(request: Request, principal: BrowserUser, db: DbDep):
    """End every session of the caller but this one; returns how many ended."""
    ended = accounts.close_user_browser_sessions(db, principal.user.id, keep_sha256=sha256_hex(principal.session_id))
    record(db, request, principal, "session_end", status=200, detail=f"{ended} other session(s) ended")
    return {"ended_sessions": ended}
