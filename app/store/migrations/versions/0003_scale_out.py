"""Scale-out and audit: jobs gain ``pipeline_version``, ``dispatched_at`` and ``heartbeat_at`` (the
distributed engine's idempotency key and leases), analyses the ``pipeline_version`` and ``files_version``
they were computed from, and the append-only ``audit_events`` table.
Checked against the models by tests/app/web/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-01 15:20:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0003'
down_revision = '0002'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.add_column(sa.Column('pipeline_version', sa.String(length=40), server_default='', nullable=False))
        batch_op.add_column(sa.Column('dispatched_at', sa.DateTime(), nullable=True))
        batch_op.add_column(sa.Column('heartbeat_at', sa.DateTime(), nullable=True))
    with op.batch_alter_table('analyses', schema=None) as batch_op:
        batch_op.add_column(sa.Column('pipeline_version', sa.String(length=40), server_default='', nullable=False))
        batch_op.add_column(sa.Column('files_version', sa.Integer(), nullable=True))
    op.create_table(
        'audit_events',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('clinic_id', sa.Integer(), nullable=False),
        sa.Column('at', sa.DateTime(), nullable=False),
        sa.Column('actor_kind', sa.String(length=10), nullable=False),
        sa.Column('user_id', sa.Integer(), nullable=True),
        sa.Column('token_id', sa.Integer(), nullable=True),
        sa.Column('actor', sa.String(length=320), nullable=False),
        sa.Column('action', sa.String(length=20), nullable=False),
        sa.Column('patient_id', sa.Integer(), nullable=True),
        sa.Column('session_id', sa.Integer(), nullable=True),
        sa.Column('resource', sa.String(length=300), nullable=False),
        sa.Column('client', sa.String(length=64), nullable=False),
        sa.ForeignKeyConstraint(['clinic_id'], ['clinics.id'], name=op.f('fk_audit_events_clinic_id_clinics'),
                                ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_audit_events')),
    )
    with op.batch_alter_table('audit_events', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_audit_events_at'), ['at'], unique=False)
        batch_op.create_index(batch_op.f('ix_audit_events_clinic_id'), ['clinic_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_audit_events_patient_id'), ['patient_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_audit_events_user_id'), ['user_id'], unique=False)


def downgrade() -> None:
    op.drop_table('audit_events')
    with op.batch_alter_table('analyses', schema=None) as batch_op:
        batch_op.drop_column('files_version')
        batch_op.drop_column('pipeline_version')
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.drop_column('heartbeat_at')
        batch_op.drop_column('dispatched_at')
        batch_op.drop_column('pipeline_version')
