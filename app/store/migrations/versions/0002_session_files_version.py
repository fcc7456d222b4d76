"""Sessions: ``files_version`` (bumped by every upload or deletion of a recording) and ``ingestion_version``
(the files_version the stored ingestion check was computed from), so a stale check is recognised.
Checks stored before this revision are taken as belonging to version 0 (the files they were made from).
Checked against the models by tests/app/web/test_db.py.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22 06:45:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0002'
down_revision = '0001'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('sessions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('files_version', sa.Integer(), server_default='0', nullable=False))
        batch_op.add_column(sa.Column('ingestion_version', sa.Integer(), nullable=True))
    op.execute("UPDATE sessions SET ingestion_version = 0 WHERE ingestion IS NOT NULL")


def downgrade() -> None:
    with op.batch_alter_table('sessions', schema=None) as batch_op:
        batch_op.drop_column('ingestion_version')
        batch_op.drop_column('files_version')
