"""Uploads driven by hand at the ASGI level (what the test client cannot do): slow uploads hold no database
connection and are capped, the body is counted whatever the headers say (chunked, no Content-Length), only
the known form fields pass, and a client that disconnects mid-upload is handled quietly."""

from __future__ import annotations

import asyncio
import logging

import pytest

from web_helpers import BOUNDARY, AsgiCall, clinic_token, make_settings, multipart, new_session

CTYPE = f"multipart/form-data; boundary={BOUNDARY}"


def _setup(tmp_path, **extra):
    """Settings, a clinician header and an empty session (made through a first app, then closed)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", **extra)
    h = clinic_token(settings, "U")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
    return settings, h | {"content-type": CTYPE}, sid


def _run(app, scenario):
    """``scenario()`` inside the app's lifespan, on a fresh event loop in its own thread (another test, e.g.
    Playwright's sync API, may have left a loop running in this one)."""
    from concurrent.futures import ThreadPoolExecutor

    async def main():
        async with app.router.lifespan_context(app):
            return await scenario()

    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, main()).result()


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_slow_uploads_hold_no_database_connection_and_are_capped(tmp_path, backend, request):
    """Half-sent uploads: no pooled connection is held (on PostgreSQL that was an idle transaction each),
    other requests are served, and past CHAKAMO_MAX_UPLOADS an upload is refused with 503 at once."""
    from app.web.main import create_app

    db_url = {} if backend == "sqlite" else {"DATABASE_URL": request.getfixturevalue("pg_url")}
    settings, h, sid = _setup(tmp_path, CHAKAMO_MAX_UPLOADS=3, **db_url)
    app = create_app(settings)
    url = f"/api/v1/sessions/{sid}/recordings"

    async def scenario():
        slow = []
        for i in range(3):
            body = multipart([(f"a{i}.csv", b"time,acc_x\n" + b"0,1\n" * 2000)])
            slow.append(AsgiCall(app, "POST", url, h, [body[:500], body[500:]], pause_after=1))
        tasks = [asyncio.create_task(c.run()) for c in slow]
        await asyncio.wait_for(asyncio.gather(*(c.paused.wait() for c in slow)), 60)
        # three uploads are half-sent: not one database connection may be held meanwhile
        held = app.state.db.engine.pool.checkedout()
        listing = await AsgiCall(app, "GET", "/api/v1/patients", h).run()
        extra = await AsgiCall(app, "POST", url, h, [multipart([("b.csv", b"x")])]).run()
        for c in slow:
            c.resume()
        await asyncio.wait_for(asyncio.gather(*tasks), 120)
        after = await AsgiCall(app, "POST", url, h, [multipart([("c.csv", b"time,acc_x\n")])]).run()
        return held, listing, extra, slow, after

    held, listing, extra, slow, after = _run(app, scenario)
    assert held == 0
    assert listing.status == 200 and [p["external_id"] for p in listing.json()] == ["P-1"]
    assert extra.status == 503 and "try again" in extra.json()["detail"]
    assert [c.status for c in slow] == [201, 201, 201]
    assert after.status == 201  # the slots were given back


def test_a_chunked_body_without_length_is_counted(tmp_path):
    """No Content-Length: a huge epilogue after the closing boundary (ignored by the multipart parser, so
    unbounded before the fix) is cut at the ceiling."""
    from app.web.main import create_app

    settings, h, sid = _setup(tmp_path, CHAKAMO_MAX_FILE_MB=0.01, CHAKAMO_MAX_FILES=3)
    app = create_app(settings)
    url = f"/api/v1/sessions/{sid}/recordings"
    epilogue = [b"e" * 65536] * 8  # 512 kB after the last boundary; the ceiling is ~228 kB
    body = multipart([("a.csv", b"time,acc_x\n")])

    async def scenario():
        big = await AsgiCall(app, "POST", url, h, [body, *epilogue], content_length=False).run()
        ok = await AsgiCall(app, "POST", url, h, [body[:40], body[40:]], content_length=False).run()
        return big, ok

    big, ok = _run(app, scenario)
    assert big.status == 413 and "larger than 3 files of 0.01 MB" in big.json()["detail"]
    assert ok.status == 201, ok.body
    assert [p.name for p in settings.blob_dir.joinpath(".incoming").iterdir()] == []


def test_only_the_known_form_fields_are_accepted(client, settings):
    h = clinic_token(settings, "F")
    _, sid = new_session(client, h)
    url = f"/api/v1/sessions/{sid}/recordings"
    f = [("files", ("a.csv", b"time,acc_x\n", "text/csv"))]
    r = client.post(url, headers=h, data={"colour": "red"}, files=f)
    assert r.status_code == 400 and "'colour' is not accepted" in r.json()["detail"]
    r = client.post(url, headers=h, data={f"x{i}": "1" for i in range(3000)}, files=f)
    assert r.status_code == 400
    r = client.post(url, headers=h, data={"segment": "thigh", "role": "task"}, files=f)
    assert r.status_code == 201, r.text


def test_a_repeated_form_field_is_refused(tmp_path):
    """Ten segment fields in one body: refused at the second (the body may hold each field once)."""
    from app.web.main import create_app

    settings, h, sid = _setup(tmp_path, CHAKAMO_MAX_FILES=3)
    app = create_app(settings)
    part = f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="segment"\r\n\r\nthigh\r\n'.encode()
    body = part * 10 + f"--{BOUNDARY}--\r\n".encode()

    async def scenario():
        return await AsgiCall(app, "POST", f"/api/v1/sessions/{sid}/recordings", h, [body]).run()

    r = _run(app, scenario)
    assert r.status == 400 and "sent twice" in r.json()["detail"]


def test_a_client_disconnecting_mid_upload_is_handled_quietly(tmp_path, caplog):
    from app.web.main import create_app

    settings, h, sid = _setup(tmp_path)
    app = create_app(settings)
    body = multipart([("a.csv", b"time,acc_x\n" + b"0,1\n" * 5000)])

    async def scenario():
        call = AsgiCall(app, "POST", f"/api/v1/sessions/{sid}/recordings", h, [body[:3000], body[3000:]],
                        pause_after=1)
        task = asyncio.create_task(call.run())
        await asyncio.wait_for(call.paused.wait(), 60)
        call.resume(disconnect=True)
        await asyncio.wait_for(task, 60)  # before the fix: ClientDisconnect escaped with a traceback
        listing = await AsgiCall(app, "GET", f"/api/v1/sessions/{sid}", h).run()
        return listing

    with caplog.at_level(logging.INFO):
        listing = _run(app, scenario)
    assert listing.json()["n_recordings"] == 0
    assert [p for p in settings.blob_dir.joinpath(".incoming").iterdir()] == []  # the partial file is gone
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert any("disconnected" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("n", [8])
def test_concurrent_creates_answer_409_not_500(client, settings, n):
    """Racing creates of one patient / one user: one 201, the rest 409 (never an IntegrityError 500)."""
    from concurrent.futures import ThreadPoolExecutor

    h = clinic_token(settings, "R")
    with ThreadPoolExecutor(n) as pool:
        codes = list(pool.map(lambda _: client.post("/api/v1/patients", json={"external_id": "SAME", "side": "left"},
                                                    headers=h).status_code, range(n)))
    assert sorted(codes) == [201] + [409] * (n - 1), codes
    admin = clinic_token(settings, "R", role="admin")
    body = {"email": "x@y.org", "name": "X", "role": "clinician", "password": "a long password"}
    with ThreadPoolExecutor(4) as pool:
        codes = list(pool.map(lambda _: client.post("/api/v1/users", json=body, headers=admin).status_code, range(4)))
    assert sorted(codes) == [201, 409, 409, 409], codes
