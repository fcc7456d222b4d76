"""Shared dependencies of the routers: settings, database session, blob store, job runner, the caller.

The cheap dependencies are ``async`` (no worker-thread hop per request); those touching the database are
plain functions (FastAPI runs them in its thread pool).  Everything comes from ``request.app.state`` (set by :func:`app.web.main.create_app`), so one process can hold
several apps (tests) and tests can swap any of them with ``app.dependency_overrides``.

The caller (:class:`Principal`) is found from ``Authorization: Bearer <token>`` (an API token: its clinic and
role) or from the ``chakamo_session`` cookie (a browser session: its user's clinic and role).  A
cookie-authenticated POST/PUT/PATCH/DELETE must carry ``X-CSRF-Token`` (else 403); bearer requests need
none (a browser never adds that header by itself).  Roles are ordered read_only < clinician < admin
(:data:`app.web.security.ROLE_RANK`); :func:`require` builds a dependency refusing lower roles with 403.
An API token past its ``expires_at`` answers 401; a token with scopes (:mod:`app.store.tokens`) is refused (403)
on a route outside them (:func:`needed_scope`: the router's resource, read for GET, write otherwise).

The upload route does not use the per-request session: a request body can stream for minutes, and a
session opened by a dependency stays open (a pooled connection, on PostgreSQL an open transaction) until
the route returns.  :data:`UploadClinician` finds the caller in a short session of its own, closed before
the body is read, and gives a detached :class:`Principal` (tests overriding the caller override
:func:`get_upload_principal` too).  Clinic scoping: every router loads rows
through the ``scoped_*`` helpers (the caller's clinic given to :mod:`app.store`'s lookups) which answer 404
for another clinic's ids — the same answer as for an unknown id, so ids of other clinics cannot even be probed.

Refusals of authentication and authorisation (401 for credentials presented but wrong, 403, and 404 for
another clinic's id) are recorded as ``denied`` audit events (:func:`app.web.audit.record_refusal`, in a
transaction of their own).

Domain errors: the store and jobs services raise :mod:`app.store.errors` classes (no HTTP there);
:func:`domain_errors`, a dependency of every API route (:func:`app.web.api.api_router`), turns them into
``HTTPException`` by :data:`STATUS_OF` — the one place where they get their status codes — with their
sentence as ``detail``.  It wraps the route's other dependencies, so the request's database session has
been rolled back by then, as for an ``HTTPException`` raised by the route itself.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, HTTPException, Request
from fastapi.security import HTTPBearer
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from app.choices import TOKEN_SCOPES
from app.jobs.work import JobRunner
from app.settings import Settings
from app.store import accounts, tokens
from app.store.blobs import BlobStore
from app.store.checks import IngestionChecker
from app.store.database import POOL_OVERFLOW, POOL_SIZE
from app.store.errors import Conflict, DomainError, Invalid, LimitExceeded, NotFound, PreconditionFailed
from app.store.models import Job, KneeSession, Patient, User, utcnow
from app.store.patients import clinic_patient
from app.store.sessions import clinic_job, clinic_session
from app.web.audit import record_refusal
from app.web.refusals import Refusal
from app.web.security import ROLE_RANK, csrf_ok, csrf_token, sha256_hex

COOKIE = "chakamo_session"
CSRF_HEADER = "X-CSRF-Token"
_UNSAFE = {"POST", "PUT", "PATCH", "DELETE"}


async def get_settings_dep(request: Request) -> Settings:
    return request.app.state.settings


#: requests holding a request session (:data:`DbDep`) at once, fewer than the pool's connections
#: (:data:`app.store.database.POOL_SIZE` + ``POOL_OVERFLOW``): the others wait for a turn without a thread
#: (:func:`_session_turn`); the ten left over serve what takes a connection only inside one thread hop (uploads'
#: and logins' own sessions, refusals' records, the job threads).  More of those at once only wait in the pool for
#: a moment: none of them, and no turn holder, waits for a second connection while holding one (``_refuse``)
REQUEST_SESSIONS = POOL_SIZE + POOL_OVERFLOW - 10


async def _session_turn(request: Request):
    """A turn to hold a request session, waited for on the event loop (no thread held) and kept until the
    session has committed and closed.

    Why: a request session keeps its pooled connection from the route's first query until its commit, across
    a thread hop (a ``def`` route, then its response's validation on another pool thread).  Unbounded, every
    connection could belong to a request parked for a thread while every thread (40) sat in the pool waiting for
    a connection: nothing moved until the pool's timeout (10 s, then 500s) — the upload burst of issue 16.  With
    fewer turns than connections, a thread waiting in the pool always waits for a connection held by a thread
    that moves on (or by a commit, which runs off the threads' limit)."""
    async with request.app.state.session_turns:
        yield


def get_db(request: Request, _turn: Annotated[None, Depends(_session_turn, scope="function")]) -> Iterator[Session]:
    """One database session per request, committed when the route returns normally, before the response."""
    with request.app.state.db.session() as s:
        yield s


async def get_store(request: Request) -> BlobStore:
    return request.app.state.store


async def get_runner(request: Request) -> JobRunner:
    return request.app.state.runner


def checker_of(request: Request) -> IngestionChecker:
    """The app's ingestion checker (database, blob store, temporary folder, warm helper process)."""
    state = request.app.state
    return IngestionChecker(state.db, state.store, state.settings.tmp_dir, state.check_pool)


async def get_checker(request: Request) -> IngestionChecker:
    return checker_of(request)


SettingsDep = Annotated[Settings, Depends(get_settings_dep)]
#: ``scope="function"``: the commit happens before the response is sent (the client's next request sees it)
DbDep = Annotated[Session, Depends(get_db, scope="function")]
StoreDep = Annotated[BlobStore, Depends(get_store)]
RunnerDep = Annotated[JobRunner, Depends(get_runner)]
CheckerDep = Annotated[IngestionChecker, Depends(get_checker)]

#: the status code of each domain error (:mod:`app.store.errors`; subclasses such as
#: :class:`app.store.sessions.Busy` or :class:`app.jobs.queue.NotReady` take their base's)
STATUS_OF: dict[type[DomainError], int] = {NotFound: 404, Conflict: 409, Invalid: 400, LimitExceeded: 413,
                                           PreconditionFailed: 412}


def http_error(error: DomainError) -> HTTPException:
    """The ``HTTPException`` answering ``error`` (:data:`STATUS_OF`; 400 for a class not listed)."""
    status = next((code for cls, code in STATUS_OF.items() if isinstance(error, cls)), 400)
    if error.code is not None:   # its sentence in es/en/pt, with code and params (app.web.refusals)
        return Refusal(status, error.code, **error.params)
    return HTTPException(status, error.detail)


async def domain_errors(request: Request):
    """A dependency of every API route: a domain error raised by the route (or by a dependency resolved after
    this one) answers as :func:`http_error` says (module docstring).  A 404 for an id another clinic owns is
    recorded in *that* clinic's audit log (:func:`app.web.audit.record_refusal`)."""
    try:
        yield
    except DomainError as error:
        principal = getattr(request.state, "principal", None)
        owner = getattr(error, "owner_clinic_id", None)
        if isinstance(error, NotFound) and owner is not None and principal is not None \
                and owner != principal.clinic_id:
            await run_in_threadpool(record_refusal, request.app.state.db, request, 404,
                                    f"another clinic's id (caller's clinic {principal.clinic_id})",
                                    principal=principal, clinic_id=owner)
        raise http_error(error) from None


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
    #: an API token's scopes (None: every scope of its role; browser sessions have no scopes)
    scopes: frozenset[str] | None = None
    #: when the caller's API token ends (None: never, and for browser sessions)
    token_expires_at: dt.datetime | None = None
    #: the caller's API token's label (the audit log names the token by it; None for browser sessions)
    token_label: str | None = None


#: declares the bearer scheme in OpenAPI (the /docs "Authorize" button); the header is parsed below
_bearer_doc = HTTPBearer(auto_error=False, description="An API token from `chakamo tokens create`.")


def get_principal(request: Request, db: DbDep, settings: SettingsDep, _doc=Depends(_bearer_doc)) -> Principal:
    """The authenticated caller, or 401; 403 for a cookie-authenticated unsafe request without CSRF header.

    Ends the request session's transaction before returning, which gives its pooled connection back: the route
    runs on another thread-pool thread, and a request parked between the two hops must not hold a connection.
    Held, it deadlocked an upload burst (issue 16): all 40 request threads sat in the pool waiting for a
    connection (``resolve_principal``'s first query) while the 40 connections belonged to authenticated requests
    waiting for a thread to run their route, until the pool's timeout.  The commit writes nothing (authentication
    only reads) and expires nothing (``expire_on_commit=False``): the caller's rows stay loaded, and the route's
    first query checks a connection out again."""
    principal = resolve_principal(request, db, settings)
    db.commit()
    return principal


def _refuse(request: Request, db: Session, status: int, code: str, why: str, *, clinic_id: int | None = None,
            user_id: int | None = None, actor: str = "", headers: dict | None = None, **params) -> HTTPException:
    """The :class:`~app.web.refusals.Refusal` (catalogue ``code``) of a refused authentication, recorded first
    (``denied``, :mod:`app.web.audit`).  ``db``'s transaction (the look-up, which only read) ends before the record's
    own session takes a connection: a thread never waits in the pool while holding a connection, or a flood of
    wrong credentials could hold every connection and wait for a second (:func:`_session_turn`'s argument)."""
    db.commit()
    record_refusal(request.app.state.db, request, status, why, clinic_id=clinic_id, user_id=user_id, actor=actor)
    return Refusal(status, code, headers=headers, **params)


def resolve_principal(request: Request, db: Session, settings: Settings) -> Principal:
    """:func:`get_principal`'s work on a given database session.  Credentials that are presented but wrong (a
    malformed header, an unknown or revoked token, an expired or closed session, a missing CSRF header) are
    recorded as ``denied``; a request with no credentials at all is not (a browser opening the login page)."""
    auth = request.headers.get("authorization", "")
    if auth:
        scheme, _, token = auth.partition(" ")
        if scheme.lower() != "bearer" or not token.strip():
            raise _refuse(request, db, 401, "auth.bearer_malformed", "malformed Authorization header",
                          headers={"WWW-Authenticate": "Bearer"})
        row = accounts.active_token(db, sha256_hex(token.strip()))
        if row is None:
            raise _refuse(request, db, 401, "auth.token_unknown", "unknown or revoked API token",
                          headers={"WWW-Authenticate": "Bearer"})
        if tokens.expired(row):
            raise _refuse(request, db, 401, "auth.token_expired", "expired API token",
                          clinic_id=row.clinic_id, headers={"WWW-Authenticate": 'Bearer error="invalid_token"'})
        principal = Principal(clinic_id=row.clinic_id, clinic_name=row.clinic.name, role=row.role, via="bearer",
                              token_id=row.id, scopes=tokens.scopes_of(row), token_expires_at=row.expires_at,
                              token_label=row.label)
        request.state.principal = principal
        return principal
    sid = request.cookies.get(COOKIE)
    if not sid:
        raise Refusal(401, "auth.not_logged_in")
    row = accounts.browser_session(db, sha256_hex(sid))
    if row is None or row.expires_at <= utcnow() or not row.user.active:
        why = "unknown or closed session" if row is None else \
            "expired session" if row.expires_at <= utcnow() else "deactivated account"
        raise _refuse(request, db, 401, "auth.login_closed", why,
                      clinic_id=row.user.clinic_id if row else None, user_id=row.user_id if row else None,
                      actor=row.user.email if row else "")
    if request.method in _UNSAFE and not csrf_ok(settings.key, sid, request.headers.get(CSRF_HEADER)):
        raise _refuse(request, db, 403, "auth.csrf", "missing or wrong CSRF header", clinic_id=row.user.clinic_id,
                      user_id=row.user_id, actor=row.user.email, header=CSRF_HEADER)
    user = row.user
    principal = Principal(clinic_id=user.clinic_id, clinic_name=user.clinic.name, role=user.role, via="cookie",
                          user=user, session_id=sid, csrf_token=csrf_token(settings.key, sid))
    request.state.principal = principal
    return principal


PrincipalDep = Annotated[Principal, Depends(get_principal)]


def _role_ok(principal: Principal, role: str) -> bool:
    return ROLE_RANK.get(principal.role, -1) >= ROLE_RANK[role]


def _role_refusal(principal: Principal, role: str) -> HTTPException:
    return Refusal(403, "auth.role_needed", role=role, yours=principal.role)


def _role_why(principal: Principal, role: str) -> str:
    return f"role {principal.role} below {role}"


#: the scope family of each router's tag (:data:`app.choices.TOKEN_SCOPES`); routers not listed need no scope
#: (``auth``, ``options``, ``clinics``: who the caller is and the option lists)
SCOPE_OF_TAG = {"patients": "patients", "sessions": "sessions", "recordings": "recordings", "jobs": "jobs",
                "results": "results", "artefacts": "results", "fhir": "fhir", "audit": "audit", "users": "users",
                "tokens": "users", "webhooks": "jobs", "interpretation": "results"}
UNSCOPED_TAGS = frozenset({"auth", "options", "clinics"})
#: the ``openapi_extra`` member naming a route's own scope where its router's family is not what it touches
#: (``GET /patients/{id}/trend`` reads results): :func:`route_scope`
SCOPE_MEMBER = "x-chakamo-scope"


def route_scope(scope: str, **openapi_extra) -> dict:
    """``openapi_extra`` of a route that needs ``scope`` (one of :data:`app.choices.TOKEN_SCOPES`) whatever its
    router; also shown in the OpenAPI document."""
    if scope not in TOKEN_SCOPES:
        raise ValueError(f"unknown scope {scope}")
    return {SCOPE_MEMBER: scope, **openapi_extra}


def needed_scope(request: Request) -> str | None:
    """The scope the request's route needs: the one it names (:func:`route_scope`), else its router's family
    and ``read`` for GET/HEAD, else ``write`` (None: no scope needed).  A route of a router missing from
    :data:`SCOPE_OF_TAG` needs a scope no token has (refused to scoped tokens: a new router must be given its
    family)."""
    route = request.scope.get("route")
    own = (getattr(route, "openapi_extra", None) or {}).get(SCOPE_MEMBER)
    if own is not None:
        return own
    tag = (getattr(route, "tags", None) or ["?"])[0]
    if tag in UNSCOPED_TAGS:
        return None
    family = SCOPE_OF_TAG.get(tag, f"unlisted-{tag}")
    return f"{family}:{'read' if request.method in ('GET', 'HEAD') else 'write'}"


def _scope_refusal(request: Request, principal: Principal) -> HTTPException | None:
    """403 (recorded) when the caller's token lacks the route's scope; None when it may go on."""
    if principal.scopes is None:
        return None
    scope = needed_scope(request)
    if scope is None or scope in principal.scopes:
        return None
    record_refusal(request.app.state.db, request, 403, f"token lacks scope {scope}", principal=principal)
    return Refusal(403, "auth.scope_missing", scope=scope, scopes=" ".join(sorted(principal.scopes)))


def refuse_grant_beyond(request: Request, principal: Principal, *, scopes: Iterable[str] | None,
                        expires_at: dt.datetime | None) -> None:
    """403 (recorded) when an API-token caller would hand out more than it holds: a token (created or rotated) with
    a scope it lacks (``scopes`` None: every scope) or ending after it (``expires_at`` None: never), or a user
    account, which holds its role with every scope and no end (pass None, None).  A token never outgrows the token
    that made it, so a scoped or expiring admin token cannot mint an unlimited one; a browser session (a person
    who logged in) and ``chakamo`` on the server are not limited by this rule."""
    if principal.via != "bearer":
        return
    if principal.scopes is not None and (scopes is None or not set(scopes) <= principal.scopes):
        record_refusal(request.app.state.db, request, 403, "grant beyond the token's scopes", principal=principal)
        raise Refusal(403, "auth.grant_beyond_scopes", scopes=" ".join(sorted(principal.scopes)))
    end = principal.token_expires_at
    if end is not None and (expires_at is None or expires_at > end):
        record_refusal(request.app.state.db, request, 403, "grant beyond the token's expiry", principal=principal)
        raise Refusal(403, "auth.grant_beyond_expiry", until=f"{end:%Y-%m-%d %H:%M}")


def get_upload_principal(request: Request, _doc=Depends(_bearer_doc)) -> Principal:
    """The caller of an upload, at least clinician: looked up in a short session closed before the body is
    read (module docstring)."""
    with request.app.state.db.session() as db:
        principal = resolve_principal(request, db, request.app.state.settings)
    if not _role_ok(principal, "clinician"):
        record_refusal(request.app.state.db, request, 403, _role_why(principal, "clinician"), principal=principal)
        raise _role_refusal(principal, "clinician")
    refusal = _scope_refusal(request, principal)
    if refusal is not None:
        raise refusal
    return principal


UploadClinician = Annotated[Principal, Depends(get_upload_principal)]


def require(role: str):
    """A dependency giving the caller if their role is at least ``role``, else 403."""

    async def dependency(request: Request, principal: PrincipalDep) -> Principal:  # async: no thread hop
        if not _role_ok(principal, role):  # recorded (a thread hop only for a refusal)
            await run_in_threadpool(record_refusal, request.app.state.db, request, 403, _role_why(principal, role),
                                    principal=principal)
            raise _role_refusal(principal, role)
        if principal.scopes is not None:  # a scoped token: the route's scope too (a thread hop only for those)
            refusal = await run_in_threadpool(_scope_refusal, request, principal)
            if refusal is not None:
                raise refusal
        return principal

    return dependency


Reader = Annotated[Principal, Depends(require("read_only"))]
Clinician = Annotated[Principal, Depends(require("clinician"))]
Admin = Annotated[Principal, Depends(require("admin"))]


def scoped_patient(db: Session, principal: Principal, patient_id: int) -> Patient:
    """Patient ``patient_id`` of the caller's clinic (else 404, via :class:`app.store.errors.NotFound`)."""
    return clinic_patient(db, principal.clinic_id, patient_id)


def scoped_session(db: Session, principal: Principal, session_id: int, lock: bool = False) -> KneeSession:
    """Session ``session_id`` of the caller's clinic, else 404; ``lock``: :func:`app.store.sessions.clinic_session`."""
    return clinic_session(db, principal.clinic_id, session_id, lock=lock)


def scoped_job(db: Session, principal: Principal, job_id: int) -> Job:
    """Job ``job_id`` of the caller's clinic, else 404."""
    return clinic_job(db, principal.clinic_id, job_id)


__all__ = ["COOKIE", "CSRF_HEADER", "STATUS_OF", "Admin", "CheckerDep", "Clinician", "DbDep", "Principal",
           "PrincipalDep", "Reader", "RunnerDep", "SettingsDep", "StoreDep", "UploadClinician", "checker_of",
           "domain_errors", "get_checker", "get_db", "get_principal", "get_runner", "get_settings_dep", "get_store",
           "get_upload_principal", "http_error", "needed_scope", "refuse_grant_beyond", "require", "route_scope", "resolve_principal", "scoped_job", "scoped_patient",
           "scoped_session"]
