"""Webhooks reach only the hosts the operator allows (no server-side request forgery), and a clinic's delivery
trail never tells why a connection failed (review of issue 17's webhooks).

Real sockets on loopback: a listening receiver (``http.server``) and a closed port; the host checks resolve
real names (``localhost``).
"""

from __future__ import annotations

import datetime as dt
import socket
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from web_helpers import make_settings

from app.store import webhooks
from app.store.sealed import PREFIX, seal, unseal
from app.web.outbound import AddressRefused, resolve
from app.web.webhooks import HTTP_STATUS, NO_CONNECTION, SECRET_UNREADABLE, send


def _client(tmp_path, allowed: str):
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_WEBHOOK_ALLOWED_HOSTS=allowed)
    client = TestClient(create_app(settings))
    client.__enter__()
    admin_cli.create_clinic(settings, "Hospital Safe")
    token = admin_cli.create_token(settings, clinic="Hospital Safe", role="admin")
    client.headers["Authorization"] = f"Bearer {token}"
    return client


@pytest.mark.parametrize(("allowed", "url"), [
    ("", "https://hooks.example.org/x"),  # no setting: no webhooks at all
    ("hooks.example.org", "http://127.0.0.1:6379/"),
    ("hooks.example.org", "http://169.254.169.254/latest/meta-data/"),
    ("*.example.org", "https://intranet.example.com/"),
])
def test_a_host_the_operator_did_not_allow_is_refused_in_three_languages(tmp_path, allowed, url):
    client = _client(tmp_path, allowed)
    try:
        r = client.post("/api/v1/webhooks", json={"url": url})
        assert r.status_code == 400, r.text
        body = r.json()
        assert body["code"] == "webhook.url_refused" and set(body["message"]) == {"es", "en", "pt"}
        assert "CHAKAMO_WEBHOOK_ALLOWED_HOSTS" in body["message"]["pt"]
        assert client.get("/api/v1/webhooks").json() == []
        bad = client.post("/api/v1/webhooks", json={"url": "ftp://x"}).json()
        assert bad["code"] == "webhook.url_invalid" and set(bad["message"]) == {"es", "en", "pt"}
    finally:
        client.__exit__(None, None, None)


def test_internal_addresses_are_refused_at_send_time_unless_named_exactly():
    for host in ("localhost", "127.0.0.1", "169.254.169.254", "10.1.2.3", "192.168.0.1", "224.0.0.1", "::1",
                 "0.0.0.0"):
        with pytest.raises(AddressRefused):
            resolve(host, 80, ("*",))  # a wildcard never opens an internal address
    with pytest.raises(AddressRefused):
        resolve("127.0.0.1", 80, ("*.example.org",))
    assert resolve("127.0.0.1", 80, ("127.0.0.1",)) == ("127.0.0.1",)  # the operator named it
    assert set(resolve("localhost", 80, ("localhost",))) <= {"127.0.0.1", "::1"}


KEY = b"an operator's key of at least 32 characters"


def _due(url: str) -> webhooks.Due:
    return webhooks.Due(1, url, seal(KEY, "s" * 43), "job.done", {"event": "job.done"}, 1, dt.datetime.now(dt.timezone.utc) + dt.timedelta(seconds=webhooks.LEASE_S), 1)  # as claim_due leases it


def test_the_trail_says_could_not_connect_never_the_cause():
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert send(_due(f"http://127.0.0.1:{port}/"), ("127.0.0.1",), KEY) == (None, NO_CONNECTION)
    # refused (not allowed) looks the same as closed: no port scanning through the trail
    assert send(_due(f"http://127.0.0.1:{port}/"), ("*",), KEY) == (None, NO_CONNECTION)


def test_a_secret_sealed_under_another_key_is_a_failed_attempt_not_a_jammed_delivery():
    """After CHAKAMO_SECRET_KEY changes, the delivery is answered as a failed attempt the trail explains (it raised
    InvalidTag out of the sender's round before: never recorded, claimed again every lease; review finding)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    other = b"another operator key, also 32 characters long"
    assert send(_due(f"http://127.0.0.1:{port}/"), ("127.0.0.1",), other) == (None, SECRET_UNREADABLE)


def test_an_allowed_receiver_gets_the_post_on_the_checked_address():
    got = []

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self):  # noqa: N802 — http.server's name
            got.append((self.path, self.headers["Host"], self.rfile.read(int(self.headers["Content-Length"]))))
            self.send_response(503 if len(got) > 1 else 204)
            self.end_headers()

        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/hook?x=1"
        assert send(_due(url), ("127.0.0.1",), KEY) == (204, "")
        assert send(_due(url), ("127.0.0.1",), KEY) == (503, HTTP_STATUS)
        assert got[0][0] == "/hook?x=1" and got[0][1].startswith("127.0.0.1")
    finally:
        server.shutdown()


def test_a_webhook_secret_is_stored_sealed_and_shown_only_once(tmp_path):
    from cryptography.exceptions import InvalidTag

    from app.store.database import Database
    from app.store.models import WebhookSubscription

    client = _client(tmp_path, "hooks.example.org")
    try:
        body = {"url": "https://hooks.example.org/x", "events": ["job.done"]}
        first = client.post("/api/v1/webhooks", json=body, headers={"Idempotency-Key": "h-1"})
        replay = client.post("/api/v1/webhooks", json=body, headers={"Idempotency-Key": "h-1"})
        secret = first.json()["secret"]
        assert first.status_code == replay.status_code == 201 and len(secret) == 43
        assert replay.headers["idempotent-replayed"] == "true" and replay.json()["secret"] is None
        assert replay.json()["id"] == first.json()["id"]
        settings = client.app.state.settings
    finally:
        client.__exit__(None, None, None)
    db = Database(settings.db_url)
    try:
        with db.session() as s:
            stored = s.query(WebhookSubscription).one().secret
    finally:
        db.dispose()
    assert stored.startswith(PREFIX) and secret not in stored and len(stored) <= 100
    assert unseal(settings.key, stored) == secret
    with pytest.raises(InvalidTag):  # a copy of the database without the key opens nothing
        unseal(b"another key of at least thirty-two characters", stored)
