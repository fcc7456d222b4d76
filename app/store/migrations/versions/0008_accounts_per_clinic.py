"""Accounts belong to a clinic: an email is unique within its clinic (``uq_users_email_clinic`` on ``(email,
clinic_id)``) instead of across clinics (``uq_users_email``).  Issue 16 finding 10b: an admin creating an account
for an email used in another clinic got a 409, which told them that the other clinic had that person; now the
email is only refused when it is taken in the admin's own clinic.  Logging in names the clinic when the email has
accounts in several (:func:`app.store.accounts.login_account`).

SQLite cannot drop a table's UNIQUE constraint: the batch operation rebuilds ``users``, and dropping the old
table with foreign keys on (every connection of :mod:`app.store.database` has them on, and the pragma cannot be
changed inside the migration's transaction) would cascade to ``browser_sessions``: everybody would be logged out
by the upgrade.  The sessions are kept aside in a temporary table and put back.
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0008
Revises: 0007
Create Date: 2026-12-02 04:00:00
"""
from alembic import op


revision = '0008'
down_revision = '0007'
branch_labels = None
depends_on = None


def _rebuild_users(drop: str, create: str, columns: list[str]) -> None:
    sqlite = op.get_bind().dialect.name == "sqlite"
    if sqlite:  # (module docstring) the rebuild's DROP TABLE would cascade to the browser sessions
        op.execute("CREATE TEMP TABLE keep_browser_sessions AS SELECT * FROM browser_sessions")
    with op.batch_alter_table('users', schema=None) as batch_op:
        batch_op.drop_constraint(drop, type_='unique')
        batch_op.create_unique_constraint(create, columns)
    if sqlite:
        op.execute("INSERT INTO browser_sessions SELECT * FROM keep_browser_sessions "
                   "WHERE user_id IN (SELECT id FROM users) "
                   "AND id NOT IN (SELECT id FROM browser_sessions)")
        op.execute("DROP TABLE keep_browser_sessions")


def upgrade() -> None:
    _rebuild_users('uq_users_email', 'uq_users_email_clinic', ['email', 'clinic_id'])


def downgrade() -> None:
    # fails (IntegrityError) while an email has accounts in two clinics: the operator must first remove one
    _rebuild_users('uq_users_email_clinic', 'uq_users_email', ['email'])
