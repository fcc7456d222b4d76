"""Request bodies are limited on every route but the recordings upload (issue 16, finding 3; ``app/web/limits.py``).

Driven by hand at the ASGI level (a declared length with no body behind it, chunked bodies without a length)
and over a real socket under uvicorn (the 413 arrives and the connection is closed while the client is still
sending: nobody is left waiting).
"""

from __future__ import annotations

import asyncio
import json
import socket
import threading
import time

import pytest

from web_helpers import AsgiCall, clinic_token, make_settings, multipart, new_session, BOUNDARY

LIMIT_KB = 64


def _app(tmp_path):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_MAX_BODY_KB=LIMIT_KB)
    h = clinic_token(settings, "Body")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
    return create_app(settings), settings, h, sid


def _run(app, scenario):
    from concurrent.futures import ThreadPoolExecutor

    async def main():
        async with app.router.lifespan_context(app):
            return await scenario()

    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, main()).result()


def test_a_declared_length_above_the_limit_is_refused_before_a_byte_is_read(tmp_path):
    app, settings, h, _ = _app(tmp_path)
    json_h = h | {"content-type": "application/json"}

    async def scenario():
        calls = []
        for path, headers in (("/api/v1/patients", json_h), ("/api/v1/auth/login", {"content-type": "application/json"})):
            call = AsgiCall(app, "POST", path, headers, [b"{" + b" " * 1000], content_length=False)
            call.headers.append((b"content-length", str(200 * 2**20).encode()))  # 200 MB announced
            calls.append(await call.run())
        return calls

    for call in _run(app, scenario):  # anonymous or not: 413 before the 401/422 would need the body
        assert call.status == 413, call.body
        assert call._i == 0  # not one body message was taken
        body = call.json()
        assert body["code"] == "request.body_too_large" and f"{LIMIT_KB} kB" in body["detail"]
        assert set(body["message"]) == {"es", "en", "pt"} and f"{LIMIT_KB} kB" in body["message"]["es"]


def test_a_chunked_body_is_counted_and_cut_at_the_limit(tmp_path):
    app, settings, h, _ = _app(tmp_path)
    json_h = h | {"content-type": "application/json"}
    chunk = b" " * 8192
    small = json.dumps({"external_id": "CHUNKED-1", "side": "left"}).encode()

    async def scenario():
        big = await AsgiCall(app, "POST", "/api/v1/patients", json_h, [chunk] * 64, content_length=False).run()
        ok = await AsgiCall(app, "POST", "/api/v1/patients", json_h, [small[:10], small[10:]],
                            content_length=False).run()
        return big, ok

    big, ok = _run(app, scenario)
    assert big.status == 413 and big.json()["code"] == "request.body_too_large"
    assert big._i <= LIMIT_KB * 1024 // len(chunk) + 1  # read up to the limit, not the 512 kB sent
    assert ok.status == 201, ok.body  # a chunked body within the limit reaches the route whole
    assert ok.json()["external_id"] == "CHUNKED-1"


def test_the_recordings_upload_is_not_limited_by_it(tmp_path):
    """The upload route streams past the body limit (its own limits apply), chunked or with a length."""
    app, settings, h, sid = _app(tmp_path)
    up = h | {"content-type": f"multipart/form-data; boundary={BOUNDARY}"}
    data = b"time,acc_x\n" + b"0.000,1.000\n" * 20000  # 240 kB, above the 64 kB limit
    body = multipart([("a.csv", data)])
    body2 = multipart([("b.csv", data)])
    pieces = [body[i:i + 65536] for i in range(0, len(body), 65536)]

    async def scenario():
        chunked = await AsgiCall(app, "POST", f"/api/v1/sessions/{sid}/recordings", up, pieces,
                                 content_length=False).run()
        sized = await AsgiCall(app, "POST", f"/api/v1/sessions/{sid}/recordings", up, [body2]).run()
        return chunked, sized

    chunked, sized = _run(app, scenario)
    assert chunked.status == 201, chunked.body
    assert sized.status == 201, sized.body


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_over_a_real_socket_the_refusal_arrives_and_the_connection_closes(tmp_path):
    """A client announcing 200 MB and sending slowly gets the 413 and a closed connection, not a wait."""
    uvicorn = pytest.importorskip("uvicorn")
    from app.web.main import UVICORN_OPTIONS, create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_MAX_BODY_KB=LIMIT_KB)
    port = _free_port()
    srv = uvicorn.Server(uvicorn.Config(create_app(settings), host="127.0.0.1", port=port, log_level="warning",
                                        access_log=False, **UVICORN_OPTIONS))
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 120
    while not srv.started:
        assert thread.is_alive() and time.monotonic() < deadline, "the app did not start on loopback"
        time.sleep(0.05)
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
            sock.sendall(b"POST /api/v1/patients HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                         b"Content-Length: 209715200\r\n\r\n" + b" " * 4096)
            answer = b""
            while True:  # the server answers and closes; a hang would end in socket.timeout (30 s)
                got = sock.recv(65536)
                if not got:
                    break
                answer += got
        head, _, body = answer.partition(b"\r\n\r\n")
        assert head.startswith(b"HTTP/1.1 413"), head
        assert b"connection: close" in head.lower()
        assert b"server:" not in head.lower()  # finding 10e: no server banner
        assert json.loads(body)["code"] == "request.body_too_large"
    finally:
        srv.should_exit = True
        thread.join(timeout=30)


def test_the_default_limit_is_one_megabyte(tmp_path):
    """Without ``CHAKAMO_MAX_BODY_KB`` the limit is the issue's "about 1 MB": a body of 1 MiB reaches the route
    (422, not JSON), one byte more is refused unread (413)."""
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    assert settings.max_body_kb == 1024
    h = clinic_token(settings, "Default") | {"content-type": "application/json"}
    app = create_app(settings)
    mib = 2**20

    async def scenario():
        at = await AsgiCall(app, "POST", "/api/v1/patients", h, [b"{" + b" " * (mib - 1)]).run()
        over = AsgiCall(app, "POST", "/api/v1/patients", h, [b"{" + b" " * mib])
        return at, await over.run()

    at, over = _run(app, scenario)
    assert at.status == 422, at.body
    assert over.status == 413 and over._i == 0, over.body
