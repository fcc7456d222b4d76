"""``/users``: the clinic's accounts (admin only).

* ``GET /users`` lists them; ``POST /users`` creates one (the password must pass :mod:`app.web.passwords`: 422 in
  the caller's language); ``PATCH /users/{id}`` changes a role or the active flag (an admin cannot change their
  own, so a clinic always keeps the admin who is acting); deactivating ends the user's browser sessions.
* ``POST /users/{id}/unlock`` clears the account's login counters (:mod:`app.web.throttle`): a user slowed down
  by failed logins — theirs or someone else's — can log in again at once.  It clears the email's counters and
  this clinic's account counter, never the counter of the same email's account in another clinic.

Only a caller holding what an account holds manages accounts: a browser session, or an API token with no scopes
and no end (:func:`app.web.api.deps.refuse_grant_beyond`; 403 for a scoped or expiring token, whose holder would
otherwise make itself an unlimited admin account).

Accounts are per clinic (issue 16 finding 10b): an email is unique within its clinic, and the same person may
have an account in several clinics (logging in names the clinic then: :mod:`app.web.api.auth`).  A new
account's email is refused (409, ``account.email_unavailable``) only when the caller's own clinic already has
it — which the admin can see in their own list anyway; accounts of other clinics are never looked at, so
creating an account tells an admin nothing about any other clinic.  Each refusal is recorded (``user_create``,
409).  Every creation and change is audited (:mod:`app.web.audit`).
"""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Request
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool

from app.store import accounts
from app.store.errors import Conflict
from app.web.api.deps import Admin, DbDep, refuse_grant_beyond
from app.web.api.schemas import RoleName, UserIn, UserOut, _In, user_out
from app.web.audit import record
from app.web.messages import refusal
from app.web.passwords import WeakPassword, check_password_strength
from app.web.security import Busy, hash_password_async
from app.web.throttle import LoginThrottle

router = APIRouter(prefix="/users", tags=["users"])


class UserAdminOut(UserOut):
    active: bool


class UserPatchIn(_In):
    role: RoleName | None = None
    active: bool | None = None


class UnlockOut(BaseModel):
    cleared: int
    status: Literal["unlocked"] = "unlocked"


def _admin_out(u) -> dict:
    return {**user_out(u), "active": u.active}


@router.get("", response_model=list[UserAdminOut])
def list_users(principal: Admin, db: DbDep):
    return [_admin_out(u) for u in accounts.clinic_users(db, principal.clinic_id)]


@router.post("", response_model=UserOut, status_code=201)
async def create_user(body: UserIn, request: Request, principal: Admin):
    """A new user of the caller's clinic (module docstring for the refusals)."""
    await run_in_threadpool(refuse_grant_beyond, request, principal, scopes=None, expires_at=None)
    email = body.email.lower()
    try:
        check_password_strength(body.password, email=email, name=body.name)
    except WeakPassword as error:
        raise refusal(request, 422, error.code, **error.params) from None
    try:
        password_hash = await hash_password_async(body.password)
    except Busy:
        raise refusal(request, 503, "password.busy", headers={"Retry-After": "2"}) from None

    def store() -> dict | None:
        db_ = request.app.state.db
        try:
            with db_.session() as s:
                user = accounts.add_user(s, principal.clinic_id, email=email, name=body.name, role=body.role,
                                         password_hash=password_hash)
                record(s, request, principal, "user_create", status=201, detail=f"user {user.id} role {user.role}")
                return user_out(user)
        except Conflict:  # taken in this clinic (module docstring)
            with db_.session() as s:
                record(s, request, principal, "user_create", status=409, detail="email already in use")
            return None

    out = await run_in_threadpool(store)
    if out is None:
        raise refusal(request, 409, "account.email_unavailable", email=email)
    return out


def _user_of_clinic(request: Request, principal: Admin, db: DbDep, user_id: int):
    user = accounts.clinic_user(db, principal.clinic_id, user_id)
    if user is None:
        raise refusal(request, 404, "account.no_user", id=user_id)
    return user


@router.patch("/{user_id}", response_model=UserAdminOut)
def change_user(user_id: int, body: UserPatchIn, request: Request, principal: Admin, db: DbDep):
    """Change a user's role or active flag (not one's own); deactivation ends their browser sessions."""
    user = _user_of_clinic(request, principal, db, user_id)
    refuse_grant_beyond(request, principal, scopes=None, expires_at=None)  # an account's role has no scopes nor end
    if principal.user is not None and principal.user.id == user.id and \
            (body.role not in (None, user.role) or body.active is False):
        raise refusal(request, 400, "account.not_yourself")
    changes = []
    if body.role is not None and body.role != user.role:
        changes.append(f"role {user.role} -> {body.role}")
        user.role = body.role
    if body.active is not None and body.active != user.active:
        changes.append("activated" if body.active else "deactivated")
        user.active = body.active
        if not body.active:
            ended = accounts.close_user_browser_sessions(db, user.id)
            changes.append(f"{ended} session(s) ended")
    if changes:
        record(db, request, principal, "user_change", status=200, detail=f"user {user.id}: " + ", ".join(changes))
    return _admin_out(user)


@router.post("/{user_id}/unlock", response_model=UnlockOut)
def unlock_user(user_id: int, request: Request, principal: Admin, db: DbDep):
    """Clear the user's login counters: they can log in again at once (module docstring)."""
    user = _user_of_clinic(request, principal, db, user_id)
    refuse_grant_beyond(request, principal, scopes=None, expires_at=None)  # gives an account its logins back
    cleared = LoginThrottle.unlock(db, user.email, user.clinic.name)
    record(db, request, principal, "unlock", status=200, detail=f"user {user.id}: {cleared} counter(s) cleared")
    return {"cleared": cleared}


__all__ = ["router"]
