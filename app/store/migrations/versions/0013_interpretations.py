"""The clinician's interpretation and sign-off of an analysis, with its amendments (issue 17 §3): tables
``interpretations`` (one per analysis: the text, who signed it, their role, when) and ``interpretation_amendments``
(each amendment's earlier and new text, by whom, when, why).  Checked against the models by
tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0013
Revises: 0012
Create Date: 2026-12-02 07:00:00
"""
from alembic import op
import sqlalchemy as sa



revision = '0013'
down_revision = '0012'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'interpretations',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('clinic_id', sa.Integer(), nullable=False),
        sa.Column('session_id', sa.Integer(), nullable=False),
        sa.Column('analysis_id', sa.Integer(), nullable=False),
        sa.Column('text', sa.Text(), nullable=False),
        sa.Column('updated_by', sa.String(length=320), nullable=False),
        sa.Column('updated_at', sa.DateTime(), nullable=False),
        sa.Column('signed_by_user_id', sa.Integer(), nullable=True),
        sa.Column('signed_by', sa.String(length=320), nullable=True),
        sa.Column('signed_role', sa.String(length=20), nullable=True),
        sa.Column('signed_at', sa.DateTime(), nullable=True),
        sa.ForeignKeyConstraint(['analysis_id'], ['analyses.id'], name=op.f('fk_interpretations_analysis_id_analyses'),
                                ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['clinic_id'], ['clinics.id'], name=op.f('fk_interpretations_clinic_id_clinics'),
                                ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['session_id'], ['sessions.id'], name=op.f('fk_interpretations_session_id_sessions'),
                                ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['signed_by_user_id'], ['users.id'],
                                name=op.f('fk_interpretations_signed_by_user_id_users'), ondelete='SET NULL'),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_interpretations')),
        sa.UniqueConstraint('analysis_id', name=op.f('uq_interpretations_analysis_id')),
    )
    with op.batch_alter_table('interpretations', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_interpretations_clinic_id'), ['clinic_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_interpretations_session_id'), ['session_id'], unique=False)
    op.create_table(
        'interpretation_amendments',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('interpretation_id', sa.Integer(), nullable=False),
        sa.Column('previous_text', sa.Text(), nullable=False),
        sa.Column('text', sa.Text(), nullable=False),
        sa.Column('reason', sa.Text(), nullable=False),
        sa.Column('user_id', sa.Integer(), nullable=True),
        sa.Column('by', sa.String(length=320), nullable=False),
        sa.Column('role', sa.String(length=20), nullable=False),
        sa.Column('at', sa.DateTime(), nullable=False),
        sa.ForeignKeyConstraint(['interpretation_id'], ['interpretations.id'],
                                name=op.f('fk_interpretation_amendments_interpretation_id_interpretations'),
                                ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['user_id'], ['users.id'], name=op.f('fk_interpretation_amendments_user_id_users'),
                                ondelete='SET NULL'),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_interpretation_amendments')),
    )
    with op.batch_alter_table('interpretation_amendments', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_interpretation_amendments_interpretation_id'), ['interpretation_id'],
                              unique=False)


def downgrade() -> None:
    with op.batch_alter_table('interpretation_amendments', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_interpretation_amendments_interpretation_id'))
    op.drop_table('interpretation_amendments')
    with op.batch_alter_table('interpretations', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_interpretations_session_id'))
        batch_op.drop_index(batch_op.f('ix_interpretations_clinic_id'))
    op.drop_table('interpretations')
