"""A deeply nested or huge ``session.json`` (issue 16, finding 5): refused at upload, and one stored before the
caps existed is an ingestion error of its session (GET and process answer, not 500) instead of breaking it."""

from __future__ import annotations

import json

from web_helpers import clinic_token, make_settings, new_session

DEEP = ("[" * 100_000 + "]" * 100_000).encode()  # json.loads raises RecursionError on it
CSV = b"time,acc_x\n0,1\n"


def _codes(r):
    body = r.json()
    return r.status_code, body.get("code"), set(body.get("message", {}))


def test_a_deep_or_huge_manifest_is_refused_at_upload(client, settings):
    from app.pipeline.ingestion.session import MAX_MANIFEST_DEPTH, MAX_MANIFEST_KB

    h = clinic_token(settings, "Deep")
    _, sid = new_session(client, h)
    url = f"/api/v1/sessions/{sid}/recordings"
    r = client.post(url, headers=h, files=[("files", ("session.json", DEEP, "application/json"))])
    assert _codes(r) == (400, "manifest.too_deep", {"es", "en", "pt"}), r.text
    nested = json.dumps({"side": "right", "observations": "x",
                         "recordings": [{"files": ["a.csv"], "segment": "thigh", "role": "task"}]})
    deeper = '{"side": "right", "x": ' + "[" * MAX_MANIFEST_DEPTH + "]" * MAX_MANIFEST_DEPTH + "}"
    r = client.post(url, headers=h, files=[("files", ("session.json", deeper.encode(), "application/json"))])
    assert r.status_code == 400 and r.json()["code"] == "manifest.too_deep"
    huge = json.dumps({"side": "right", "observations": "x" * (MAX_MANIFEST_KB * 1024)}).encode()
    r = client.post(url, headers=h, files=[("files", ("session.json", huge, "application/json"))])
    assert _codes(r) == (413, "manifest.too_large", {"es", "en", "pt"}), r.text
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).json()["n_recordings"] == 0  # nothing stored
    r = client.post(url, headers=h, files=[("files", ("a.csv", CSV, "text/csv")),
                                           ("files", ("session.json", nested.encode(), "application/json"))])
    assert r.status_code == 201, r.text  # a real manifest (4 deep) is taken


def test_a_deep_manifest_stored_before_the_caps_is_an_ingestion_error(tmp_path):
    """Stored straight through the data layer (as an upload before this fix did): reading and processing its
    session answer the ingestion's sentence, every time, and the helper process is not restarted for it."""
    import os

    from fastapi.testclient import TestClient

    from app.store import recordings
    from app.store.models import KneeSession
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_RENDER_PROCESSES=1, CHAKAMO_CHECK_PROCESSES=1)
    h = clinic_token(settings, "Old")
    with TestClient(create_app(settings)) as client:
        pool = client.app.state.check_pool
        assert pool.wait_warm(120)
        pid = pool.run(os.getpid)
        _, sid = new_session(client, h)
        files = []
        for name, data in (("a.csv", CSV), ("session.json", DEEP)):
            w = client.app.state.store.writer()
            w.write(data)
            files.append((name, w))
        with client.app.state.db.session() as db:
            clinic = db.get(KneeSession, sid).clinic_id
            recordings.store_upload(db, clinic, sid, files, segment=None, role=None, max_files=40)
        for _ in range(2):  # before the fix: 500 each time, and each one restarted the helper
            r = client.get(f"/api/v1/sessions/{sid}", headers=h)
            assert r.status_code == 200, r.text
            assert "nested more than" in r.json()["ingestion"]["error"]
        r = client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=h)
        assert 400 <= r.status_code < 500 and "nested more than" in r.json()["detail"], r.text
        assert pool.run(os.getpid) == pid  # the same helper process: no restart for an error
