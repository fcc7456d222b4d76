"""Webhook deliveries are sent once across servers and one dead receiver holds up no one else (review of issue
17's webhooks: a round used to claim 20 deliveries under one 60 s lease and send them 10 s each, so the lease ran
out and another server sent them again, and the late attempt was recorded over the other server's).

A real database (SQLite and PostgreSQL) migrated by the product; real receivers on loopback (``http.server``) and a real closed
port.
"""

from __future__ import annotations

import datetime as dt
import socket
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from app.store import webhooks
from app.store.database import Database
from app.store.models import Clinic, WebhookDelivery, utcnow
from app.store.sealed import seal
from app.web.webhooks import WebhookSender


@pytest.fixture
def db(tmp_path, database_url):
    database = Database(database_url or f"sqlite:///{tmp_path / 'hooks.db'}")
    database.migrate()
    yield database
    database.dispose()


def _subscription(db, url: str, deliveries: int) -> int:
    with db.session() as s:
        clinic = Clinic(name=f"Clinic {url}")
        s.add(clinic)
        s.flush()
        sub = webhooks.add_subscription(s, clinic.id, url=url, events=["job.done"],
                                        secret=seal(b"k" * 32, "k" * 40))  # stored sealed, as the API does
        for job_id in range(deliveries):
            s.add(WebhookDelivery(subscription_id=sub.id, clinic_id=clinic.id, job_id=job_id, event="job.done",
                                  payload={"event": "job.done"}, state="pending", attempts=0,
                                  next_attempt_at=utcnow() - dt.timedelta(seconds=1), last_error=""))
        s.commit()
        return sub.id


def test_an_attempt_whose_lease_ran_out_is_not_recorded_over_the_new_owner(db):
    _subscription(db, "https://hooks.example.org/x", 1)
    with db.session() as s:
        first = webhooks.claim_due(s)
        assert first is not None and webhooks.claim_due(s) is None  # leased: no one else takes it
    later = utcnow() + dt.timedelta(seconds=webhooks.LEASE_S + 1)
    with db.session() as s:  # the first server is slow: its lease ran out and another server claims it
        second = webhooks.claim_due(s, now=later)
        assert second is not None and second.id == first.id
    with db.session() as s:
        assert webhooks.record_attempt(s, first, status=None, error="could not connect", base_s=10) == "lost"
    with db.session() as s:
        assert webhooks.record_attempt(s, second, status=200, error="", base_s=10, now=later) == "delivered"
        row = s.get(WebhookDelivery, first.id)
        assert (row.attempts, row.state, row.last_status) == (1, "delivered", 200)


def test_a_dead_receiver_gets_one_attempt_a_round_and_holds_no_one_up(db):
    got = []

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self):  # noqa: N802 — http.server's name
            got.append(self.rfile.read(int(self.headers["Content-Length"])))
            self.send_response(200)
            self.end_headers()

        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    with socket.socket() as closed:
        closed.bind(("127.0.0.1", 0))
        dead_port = closed.getsockname()[1]
    try:
        dead = _subscription(db, f"http://127.0.0.1:{dead_port}/dead", 5)
        live = _subscription(db, f"http://127.0.0.1:{server.server_address[1]}/live", 2)
        sender = WebhookSender(db, 10.0, ("127.0.0.1",), b"k" * 32)
        assert sender.run_once() == 3  # the dead one's first failure ends its round
        with db.session() as s:
            rows = s.query(WebhookDelivery).all()
            dead_tries = sum(r.attempts for r in rows if r.subscription_id == dead)
            live_done = sum(r.state == "delivered" for r in rows if r.subscription_id == live)
        assert dead_tries == 1 and live_done == 2 and len(got) == 2
    finally:
        server.shutdown()
