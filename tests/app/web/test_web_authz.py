"""Clinic isolation: clinic B cannot read, list, process, change or download anything of clinic A by any id
(always 404, the answer for an unknown id), and roles limit what a clinic's own callers may do."""

from __future__ import annotations

import pytest

from web_helpers import clinic_token, demo_files, make_settings, new_session, wait_job


@pytest.fixture(scope="module")
def world(tmp_path_factory, demo_dir):
    """Clinic A with a processed session; clinic B with a token (and a patient of its own)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path_factory.mktemp("authz") / "data")
    a = clinic_token(settings, "Clinic A")
    b = clinic_token(settings, "Clinic B")
    with TestClient(create_app(settings)) as client:
        pid, sid = new_session(client, a, "A-1")
        rec = client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=a).json()
        job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=a).json()["job_id"], a)
        assert job["status"] == "done", job
        _, bsid = new_session(client, b, "B-1")
        yield {"client": client, "a": a, "b": b, "pid": pid, "sid": sid, "jid": job["id"], "bsid": bsid,
               "aid": job["analysis_id"], "rid": rec["recordings"][0]["id"], "settings": settings}


READS = ["/api/v1/patients/{pid}", "/api/v1/patients/{pid}/sessions", "/api/v1/patients/{pid}/trend",
         "/api/v1/sessions/{sid}", "/api/v1/jobs/{jid}", "/api/v1/sessions/{sid}/results",
         "/api/v1/sessions/{sid}/results?analysis_id={aid}", "/api/v1/sessions/{sid}/report.pdf?lang=pt",
         "/api/v1/sessions/{sid}/angles.xlsx", "/api/v1/sessions/{sid}/quaternions.xlsx",
         "/api/v1/sessions/{sid}/report.html", "/api/v1/sessions/{sid}/scene.viser",
         "/api/v1/sessions/{sid}/scene.png", "/api/v1/fhir/DiagnosticReport/{sid}"]


@pytest.mark.parametrize("path", READS)
def test_other_clinic_cannot_read(world, path):
    c, url = world["client"], path.format(**world)
    assert c.get(url, headers=world["a"]).status_code == 200
    r = c.get(url, headers=world["b"])
    assert r.status_code == 404, (url, r.status_code, r.text[:200])
    assert "check the id" in r.json()["detail"]


def test_other_clinic_cannot_list(world):
    c = world["client"]
    mine = c.get("/api/v1/patients", headers=world["b"]).json()
    assert [p["external_id"] for p in mine] == ["B-1"]
    assert c.get("/api/v1/patients?q=A-1", headers=world["b"]).json() == []
    assert c.get("/api/v1/clinics/current", headers=world["b"]).json()["name"] == "Clinic B"


def test_other_clinic_cannot_write(world):
    c, b = world["client"], world["b"]
    sid, pid, rid = world["sid"], world["pid"], world["rid"]
    assert c.post(f"/api/v1/sessions/{sid}/process", json={}, headers=b).status_code == 404
    assert c.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=b).status_code == 404
    r = c.post(f"/api/v1/sessions/{sid}/recordings", files=[("files", ("x.csv", b"a,b\n", "text/csv"))], headers=b)
    assert r.status_code == 404
    assert c.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=b).status_code == 404
    # nothing changed for A
    s = c.get(f"/api/v1/sessions/{sid}", headers=world["a"]).json()
    assert s["n_recordings"] == 24 and len(s["jobs"]) == 1
    # the same external id is free in another clinic (ids are per clinic)
    assert c.post("/api/v1/patients", json={"external_id": "A-1", "side": "left"}, headers=b).status_code == 201


def test_roles(world):
    c, settings = world["client"], world["settings"]
    ro = clinic_token(settings, "Clinic A", role="read_only")
    assert c.get(f"/api/v1/sessions/{world['sid']}", headers=ro).status_code == 200
    r = c.post("/api/v1/patients", json={"external_id": "RO", "side": "left"}, headers=ro)
    assert r.status_code == 403 and "clinician" in r.json()["detail"]
    assert c.post(f"/api/v1/sessions/{world['sid']}/process", json={}, headers=ro).status_code == 403
    assert c.get("/api/v1/users", headers=world["a"]).status_code == 403  # clinician token: not admin
    admin = clinic_token(settings, "Clinic A", role="admin")
    assert c.get("/api/v1/users", headers=admin).json() == []


def test_no_or_bad_credentials(world):
    c = world["client"]
    assert c.get("/api/v1/patients").status_code == 401
    assert c.get("/api/v1/patients", headers={"Authorization": "Bearer chk_nope"}).status_code == 401
    assert c.get("/api/v1/patients", headers={"Authorization": "Basic abc"}).status_code == 401


ANALYSIS_READS = ["/api/v1/sessions/{bsid}/results?analysis_id={aid}",
                  "/api/v1/sessions/{bsid}/report.pdf?analysis_id={aid}",
                  "/api/v1/sessions/{bsid}/angles.xlsx?analysis_id={aid}",
                  "/api/v1/sessions/{bsid}/scene.viser?analysis_id={aid}",
                  "/api/v1/sessions/{bsid}/scene.png?analysis_id={aid}",
                  "/api/v1/fhir/DiagnosticReport/{bsid}?analysis_id={aid}"]


@pytest.mark.parametrize("path", ANALYSIS_READS)
def test_another_clinics_analysis_id_with_ones_own_session_id(world, path):
    """Clinic B names its own session but clinic A's analysis: 404, nothing of A's analysis comes back."""
    r = world["client"].get(path.format(**world), headers=world["b"])
    assert r.status_code == 404 and "check the id" in r.json()["detail"], r.text[:200]


def _patient_sex(world, value):
    from app.store.database import Database
    from app.store.models import Patient

    db = Database(world["settings"].db_url)
    with db.session() as s:
        s.get(Patient, world["pid"]).sex = value
    db.dispose()


def test_fhir_export_of_data_it_cannot_express_is_409_with_a_sentence(world):
    """A sex typed as free text before the API restricted it: the export says what is wrong (not a 500)."""
    c, url = world["client"], f"/api/v1/fhir/DiagnosticReport/{world['sid']}"
    _patient_sex(world, "mujer")
    try:
        r = c.get(url, headers=world["a"])
        assert r.status_code == 409 and "sex" in r.json()["detail"] and "mujer" in r.json()["detail"]
    finally:
        _patient_sex(world, None)
    assert c.get(url, headers=world["a"]).status_code == 200


def test_a_damaged_stored_file_answers_a_reference_not_a_path(world, caplog):
    import logging

    from app.store.database import Database
    from app.store.models import Artefact

    c, settings = world["client"], world["settings"]
    db = Database(settings.db_url)
    with db.session() as s:
        sha = s.query(Artefact).filter_by(analysis_id=world["aid"], name="results.json").one().sha256
    db.dispose()
    path = c.app.state.store.path(sha)
    good = path.read_bytes()
    path.write_bytes(good[:-1] + b" ")
    try:
        with caplog.at_level(logging.ERROR, logger="chakamo"):
            r = c.get(f"/api/v1/sessions/{world['sid']}/results", headers=world["a"])
    finally:
        path.write_bytes(good)
    assert r.status_code == 500
    detail = r.json()["detail"]
    assert "reference" in detail and str(settings.data_dir) not in detail and sha[:12] not in detail
    ref = detail.split("reference ")[1][:8]
    assert any(ref in rec.getMessage() and sha[:12] in rec.getMessage() for rec in caplog.records)
    assert c.get(f"/api/v1/sessions/{world['sid']}/results", headers=world["a"]).status_code == 200


def _scene_bytes(world, data: bytes | None) -> bytes:
    """Swap the stored scene.viser of clinic A's analysis for ``data`` (a blob row and file of its own, as the
    store keeps them), or with ``None`` only read it: the bytes it had."""
    from sqlalchemy import select

    from app.store.blobs import BlobStore
    from app.store.database import Database
    from app.store.models import Artefact, Blob

    db, store = Database(world["settings"].db_url), BlobStore(world["settings"].blob_dir)
    try:
        with db.session() as s:
            art = s.scalars(select(Artefact).where(Artefact.analysis_id == world["aid"],
                                                   Artefact.name == "scene.viser")).one()
            old = store.read(art.sha256)
            if data is not None:
                sha, size = store.put(data)
                if s.get(Blob, sha) is None:
                    s.add(Blob(sha256=sha, size_bytes=size))
                    s.flush()
                art.sha256, art.size_bytes = sha, size
        return old
    finally:
        db.dispose()


def test_a_scene_the_still_cannot_draw_is_refused_in_three_languages(world):
    """A stored scene.viser of another viser major version (0.x: no ``props`` on its meshes): 404
    ``store.no_still`` with the catalogue's sentence in es/en/pt, like a missing artefact, not a bare 500."""
    import msgspec.msgpack
    import zstandard

    from app.pipeline.service_messages import CATALOGUE
    from reports.scene import inner_payload

    c, url = world["client"], f"/api/v1/sessions/{world['sid']}/scene.png"
    good = _scene_bytes(world, None)
    inner, recording = inner_payload(good)
    n = int.from_bytes(inner[:8], "little")
    recording["viserVersion"] = "0.2.23"
    packed = msgspec.msgpack.encode(recording)   # the buffers' alignment is not kept: the version is read first
    body = len(packed).to_bytes(8, "little") + packed + inner[8 + n:]
    old = _scene_bytes(world, len(body).to_bytes(8, "little") + zstandard.ZstdCompressor().compress(body))
    try:
        r = c.get(url, headers=world["a"])
        assert r.status_code == 404, (r.status_code, r.text[:300])
        assert r.json()["code"] == "store.no_still"
        assert r.json()["message"] == {lang: CATALOGUE["store.no_still"][lang].format(analysis_id=world["aid"])
                                       for lang in ("es", "en", "pt")}
    finally:
        _scene_bytes(world, old)
    assert c.get(url, headers=world["a"]).status_code == 200
