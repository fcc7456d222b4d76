"""Authentication and its audit (issue 16): the login throttle's counters move into the database
(``login_attempts``: every API server reserves attempts in the same rows), and audit events can record security
events — ``status`` (the answer's code), ``detail`` (what changed or why it was refused) and a null ``clinic_id``
for events no clinic can be named for (a login with an unknown email, a request without valid credentials);
browser sessions remember the address and browser they were opened from (the user's list of their sessions).
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-01 23:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0005'
down_revision = '0004'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'login_attempts',
        sa.Column('key', sa.String(length=420), nullable=False),
        sa.Column('email', sa.String(length=320), nullable=True),
        sa.Column('attempts', sa.Integer(), nullable=False),
        sa.Column('delay_s', sa.Float(), nullable=False),
        sa.Column('next_s', sa.Float(), nullable=False),
        sa.Column('last_s', sa.Float(), nullable=False),
        sa.PrimaryKeyConstraint('key', name=op.f('pk_login_attempts')),
    )
    with op.batch_alter_table('login_attempts', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_login_attempts_email'), ['email'], unique=False)
    with op.batch_alter_table('browser_sessions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('client', sa.String(length=64), server_default='', nullable=False))
        batch_op.add_column(sa.Column('user_agent', sa.String(length=200), server_default='', nullable=False))
    with op.batch_alter_table('audit_events', schema=None) as batch_op:
        batch_op.add_column(sa.Column('status', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('detail', sa.String(length=300), server_default='', nullable=False))
        batch_op.alter_column('clinic_id', existing_type=sa.Integer(), nullable=True)


def downgrade() -> None:
    op.execute("DELETE FROM audit_events WHERE clinic_id IS NULL")
    with op.batch_alter_table('audit_events', schema=None) as batch_op:
        batch_op.alter_column('clinic_id', existing_type=sa.Integer(), nullable=False)
        batch_op.drop_column('detail')
        batch_op.drop_column('status')
    with op.batch_alter_table('browser_sessions', schema=None) as batch_op:
        batch_op.drop_column('user_agent')
        batch_op.drop_column('client')
    with op.batch_alter_table('login_attempts', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_login_attempts_email'))
    op.drop_table('login_attempts')
