"""Uploads: limits (size, count, type) with clear errors, duplicates, segment/role form fields, deletion,
and processing refused (409) while the ingestion check fails."""

from __future__ import annotations

import pytest

from web_helpers import clinic_token, demo_files, make_settings, new_session


@pytest.fixture
def small(tmp_path):
    """An app with tiny limits: 0.01 MB per file, 3 files."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_MAX_FILE_MB=0.01, CHAKAMO_MAX_FILES=3)
    h = clinic_token(settings, "S")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
        yield c, h, sid, settings


def _stored_blobs(settings) -> list:
    return [p for p in settings.blob_dir.rglob("*") if p.is_file()]


def test_file_too_large(small):
    c, h, sid, settings = small
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
               files=[("files", ("ok.csv", b"a" * 100, "text/csv")), ("files", ("big.csv", b"x" * 20_000, "text/csv"))])
    assert r.status_code == 413 and "big.csv" in r.json()["detail"] and "0.01 MB" in r.json()["detail"]
    assert _stored_blobs(settings) == []  # nothing kept, not even the file that fitted
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).json()["n_recordings"] == 0


def test_body_too_large_is_refused_before_reading(small):
    c, h, sid, _ = small
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
               files=[("files", ("huge.csv", b"x" * 400_000, "text/csv"))])
    assert r.status_code == 413 and "larger than 3 files of 0.01 MB" in r.json()["detail"]


def test_too_many_files(small):
    c, h, sid, _ = small
    files = [("files", (f"f{i}.csv", b"a", "text/csv")) for i in range(4)]
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files)
    assert r.status_code == 413 and "at most 3" in r.json()["detail"]
    ok = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files[:2])
    assert ok.status_code == 201
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files[2:])
    assert r.status_code == 413 and "2 already stored" in r.json()["detail"]


@pytest.mark.parametrize("name", ["notes.txt", "run.exe", "data.json", "noextension"])
def test_wrong_type(small, name):
    c, h, sid, _ = small
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=[("files", (name, b"a", "text/plain"))])
    assert r.status_code == 415 and name in r.json()["detail"]


def test_not_multipart_and_empty(small):
    c, h, sid, _ = small
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, json={"files": []})
    assert r.status_code == 415 and "multipart" in r.json()["detail"]
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, data={"segment": "thigh"},
               files=[("other", ("a.csv", b"a", "text/csv"))])
    assert r.status_code == 400 and "'files'" in r.json()["detail"]
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, data={"segment": "knee"},
               files=[("files", ("a.csv", b"a", "text/csv"))])
    assert r.status_code == 400 and "segment" in r.json()["detail"]


def test_duplicate_name_then_delete_and_replace(small):
    c, h, sid, _ = small
    f = [("files", ("a.csv", b"time,acc_x\n", "text/csv"))]
    first = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=f)
    assert first.status_code == 201
    ing = first.json()["ingestion"]
    assert ing["ok"] is False and ing["error"]
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=f)
    assert r.status_code == 409 and "delete" in r.json()["detail"]
    r = c.post(f"/api/v1/sessions/{sid}/process", headers=h, json={})
    assert r.status_code == 409
    rid = first.json()["recordings"][0]["id"]
    assert c.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=h).status_code == 204
    assert c.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=h).status_code == 404
    s = c.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert s["status"] == "empty" and s["recordings"] == []
    assert c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=f).status_code == 201


def test_incomplete_session_names_what_is_missing(client, settings, demo_dir):
    h = clinic_token(settings, "I")
    _, sid = new_session(client, h)
    files = [f for f in demo_files(demo_dir) if "laydown-pierna" not in f[1][0]]
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files)
    assert r.status_code == 201
    ing = r.json()["ingestion"]
    assert ing["ok"] is False and "lying of the shank" in ing["error"]
    assert "/tmp" not in ing["error"] and "session-" not in ing["error"]
    assert client.get(f"/api/v1/sessions/{sid}", headers=h).json()["status"] == "incomplete"
    r = client.post(f"/api/v1/sessions/{sid}/process", headers=h, json={})
    assert r.status_code == 409 and "lying of the shank" in r.json()["detail"]


def test_segment_and_role_from_the_upload_form(client, settings, demo_dir):
    """Files whose names say nothing: the wizard's segment/role fields make the session readable."""
    h = clinic_token(settings, "W")
    _, sid = new_session(client, h)
    words = {"calibracion-sensor": "mag_calibration", "standing": "standing", "laydown": "lying", "step": "task"}
    segs = {"muslo": "thigh", "pierna": "shank"}
    ing = None
    for word, role in words.items():
        for seg_word, segment in segs.items():
            prefix = f"{word}-{seg_word}-"
            files = [("files", (name.replace(prefix, f"rec-{role[:3]}{segment[:2]}-"), data, ct))
                     for _, (name, data, ct) in demo_files(demo_dir) if name.startswith(prefix)]
            assert len(files) == 3
            r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files,
                            data={"segment": segment, "role": role})
            assert r.status_code == 201, r.text
            assert {x["segment"] for x in r.json()["recordings"]} == {segment}
            ing = r.json()["ingestion"]
    assert ing["ok"] is True, ing
    assert any("session.json" in m for m in ing["messages"])
