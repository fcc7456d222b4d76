"""Migration 0017 makes a webhook delivery unique per subscription, job and event, and gives the FHIR push's
retraction rows (stored until then with their job's id negated) their job's real id; downgrading negates them again.
From a real database at revision 0016 holding a pushed report and its retraction as 0016's code stored them
(SQLite, and PostgreSQL when ``CHAKAMO_TEST_POSTGRES_URL`` names a server)."""

from __future__ import annotations

JOB = 7
#: id -> (subscription, job_id, event, state, attempts, last_status, last_error) as 0016's code stored them: the FHIR
#: push of job 7, its retraction (job id negated), a clinic webhook's delivery of the same job, another job's push
ROWS = {1: (1, JOB, "job.done", "delivered", 2, 200, ""),
        2: (1, -JOB, "analysis.superseded", "pending", 1, None, "webhook.no_connection"),
        3: (2, JOB, "job.done", "failed", 8, 500, "webhook.http_status"),
        4: (1, JOB + 1, "job.done", "pending", 0, None, "")}
COLUMNS = "id, subscription_id, job_id, event, state, attempts, last_status, last_error"


def _at_0016_with_a_negated_retraction(url: str):
    from alembic import command

    from app.store.database import Database, alembic_config

    db = Database(url)
    command.upgrade(alembic_config(db.engine), "0016")
    with db.engine.begin() as conn:
        conn.exec_driver_sql("INSERT INTO clinics (id, name, created_at) VALUES (1, 'C', '2026-01-01')")
        for sid, kind in ((1, "fhir"), (2, "webhook")):
            conn.exec_driver_sql("INSERT INTO webhook_subscriptions (id, clinic_id, url, events, secret, created_at, "
                                 f"label, kind) VALUES ({sid}, 1, 'https://ris.example/h', 'job.done', '', "
                                 f"'2026-01-01', '', '{kind}')")
        for did, (sid, job, event, state, attempts, status, error) in ROWS.items():
            conn.exec_driver_sql(
                "INSERT INTO webhook_deliveries (id, subscription_id, clinic_id, job_id, event, payload, state, "
                "attempts, next_attempt_at, last_status, last_error, created_at) VALUES "
                f"({did}, {sid}, 1, {job}, '{event}', '{{\"event\": \"{event}\", \"job\": {{\"id\": {abs(job)}}}}}', "
                f"'{state}', {attempts}, '2026-01-01', {'NULL' if status is None else status}, '{error}', "
                "'2026-01-01')")
    return db


def _rows(db) -> dict[int, tuple]:
    from sqlalchemy import text

    with db.engine.connect() as conn:
        return {r[0]: tuple(r[1:]) for r in conn.execute(text(f"SELECT {COLUMNS} FROM webhook_deliveries"))}


def _refused(db, sid: int, job: int, event: str) -> bool:
    """Whether the unique constraint refuses one more delivery ``(sid, job, event)`` (rolled back; its id given: the
    rows above were inserted with theirs, so PostgreSQL's sequence would hand out 1 again)."""
    from sqlalchemy.exc import IntegrityError

    try:
        with db.engine.begin() as conn:
            conn.exec_driver_sql("INSERT INTO webhook_deliveries (id, subscription_id, clinic_id, job_id, event, payload, "
                                 "state, attempts, next_attempt_at, last_error, created_at) VALUES "
                                 f"(100, {sid}, 1, {job}, '{event}', '{{}}', 'pending', 0, '2026-01-01', '', '2026-01-01')")
            raise _Rollback
    except IntegrityError:
        return True
    except _Rollback:
        return False


class _Rollback(Exception):
    """Leaves :func:`_refused`'s transaction undone when the row went in."""


def _check(url: str) -> None:
    from alembic import command
    from sqlalchemy import inspect

    from app.store.database import alembic_config

    db = _at_0016_with_a_negated_retraction(url)
    try:
        # SQLite rebuilds the table: dropping the old one must fire no ON DELETE CASCADE, so none may point at it
        inspector = inspect(db.engine)
        assert not [(t, fk) for t in inspector.get_table_names() for fk in inspector.get_foreign_keys(t)
                    if fk["referred_table"] == "webhook_deliveries"]
        if db.engine.dialect.name == "sqlite":  # the product's engine migrates with SQLite's foreign keys on
            with db.engine.connect() as conn:
                assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert _rows(db) == ROWS

        db.migrate()
        after = _rows(db)
        assert after == ROWS | {2: (1, JOB) + ROWS[2][2:]}  # every row kept; the retraction names its job
        assert _refused(db, 1, JOB, "analysis.superseded")  # still one retraction per pushed report
        assert _refused(db, 1, JOB, "job.done")
        assert not _refused(db, 1, JOB, "job.failed")  # the event is part of the key now

        command.downgrade(alembic_config(db.engine), "0016")
        assert _rows(db) == ROWS  # the retraction negated again
        assert _refused(db, 1, JOB, "job.failed")  # the old pair is the key again

        db.migrate()
        assert _rows(db) == after
        with db.engine.begin() as conn:  # the rebuilt table still follows its subscription away
            conn.exec_driver_sql("DELETE FROM webhook_subscriptions WHERE id = 1")
        assert set(_rows(db)) == {3}
    finally:
        db.dispose()


def test_0017_gives_retractions_their_job_on_sqlite(tmp_path):
    _check(f"sqlite:///{tmp_path}/m.db")


def test_0017_gives_retractions_their_job_on_postgresql(pg_url):
    _check(pg_url)
