"""Signed webhooks and the server-sent event stream (issue 17, §1: integrators had to poll).

A real server (uvicorn on loopback) processes a real session; a real HTTP receiver (``http.server`` on another
loopback port) answers the first delivery 500 and the second 200.  The receiver checks the HMAC-SHA256
signature with Python's own ``hmac`` over the raw body (not with the product's code), the retry carries the same
delivery id, and the delivery trail records both attempts.  Meanwhile an ``EventSource``-like reader of
``GET /events`` (httpx streaming) sees the job reach ``done``.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from test_browser_e2e import _loopback_socket
from web_helpers import demo_files


class Receiver:
    """An HTTP endpoint recording every POST; answers ``codes`` in turn (then 200)."""

    def __init__(self, codes: list[int]) -> None:
        self.codes, self.got = list(codes), []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 — http.server's name
                body = self.rfile.read(int(self.headers["Content-Length"]))
                outer.got.append((self.headers, body))  # case-insensitive look-ups
                self.send_response(outer.codes.pop(0) if outer.codes else 200)
                self.end_headers()

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/chakamo-hook"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()


@pytest.fixture
def live(tmp_path):
    uvicorn = pytest.importorskip("uvicorn")
    from web_helpers import make_settings

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_WEBHOOK_RETRY_S=0.5, CHAKAMO_WEBHOOK_ALLOWED_HOSTS="127.0.0.1")
    sock = _loopback_socket()
    srv = uvicorn.Server(uvicorn.Config(create_app(settings), log_level="warning", access_log=False))
    thread = threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    while not srv.started:
        assert thread.is_alive()
        time.sleep(0.05)
    admin_cli.create_clinic(settings, "Hospital Hooks")
    token = admin_cli.create_token(settings, clinic="Hospital Hooks", role="admin")
    try:
        yield f"http://127.0.0.1:{sock.getsockname()[1]}", {"Authorization": f"Bearer {token}"}
    finally:
        srv.should_exit = True
        thread.join(timeout=30)
        sock.close()


def _until(what, timeout_s: float = 300.0):
    end = time.monotonic() + timeout_s
    while not (value := what()):
        assert time.monotonic() < end, "timed out"
        time.sleep(0.2)
    return value


def test_a_finished_job_is_pushed_signed_and_retried_and_streamed(live, demo_dir):
    import httpx

    base, h = live
    receiver = Receiver([500])
    api = httpx.Client(base_url=base + "/api/v1", headers=h, timeout=120)
    r = api.post("/webhooks", json={"url": receiver.url, "events": ["job.done", "job.failed"], "label": "RIS"})
    assert r.status_code == 201, r.text
    hook = r.json()
    secret = hook["secret"]
    assert secret and r.headers["location"] == f"/api/v1/webhooks/{hook['id']}"
    assert api.get("/webhooks").json()[0]["secret"] is None  # shown once
    again = api.post("/webhooks", json={"url": receiver.url, "events": ["job.done", "job.failed"], "label": "RIS"},
                     headers={"Idempotency-Key": "hook-1"})
    repeat = api.post("/webhooks", json={"url": receiver.url, "events": ["job.done", "job.failed"], "label": "RIS"},
                      headers={"Idempotency-Key": "hook-1"})
    assert again.status_code == repeat.status_code == 201 and repeat.json() == again.json() | {"secret": None}
    assert repeat.headers["idempotent-replayed"] == "true"
    assert api.delete(f"/webhooks/{again.json()['id']}").status_code == 204
    assert len(api.get("/webhooks").json()) == 1
    assert api.post("/webhooks", json={"url": "ftp://x"}).status_code == 400

    pid = api.post("/patients", json={"external_id": "WH-1", "side": "right"}).json()["id"]
    sid = api.post(f"/patients/{pid}/sessions", json={"step_height_m": 0.17}).json()["id"]
    assert api.post(f"/sessions/{sid}/recordings", files=demo_files(demo_dir)).status_code == 201

    seen: list[dict] = []

    def listen():
        with httpx.stream("GET", base + "/api/v1/events", headers=h, timeout=300) as resp:
            assert resp.headers["content-type"].startswith("text/event-stream")
            event = None
            for line in resp.iter_lines():
                if line.startswith("event: "):
                    event = line[7:]
                elif line.startswith("data: ") and event == "job":
                    seen.append(json.loads(line[6:]))
                    if seen[-1]["status"] in ("done", "failed"):
                        return

    listener = threading.Thread(target=listen, daemon=True)
    listener.start()
    time.sleep(1.5)  # the stream is open before the job starts
    job_id = api.post(f"/sessions/{sid}/process", json={"filter": "chakamo"}).json()["job_id"]

    _until(lambda: len(receiver.got) >= 2)
    (h1, b1), (h2, b2) = receiver.got[:2]
    assert b1 == b2 and h1["X-ChakaMo-Delivery"] == h2["X-ChakaMo-Delivery"]  # the same delivery, retried
    for headers, body in receiver.got[:2]:
        parts = dict(p.split("=", 1) for p in headers["X-ChakaMo-Signature"].split(","))
        expected = hmac.new(secret.encode(), parts["t"].encode() + b"." + body, hashlib.sha256).hexdigest()
        assert hmac.compare_digest(parts["v1"], expected)
        assert abs(time.time() - int(parts["t"])) < 600
        assert headers["X-ChakaMo-Event"] == "job.done"
    payload = json.loads(b2)
    assert payload["event"] == "job.done" and payload["job"]["id"] == job_id
    assert payload["job"]["session_id"] == sid and payload["links"]["results"] == f"/api/v1/sessions/{sid}/results"
    assert "WH-1" not in b2.decode()  # ids and links only, no patient data
    assert api.get(f"/jobs/{job_id}").json()["status"] == "done"

    trail = _until(lambda: [d for d in api.get(f"/webhooks/{hook['id']}/deliveries").json()
                            if d["state"] == "delivered"])
    assert trail[0]["attempts"] == 2 and trail[0]["last_status"] == 200 and trail[0]["job_id"] == job_id

    listener.join(timeout=120)
    assert seen and seen[-1] == {**seen[-1], "id": job_id, "status": "done"}
    assert {s["status"] for s in seen} >= {"done"} and len(seen) >= 2  # it was seen changing, not only ended

    assert api.delete(f"/webhooks/{hook['id']}").status_code == 204
    assert api.get("/webhooks").json() == []
