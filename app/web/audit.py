"""The audit log: who viewed, downloaded, exported or changed which patient's data (OWASP ASVS V7, V8.3).

:func:`record` adds one :class:`app.store.models.AuditEvent` for the calling :class:`app.web.api.deps.Principal`:
the actor (a browser user — its id and email — or an API token — its id and label), the action
(:data:`ACTIONS`), the patient and session concerned, the request's method and path, and the client address.

Same transaction, fail closed.  The event is added to the database session that carries the request's own
work and flushed at once: it commits together with the response's data (a created patient and its
``create`` event, an upload and its ``upload`` event) or not at all.  For reads this means a read whose
audit row cannot be written fails (500) instead of disclosing data unrecorded — ASVS 7.1 wants the log
complete, and an unlogged disclosure of patient data is worse than a refused one; the price is that a full
or read-only database blocks reads as well as writes.  A request refused before its data was loaded (401,
403, 404 — also another clinic's ids) leaves no event: nothing was disclosed.

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
``GET /fhir/DiagnosticReport/{id}``                     ``export``    patient / session
``POST /sessions/{id}/process``                         ``process``   patient / session
======================================================  ============  ====================================

Deliberately not recorded: ``GET /jobs/{id}`` (the UI polls it many times a second while a job runs; it
shows the job's progress, not patient data) and the audit log itself.  The query string is not stored (a
search term is itself patient data and the log should not copy it).  Rows are append-only from the API:
``app.web.api.audit`` only lists them (:func:`app.store.audit.list_events`); nothing in the product updates or
deletes them (a clinic's deletion cascades to its events).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sqlalchemy.orm import Session

from app.store.accounts import token_label
from app.store.audit import add_event
from app.store.models import AuditEvent

if TYPE_CHECKING:  # types only: this module must not import the API package (a worker may call it)
    from fastapi import Request

    from app.web.api.deps import Principal

#: the actions an event may have (the table above)
ACTIONS: tuple[str, ...] = ("list", "search", "view", "create", "upload", "delete", "download", "export",
                            "process", "update")
#: column widths of :class:`AuditEvent` (longer values are cut, never refused: the read must not fail on them)
_RESOURCE_CHARS, _CLIENT_CHARS, _ACTOR_CHARS = 300, 64, 320


def _actor(db: Session, principal: "Principal") -> tuple[str, int | None, int | None, str]:
    """``(actor_kind, user_id, token_id, label)`` of the caller."""
    if principal.user is not None:
        return "user", principal.user.id, None, principal.user.email
    name = token_label(db, principal.token_id) if principal.token_id is not None else None
    label = f"token {principal.token_id}" + (f" ({name})" if name else "")
    return "token", None, principal.token_id, label


def record(db: Session, request: "Request", principal: "Principal", action: str, *, patient_id: int | None = None,
           session_id: int | None = None) -> AuditEvent:
    """Add (and flush) the audit event of ``principal`` doing ``action`` on the patient/session in ``db``'s
    transaction — the one that carries the request's work, so both commit together (module docstring).

    Call it once the data to be answered has been loaded (so a 404 leaves no event) and after anything
    that rolls ``db`` back (:meth:`app.store.checks.IngestionChecker.ensure_fresh` does).  Raises ``ValueError``
    for an action outside :data:`ACTIONS` (a programming error, caught by the tests)."""
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}; use one of {', '.join(ACTIONS)}")
    kind, user_id, token_id, label = _actor(db, principal)
    # flushed at once: a failing insert fails the request here, before any data is answered
    return add_event(db, clinic_id=principal.clinic_id, actor_kind=kind, user_id=user_id, token_id=token_id,
                     actor=label[:_ACTOR_CHARS], action=action, patient_id=patient_id, session_id=session_id,
                     resource=f"{request.method} {request.url.path}"[:_RESOURCE_CHARS],
                     client=(request.client.host if request.client else "")[:_CLIENT_CHARS])


__all__ = ["ACTIONS", "record"]


def record_operator(db: Session, *, clinic_id: int, action: str, actor: str, resource: str,
                    patient_id: int | None = None, session_id: int | None = None) -> AuditEvent:
    """Add (and flush) the event of an operator's command (``chakamo patients erase …``) or of the retention
    policy: actor kind ``operator``, ``actor`` what ran it, ``resource`` the command; no client address.
    Same rules as :func:`record` (``db``'s transaction, fail closed, :data:`ACTIONS`)."""
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}; use one of {', '.join(ACTIONS)}")
    return add_event(db, clinic_id=clinic_id, actor_kind="operator", user_id=None, token_id=None,
                     actor=actor[:_ACTOR_CHARS], action=action, patient_id=patient_id, session_id=session_id,
                     resource=resource[:_RESOURCE_CHARS], client="")


__all__ += ["record_operator"]
