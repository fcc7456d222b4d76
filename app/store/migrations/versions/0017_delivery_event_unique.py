"""A webhook delivery is unique per subscription, job *and event* (``uq_webhook_delivery_job``): the FHIR push's
retraction of a report (``analysis.superseded``, :data:`app.store.webhooks.RETRACTION`) names the job it retracts,
beside that job's ``job.done`` push.  Until now the retraction's row held the job's id negated (``job_id = −job``)
to pass the subscription-and-job pair; upgrading turns those ids positive, downgrading negates them again.

SQLite rebuilds the table (alembic batch mode: copied row for row into a new table, the old one dropped): no table
references ``webhook_deliveries``, so dropping it fires no ``ON DELETE CASCADE``.  PostgreSQL drops and creates
the constraint.  Checked by tests/app/store/test_migration_0017.py (both) and test_db.py (the models).

Revision ID: 0017
Revises: 0016
Create Date: 2026-12-02 08:00:00
"""
from alembic import op
import sqlalchemy as sa


revision = '0017'
down_revision = '0016'
branch_labels = None
depends_on = None

RETRACTION = 'analysis.superseded'  # app.store.webhooks.RETRACTION, as of this revision
_deliveries = sa.table('webhook_deliveries', sa.column('job_id', sa.Integer), sa.column('event', sa.String))


def _unique(columns: list[str]) -> None:
    with op.batch_alter_table('webhook_deliveries', schema=None) as batch_op:
        batch_op.drop_constraint('uq_webhook_delivery_job', type_='unique')
        batch_op.create_unique_constraint('uq_webhook_delivery_job', columns)


def upgrade() -> None:
    _unique(['subscription_id', 'job_id', 'event'])  # first: a positive retraction would clash with its job.done
    op.execute(_deliveries.update().where(_deliveries.c.job_id < 0, _deliveries.c.event == RETRACTION)
               .values(job_id=-_deliveries.c.job_id))


def downgrade() -> None:
    op.execute(_deliveries.update().where(_deliveries.c.job_id > 0, _deliveries.c.event == RETRACTION)
               .values(job_id=-_deliveries.c.job_id))
    _unique(['subscription_id', 'job_id'])
