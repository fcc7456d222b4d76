"""Jobs gain ``heading``: the thigh–shank heading the processing request chose (``auto``, ``magnetometer`` or
``constraint``, :data:`app.choices.HEADINGS`); jobs queued before this revision ran with the magnetometers, but
they are done, so ``auto`` (the default since) is what any job still queued runs with.
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0004
Revises: 0003
Create Date: 2026-12-01 21:10:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0004'
down_revision = '0003'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.add_column(sa.Column('heading', sa.String(length=20), server_default='auto', nullable=False))


def downgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.drop_column('heading')
