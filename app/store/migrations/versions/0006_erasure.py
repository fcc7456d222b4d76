"""Erasure and correction: patients and sessions gain ``version`` (the ``ETag`` of ``If-Match``) and
``updated_at``; analyses ``superseded_at`` (a report whose recordings were deleted or whose printed facts were
corrected is no longer served as final); artefacts' ``sha256`` is indexed (blob reference counts); and the
``blob_erasures`` table records every stored file whose last reference went, pending until its bytes are gone
(:mod:`app.store.erasure`).  Rows from before this revision are version 1, never updated, not superseded.
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0006
Revises: 0005
Create Date: 2026-12-01 23:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0006'
down_revision = '0005'
branch_labels = None
depends_on = None


def upgrade() -> None:
    for table in ('patients', 'sessions'):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.add_column(sa.Column('version', sa.Integer(), server_default='1', nullable=False))
            batch_op.add_column(sa.Column('updated_at', sa.DateTime(), nullable=True))
    with op.batch_alter_table('analyses', schema=None) as batch_op:
        batch_op.add_column(sa.Column('superseded_at', sa.DateTime(), nullable=True))
    with op.batch_alter_table('artefacts', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_artefacts_sha256'), ['sha256'], unique=False)
    op.create_table(
        'blob_erasures',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('sha256', sa.String(length=64), nullable=False),
        sa.Column('size_bytes', sa.Integer(), nullable=True),
        sa.Column('state', sa.String(length=10), nullable=False),
        sa.Column('reason', sa.String(length=20), nullable=False),
        sa.Column('clinic_id', sa.Integer(), nullable=True),
        sa.Column('patient_id', sa.Integer(), nullable=True),
        sa.Column('session_id', sa.Integer(), nullable=True),
        sa.Column('audit_event_id', sa.Integer(), nullable=True),
        sa.Column('actor', sa.String(length=320), nullable=False),
        sa.Column('requested_at', sa.DateTime(), nullable=False),
        sa.Column('done_at', sa.DateTime(), nullable=True),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_blob_erasures')),
    )
    with op.batch_alter_table('blob_erasures', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_blob_erasures_clinic_id'), ['clinic_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_blob_erasures_sha256'), ['sha256'], unique=False)
        batch_op.create_index(batch_op.f('ix_blob_erasures_state'), ['state'], unique=False)


def downgrade() -> None:
    op.drop_table('blob_erasures')
    with op.batch_alter_table('artefacts', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_artefacts_sha256'))
    with op.batch_alter_table('analyses', schema=None) as batch_op:
        batch_op.drop_column('superseded_at')
    for table in ('sessions', 'patients'):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.drop_column('updated_at')
            batch_op.drop_column('version')
