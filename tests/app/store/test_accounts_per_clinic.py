"""Migration 0008 (accounts per clinic, issue 16 finding 10b) and the ``chakamo users`` commands on an email with
accounts in two clinics."""

from __future__ import annotations

import pytest


def test_upgrade_to_0008_keeps_every_browser_session(tmp_path):
    """SQLite rebuilds ``users`` to drop its old UNIQUE(email); with foreign keys on, dropping the old table would
    cascade to the browser sessions and log everybody out.  After the upgrade the session is there, an email may
    have an account in a second clinic, and never two in one."""
    from alembic import command
    from sqlalchemy.exc import IntegrityError

    from app.store.database import Database, alembic_config

    db = Database(f"sqlite:///{tmp_path}/u.db")
    command.upgrade(alembic_config(db.engine), "0007")
    with db.engine.begin() as conn:
        conn.exec_driver_sql("INSERT INTO clinics (id, name, created_at) VALUES (1, 'A', '2026-01-01'), "
                             "(2, 'B', '2026-01-01')")
        conn.exec_driver_sql("INSERT INTO users (id, clinic_id, email, name, role, password_hash, active, created_at) "
                             "VALUES (1, 1, 'x@y.test', '', 'admin', 'h', 1, '2026-01-01')")
        conn.exec_driver_sql("INSERT INTO browser_sessions (id, user_id, session_sha256, created_at, expires_at, "
                             "client, user_agent) VALUES (7, 1, 'abc', '2026-01-01', '2099-01-01', '10.0.0.1', 'ff')")
    db.migrate()
    insert = ("INSERT INTO users (clinic_id, email, name, role, password_hash, active, created_at) "
              "VALUES ({}, 'x@y.test', '', 'admin', 'h', 1, '2026-01-01')")
    with db.engine.begin() as conn:
        assert conn.exec_driver_sql("SELECT id, user_id, client FROM browser_sessions").all() == [(7, 1, "10.0.0.1")]
        conn.exec_driver_sql(insert.format(2))
    with pytest.raises(IntegrityError), db.engine.begin() as conn:
        conn.exec_driver_sql(insert.format(1))
    db.dispose()


def test_user_commands_name_the_clinic_when_an_email_has_two_accounts(tmp_path):
    from app.cli import admin as admin_cli
    from app.settings import Settings

    settings = Settings(CHAKAMO_ENV="development", CHAKAMO_DATA_DIR=tmp_path / "data")
    for clinic in ("Norte", "Sur"):
        admin_cli.create_clinic(settings, clinic)
        admin_cli.create_user(settings, clinic=clinic, email="Ana@H.test", role="clinician",
                              password="a long enough password")
    with pytest.raises(ValueError, match="already has an account in 'Sur'"):
        admin_cli.create_user(settings, clinic="Sur", email="ana@h.test", role="admin", password="another long one!")
    with pytest.raises(ValueError, match="several clinics.*'Norte', 'Sur'.*--clinic"):
        admin_cli.set_password(settings, email="ana@h.test", password="a brand new secret")
    with pytest.raises(ValueError, match="several clinics"):
        admin_cli.deactivate_user(settings, email="ana@h.test")
    assert admin_cli.set_password(settings, email="ana@h.test", password="a brand new secret", clinic="Sur") == 0
    assert admin_cli.deactivate_user(settings, email="ana@h.test", clinic="Norte") == 0
    with pytest.raises(ValueError, match="no user with the email 'nobody@h.test' in 'Sur'"):
        admin_cli.deactivate_user(settings, email="nobody@h.test", clinic="Sur")
