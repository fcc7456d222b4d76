"""Migration 0012 seals every webhook secret stored in plain text (made before AES-GCM sealing existed) and turns
the trail's sentences into codes; from a real database at revision 0011 (SQLite, and PostgreSQL when
``CHAKAMO_TEST_POSTGRES_URL`` names a server)."""

from __future__ import annotations

import pytest

KEY = b"the operator's key, at least 32 characters long"


def _at_0011_with_a_plain_secret(url: str, sealed_under: bytes = KEY):
    """A database at 0011 with a plain secret (row 1) and one sealed under ``sealed_under`` (row 2)."""
    from alembic import command

    from app.store.database import Database, alembic_config
    from app.store.sealed import seal

    db = Database(url)
    command.upgrade(alembic_config(db.engine), "0011")
    with db.engine.begin() as conn:
        conn.exec_driver_sql("INSERT INTO clinics (id, name, created_at) VALUES (1, 'C', '2026-01-01')")
        for sid, secret in ((1, "plain-secret-made-before-sealing-0123456789a"), (2, seal(sealed_under, "already-sealed"))):
            conn.exec_driver_sql("INSERT INTO webhook_subscriptions (id, clinic_id, url, events, secret, created_at, "
                                 f"label) VALUES ({sid}, 1, 'https://ris.example/h', 'job.done', '{secret}', "
                                 "'2026-01-01', '')")
        for did, error, status in ((1, "could not connect", "NULL"), (2, "HTTP 500", "500"),
                                   (3, "secret unreadable: subscribe again", "NULL"), (4, "", "200")):
            conn.exec_driver_sql("INSERT INTO webhook_deliveries (id, subscription_id, clinic_id, job_id, event, "
                                 "payload, state, attempts, next_attempt_at, last_status, last_error, created_at) "
                                 f"VALUES ({did}, 1, 1, {did}, 'job.done', '{{}}', 'pending', 1, '2026-01-01', "
                                 f"{status}, '{error}', '2026-01-01')")
    return db


def _check(url: str) -> None:
    from sqlalchemy import text

    from app.store.sealed import sealed, unseal

    db = _at_0011_with_a_plain_secret(url)
    try:
        with pytest.raises(RuntimeError, match="CHAKAMO_SECRET_KEY"):  # no key: stops, changes nothing
            db.migrate(None)
        with db.engine.connect() as conn:
            assert conn.execute(text("SELECT secret FROM webhook_subscriptions WHERE id = 1")).scalar() \
                == "plain-secret-made-before-sealing-0123456789a"
            assert conn.execute(text("SELECT version_num FROM alembic_version")).scalar() == "0011"
        db.migrate(KEY)
        with db.engine.connect() as conn:
            secrets = dict(conn.execute(text("SELECT id, secret FROM webhook_subscriptions")).all())
            errors = dict(conn.execute(text("SELECT id, last_error FROM webhook_deliveries")).all())
            kinds = set(conn.execute(text("SELECT kind FROM webhook_subscriptions")).scalars())
        assert all(sealed(s) for s in secrets.values()) and len(secrets[1]) <= 100
        assert unseal(KEY, secrets[1]) == "plain-secret-made-before-sealing-0123456789a"
        assert unseal(KEY, secrets[2]) == "already-sealed"  # a sealed one is left alone
        assert errors == {1: "webhook.no_connection", 2: "webhook.http_status", 3: "webhook.secret_unreadable", 4: ""}
        assert kinds == {"webhook"}
    finally:
        db.dispose()


def test_0012_seals_plain_secrets_on_sqlite(tmp_path):
    _check(f"sqlite:///{tmp_path}/m.db")


def test_0012_seals_plain_secrets_on_postgresql(pg_url):
    _check(pg_url)


def test_0012_goes_down_and_up_again(tmp_path):
    from alembic import command
    from sqlalchemy import text

    from app.store.database import alembic_config

    db = _at_0011_with_a_plain_secret(f"sqlite:///{tmp_path}/d.db")
    try:
        db.migrate(KEY)
        command.downgrade(alembic_config(db.engine), "0011")
        with db.engine.connect() as conn:
            errors = dict(conn.execute(text("SELECT id, last_error FROM webhook_deliveries")).all())
        assert errors == {1: "could not connect", 2: "HTTP 500", 3: "secret unreadable: subscribe again", 4: ""}
        db.migrate(None)  # sealed already: no key needed
    finally:
        db.dispose()


def _refuses_a_key_that_opens_no_sealed_secret(url: str) -> None:
    """Sealing under a mistyped key would lock the plain secrets away for good: a key under which no secret sealed
    already opens is refused, and nothing changes."""
    from sqlalchemy import text

    db = _at_0011_with_a_plain_secret(url, sealed_under=b"the server's real key, 32 characters or more")
    try:
        with pytest.raises(RuntimeError, match="not the server's key"):
            db.migrate(KEY)
        with db.engine.connect() as conn:
            assert conn.execute(text("SELECT secret FROM webhook_subscriptions WHERE id = 1")).scalar() \
                == "plain-secret-made-before-sealing-0123456789a"
            assert conn.execute(text("SELECT version_num FROM alembic_version")).scalar() == "0011"
        db.migrate(b"the server's real key, 32 characters or more")
    finally:
        db.dispose()


def test_0012_refuses_a_key_that_opens_no_sealed_secret_on_sqlite(tmp_path):
    _refuses_a_key_that_opens_no_sealed_secret(f"sqlite:///{tmp_path}/k.db")


def test_0012_refuses_a_key_that_opens_no_sealed_secret_on_postgresql(pg_url):
    _refuses_a_key_that_opens_no_sealed_secret(pg_url)


def test_an_unsealed_value_is_refused_not_used_as_a_key():
    from app.store.sealed import seal, unseal

    with pytest.raises(ValueError):
        unseal(KEY, "plain-secret")
    assert unseal(KEY, seal(KEY, "x")) == "x"
