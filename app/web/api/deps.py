"""Shared dependencies of the routers: settings, database session, blob store, job runner, the caller.

The cheap dependencies are ``async`` (no worker-thread hop per request); those touching the database are
plain functions (FastAPI runs them in its thread pool).  Everything comes from ``request.app.state`` (set by :func:`app.web.main.create_app`), so one process can hold
several apps (tests) and tests can swap any of them with ``app.dependency_overrides``.

The caller (:class:`Principal`) is found from ``Authorization: Bearer <token>`` (an API token: its clinic and
role) or from the ``chakamo_session`` cookie (a browser session: its user's clinic and role).  A
cookie-authenticated POST/PUT/PATCH/DELETE must carry ``X-CSRF-Token`` (else 403); bearer requests need
none (a browser never adds that header by itself).  Roles are ordered read_only < clinician < admin
(:data:`app.web.security.ROLE_RANK`); :func:`require` builds a dependency refusing lower roles with 403.

The upload route does not use the per-request session: a request body can stream for minutes, and a
session opened by a dependency stays open (a pooled connection, on PostgreSQL an open transaction) until
the route returns.  :data:`UploadClinician` finds the caller in a short session of its own, closed before
the body is read, and gives a detached :class:`Principal` (tests overriding the caller override
:func:`get_upload_principal` too).  Clinic scoping: every router loads rows
through :func:`scoped` helpers which answer 404 for another clinic's ids — the same answer as for an unknown
id, so ids of other clinics cannot even be probed.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, HTTPException, Request
from fastapi.security import HTTPBearer
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.store.models import ApiToken, BrowserSession, Job, KneeSession, Patient, User, utcnow
from app.jobs.work import JobRunner
from app.web.security import ROLE_RANK, csrf_ok, csrf_token, sha256_hex
from app.settings import Settings
from app.store.blobs import BlobStore

COOKIE = "chakamo_session"
CSRF_HEADER = "X-CSRF-Token"
_UNSAFE = {"POST", "PUT", "PATCH", "DELETE"}


async def get_settings_dep(request: Request) -> Settings:
    return request.app.state.settings


def get_db(request: Request) -> Iterator[Session]:
    """One database session per request, committed when the route returns normally, before the response."""
    with request.app.state.db.session() as s:
        yield s


async def get_store(request: Request) -> BlobStore:
    return request.app.state.store


async def get_runner(request: Request) -> JobRunner:
    return request.app.state.runner


SettingsDep = Annotated[Settings, Depends(get_settings_dep)]
#: ``scope="function"``: the commit happens before the response is sent (the client's next request sees it)
DbDep = Annotated[Session, Depends(get_db, scope="function")]
StoreDep = Annotated[BlobStore, Depends(get_store)]
RunnerDep = Annotated[JobRunner, Depends(get_runner)]


@dataclass(frozen=True)
class Principal:
    """Who calls: ``clinic_id`` scopes every query; ``via`` is ``bearer`` or ``cookie``."""

    clinic_id: int
    clinic_name: str
    role: str
    via: str
    user: User | None = None
    token_id: int | None = None
    session_id: str | None = None  # the cookie's raw value (for the CSRF token), cookie callers only
    csrf_token: str | None = None


#: declares the bearer scheme in OpenAPI (the /docs "Authorize" button); the header is parsed below
_bearer_doc = HTTPBearer(auto_error=False, description="An API token from `chakamo tokens create`.")


def get_principal(request: Request, db: DbDep, settings: SettingsDep, _doc=Depends(_bearer_doc)) -> Principal:
    """The authenticated caller, or 401; 403 for a cookie-authenticated unsafe request without CSRF header."""
    return resolve_principal(request, db, settings)


def resolve_principal(request: Request, db: Session, settings: Settings) -> Principal:
    """:func:`get_principal`'s work on a given database session."""
    auth = request.headers.get("authorization", "")
    if auth:
        scheme, _, token = auth.partition(" ")
        if scheme.lower() != "bearer" or not token.strip():
            raise HTTPException(401, "The Authorization header must be 'Bearer <token>'; create a token with "
                                     "`chakamo tokens create`.", headers={"WWW-Authenticate": "Bearer"})
        row = db.scalar(select(ApiToken).where(ApiToken.token_sha256 == sha256_hex(token.strip()),
                                               ApiToken.revoked_at.is_(None)))
        if row is None:
            raise HTTPException(401, "Unknown or revoked API token; check it or create a new one with "
                                     "`chakamo tokens create`.", headers={"WWW-Authenticate": "Bearer"})
        return Principal(clinic_id=row.clinic_id, clinic_name=row.clinic.name, role=row.role, via="bearer",
                         token_id=row.id)
    sid = request.cookies.get(COOKIE)
    if not sid:
        raise HTTPException(401, "Not logged in; log in, or send 'Authorization: Bearer <token>'.")
    row = db.scalar(select(BrowserSession).where(BrowserSession.session_sha256 == sha256_hex(sid)))
    if row is None or row.expires_at <= utcnow() or not row.user.active:
        raise HTTPException(401, "Your session has expired or was closed; log in again.")
    if request.method in _UNSAFE and not csrf_ok(settings.key, sid, request.headers.get(CSRF_HEADER)):
        raise HTTPException(403, f"Missing or wrong {CSRF_HEADER} header; send the csrf_token that login and "
                                 "/auth/me return.")
    user = row.user
    return Principal(clinic_id=user.clinic_id, clinic_name=user.clinic.name, role=user.role, via="cookie",
                     user=user, session_id=sid, csrf_token=csrf_token(settings.key, sid))


PrincipalDep = Annotated[Principal, Depends(get_principal)]


def _check_role(principal: Principal, role: str) -> Principal:
    if ROLE_RANK.get(principal.role, -1) < ROLE_RANK[role]:
        raise HTTPException(403, f"This needs the {role} role (yours is {principal.role}); ask a clinic admin.")
    return principal


def get_upload_principal(request: Request, _doc=Depends(_bearer_doc)) -> Principal:
    """The caller of an upload, at least clinician: looked up in a short session closed before the body is
    read (module docstring)."""
    with request.app.state.db.session() as db:
        principal = resolve_principal(request, db, request.app.state.settings)
    return _check_role(principal, "clinician")


UploadClinician = Annotated[Principal, Depends(get_upload_principal)]


def require(role: str):
    """A dependency giving the caller if their role is at least ``role``, else 403."""

    async def dependency(principal: PrincipalDep) -> Principal:  # async: no thread hop for a comparison
        return _check_role(principal, role)

    return dependency


Reader = Annotated[Principal, Depends(require("read_only"))]
Clinician = Annotated[Principal, Depends(require("clinician"))]
Admin = Annotated[Principal, Depends(require("admin"))]


def scoped_patient(db: Session, principal: Principal, patient_id: int) -> Patient:
    row = db.get(Patient, patient_id)
    if row is None or row.clinic_id != principal.clinic_id:
        raise HTTPException(404, f"No patient {patient_id} in your clinic; check the id.")
    return row


def scoped_session(db: Session, principal: Principal, session_id: int, lock: bool = False) -> KneeSession:
    """Session ``session_id`` of the caller's clinic, or 404.  ``lock``: ``SELECT … FOR UPDATE`` (PostgreSQL;
    SQLite serialises writers anyway), so that changes of one session's files and jobs happen one at a time."""
    if lock:  # the row alone (the ORM's joined patient cannot be locked on PostgreSQL's outer join)
        db.execute(select(KneeSession.id).where(KneeSession.id == session_id).with_for_update())
    row = db.get(KneeSession, session_id)
    if row is None or row.clinic_id != principal.clinic_id:
        raise HTTPException(404, f"No session {session_id} in your clinic; check the id.")
    return row


def refuse_while_processing(db: Session, session_id: int, what: str) -> None:
    """409 when a job of session ``session_id`` is queued or running (its files must not change under it)."""
    job_id = db.scalar(select(Job.id).where(Job.session_id == session_id, Job.status.in_(("queued", "running")))
                       .order_by(Job.id))
    if job_id is not None:
        raise HTTPException(409, f"Session {session_id} is being processed (job {job_id}); {what} when that job has "
                                 "finished.")


def scoped_job(db: Session, principal: Principal, job_id: int) -> Job:
    row = db.get(Job, job_id)
    if row is None or row.clinic_id != principal.clinic_id:
        raise HTTPException(404, f"No job {job_id} in your clinic; check the id.")
    return row


__all__ = ["COOKIE", "CSRF_HEADER", "Admin", "Clinician", "DbDep", "Principal", "PrincipalDep", "Reader", "RunnerDep",
           "SettingsDep", "StoreDep", "UploadClinician", "get_db", "get_principal", "get_runner", "get_settings_dep",
           "get_store", "get_upload_principal", "refuse_while_processing", "require", "resolve_principal",
           "scoped_job", "scoped_patient", "scoped_session"]
