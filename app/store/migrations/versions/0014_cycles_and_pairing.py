"""Jobs gain ``cycle_exclusions``: the cycles the clinician excluded when asking for the analysis again
(``[{"cycle", "knee", "reason", "by", "at"}]``, :class:`app.pipeline.exclusions.CycleExclusion`); null for every
earlier job and every ordinary processing.  A job that carries it (an empty list too: every cycle re-included)
supersedes the session's earlier analyses when it stores its own (:mod:`app.jobs.work`).
Sessions gain ``paired_session_id`` and ``knee``: two one-knee sessions of a patient paired into one of both knees
(:mod:`app.store.pairing`); null for every earlier session.  Columns are only added (no table rebuild: on SQLite
a rebuild of ``sessions`` would cascade to its recordings), so the partner's id has no foreign key.
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0014
Revises: 0013
Create Date: 2026-12-02 07:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0014'
down_revision = '0013'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.add_column(sa.Column('cycle_exclusions', sa.JSON(), nullable=True))
    with op.batch_alter_table('sessions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('paired_session_id', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('knee', sa.String(length=5), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('sessions', schema=None) as batch_op:
        batch_op.drop_column('knee')
        batch_op.drop_column('paired_session_id')
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.drop_column('cycle_exclusions')
