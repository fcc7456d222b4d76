"""Accounts: API tokens, browser sessions and users as the API finds and changes them.

Secrets are looked up by their sha256 only (the caller hashes them, :func:`app.web.security.sha256_hex`);
an account is a clinic's (issue 16 finding 10b): an email is unique within its clinic and may have accounts in
several clinics, so a login names the clinic when its email has more than one (:func:`login_account`).
"""

from __future__ import annotations

import datetime as dt

from sqlalchemy import case, delete, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.store.errors import Conflict, NotFound
from app.store.models import ApiToken, BrowserSession, Clinic, LoginAttempts, User, utcnow


def active_token(db: Session, token_sha256: str) -> ApiToken | None:
    """The API token of this hash unless it was revoked."""
    return db.scalar(select(ApiToken).where(ApiToken.token_sha256 == token_sha256, ApiToken.revoked_at.is_(None)))


def browser_session(db: Session, session_sha256: str) -> BrowserSession | None:
    """The browser session of this cookie hash (expired or not: the caller decides)."""
    return db.scalar(select(BrowserSession).where(BrowserSession.session_sha256 == session_sha256))


def open_browser_session(db: Session, user_id: int, session_sha256: str, hours: float, *, client: str = "",
                         user_agent: str = "") -> BrowserSession:
    """A new browser session of ``hours`` opened from ``client`` with ``user_agent`` (both cut to their columns);
    expired sessions of every user are removed on the way."""
    now = utcnow()
    db.execute(delete(BrowserSession).where(BrowserSession.expires_at < now))  # housekeeping
    row = BrowserSession(user_id=user_id, session_sha256=session_sha256, created_at=now,
                         expires_at=now + dt.timedelta(hours=hours), client=client[:64], user_agent=user_agent[:200])
    db.add(row)
    return row


def close_browser_session(db: Session, session_sha256: str) -> None:
    db.execute(delete(BrowserSession).where(BrowserSession.session_sha256 == session_sha256))


def user_browser_sessions(db: Session, user_id: int) -> list[BrowserSession]:
    """The user's unexpired browser sessions, newest first."""
    return list(db.scalars(select(BrowserSession).where(BrowserSession.user_id == user_id,
                                                        BrowserSession.expires_at > utcnow())
                           .order_by(BrowserSession.id.desc())))


def close_user_browser_sessions(db: Session, user_id: int, *, keep_sha256: str | None = None,
                                only_id: int | None = None) -> int:
    """Delete the user's browser sessions (all, all but ``keep_sha256``, or only the one of id ``only_id``);
    returns how many were deleted."""
    stmt = delete(BrowserSession).where(BrowserSession.user_id == user_id)
    if keep_sha256 is not None:
        stmt = stmt.where(BrowserSession.session_sha256 != keep_sha256)
    if only_id is not None:
        stmt = stmt.where(BrowserSession.id == only_id)
    return db.execute(stmt).rowcount or 0


def clinic_user(db: Session, clinic_id: int, user_id: int) -> User | None:
    """User ``user_id`` if it belongs to clinic ``clinic_id`` (else None: the caller answers 404)."""
    user = db.get(User, user_id)
    return user if user is not None and user.clinic_id == clinic_id else None


# ------------------------------------------------------------------------------------ login attempt counters
def _ensure_attempt_row(db: Session, key: str, email: str | None) -> None:
    """The counter row of ``key`` (made if missing; atomic against a concurrent insert)."""
    name = db.get_bind().dialect.name
    if name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    else:
        from sqlalchemy.dialects.sqlite import insert
    db.execute(insert(LoginAttempts).values(key=key, email=email, attempts=0, delay_s=0.0, next_s=0.0, last_s=0.0)
               .on_conflict_do_nothing(index_elements=["key"]))


def reserve_attempt(db: Session, key: str, email: str | None, now_s: float, *, free: int, base_s: float,
                    cap_s: float, forget_s: float) -> bool:
    """Reserve one login attempt of ``key`` at ``now_s`` (Unix seconds) in one atomic ``UPDATE``; False when the
    key must wait (the caller answers 429 and checks no password).

    With ``n`` the key's attempts after this one (back to 1 when the key was idle ``forget_s``), the next attempt
    may come no earlier than ``now_s + d(n)``, ``d(n) = 0`` for ``n < free`` and ``min(cap_s, base_s·2^(n−free))``
    after: the delay doubles per attempt (``delay_s`` holds the last ``d``).  The ``WHERE`` admits the attempt only
    if ``next_s <= now_s``; on PostgreSQL a concurrent reservation of the same row waits for this one's commit and
    re-evaluates the ``WHERE`` on the new row (READ COMMITTED), on SQLite writers are serialised — so a burst can
    never reserve more attempts than the rule allows, whichever server each request reaches.  A free attempt
    leaves ``next_s`` at 0 (not ``now_s``): a request that read the clock earlier but reached the row later is
    not refused by its predecessor's clock."""
    _ensure_attempt_row(db, key, email)
    stale = LoginAttempts.last_s < now_s - forget_s
    n_new = case((stale, 1), else_=LoginAttempts.attempts + 1)
    old = case((stale, 0.0), else_=LoginAttempts.delay_s)
    delay = case((n_new < free, 0.0), (old <= 0.0, base_s), (old * 2.0 >= cap_s, cap_s), else_=old * 2.0)
    result = db.execute(update(LoginAttempts)
                        .where(LoginAttempts.key == key, (LoginAttempts.next_s <= now_s) | stale)
                        .values(attempts=n_new, delay_s=delay, next_s=case((delay > 0.0, now_s + delay), else_=0.0),
                                last_s=now_s)
                        .execution_options(synchronize_session=False))
    return result.rowcount == 1


def attempt_wait_s(db: Session, keys: list[str], now_s: float) -> float:
    """Seconds until every key of ``keys`` admits an attempt again (0 when they all do)."""
    nexts = db.scalars(select(LoginAttempts.next_s).where(LoginAttempts.key.in_(keys))).all()
    return max([0.0, *(n - now_s for n in nexts)])


def reset_attempts(db: Session, keys: list[str]) -> None:
    """Counters of ``keys`` back to zero (a successful login resets its email's keys)."""
    db.execute(update(LoginAttempts).where(LoginAttempts.key.in_(keys))
               .values(attempts=0, delay_s=0.0, next_s=0.0).execution_options(synchronize_session=False))


def refund_attempt(db: Session, key: str, *, free: int, base_s: float) -> None:
    """Undo the reservation of a successful login from a shared address: the key's state before it, so a clinic
    behind one address that logs in all morning is never slowed by its own successes (nor an attacker with one
    valid account helped by them).

    The reservation that admitted this login found ``next_s <= now`` (else it was refused), so admitting at once
    again (``next_s = 0``) restores it exactly; ``delay_s`` goes back along :func:`reserve_attempt`'s rule, 0 for
    ``n − 1 < free`` and ``d/2`` (at least ``base_s``) after — exact except past the cap, where ``d/2`` is the
    lower bound of the delay before."""
    n_prev = LoginAttempts.attempts - 1
    prev_delay = case((n_prev < free, 0.0), (LoginAttempts.delay_s / 2.0 < base_s, base_s),
                      else_=LoginAttempts.delay_s / 2.0)
    db.execute(update(LoginAttempts).where(LoginAttempts.key == key, LoginAttempts.attempts > 0)
               .values(attempts=n_prev, delay_s=prev_delay, next_s=0.0)
               .execution_options(synchronize_session=False))


def delete_attempts_of_email(db: Session, email: str, *, also_key: str | None = None) -> int:
    """Forget the counters kept under ``email`` and the counter ``also_key`` (an admin's unlock); returns how
    many rows went."""
    where = LoginAttempts.email == email
    if also_key is not None:
        where = where | (LoginAttempts.key == also_key)
    return db.execute(delete(LoginAttempts).where(where)).rowcount or 0


def prune_attempts(db: Session, before_s: float) -> None:
    """Delete counters idle since before ``before_s`` (they would start from zero anyway)."""
    db.execute(delete(LoginAttempts).where(LoginAttempts.last_s < before_s, LoginAttempts.next_s < before_s))


def user_by_id(db: Session, user_id: int, *, lock: bool = False) -> User | None:
    """The user ``user_id`` of any clinic (a login's own account, found before by its email), or None; ``lock``:
    its row locked until ``db`` commits (``FOR UPDATE OF users`` on PostgreSQL — only the user's row, not the
    rows its eager relationships join in; SQLite serialises writers)."""
    return db.get(User, user_id, with_for_update={"of": User} if lock else None)


def login_account(db: Session, email: str, clinic: str | None = None) -> User | None:
    """The account a login of ``email`` opens: with ``clinic`` (a clinic's name) that clinic's account of the
    email; without it the email's only account.  None when there is no such account, *and* when the email has
    accounts in several clinics but no clinic was named — the caller answers that exactly like an unknown email
    (same refusal, same work), so a login never tells anyone how many clinics know an email.

    One statement whatever the answer: at most two accounts are read (two suffice to know the email is
    ambiguous)."""
    stmt = select(User).where(User.email == email)
    if clinic is not None:
        stmt = stmt.join(Clinic, Clinic.id == User.clinic_id).where(Clinic.name == clinic)
    found = list(db.scalars(stmt.order_by(User.id).limit(2)))
    return found[0] if len(found) == 1 else None


def clinic_named(db: Session, name: str) -> Clinic:
    """Clinic ``name`` for the operator's commands; :class:`NotFound` (``store.clinic_unknown``, naming the known
    clinics) when there is none."""
    clinic = db.scalar(select(Clinic).where(Clinic.name == name))
    if clinic is None:
        known = ", ".join(repr(c) for c in db.scalars(select(Clinic.name).order_by(Clinic.name))) or "-"
        raise NotFound(code="store.clinic_unknown", name=name, known=known)
    return clinic


def clinic_users(db: Session, clinic_id: int) -> list[User]:
    return list(db.scalars(select(User).where(User.clinic_id == clinic_id).order_by(User.id)))


def clinic_user_by_email(db: Session, clinic_id: int, email: str) -> User | None:
    """The account of ``email`` in clinic ``clinic_id`` (accounts of other clinics are never looked at)."""
    return db.scalar(select(User).where(User.clinic_id == clinic_id, User.email == email))


def _taken(email: str) -> Conflict:
    return Conflict(code="store.email_taken", email=email)


def refuse_taken_email(db: Session, clinic_id: int, email: str) -> None:
    """:class:`Conflict` when ``email`` has an account in clinic ``clinic_id``; an account of the same email in
    another clinic is no obstacle and is never looked at (issue 16 finding 10b: the answer must not depend on
    other clinics)."""
    if clinic_user_by_email(db, clinic_id, email) is not None:
        raise _taken(email)


def add_user(db: Session, clinic_id: int, *, email: str, name: str, role: str, password_hash: str) -> User:
    """A new user of the clinic; :class:`Conflict` when the email is taken in this clinic — also when two
    requests race (the unique constraint on ``(email, clinic_id)`` decides)."""
    refuse_taken_email(db, clinic_id, email)
    user = User(clinic_id=clinic_id, email=email, name=name, role=role, password_hash=password_hash)
    db.add(user)
    try:
        db.flush()
    except IntegrityError:  # created by a concurrent request between the check and the insert
        raise _taken(email) from None
    db.refresh(user)
    return user


__all__ = ["active_token", "add_user", "attempt_wait_s", "browser_session", "clinic_user", "clinic_user_by_email",
           "clinic_users", "close_browser_session", "close_user_browser_sessions", "delete_attempts_of_email",
           "login_account", "open_browser_session", "prune_attempts", "refund_attempt", "refuse_taken_email",
           "reserve_attempt", "reset_attempts", "user_browser_sessions", "user_by_id"]
