"""Webhook secrets stored in plain text (made before sealing existed) are sealed with AES-GCM under
``CHAKAMO_SECRET_KEY`` (:mod:`app.store.sealed`), so none remains readable from a copy of the database; the
deliveries' ``last_error`` sentences become codes (``could not connect`` → ``webhook.no_connection``, ``HTTP <n>``
→ ``webhook.http_status``, ``secret unreadable: subscribe again`` → ``webhook.secret_unreadable``: rendered in
es/en/pt by ``app.web.webhooks.trail_error``); subscriptions gain ``kind`` (``webhook``, or ``fhir`` for the FHIR
push of ``app.web.fhir_push``, at most one per clinic); patients gain ``fhir_reference`` (the hospital's own FHIR
Patient).

Sealing needs the key: :meth:`app.store.database.Database.migrate` passes it as the config attribute
``sealing_key``.  Without it and with a plain secret stored, the upgrade stops with a sentence saying so (nothing is
changed): a secret sealed under another key could never be opened again.  With a key given, when secrets are
sealed already and none of them opens under it, the key is not the server's: the upgrade stops too.  The downgrade keeps the secrets sealed
(the code of 0011 reads sealed secrets too), turns the codes back into sentences and drops the FHIR push's
subscriptions with their deliveries (their trail is lost).
Checked against the models by tests/app/store/test_db.py (SQLite) and test_web_postgres.py (PostgreSQL).

Revision ID: 0012
Revises: 0011
Create Date: 2026-12-02 07:20:00
"""
from alembic import context, op
import sqlalchemy as sa

from cryptography.exceptions import InvalidTag

from app.store.sealed import seal, sealed, unseal


revision = '0012'
down_revision = '0011'
branch_labels = None
depends_on = None

_SENTENCES = {"could not connect": "webhook.no_connection",
              "secret unreadable: subscribe again": "webhook.secret_unreadable"}


def _opens(key: bytes, stored: str) -> bool:
    """Whether ``stored`` (sealed) opens under ``key``."""
    try:
        unseal(key, stored)
    except (InvalidTag, ValueError):
        return False
    return True


def upgrade() -> None:
    bind = op.get_bind()
    subscriptions = sa.table("webhook_subscriptions", sa.column("id", sa.Integer), sa.column("secret", sa.String))
    plain = [(i, s) for i, s in bind.execute(sa.select(subscriptions.c.id, subscriptions.c.secret)) if not sealed(s)]
    key = (context.config.attributes if context.config is not None else {}).get("sealing_key")
    if plain and not key:
        raise RuntimeError(f"{len(plain)} webhook secret(s) are stored in plain text and migration 0012 seals them "
                           "under CHAKAMO_SECRET_KEY, which is not set here; set CHAKAMO_SECRET_KEY to the server's "
                           "key and run the command again (nothing was changed)")
    opened = [s for _, s in bind.execute(sa.select(subscriptions.c.id, subscriptions.c.secret)) if sealed(s)]
    if plain and opened and not any(_opens(key, s) for s in opened):
        raise RuntimeError(f"none of the {len(opened)} webhook secret(s) already sealed opens under the "
                           "CHAKAMO_SECRET_KEY given here, so it is not the server's key, and migration 0012 would "
                           f"seal {len(plain)} plain secret(s) under it for good; set CHAKAMO_SECRET_KEY to the "
                           "server's key and run the command again (nothing was changed)")
    for row_id, secret in plain:
        bind.execute(subscriptions.update().where(subscriptions.c.id == row_id).values(secret=seal(key, secret)))

    deliveries = sa.table("webhook_deliveries", sa.column("last_error", sa.String))
    for sentence, code in _SENTENCES.items():
        bind.execute(deliveries.update().where(deliveries.c.last_error == sentence).values(last_error=code))
    bind.execute(deliveries.update().where(deliveries.c.last_error.like("HTTP %"))
                 .values(last_error="webhook.http_status"))

    with op.batch_alter_table('webhook_subscriptions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('kind', sa.String(length=10), server_default='webhook', nullable=False))
    op.create_index('uq_webhook_subscriptions_fhir_clinic', 'webhook_subscriptions', ['clinic_id'], unique=True,
                    sqlite_where=sa.text("kind = 'fhir'"), postgresql_where=sa.text("kind = 'fhir'"))
    with op.batch_alter_table('patients', schema=None) as batch_op:
        batch_op.add_column(sa.Column('fhir_reference', sa.String(length=300), nullable=True))


def downgrade() -> None:
    bind = op.get_bind()
    with op.batch_alter_table('patients', schema=None) as batch_op:
        batch_op.drop_column('fhir_reference')
    bind.execute(sa.text("DELETE FROM webhook_deliveries WHERE subscription_id IN "
                         "(SELECT id FROM webhook_subscriptions WHERE kind = 'fhir')"))
    bind.execute(sa.text("DELETE FROM webhook_subscriptions WHERE kind = 'fhir'"))
    op.drop_index('uq_webhook_subscriptions_fhir_clinic', table_name='webhook_subscriptions')
    with op.batch_alter_table('webhook_subscriptions', schema=None) as batch_op:
        batch_op.drop_column('kind')
    deliveries = sa.table("webhook_deliveries", sa.column("last_error", sa.String),
                          sa.column("last_status", sa.Integer))
    for sentence, code in _SENTENCES.items():
        bind.execute(deliveries.update().where(deliveries.c.last_error == code).values(last_error=sentence))
    bind.execute(deliveries.update().where(deliveries.c.last_error == "webhook.http_status")
                 .values(last_error="HTTP " + sa.cast(deliveries.c.last_status, sa.String)))
