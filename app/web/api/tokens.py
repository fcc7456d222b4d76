"""``/tokens``: the clinic's API tokens for hospital systems (admin only), as ``chakamo tokens`` does on the server.

* ``GET /tokens`` lists them (never the token: only its sha256 is stored), with their state (``active``,
  ``expired``, ``revoked``), role, scopes and expiry.
* ``POST /tokens`` creates one (:func:`app.store.tokens.add_token`: a role, optional scopes of
  :data:`app.choices.TOKEN_SCOPES` and a lifetime in days); the answer carries the token in clear, the only time
  it exists so, to be copied into the hospital system.
* ``POST /tokens/{id}/rotate`` creates its successor (same label, role, scopes and lifetime) and lets the old one
  work for ``grace_hours`` more (:func:`app.store.tokens.rotate_token`); the new token is in the answer, once.
* ``POST /tokens/{id}/revoke`` ends it at once (401 from then on); revoking a revoked token changes nothing.

Another clinic's token is 404 like an unknown id.  Every creation, rotation and revocation is audited
(``token_create`` / ``token_rotate`` / ``token_revoke``, :mod:`app.web.audit`) in the transaction that makes it.

A token never outgrows the token that made it (:func:`app.web.api.deps.refuse_grant_beyond`): an admin calling
with an API token creates or rotates only tokens whose scopes are among its own and which end no later than it
(403 otherwise; a token rotating itself is refused when it has an end, as its successor would end later).  An
admin logged in to the browser, or ``chakamo tokens`` on the server, is not limited so.
"""

from __future__ import annotations

import datetime as dt
from typing import Literal

from fastapi import APIRouter, Request
from pydantic import BaseModel, Field

from app.choices import TOKEN_SCOPES
from app.store import tokens
from app.store.models import utcnow
from app.web.api.deps import Admin, DbDep, refuse_grant_beyond
from app.web.api.schemas import RoleName, _In
from app.web.audit import record
from app.web.security import new_token, sha256_hex

router = APIRouter(prefix="/tokens", tags=["tokens"])
Scope = Literal[TOKEN_SCOPES]  # type: ignore[valid-type]


class TokenIn(_In):
    label: str = Field("", max_length=200, description="what the token is for, e.g. the hospital system")
    role: RoleName = "clinician"
    #: refused that many days from now; null: never
    expires_days: float | None = Field(None, gt=0, le=tokens.MAX_DAYS)
    #: what it may touch within its role; null: everything its role allows
    scopes: list[Scope] | None = Field(None, min_length=1)


class RotateIn(_In):
    #: hours the old token keeps working (0: it ends now)
    grace_hours: float = Field(24.0, ge=0, le=24 * 30)


class TokenOut(BaseModel):
    id: int
    label: str
    role: str
    scopes: list[str] | None
    created_at: dt.datetime
    expires_at: dt.datetime | None
    revoked_at: dt.datetime | None
    state: Literal["active", "expired", "revoked"]


class TokenCreatedOut(TokenOut):
    #: the token in clear: shown this once, never stored
    token: str


class RotatedOut(BaseModel):
    old: TokenOut
    new: TokenCreatedOut


def _out(t) -> dict:
    scopes = tokens.scopes_of(t)
    return {"id": t.id, "label": t.label, "role": t.role, "scopes": None if scopes is None else sorted(scopes),
            "created_at": t.created_at, "expires_at": t.expires_at, "revoked_at": t.revoked_at,
            "state": tokens.state(t)}


@router.get("", response_model=list[TokenOut])
def list_tokens(principal: Admin, db: DbDep):
    return [_out(t) for t in tokens.clinic_tokens(db, principal.clinic_id)]


@router.post("", response_model=TokenCreatedOut, status_code=201)
def create_token(body: TokenIn, request: Request, principal: Admin, db: DbDep):
    """A new token of the caller's clinic; the answer's ``token`` is the only copy in clear."""
    now = utcnow()
    refuse_grant_beyond(request, principal, scopes=body.scopes, expires_at=None if body.expires_days is None
                        else now + dt.timedelta(days=body.expires_days))
    secret = new_token()
    row = tokens.add_token(db, principal.clinic_id, token_sha256=sha256_hex(secret), role=body.role, label=body.label,
                           expires_days=body.expires_days, scopes=body.scopes, now=now)
    record(db, request, principal, "token_create", status=201,
           detail=f"token {row.id} role {row.role}" + (f" scopes {row.scopes}" if row.scopes else ""))
    return {**_out(row), "token": secret}


@router.post("/{token_id}/rotate", response_model=RotatedOut)
def rotate_token(token_id: int, request: Request, principal: Admin, db: DbDep, body: RotateIn | None = None):
    """The successor of token ``token_id`` (in clear, once) and the old one ending after the grace period."""
    body = body or RotateIn()
    old = tokens.clinic_token(db, principal.clinic_id, token_id)  # 404 for another clinic's
    now = utcnow()
    refuse_grant_beyond(request, principal, scopes=tokens.scopes_of(old), expires_at=None if old.expires_at is None
                        else now + (old.expires_at - old.created_at))  # the successor's (rotate_token)
    secret = new_token()
    old, new = tokens.rotate_token(db, token_id, sha256_hex(secret), grace_hours=body.grace_hours, now=now)
    record(db, request, principal, "token_rotate", status=200,
           detail=f"token {new.id} replaces token {old.id} (ends {old.expires_at:%Y-%m-%d %H:%M} UTC)")
    return {"old": _out(old), "new": {**_out(new), "token": secret}}


@router.post("/{token_id}/revoke", response_model=TokenOut)
def revoke_token(token_id: int, request: Request, principal: Admin, db: DbDep):
    """End token ``token_id`` now (a revoked one stays as it was)."""
    token = tokens.clinic_token(db, principal.clinic_id, token_id)
    if tokens.revoke(token):
        record(db, request, principal, "token_revoke", status=200, detail=f"token {token.id} revoked")
    return _out(token)


__all__ = ["router"]
