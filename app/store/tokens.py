"""API tokens: creation with an expiry and scopes, rotation, and the checks the API makes on a token it found.

A token has a role (what its clinic's user of that role may do), optionally ``scopes`` (a subset of
:data:`app.choices.TOKEN_SCOPES`: the resources it may read or write within its role; none: all) and optionally
``expires_at`` (refused from then on, 401).  Rotation (:func:`rotate_token`) creates the successor — same
clinic, label, role, scopes and lifetime — and sets the old token to expire after a grace period, so the
hospital system can switch over without an outage; a grace of 0 ends the old token at once.  Only the
token's sha256 is stored; the token itself exists in clear once, in the creating command's output.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.choices import TOKEN_MAX_DAYS, TOKEN_SCOPES, USER_ROLE_NAMES
from app.store.errors import Invalid, NotFound
from app.store.models import ApiToken, utcnow

#: the longest lifetime a token may be given (ten years: app.choices.TOKEN_MAX_DAYS)
MAX_DAYS = TOKEN_MAX_DAYS


def parse_scopes(scopes: Iterable[str] | None) -> str | None:
    """The stored form of ``scopes`` (space-separated, sorted; None: every scope); :class:`Invalid` for an
    unknown one.  Each item may itself hold several, separated by spaces or commas."""
    if scopes is None:
        return None
    items = sorted({part for s in scopes for part in s.replace(",", " ").split() if part})
    unknown = [s for s in items if s not in TOKEN_SCOPES]
    if unknown:
        raise Invalid(code="store.unknown_scope", scopes=", ".join(unknown), examples=", ".join(TOKEN_SCOPES[:4]),
                      all=" ".join(TOKEN_SCOPES))
    if not items:
        raise Invalid(code="store.no_scope")
    return " ".join(items)


def scopes_of(token: ApiToken) -> frozenset[str] | None:
    """The token's scopes (None: every scope of its role)."""
    return None if token.scopes is None else frozenset(token.scopes.split())


def expired(token: ApiToken, now: dt.datetime | None = None) -> bool:
    return token.expires_at is not None and token.expires_at <= (now or utcnow())


def add_token(db: Session, clinic_id: int, *, token_sha256: str, role: str, label: str = "",
              expires_days: float | None = None, scopes: Iterable[str] | None = None,
              now: dt.datetime | None = None) -> ApiToken:
    """A new token of the clinic (flushed); :class:`Invalid` for an unknown role or scope or a lifetime outside
    (0, :data:`MAX_DAYS`] days."""
    if role not in USER_ROLE_NAMES:
        raise Invalid(code="store.unknown_token_role", role=str(role), allowed=", ".join(USER_ROLE_NAMES))
    if expires_days is not None and not 0 < expires_days <= MAX_DAYS:
        raise Invalid(code="store.expiry_out_of_range", days=f"{expires_days:g}", limit=MAX_DAYS)
    expires_at = (now or utcnow()) + dt.timedelta(days=expires_days) if expires_days is not None else None
    row = ApiToken(clinic_id=clinic_id, label=label, role=role, token_sha256=token_sha256,
                   scopes=parse_scopes(scopes), expires_at=expires_at)
    db.add(row)
    db.flush()
    return row


def rotate_token(db: Session, token_id: int, new_sha256: str, *, grace_hours: float = 24.0,
                 now: dt.datetime | None = None) -> tuple[ApiToken, ApiToken]:
    """``(old, new)``: a successor of token ``token_id`` with the same clinic, label, role, scopes and lifetime,
    and the old one set to expire ``grace_hours`` from now (sooner if it expired sooner already).
    :class:`NotFound` for an unknown id, :class:`Invalid` for a revoked or expired token (create a new one)."""
    now = now or utcnow()
    old = db.get(ApiToken, token_id)
    if old is None:
        raise NotFound(code="store.no_token", token_id=token_id)
    if old.revoked_at is not None or expired(old, now):
        raise Invalid(code="store.token_dead", token_id=token_id)
    if not 0 <= grace_hours <= 24 * 30:
        raise Invalid(code="store.grace_out_of_range", hours=f"{grace_hours:g}", limit=24 * 30)
    lifetime = old.expires_at - old.created_at if old.expires_at is not None else None
    new = ApiToken(clinic_id=old.clinic_id, label=old.label, role=old.role, token_sha256=new_sha256,
                   scopes=old.scopes, expires_at=now + lifetime if lifetime is not None else None)
    db.add(new)
    end = now + dt.timedelta(hours=grace_hours)
    old.expires_at = min(old.expires_at, end) if old.expires_at is not None else end
    db.flush()
    return old, new


def clinic_tokens(db: Session, clinic_id: int) -> list[ApiToken]:
    """The clinic's API tokens, oldest first (never the token: only its sha256 is stored)."""
    return list(db.scalars(select(ApiToken).where(ApiToken.clinic_id == clinic_id).order_by(ApiToken.id)))


def clinic_token(db: Session, clinic_id: int, token_id: int) -> ApiToken:
    """Token ``token_id`` of the clinic; :class:`NotFound` for an unknown id or another clinic's token."""
    token = db.get(ApiToken, token_id)
    if token is None or token.clinic_id != clinic_id:
        raise NotFound(code="store.no_token", token_id=token_id)
    return token


def revoke(token: ApiToken, now: dt.datetime | None = None) -> bool:
    """Revoke ``token`` (the API answers 401 to it from now on); False when it was revoked already (its first
    date is kept, so offboarding can run twice)."""
    if token.revoked_at is not None:
        return False
    token.revoked_at = now or utcnow()
    return True


def state(token: ApiToken, now: dt.datetime | None = None) -> str:
    """``revoked``, ``expired`` or ``active``."""
    if token.revoked_at is not None:
        return "revoked"
    return "expired" if expired(token, now) else "active"


__all__ = ["MAX_DAYS", "add_token", "clinic_token", "clinic_tokens", "expired", "parse_scopes", "revoke",
           "rotate_token", "scopes_of", "state"]
