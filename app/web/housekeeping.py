"""Periodic housekeeping of the stored data, run by the embedded job runner at start and hourly
(:class:`app.jobs.inprocess.ThreadJobRunner`'s ``housekeeping``, set by :func:`app.web.main.make_runner`).

:func:`housekeeping`: the erasure sweep (:func:`app.store.erasure.sweep`: marks a crash left pending, blob rows
nothing references, files no row names), the expiry of old ``Idempotency-Key`` records and, when ``CHAKAMO_RETENTION_DAYS`` is set, the retention policy
(:mod:`app.store.retention`), whose erasures are audited as the operator (:func:`app.web.audit.record_operator`).
It lives in the web layer because the audit log's writer does; the jobs layer only calls it.  With the Celery
backend nothing runs it periodically yet: schedule ``chakamo retention --apply`` (cron, a systemd timer).
"""

from __future__ import annotations

import logging

log = logging.getLogger("chakamo.erasure")


def operator_recorder(actor: str):
    """A ``record`` for :func:`app.store.retention.apply_retention`: ``delete`` events of actor ``actor``."""
    from app.web.audit import record_operator

    def record(db, *, clinic_id: int, patient_id: int | None, session_id: int | None, resource: str):
        return record_operator(db, clinic_id=clinic_id, action="delete", actor=actor, resource=resource,
                               patient_id=patient_id, session_id=session_id)

    return record


def housekeeping(settings, database, store, now=None) -> None:
    """The erasure sweep, then the retention policy when it is on (module docstring); ``now`` fixes the clock."""
    from app.store.erasure import sweep
    from app.store.models import utcnow
    from app.store.retention import apply_retention

    sweep(database, store)
    from app.store.idempotency import forget_old

    with database.session() as db:  # Idempotency-Keys past their keeping time (app.store.idempotency)
        forget_old(db, now)
    if settings.retention_days > 0:
        report = apply_retention(database, store, settings.retention_days, now=now or utcnow(), dry_run=False,
                                 record=operator_recorder(f"retention policy ({settings.retention_days} days)"))
        if report.erased_sessions:
            log.info("retention: %d sessions erased (%d stored files)", report.erased_sessions, report.erased_files)


__all__ = ["housekeeping", "operator_recorder"]
