"""The audit log: who viewed, downloaded, exported or changed which patient's data (OWASP ASVS V7, V8.3).

:func:`record` adds one :class:`app.store.models.AuditEvent` for the calling :class:`app.web.api.deps.Principal`:
the actor (a browser user — its id and email — or an API token — its id and label), the action
(:data:`ACTIONS`), the patient and session concerned, the request's method and path, and the client address.

Same transaction, fail closed.  The event is added to the database session that carries the request's own
work and written by its commit, which comes before the answer: it commits together with the response's data (a created patient and its
``create`` event, an upload and its ``upload`` event) or not at all.  For reads this means a read whose
audit row cannot be written fails (500) instead of disclosing data unrecorded — ASVS 7.1 wants the log
complete, and an unlogged disclosure of patient data is worse than a refused one; the price is that a full
or read-only database blocks reads as well as writes.  A read's event, the only row its transaction writes, is
written by the database's group commit (:mod:`app.store.group_commit`) together with the other reads' events that
arrive meanwhile — still before the answer, still failing the read if it is refused.  A request refused before its data was loaded leaves
no data event (nothing was disclosed) but a ``denied`` security event (below).

What the routes record (one event per request):

======================================================  ============  ====================================
route                                                   action        patient / session
======================================================  ============  ====================================
``GET /patients`` (no ``q``)                            ``list``      null / null
``GET /patients?q=…``                                   ``search``    the patient if exactly one matched
``POST /patients``                                      ``create``    the new patient
``GET /patients/{id}``, ``…/sessions``, ``…/trend``     ``view``      the patient
``POST /patients/{id}/sessions``                        ``create``    the patient / the new session
``GET /sessions/{id}`` (its recordings, the list)       ``view``      the session's patient / session
``POST /sessions/{id}/recordings``                      ``upload``    patient / session
``DELETE /sessions/{id}/recordings/{rid}``              ``delete``    patient / session
``PATCH /patients/{id}``, ``PATCH /sessions/{id}``      ``update``    patient / (session)
``DELETE /patients/{id}``, ``DELETE /sessions/{id}``    ``delete``    patient / (session)
``GET /sessions/{id}/results``                          ``view``      patient / session
``GET /sessions/{id}/report.pdf`` … ``scene.viser``     ``download``  patient / session
``GET /sessions/{id}/scene.png`` (the 3D view's still)  ``download``  patient / session
``GET /fhir/DiagnosticReport/{id}``                     ``export``    patient / session
``POST /sessions/{id}/process``                         ``process``   patient / session
``GET /sessions/{id}/interpretation``                   ``view``      patient / session
``POST /sessions/{id}/interpretation`` (the draft)      ``update``    patient / session
``POST /sessions/{id}/interpretation/sign``             ``sign``      patient / session
``POST /sessions/{id}/interpretation/amendments``       ``amend``     patient / session
======================================================  ============  ====================================

Security events (OWASP ASVS 7.1.3, 7.2.1, 7.2.2; issue 16 finding 7) — ``status`` holds the answer's code and
``detail`` what changed or why (never a password or a token):

========================================================  ===================  ==========================================
what                                                      action               clinic / actor
========================================================  ===================  ==========================================
a successful login                                        ``login``            the user's
a wrong password (or an unknown or deactivated account)   ``login_failed``     the account's clinic, or null when the
                                                                               email has none; actor ``anonymous`` with
                                                                               the email typed
a login refused by the throttle (429), any email          ``login_refused``    the account's clinic, or null when the
                                                                               email has none (a refusal costs the same
                                                                               for both: :mod:`app.web.api.auth`)
a logout                                                  ``logout``           the user's
401 (no, unknown, revoked or expired credentials)         ``denied``           the token's or session's clinic when known
403 (role too low, missing CSRF header)                   ``denied``           the caller's
404 for another clinic's patient, session or job          ``denied``           **the owning clinic's** (its admins see
                                                                               the attempt; the caller's clinic learns
                                                                               nothing it could probe with)
a user created by an admin (role in ``detail``)           ``user_create``      the admin's
a role or active flag changed                             ``user_change``      the admin's (``role clinician -> admin``)
a password changed (self-service, or by the operator)     ``password_change``  the user's
a browser session ended by its user                       ``session_end``      the user's
an account's login counters cleared                       ``unlock``           the admin's
an API token created, rotated or revoked                  ``token_create`` /   the admin's; actor ``operator`` for
                                                          ``token_rotate`` /   ``chakamo tokens`` (the command line)
                                                          ``token_revoke``
========================================================  ===================  ==========================================

Refusals are written in a transaction of their own (:func:`record_refusal`; the request's own is rolled back),
and a failure to write them is logged, not answered: a refusal discloses nothing.  Refusals answered before any
database work — a login over the per-address concurrency cap, or when the hashing queue is full (429/503, the
flood protections of :mod:`app.web.throttle`) — are not recorded: writing a row for each request of a flood
would make the flood cost the database what the cap saves.

Deliberately not recorded: ``GET /jobs/{id}`` (the UI polls it many times a second while a job runs; it
shows the job's progress, not patient data) and the audit log itself.  The query string is not stored (a
search term is itself patient data and the log should not copy it).  Rows are append-only from the API:
``app.web.api.audit`` only lists them (:func:`app.store.audit.list_events`); nothing in the product updates or
deletes them (a clinic's deletion cascades to its events).
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from sqlalchemy.orm import Session

from app.store.audit import add_event
from app.store.models import AuditEvent

if TYPE_CHECKING:  # types only: this module must not import the API package (a worker may call it)
    from fastapi import Request

    from app.store.database import Database
    from app.store.models import User
    from app.web.api.deps import Principal

log = logging.getLogger("chakamo.audit")

#: the actions an event may have (the tables above)
ACTIONS: tuple[str, ...] = ("list", "search", "view", "create", "upload", "delete", "download", "export",
                            "process", "update", "login", "login_failed", "login_refused", "logout", "denied",
                            "user_create", "user_change", "password_change", "session_end", "unlock", "token_create",
                            "token_rotate", "token_revoke", "sign", "amend")
#: column widths of :class:`AuditEvent` (longer values are cut, never refused: the read must not fail on them)
_RESOURCE_CHARS, _CLIENT_CHARS, _ACTOR_CHARS, _DETAIL_CHARS = 300, 64, 320, 300


def _actor(principal: "Principal") -> tuple[str, int | None, int | None, str]:
    """``(actor_kind, user_id, token_id, label)`` of the caller."""
    if principal.user is not None:
        return "user", principal.user.id, None, principal.user.email
    name = principal.token_label
    label = f"token {principal.token_id}" + (f" ({name})" if name else "")
    return "token", None, principal.token_id, label


def _check(action: str) -> None:
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}; use one of {', '.join(ACTIONS)}")


def _where(request: "Request | None") -> tuple[str, str]:
    """``(resource, client)`` of a request, cut to their columns."""
    if request is None:
        return "", ""
    return (f"{request.method} {request.url.path}"[:_RESOURCE_CHARS],
            (request.client.host if request.client else "")[:_CLIENT_CHARS])


def record(db: Session, request: "Request", principal: "Principal", action: str, *, patient_id: int | None = None,
           session_id: int | None = None, status: int | None = None, detail: str = "",
           now: bool = False) -> AuditEvent:
    """Add the audit event of ``principal`` doing ``action`` on the patient/session in ``db``'s transaction — the
    one that carries the request's work, so both commit together (module docstring).  The row is written by
    that commit (:func:`app.store.database.add_at_commit`: on SQLite it then takes the write lock only inside the
    commit, never while the request waits for a thread), or at once with ``now`` (the caller needs its id).

    Call it once the data to be answered has been loaded (so a 404 leaves no event) and after anything
    that rolls ``db`` back (:meth:`app.store.checks.IngestionChecker.ensure_fresh` does).  Raises ``ValueError``
    for an action outside :data:`ACTIONS` (a programming error, caught by the tests)."""
    _check(action)
    kind, user_id, token_id, label = _actor(principal)
    resource, client = _where(request)
    # the request's commit comes before its answer (DbDep): a failing insert fails the request, no data answered
    return add_event(db, at_commit=not now, clinic_id=principal.clinic_id, actor_kind=kind, user_id=user_id,
                     token_id=token_id,
                     actor=label[:_ACTOR_CHARS], action=action, patient_id=patient_id, session_id=session_id,
                     resource=resource, client=client, status=status, detail=detail[:_DETAIL_CHARS])


def record_login(db: Session, request: "Request", action: str, *, email: str, user: "User | None",
                 status: int, detail: str = "") -> AuditEvent:
    """A login's event (``login``, ``login_failed``, ``login_refused``) in ``db``'s transaction: the account's
    clinic and id when the email has one; the actor is the user (success) or ``anonymous`` with the email typed."""
    _check(action)
    resource, client = _where(request)
    kind = "user" if action == "login" else "anonymous"
    return add_event(db, clinic_id=user.clinic_id if user else None, actor_kind=kind,
                     user_id=user.id if user else None, token_id=None, actor=email[:_ACTOR_CHARS], action=action,
                     resource=resource, client=client, status=status, detail=detail[:_DETAIL_CHARS])


def record_refusal(database: "Database", request: "Request", status: int, detail: str, *,
                   principal: "Principal | None" = None, clinic_id: int | None = None, user_id: int | None = None,
                   token_id: int | None = None, actor: str = "") -> None:
    """A ``denied`` event in a transaction of its own (module docstring); never raises (a failure is logged).

    With ``principal`` the event names the caller; ``clinic_id`` overrides its clinic (a cross-clinic 404 is
    recorded in the owning clinic)."""
    resource, client = _where(request)
    try:
        with database.session() as db:
            if principal is not None:
                kind, uid, tid, label = _actor(principal)
                user_id, token_id, actor = uid, tid, label
                clinic_id = principal.clinic_id if clinic_id is None else clinic_id
            else:
                kind = "user" if user_id is not None else "token" if token_id is not None else "anonymous"
            add_event(db, clinic_id=clinic_id, actor_kind=kind, user_id=user_id, token_id=token_id,
                      actor=actor[:_ACTOR_CHARS], action="denied", resource=resource, client=client, status=status,
                      detail=detail[:_DETAIL_CHARS])
    except Exception:  # noqa: BLE001 — a refusal is answered whatever happens to its record
        log.exception("could not record the refusal %s of %s (%s)", status, resource, detail)


def record_operator(db: Session, *, clinic_id: int | None, action: str, actor: str = "operator (command line)",
                    resource: str = "", detail: str = "", patient_id: int | None = None,
                    session_id: int | None = None, user_id: int | None = None,
                    token_id: int | None = None) -> AuditEvent:
    """Add (and flush) the event of an operator's command (``chakamo patients erase …``, ``chakamo tokens|users …``)
    or of the retention policy, in ``db``'s transaction: actor kind ``operator``, ``actor`` what ran it,
    ``resource`` the command, ``detail`` what changed; no client address.  Same rules as :func:`record` (fail
    closed, :data:`ACTIONS`)."""
    _check(action)
    return add_event(db, clinic_id=clinic_id, actor_kind="operator", user_id=user_id, token_id=token_id,
                     actor=actor[:_ACTOR_CHARS], action=action, patient_id=patient_id, session_id=session_id,
                     resource=resource[:_RESOURCE_CHARS], client="", status=None, detail=detail[:_DETAIL_CHARS])


__all__ = ["ACTIONS", "record", "record_login", "record_operator", "record_refusal"]
