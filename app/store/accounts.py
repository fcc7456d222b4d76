"""Accounts: API tokens, browser sessions and users as the API finds and changes them.

Secrets are looked up by their sha256 only (the caller hashes them, :func:`app.web.security.sha256_hex`);
emails are the login names, unique across clinics.
"""

from __future__ import annotations

import datetime as dt

from sqlalchemy import delete, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.store.errors import Conflict
from app.store.models import ApiToken, BrowserSession, User, utcnow


def active_token(db: Session, token_sha256: str) -> ApiToken | None:
    """The API token of this hash unless it was revoked."""
    return db.scalar(select(ApiToken).where(ApiToken.token_sha256 == token_sha256, ApiToken.revoked_at.is_(None)))


def token_label(db: Session, token_id: int) -> str | None:
    token = db.get(ApiToken, token_id)
    return token.label if token is not None else None


def browser_session(db: Session, session_sha256: str) -> BrowserSession | None:
    """The browser session of this cookie hash (expired or not: the caller decides)."""
    return db.scalar(select(BrowserSession).where(BrowserSession.session_sha256 == session_sha256))


def open_browser_session(db: Session, user_id: int, session_sha256: str, hours: float) -> BrowserSession:
    """A new browser session of ``hours``; expired sessions of every user are removed on the way."""
    now = utcnow()
    db.execute(delete(BrowserSession).where(BrowserSession.expires_at < now))  # housekeeping
    row = BrowserSession(user_id=user_id, session_sha256=session_sha256, created_at=now,
                         expires_at=now + dt.timedelta(hours=hours))
    db.add(row)
    return row


def close_browser_session(db: Session, session_sha256: str) -> None:
    db.execute(delete(BrowserSession).where(BrowserSession.session_sha256 == session_sha256))


def user_by_email(db: Session, email: str) -> User | None:
    return db.scalar(select(User).where(User.email == email))


def clinic_users(db: Session, clinic_id: int) -> list[User]:
    return list(db.scalars(select(User).where(User.clinic_id == clinic_id).order_by(User.id)))


def _taken(email: str) -> Conflict:
    return Conflict(f"The email {email} already has an account; use another email.")


def refuse_taken_email(db: Session, email: str) -> None:
    """:class:`Conflict` when ``email`` has an account (checked before the costly password hash)."""
    if user_by_email(db, email) is not None:
        raise _taken(email)


def add_user(db: Session, clinic_id: int, *, email: str, name: str, role: str, password_hash: str) -> User:
    """A new user of the clinic; :class:`Conflict` when the email is taken — also when two requests race
    (the unique constraint decides)."""
    refuse_taken_email(db, email)
    user = User(clinic_id=clinic_id, email=email, name=name, role=role, password_hash=password_hash)
    db.add(user)
    try:
        db.flush()
    except IntegrityError:  # created by a concurrent request between the check and the insert
        raise _taken(email) from None
    db.refresh(user)
    return user


__all__ = ["active_token", "add_user", "browser_session", "clinic_users", "close_browser_session",
           "open_browser_session", "refuse_taken_email", "token_label", "user_by_email"]
