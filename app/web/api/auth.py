"""``/auth``: browser login (session cookie + CSRF token), logout, and who am I.

The cookie ``chakamo_session`` is HttpOnly, SameSite=Strict, ``Secure`` outside development, and lives
``CHAKAMO_SESSION_HOURS``; only its sha256 is stored.  A wrong email and a wrong password get the same 401
after the same argon2 work, so login does not reveal which emails exist; repeated failures for one email, or
from one client address, are throttled (:class:`app.web.security.LoginThrottle`: 429); when too many password
checks run at once the answer is 503 (:class:`app.web.security.Busy`), never an exhausted machine.  The client
address is the connection's peer: behind a reverse proxy run uvicorn with ``--proxy-headers`` so that it is
the browser's.

A successful login whose stored hash is of an older scheme or weaker parameters
(:func:`app.web.security.needs_rehash`: the scrypt hashes of earlier versions) stores a new argon2id hash of the
password just checked, in the login's own transaction; when no hashing slot is free at that moment the
login still succeeds and the upgrade waits for the next one.
"""

from __future__ import annotations

import functools

from fastapi import APIRouter, HTTPException, Request, Response

from app.store import accounts
from app.web.api.deps import COOKIE, DbDep, PrincipalDep, SettingsDep
from app.web.api.schemas import LoginIn, MeOut, user_out
from app.web.security import Busy, csrf_token, hash_password, needs_rehash, new_session_id, sha256_hex, verify_password

router = APIRouter(prefix="/auth", tags=["auth"])


@functools.cache
def _dummy_hash() -> str:
    """A hash to check unknown emails against (same argon2 work); made at the first login, not at import."""
    return hash_password("not-a-real-password-only-for-equal-timing")


@router.post("/login", response_model=MeOut)
def login(body: LoginIn, request: Request, response: Response, db: DbDep, settings: SettingsDep):
    """Check email and password; set the session cookie; return the user and the CSRF token."""
    email = body.email.lower()
    ip = request.client.host if request.client else None
    throttle = request.app.state.login_throttle
    if throttle.blocked(email, ip):
        raise HTTPException(429, "Too many failed logins for this email or from this computer; wait 15 minutes "
                                 "and try again, or ask your clinic admin.")
    user = accounts.user_by_email(db, email)
    try:
        ok = verify_password(body.password, user.password_hash if user else _dummy_hash())
    except Busy:
        raise HTTPException(503, "The server is busy checking other logins; try again in a moment.",
                            headers={"Retry-After": "5"}) from None
    if user is None or not ok or not user.active:
        throttle.fail(email, ip)
        raise HTTPException(401, "Wrong email or password; try again or ask your clinic admin to reset it.")
    throttle.reset(email)
    if needs_rehash(user.password_hash):
        try:
            user.password_hash = hash_password(body.password)
        except Busy:  # the old hash still works; it is upgraded at a later login
            pass
    sid = new_session_id()
    accounts.open_browser_session(db, user.id, sha256_hex(sid), settings.session_hours)
    response.set_cookie(COOKIE, sid, max_age=int(settings.session_hours * 3600), httponly=True, samesite="strict",
                        secure=not settings.development, path="/")
    return {"user": user_out(user), "csrf_token": csrf_token(settings.key, sid)}


@router.post("/logout", status_code=204)
def logout(principal: PrincipalDep, db: DbDep, settings: SettingsDep) -> Response:
    """Close the browser session (a bearer caller has none: nothing to do) and clear the cookie."""
    if principal.session_id:
        accounts.close_browser_session(db, sha256_hex(principal.session_id))
    response = Response(status_code=204)
    response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict", secure=not settings.development)
    return response


@router.get("/me", response_model=MeOut)
def me(principal: PrincipalDep):
    """The logged-in user and CSRF token; for a bearer token, ``user`` is null and so is ``csrf_token``."""
    return {"user": user_out(principal.user) if principal.user else None, "csrf_token": principal.csrf_token}
