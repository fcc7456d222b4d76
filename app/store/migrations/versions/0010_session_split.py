"""Sessions gain ``split``: where the clinician confirmed or moved the cuts of each sensor's continuous recording
(``{segment: {role: [start_s, end_s]}}``, seconds from the recording's start; issue 14 §3a), stored on the server
and written into the session's ``session.json`` ``"split"`` for the check and the processing.  NULL: the automatic
split is used.  Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py.

Revision ID: 0010
Revises: 0009
Create Date: 2026-12-02 04:20:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0010'
down_revision = '0009'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('sessions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('split', sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('sessions', schema=None) as batch_op:
        batch_op.drop_column('split')
