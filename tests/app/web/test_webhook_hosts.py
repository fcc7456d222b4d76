"""A host pattern is never taken for a host, IPv6 literals are matched whole, and a delivery that no retry can mend
fails at once with a sentence that says so (second review of issue 17's webhooks).

Real sockets on loopback (``http.server`` receivers), a real database (SQLite and PostgreSQL) migrated by the
product, the real API (``TestClient``).
"""

from __future__ import annotations

import datetime as dt
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from test_webhook_safety import KEY, _client

from app.store import webhooks
from app.store.database import Database
from app.store.models import Clinic, WebhookDelivery, utcnow
from app.store.sealed import seal
from app.web.outbound import AddressRefused, resolve, usable
from app.web.webhooks import NO_CONNECTION, SECRET_UNREADABLE, WebhookSender, send, trail_error


class Receiver:
    """An http receiver on 127.0.0.1 that counts the POSTs it gets."""

    def __init__(self) -> None:
        self.got: list[str] = []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 — http.server's name
                outer.got.append(self.path)
                self.send_response(204)
                self.end_headers()

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.port = self.server.server_address[1]
        threading.Thread(target=self.server.serve_forever, daemon=True).start()


def _due(url: str, secret: str | None = None) -> webhooks.Due:
    return webhooks.Due(1, url, secret or seal(KEY, "s" * 43), "job.done", {"event": "job.done"}, 1,
                        dt.datetime.now(dt.timezone.utc) + dt.timedelta(seconds=webhooks.LEASE_S), 1)  # as claim_due leases it


@pytest.mark.parametrize("pattern", ["*", "*.hospital.example"])
def test_a_host_spelled_as_a_pattern_reaches_no_internal_address(pattern):
    """A host literally ``*`` (or ``*.hospital.example``) was "named exactly" by the pattern ``*``: every address
    the resolver gave for it was kept, loopback included, and a send to ``http://*:PORT`` reached 127.0.0.1."""
    with pytest.raises(AddressRefused):
        resolve(pattern, 80, (pattern,))
    with pytest.raises(AddressRefused):
        usable(pattern, (pattern,), ["127.0.0.1", "::1"])
    receiver = Receiver()
    try:
        assert send(_due(f"http://{pattern}:{receiver.port}/hook"), (pattern,), KEY) == (None, NO_CONNECTION)
        assert receiver.got == []
    finally:
        receiver.server.shutdown()


def test_a_webhook_url_whose_host_is_a_pattern_is_refused_in_three_languages(tmp_path):
    client = _client(tmp_path, "*")
    try:
        for url in ("https://*/", "https://*.hospital.example/hook"):
            r = client.post("/api/v1/webhooks", json={"url": url})
            assert r.status_code == 400, r.text
            body = r.json()
            assert body["code"] == "webhook.host_invalid" and set(body["message"]) == {"es", "en", "pt"}
            assert len(set(body["message"].values())) == 3
        assert client.get("/api/v1/webhooks").json() == []
        assert client.post("/api/v1/webhooks", json={"url": "https://hooks.example.org/x"}).status_code == 201
    finally:
        client.__exit__(None, None, None)


def test_an_ipv6_literal_the_operator_named_is_matched_whole():
    """``host_allowed`` reads a ``Host`` header, so an unbracketed ``::1`` lost its last group as a "port" and the
    operator's own ``::1`` was refused."""
    assert resolve("::1", 80, ("::1",)) == ("::1",)
    with pytest.raises(AddressRefused):
        resolve("::1", 80, ("*",))  # a wildcard still opens no internal address


@pytest.fixture
def db(tmp_path, database_url):
    database = Database(database_url or f"sqlite:///{tmp_path / 'hooks.db'}")
    database.migrate()
    yield database
    database.dispose()


def test_a_secret_no_key_opens_fails_the_delivery_at_once_and_says_it_is_not_retried(db):
    receiver = Receiver()
    try:
        with db.session() as s:
            clinic = Clinic(name="Clinic rotated key")
            s.add(clinic)
            s.flush()
            sub = webhooks.add_subscription(s, clinic.id, url=f"http://127.0.0.1:{receiver.port}/h",
                                            events=["job.done"], secret=seal(b"an old key of 32 characters or more", "k"))
            s.add(WebhookDelivery(subscription_id=sub.id, clinic_id=clinic.id, job_id=1, event="job.done",
                                  payload={"event": "job.done"}, state="pending", attempts=0,
                                  next_attempt_at=utcnow() - dt.timedelta(seconds=1), last_error=""))
            s.commit()
        sender = WebhookSender(db, retry_base_s=0.01, allowed_hosts=("127.0.0.1",), key=KEY)
        assert sender.run_once() == 1
        with db.session() as s:
            d = s.query(WebhookDelivery).one()
            assert (d.state, d.attempts, d.last_error) == ("failed", 1, SECRET_UNREADABLE)
        assert receiver.got == []
    finally:
        receiver.server.shutdown()


@pytest.mark.parametrize(("code", "status"), [(NO_CONNECTION, None), ("webhook.http_status", 503)])
def test_the_last_failed_attempt_says_it_is_not_retried(code, status):
    pending, failed = trail_error(code, status, "pending"), trail_error(code, status, "failed")
    assert failed["code"] == pending["code"] == code
    for lang, later, never in (("en", "retried later", "not retried"), ("es", "se reintentará más tarde",
                                                                         "no se reintentará"),
                               ("pt", "mais tarde", "não será tentado de novo")):
        assert later in pending["message"][lang] and never not in pending["message"][lang]
        assert never in failed["message"][lang] and later not in failed["message"][lang]


def test_an_attempt_is_not_made_when_its_lease_cannot_cover_it():
    """The POST's deadline is what is left of the lease (less the time to record the outcome): a FHIR bundle built
    slowly, or a claim held too long, must not send an attempt another sender may claim and send again."""
    from app.web.webhooks import RECORD_MARGIN_S

    receiver = Receiver()
    try:
        url = f"http://127.0.0.1:{receiver.port}/hook"
        late = webhooks.Due(1, url, seal(KEY, "s" * 43), "job.done", {"event": "job.done"}, 1,
                            utcnow() + dt.timedelta(seconds=RECORD_MARGIN_S / 2), 1)
        assert send(late, ("127.0.0.1",), KEY) == (None, NO_CONNECTION)
        assert receiver.got == []
        assert send(_due(url), ("127.0.0.1",), KEY) == (204, "") and receiver.got == ["/hook"]
    finally:
        receiver.server.shutdown()
