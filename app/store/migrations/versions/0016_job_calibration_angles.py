"""Jobs and analyses gain ``calibration`` and ``angle_method``: the sensor-to-segment calibration and the knee-angle
convention a processing request chose in the wizard (``ProcessOptions.calibration`` / ``.angle_method``, as
``chakamo process --calibration`` / ``--angles``); every earlier job and analysis ran with the defaults, ``static``
and ``grood_suntay``.  The analysis keeps its own copy: comparisons, the ROM trend and the session's current
analysis tell conventions and calibrations apart (a ZYX run reads other numbers of the same knee).
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0016
Revises: 0014
Create Date: 2026-12-02 07:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0016'
down_revision = '0014'  # no 0015: the number was reserved for a branch that needed no migration
branch_labels = None
depends_on = None


def upgrade() -> None:
    for table in ('jobs', 'analyses'):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.add_column(sa.Column('calibration', sa.String(length=20), nullable=False,
                                          server_default='static'))
            batch_op.add_column(sa.Column('angle_method', sa.String(length=20), nullable=False,
                                          server_default='grood_suntay'))


def downgrade() -> None:
    for table in ('analyses', 'jobs'):
        with op.batch_alter_table(table, schema=None) as batch_op:
            batch_op.drop_column('angle_method')
            batch_op.drop_column('calibration')
