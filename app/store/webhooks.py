"""Webhooks: a clinic's subscriptions, the deliveries of job events, and their attempts (the audit trail).

When a job of the clinic ends — ``done`` or ``failed`` — every subscription made before it ended and asking
for that event gets one delivery (:func:`plan_deliveries`; unique per subscription, job and event, so two servers
planning at once make one).  A delivery carries ids and links only, never a patient's data.  The sender
(:mod:`app.web.webhooks`) claims one due delivery at a time (:func:`claim_due`: its next attempt is pushed a
lease ahead in the same statement that checks it, so two servers never send one attempt twice) and records each
attempt only while that lease is still its own (:func:`record_attempt`, a conditional update): a 2xx answer delivers it; otherwise the next attempt waits ``base_s · 2^(n−1)``
(capped at :data:`MAX_BACKOFF_S`) until :data:`MAX_ATTEMPTS` attempts were made, then the delivery is
``failed``.  Every row stays as the audit trail (``GET /webhooks/{id}/deliveries``).

The FHIR push (``app.web.fhir_push``) rides on the same rows: :func:`ensure_fhir_push` gives each clinic the operator
opted in one subscription of kind ``fhir`` (made when the clinic is first opted in, so only jobs ending after that
are pushed; never listed or deleted among the clinic's webhooks), whose ``job.done`` deliveries are planned,
claimed, retried and recorded exactly like a webhook's (``GET /fhir/pushes`` is their trail).  A clinic opted out
keeps its subscription with no events (nothing planned, nothing claimed: its trail stays); opted in again, its
subscription starts afresh (only jobs ending after that).  A pushed report whose analysis is superseded since
(:func:`app.store.analyses.supersede`: a recording deleted, a printed fact corrected) gets one more delivery,
:data:`RETRACTION` (:func:`plan_deliveries`), which marks the hospital's copy entered-in-error; its row names the
same job as the push it retracts, told apart by its event (the unique subscription, job and event keep one retraction
per report: migration 0017).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

from sqlalchemy import and_, exists, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, aliased

from app.store.errors import Invalid, NotFound
from app.store.models import Analysis, Clinic, Job, KneeSession, WebhookDelivery, WebhookSubscription, utcnow

#: the events a subscription may ask for: a job's end
EVENTS = ("job.done", "job.failed")
MAX_ATTEMPTS = 8
MAX_BACKOFF_S = 3600.0
#: the one event the FHIR push sends (a finished report); an opted-out clinic's subscription has none
FHIR_EVENT = "job.done"
#: the FHIR push's delivery retracting a pushed report whose analysis was superseded (module docstring)
RETRACTION = "analysis.superseded"
#: how long a claimed attempt keeps other senders away (longer than a send's timeout)
LEASE_S = 60.0


def add_subscription(db: Session, clinic_id: int, *, url: str, events: list[str], secret: str,
                     label: str = "") -> WebhookSubscription:
    unknown = [e for e in events if e not in EVENTS]
    if unknown or not events:
        raise Invalid(code="store.unknown_event", events=", ".join(unknown), allowed=" / ".join(EVENTS))
    row = WebhookSubscription(clinic_id=clinic_id, url=url, events=" ".join(sorted(set(events))), secret=secret,
                              label=label)
    db.add(row)
    db.flush()
    return row


def subscriptions(db: Session, clinic_id: int) -> list[WebhookSubscription]:
    """The clinic's webhooks (not its FHIR push)."""
    return list(db.scalars(select(WebhookSubscription).where(WebhookSubscription.clinic_id == clinic_id,
                                                             WebhookSubscription.kind == "webhook")
                           .order_by(WebhookSubscription.id)))


def clinic_subscription(db: Session, clinic_id: int, subscription_id: int) -> WebhookSubscription:
    """The clinic's webhook ``subscription_id`` (:class:`NotFound` for another clinic's or the FHIR push)."""
    row = db.get(WebhookSubscription, subscription_id)
    if row is None or row.clinic_id != clinic_id or row.kind != "webhook":
        raise NotFound(None, row.clinic_id if row else None, code="store.no_webhook", webhook_id=subscription_id)
    return row


def delete_subscription(db: Session, clinic_id: int, subscription_id: int) -> None:
    """Delete the subscription and its deliveries (pending ones are never sent)."""
    db.delete(clinic_subscription(db, clinic_id, subscription_id))
    db.flush()


def deliveries(db: Session, clinic_id: int, subscription_id: int, limit: int = 100) -> list[WebhookDelivery]:
    """The subscription's deliveries, newest first."""
    clinic_subscription(db, clinic_id, subscription_id)
    return list(db.scalars(select(WebhookDelivery).where(WebhookDelivery.subscription_id == subscription_id)
                           .order_by(WebhookDelivery.id.desc()).limit(limit)))


def ensure_fhir_push(db: Session, url: str, clinics: tuple[str, ...]) -> tuple[str, ...]:
    """The FHIR push's subscriptions as the operator configured them (module docstring): every clinic named in
    ``clinics`` subscribed to ``job.done`` (made, or started afresh when it was opted out), every other clinic's
    opted out (no events), and every one's URL ``url`` (the operator may move the server).  The names that name no
    clinic.  Commits (two servers making one at once: the partial unique index keeps one)."""
    url = url[:2000]
    db.execute(update(WebhookSubscription).where(WebhookSubscription.kind == "fhir", WebhookSubscription.url != url)
               .values(url=url))
    db.execute(update(WebhookSubscription).where(WebhookSubscription.kind == "fhir", WebhookSubscription.events != "",
                                                 WebhookSubscription.clinic_id.not_in(
                                                     select(Clinic.id).where(Clinic.name.in_(clinics))))
               .values(events=""))
    db.commit()
    found = dict(db.execute(select(Clinic.name, Clinic.id).where(Clinic.name.in_(clinics))).all())
    subscribed = dict(db.execute(select(WebhookSubscription.clinic_id, WebhookSubscription.id)
                                 .where(WebhookSubscription.kind == "fhir")).all())
    for clinic_id in found.values():
        if clinic_id in subscribed:
            db.execute(update(WebhookSubscription).where(WebhookSubscription.id == subscribed[clinic_id],
                                                         WebhookSubscription.events == "")
                       .values(events=FHIR_EVENT, created_at=utcnow()))
            db.commit()
            continue
        db.add(WebhookSubscription(clinic_id=clinic_id, url=url, events=FHIR_EVENT, secret="", label="FHIR push",
                                   kind="fhir"))
        try:
            db.commit()
        except IntegrityError:
            db.rollback()
    return tuple(n for n in clinics if n not in found)


def fhir_pushes(db: Session, clinic_id: int, limit: int = 100) -> list[WebhookDelivery]:
    """The clinic's FHIR push deliveries, newest first (their trail)."""
    return list(db.scalars(select(WebhookDelivery).join(WebhookSubscription,
                                                        WebhookSubscription.id == WebhookDelivery.subscription_id)
                           .where(WebhookSubscription.clinic_id == clinic_id, WebhookSubscription.kind == "fhir")
                           .order_by(WebhookDelivery.id.desc()).limit(limit)))


def _payload(job: Job, patient_id: int, event: str) -> dict[str, Any]:
    return {"event": event, "job": {"id": job.id, "status": job.status, "session_id": job.session_id,
                                    "patient_id": patient_id, "analysis_id": job.analysis_id,
                                    "error_code": job.error_code,
                                    "finished_at": job.finished_at.isoformat() if job.finished_at else None},
            "links": {"job": f"/api/v1/jobs/{job.id}", "session": f"/api/v1/sessions/{job.session_id}",
                      "results": f"/api/v1/sessions/{job.session_id}/results"}}


def _plan_retractions(db: Session, limit: int) -> int:
    """A pending :data:`RETRACTION` for every delivered FHIR push whose analysis is superseded and that has none yet
    (module docstring); how many were made.  Commits."""
    planned = 0
    retraction = aliased(WebhookDelivery)
    rows = db.scalars(
        select(WebhookDelivery)
        .join(WebhookSubscription, WebhookSubscription.id == WebhookDelivery.subscription_id)
        .join(Job, Job.id == WebhookDelivery.job_id).join(Analysis, Analysis.id == Job.analysis_id)
        .where(WebhookSubscription.kind == "fhir", WebhookSubscription.events != "",
               WebhookDelivery.event == FHIR_EVENT, WebhookDelivery.state == "delivered",
               Analysis.superseded_at.is_not(None),
               ~exists().where(and_(retraction.subscription_id == WebhookDelivery.subscription_id,
                                    retraction.job_id == WebhookDelivery.job_id, retraction.event == RETRACTION)))
        .order_by(WebhookDelivery.id).limit(limit)).all()
    for d in rows:
        db.add(WebhookDelivery(subscription_id=d.subscription_id, clinic_id=d.clinic_id, job_id=d.job_id,
                               event=RETRACTION, payload=dict(d.payload) | {"event": RETRACTION}, state="pending",
                               attempts=0, next_attempt_at=utcnow(), last_error=""))
        try:
            db.commit()
            planned += 1
        except IntegrityError:  # another server planned it meanwhile
            db.rollback()
    return planned


def plan_deliveries(db: Session, limit: int = 200, kinds: tuple[str, ...] = ("webhook",)) -> int:
    """A pending delivery for every ended job a subscription (of ``kinds``) of its clinic has not got yet, and, for
    the FHIR push, a retraction of every pushed report superseded since (module docstring); how many were made.
    Commits."""
    planned = _plan_retractions(db, limit) if "fhir" in kinds else 0
    for sub in db.scalars(select(WebhookSubscription).where(WebhookSubscription.kind.in_(kinds),
                                                            WebhookSubscription.events != "")).all():
        wanted = [e.split(".", 1)[1] for e in sub.events.split()]
        rows = db.execute(
            select(Job, KneeSession.patient_id).join(KneeSession, KneeSession.id == Job.session_id)
            .where(Job.clinic_id == sub.clinic_id, Job.status.in_(wanted), Job.finished_at.is_not(None),
                   Job.finished_at >= sub.created_at,
                   ~exists().where(and_(WebhookDelivery.subscription_id == sub.id, WebhookDelivery.job_id == Job.id,
                                        WebhookDelivery.event.in_(EVENTS))))
            .order_by(Job.id).limit(limit)).all()
        for job, patient_id in rows:
            event = f"job.{job.status}"
            db.add(WebhookDelivery(subscription_id=sub.id, clinic_id=sub.clinic_id, job_id=job.id, event=event,
                                   payload=_payload(job, patient_id, event), state="pending", attempts=0,
                                   next_attempt_at=utcnow(), last_error=""))
            try:
                db.commit()
                planned += 1
            except IntegrityError:  # another server planned it meanwhile
                db.rollback()
    return planned


@dataclass(frozen=True)
class Due:
    """A delivery to attempt now: where, with which secret, what; ``lease``: until when it is ours."""

    id: int
    url: str
    secret: str
    event: str
    payload: dict
    attempt: int
    lease: dt.datetime
    subscription_id: int
    #: the subscription's kind: ``webhook`` (a clinic's) or ``fhir`` (the operator's FHIR push)
    kind: str = "webhook"
    clinic_id: int = 0


def claim_due(db: Session, now: dt.datetime | None = None, skip: frozenset[int] = frozenset(),
              kinds: tuple[str, ...] = ("webhook",)) -> Due | None:
    """The pending delivery due first now, of a subscription of ``kinds`` not in ``skip``, claimed for :data:`LEASE_S`
    (module docstring); None when none is due.  One at a time: the lease covers one send (a send's timeout is
    well under it), so it cannot run out while the sender works through a batch.  Commits."""
    now = now or utcnow()
    lease = now + dt.timedelta(seconds=LEASE_S)
    while True:
        query = (select(WebhookDelivery.id, WebhookDelivery.next_attempt_at)
                 .where(WebhookDelivery.state == "pending", WebhookDelivery.next_attempt_at <= now)
                 .order_by(WebhookDelivery.next_attempt_at, WebhookDelivery.id).limit(1))
        query = query.where(WebhookDelivery.subscription_id.in_(
            select(WebhookSubscription.id).where(WebhookSubscription.kind.in_(kinds),
                                                 WebhookSubscription.events != "")))  # "": an opted-out push
        if skip:
            query = query.where(WebhookDelivery.subscription_id.not_in(skip))
        candidate = db.execute(query).first()
        if candidate is None:
            return None
        delivery_id, due_at = candidate
        won = db.execute(update(WebhookDelivery)
                         .where(WebhookDelivery.id == delivery_id, WebhookDelivery.next_attempt_at == due_at,
                                WebhookDelivery.state == "pending")
                         .values(next_attempt_at=lease)).rowcount
        db.commit()
        if won:
            d = db.get(WebhookDelivery, delivery_id)
            sub = db.get(WebhookSubscription, d.subscription_id)
            return Due(d.id, sub.url, sub.secret, d.event, dict(d.payload), d.attempts + 1, lease, sub.id, sub.kind,
                       sub.clinic_id)
        # another server took it meanwhile: the next one


def record_attempt(db: Session, due: Due, *, status: int | None, error: str, base_s: float,
                   now: dt.datetime | None = None, give_up: bool = False) -> str:
    """Record one attempt of ``due`` (``status``: the receiver's HTTP status, None when none came; ``give_up``: a
    failure no retry can mend, the delivery fails now) when its lease is still ours; the delivery's new state (``lost``: the lease ran out and another sender owns the delivery,
    ``deleted``: its subscription was deleted).  Commits."""
    now = now or utcnow()
    d = db.get(WebhookDelivery, due.id)
    if d is None:  # its subscription was deleted meanwhile
        return "deleted"
    attempts = d.attempts + 1
    values: dict[str, Any] = {"attempts": attempts, "last_status": status, "last_error": error[:300]}
    if status is not None and 200 <= status < 300:
        values |= {"state": "delivered", "delivered_at": now}
    elif attempts >= MAX_ATTEMPTS or give_up:
        values |= {"state": "failed"}
    else:
        values |= {"next_attempt_at": now + dt.timedelta(seconds=min(MAX_BACKOFF_S, base_s * 2 ** (attempts - 1)))}
    won = db.execute(update(WebhookDelivery)
                     .where(WebhookDelivery.id == due.id, WebhookDelivery.state == "pending",
                            WebhookDelivery.next_attempt_at == due.lease, WebhookDelivery.attempts == d.attempts)
                     .values(**values)).rowcount
    db.commit()
    return values.get("state", "pending") if won else "lost"


def job_states(db: Session, clinic_id: int, since: dt.datetime) -> list[dict[str, Any]]:
    """The clinic's jobs that are queued or running, or ended at or after ``since``: ``id, session_id, status,
    progress, stage`` (the server-sent event stream's source)."""
    rows = db.scalars(select(Job).where(Job.clinic_id == clinic_id,
                                        Job.status.in_(("queued", "running")) | (Job.finished_at >= since))
                      .order_by(Job.id)).all()
    return [{"id": j.id, "session_id": j.session_id, "status": j.status, "progress": j.progress, "stage": j.stage,
             "analysis_id": j.analysis_id} for j in rows]


__all__ = ["EVENTS", "FHIR_EVENT", "LEASE_S", "RETRACTION", "ensure_fhir_push", "fhir_pushes", "MAX_ATTEMPTS", "MAX_BACKOFF_S", "Due", "add_subscription", "claim_due",
           "clinic_subscription", "delete_subscription", "deliveries", "job_states", "plan_deliveries", "record_attempt",
           "subscriptions"]
