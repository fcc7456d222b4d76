"""Recordings gain ``device``: the sensor's serial (a MetaBase MAC, from the file's name) stored with the file at
upload, so swapped sensors are seen from the server's data, not from what one browser remembers.  Jobs gain
``side`` (the clinician's override of the side the files say, as ``chakamo process --side``), and ``error_code`` /
``error_params`` (a failed job's message as a catalogue code and its values, rendered in the reader's language).
Rows made before this revision have none of them (NULL): their files are read again when the session is checked.
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0007
Revises: 0006
Create Date: 2026-12-01 23:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0007'
down_revision = '0006'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('recordings', schema=None) as batch_op:
        batch_op.add_column(sa.Column('device', sa.String(length=64), nullable=True))
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.add_column(sa.Column('side', sa.String(length=5), nullable=True))
        batch_op.add_column(sa.Column('error_code', sa.String(length=60), nullable=True))
        batch_op.add_column(sa.Column('error_params', sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.drop_column('error_params')
        batch_op.drop_column('error_code')
        batch_op.drop_column('side')
    with op.batch_alter_table('recordings', schema=None) as batch_op:
        batch_op.drop_column('device')
