"""Correction and erasure through the API (issue 16 finding 8, issue 17): PATCH and DELETE of patients and
sessions, with roles, tenant isolation, CSRF, If-Match and audit; deleting a recording supersedes the reports;
a stored file goes from disk when its last reference goes and stays while another recording has the same bytes.

The truth the tests check against: the blob store's files on disk (named by the sha256 of the uploaded demo
files, computed here with hashlib), the database rows, and the audit log read through its own route."""

from __future__ import annotations

import hashlib

import pytest

from web_helpers import clinic_token, demo_files, make_settings, wait_job

ADMIN_EMAIL, ADMIN_PASSWORD = "erase-admin@a.test", "a long enough password"


@pytest.fixture(scope="module")
def world(tmp_path_factory, demo_dir):
    """Clinic A (clinician and admin tokens, an admin user) with one processed session; clinic B's admin."""
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path_factory.mktemp("erasure") / "data")
    a = clinic_token(settings, "Erase A")
    a_admin = clinic_token(settings, "Erase A", role="admin")
    b_admin = clinic_token(settings, "Erase B", role="admin")
    admin_cli.create_user(settings, clinic="Erase A", email=ADMIN_EMAIL, role="admin", password=ADMIN_PASSWORD)
    with TestClient(create_app(settings)) as c:
        pid = c.post("/api/v1/patients", json={"external_id": "ER-1", "side": "right"}, headers=a).json()["id"]
        sid = c.post(f"/api/v1/patients/{pid}/sessions", json={"step_height_m": 0.17}, headers=a).json()["id"]
        assert c.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=a).status_code == 201
        job = wait_job(c, c.post(f"/api/v1/sessions/{sid}/process", json={}, headers=a).json()["job_id"], a)
        assert job["status"] == "done", job
        yield {"c": c, "a": a, "a_admin": a_admin, "b_admin": b_admin, "pid": pid, "sid": sid,
               "settings": settings, "demo_dir": demo_dir, "store": c.app.state.store}


def _on_disk(w, data: bytes) -> bool:
    return w["store"].path(hashlib.sha256(data).hexdigest()).is_file()


def _erasures(w) -> list:
    from sqlalchemy import select

    from app.store.models import BlobErasure

    with w["c"].app.state.db.session() as s:
        return [(e.sha256, e.state, e.reason, e.audit_event_id, e.actor) for e in
                s.scalars(select(BlobErasure).order_by(BlobErasure.id))]


def _new_session(w, external_id: str, files) -> tuple[int, int]:
    c, a = w["c"], w["a"]
    pid = c.post("/api/v1/patients", json={"external_id": external_id, "side": "left"}, headers=a).json()["id"]
    sid = c.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=a).json()["id"]
    r = c.post(f"/api/v1/sessions/{sid}/recordings", files=files, headers=a)
    assert r.status_code == 201, r.text
    return pid, sid


def test_a_deleted_recording_leaves_the_disk_but_a_copy_in_another_session_keeps_it(world):
    """The same bytes uploaded to two sessions are one stored file: it survives the first deletion and goes
    with the second, each leaving a record with the hash (never the content)."""
    c, a = world["c"], world["a"]
    data = b"acc_x (g),acc_y (g),acc_z (g)\n" + b"0.1,0.2,0.98\n" * 50 + b"# erasure test\n"
    files = [("files", ("thigh_task_generic.csv", data, "text/csv"))]
    _, s1 = _new_session(world, "ER-SHARE-1", files)
    _, s2 = _new_session(world, "ER-SHARE-2", files)
    r1 = c.get(f"/api/v1/sessions/{s1}", headers=a).json()["recordings"][0]["id"]
    r2 = c.get(f"/api/v1/sessions/{s2}", headers=a).json()["recordings"][0]["id"]
    sha = hashlib.sha256(data).hexdigest()
    assert _on_disk(world, data)
    assert c.delete(f"/api/v1/sessions/{s1}/recordings/{r1}", headers=a).status_code == 204
    assert _on_disk(world, data)  # still named by session 2's recording
    assert [e[:3] for e in _erasures(world) if e[0] == sha] == [(sha, "kept", "recording")]
    assert c.delete(f"/api/v1/sessions/{s2}/recordings/{r2}", headers=a).status_code == 204
    assert not _on_disk(world, data)
    assert [e[:3] for e in _erasures(world) if e[0] == sha] == [(sha, "kept", "recording"), (sha, "erased", "recording")]
    # the record names the request's audit event, which outlives the recording
    event_id = [e for e in _erasures(world) if e[0] == sha][-1][3]
    events = {e["id"]: e for e in c.get("/api/v1/audit", params={"limit": 1000}, headers=world["a_admin"]).json()}
    assert events[event_id]["action"] == "delete" and events[event_id]["session_id"] == s2


def test_deleting_a_recording_of_a_processed_session_supersedes_its_reports(world, demo_dir):
    c, a = world["c"], world["a"]
    pid, sid = _new_session(world, "ER-SUP", demo_files(demo_dir))
    job = wait_job(c, c.post(f"/api/v1/sessions/{sid}/process", json={}, headers=a).json()["job_id"], a)
    assert job["status"] == "done", job
    r = c.get(f"/api/v1/sessions/{sid}/results", headers=a)
    assert r.status_code == 200 and r.headers["X-Analysis-Status"] == "current"
    session = c.get(f"/api/v1/sessions/{sid}", headers=a).json()
    assert session["status"] == "done"
    rid = session["recordings"][0]["id"]
    assert c.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=a).status_code == 204
    session = c.get(f"/api/v1/sessions/{sid}", headers=a).json()
    assert session["status"] == "superseded" and session["analyses"][0]["superseded_at"]
    for path in ("results", "report.pdf", "angles.xlsx", "report.html"):
        r = c.get(f"/api/v1/sessions/{sid}/{path}", headers=a)
        assert r.status_code == 409 and "process the session again" in r.json()["detail"], (path, r.text)
    aid = session["analyses"][0]["id"]
    r = c.get(f"/api/v1/sessions/{sid}/report.pdf", params={"analysis_id": aid}, headers=a)
    assert r.status_code == 200 and r.headers["X-Analysis-Status"] == "superseded"
    assert "-superseded.pdf" in r.headers["content-disposition"]
    assert c.get(f"/api/v1/fhir/DiagnosticReport/{sid}", headers=a).status_code == 409
    r = c.get(f"/api/v1/fhir/DiagnosticReport/{sid}", params={"analysis_id": aid}, headers=a)
    assert r.status_code == 409 and "analysis_id" not in r.json()["detail"]  # not exportable by id either
    assert c.get(f"/api/v1/patients/{pid}/trend", headers=a).json()["points"] == []  # not in the trend either


def test_patch_corrects_a_patient_with_versions_and_supersedes_on_printed_fields(world):
    c, a, pid = world["c"], world["a"], world["pid"]
    r = c.get(f"/api/v1/patients/{pid}", headers=a)
    version = r.json()["version"]
    assert r.headers["ETag"] == f'"{version}"'
    r = c.patch(f"/api/v1/patients/{pid}", json={"notes": "typo fixed"}, headers=a | {"If-Match": f'"{version}"'})
    assert r.status_code == 200 and r.json()["notes"] == "typo fixed" and r.json()["version"] == version + 1
    assert r.headers["ETag"] == f'"{version + 1}"'
    # a stale version: someone corrected it meanwhile
    r = c.patch(f"/api/v1/patients/{pid}", json={"notes": "again"}, headers=a | {"If-Match": f'"{version}"'})
    assert r.status_code == 412 and "reload" in r.json()["detail"]
    assert c.get(f"/api/v1/sessions/{world['sid']}", headers=a).json()["status"] == "done"  # notes: not printed
    # an identifier another patient has
    other = c.post("/api/v1/patients", json={"external_id": "ER-TAKEN", "side": "right"}, headers=a).json()["id"]
    assert c.patch(f"/api/v1/patients/{pid}", json={"external_id": "ER-TAKEN"}, headers=a).status_code == 409
    assert c.patch(f"/api/v1/patients/{pid}", json={"side": None}, headers=a).status_code == 400
    assert c.patch(f"/api/v1/patients/{pid}", json={"colour": "x"}, headers=a).status_code == 422
    # another clinic's admin: 404, as for an unknown id
    assert c.patch(f"/api/v1/patients/{pid}", json={"notes": "x"}, headers=world["b_admin"]).status_code == 404
    assert c.patch(f"/api/v1/patients/{other}", json={"name": "Ana Pérez"}, headers=a).status_code == 200
    events = c.get("/api/v1/audit", params={"action": "update", "limit": 10}, headers=world["a_admin"]).json()
    assert [e["patient_id"] for e in events][:2] == [other, pid]


def test_patch_session_supersedes_and_redoes_the_check(world, demo_dir):
    c, a = world["c"], world["a"]
    _, sid = _new_session(world, "ER-SPATCH", demo_files(demo_dir))
    assert wait_job(c, c.post(f"/api/v1/sessions/{sid}/process", json={}, headers=a).json()["job_id"],
                    a)["status"] == "done"
    r = c.patch(f"/api/v1/sessions/{sid}", json={"step_height_m": 0.34}, headers=a)
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["step_height_m"] == 0.34 and body["status"] == "superseded" and body["version"] == 2
    assert c.get(f"/api/v1/sessions/{sid}/results", headers=a).status_code == 409
    assert c.patch(f"/api/v1/sessions/{sid}", json={"date": None}, headers=a).status_code == 400
    assert c.patch(f"/api/v1/sessions/{sid}", json={"notes": "x"}, headers=world["b_admin"]).status_code == 404


def test_erasing_a_session_needs_admin_and_if_match_and_removes_every_file(world, demo_dir):
    c, a, adm = world["c"], world["a"], world["a_admin"]
    pid, sid = _new_session(world, "ER-DEL", [("files", ("unique_thigh_task.csv",
                                                         b"acc_x (g),acc_y (g),acc_z (g)\n1,2,3\n# del\n",
                                                         "text/csv"))])
    data = b"acc_x (g),acc_y (g),acc_z (g)\n1,2,3\n# del\n"
    assert c.delete(f"/api/v1/sessions/{sid}", headers=a | {"If-Match": "*"}).status_code == 403  # clinician
    assert c.delete(f"/api/v1/sessions/{sid}", headers=world["b_admin"] | {"If-Match": "*"}).status_code == 404
    r = c.delete(f"/api/v1/sessions/{sid}", headers=adm)
    assert r.status_code == 428 and "If-Match" in r.json()["detail"]
    for lang, words in (("es", "Esta eliminación borra el registro"), ("pt", "Esta exclusão apaga o registo")):
        r = c.delete(f"/api/v1/sessions/{sid}", headers=adm | {"Accept-Language": lang})
        assert r.status_code == 428 and r.json()["code"] == "request.if_match_required"
        assert r.json()["detail"].startswith(words) and r.json()["message"][lang] == r.json()["detail"]
    for lang, words in (("es", "If-Match 'v7' no es una versión"), ("pt", "If-Match 'v7' não é uma versão")):
        r = c.delete(f"/api/v1/sessions/{sid}", headers=adm | {"If-Match": "v7", "Accept-Language": lang})
        assert r.status_code == 400 and r.json()["code"] == "request.if_match_unreadable"
        assert r.json()["detail"].startswith(words) and r.json()["params"] == {"value": "v7"}
    assert c.delete(f"/api/v1/sessions/{sid}", headers=adm | {"If-Match": '"7"'}).status_code == 412
    assert _on_disk(world, data)
    version = c.get(f"/api/v1/sessions/{sid}", headers=adm).headers["ETag"]
    assert c.delete(f"/api/v1/sessions/{sid}", headers=adm | {"If-Match": version}).status_code == 204
    assert not _on_disk(world, data)
    assert c.get(f"/api/v1/sessions/{sid}", headers=adm).status_code == 404
    events = c.get("/api/v1/audit", params={"action": "delete", "limit": 5}, headers=adm).json()
    assert (events[0]["patient_id"], events[0]["session_id"], events[0]["resource"]) == \
        (pid, sid, f"DELETE /api/v1/sessions/{sid}")


def test_erasing_a_patient_cascades_to_reports_and_files(world, demo_dir):
    """The processed session's recordings and every artefact: their stored files go unless another row names them."""
    c, a, adm = world["c"], world["a"], world["a_admin"]
    from sqlalchemy import select

    from app.store.models import Analysis, Artefact

    extra = b"acc_x (g),acc_y (g),acc_z (g)\n0,0,1\n# patient erasure\n"
    pid, sid = _new_session(world, "ER-PAT", [("files", ("thigh_task_x.csv", extra, "text/csv"))])
    with c.app.state.db.session() as s:
        before = set(s.scalars(select(Artefact.sha256)))
    proc_sid = world["sid"]
    # the module's processed session belongs to another patient; this one has a file and no analysis
    assert c.delete(f"/api/v1/patients/{pid}", headers=a | {"If-Match": "*"}).status_code == 403
    assert c.delete(f"/api/v1/patients/{pid}", headers=world["b_admin"] | {"If-Match": "*"}).status_code == 404
    assert c.delete(f"/api/v1/patients/{pid}", headers=adm).status_code == 428
    assert c.delete(f"/api/v1/patients/{pid}", headers=adm | {"If-Match": "*"}).status_code == 204
    assert not _on_disk(world, extra)
    assert c.get(f"/api/v1/patients/{pid}", headers=adm).status_code == 404
    # now the processed patient: its artefacts' files go too
    with c.app.state.db.session() as s:
        arts = set(s.scalars(select(Artefact.sha256).join(Analysis).where(Analysis.session_id == proc_sid)))
    assert arts and arts <= before and all(world["store"].path(h).is_file() for h in arts)
    # three of its recordings also stored by a session of this test's own (not another test's: under xdist the
    # module's tests may run in another worker, in any order)
    kept = sorted(demo_dir.glob("*.csv"))[:3]
    _new_session(world, "ER-KEEP", [("files", (f.name, f.read_bytes(), "text/csv")) for f in kept])
    assert c.delete(f"/api/v1/patients/{world['pid']}", headers=adm | {"If-Match": "*"}).status_code == 204
    # a file stays exactly when another session's row still names it (the same demo files processed there give
    # some byte-identical artefacts, e.g. the time series)
    with c.app.state.db.session() as s:
        still = {h for h in arts if s.scalar(select(Artefact.id).where(Artefact.sha256 == h).limit(1))}
    assert len(still) < len(arts)
    assert {h for h in arts if world["store"].path(h).is_file()} == still
    for f in kept:  # still stored by the ER-KEEP session
        assert _on_disk(world, f.read_bytes())


def test_cookie_callers_need_the_csrf_header_to_correct_or_erase(world):
    c = world["c"]
    from fastapi.testclient import TestClient

    browser = TestClient(c.app)  # the app is running (no second lifespan): a client with its own cookie jar
    r = browser.post("/api/v1/auth/login", json={"email": ADMIN_EMAIL, "password": ADMIN_PASSWORD})
    csrf = r.json()["csrf_token"]
    pid = browser.post("/api/v1/patients", json={"external_id": "ER-CSRF", "side": "right"},
                       headers={"X-CSRF-Token": csrf}).json()["id"]
    assert browser.patch(f"/api/v1/patients/{pid}", json={"name": "X"}).status_code == 403
    assert browser.delete(f"/api/v1/patients/{pid}", headers={"If-Match": "*"}).status_code == 403
    assert browser.patch(f"/api/v1/patients/{pid}", json={"name": "X"},
                         headers={"X-CSRF-Token": csrf}).status_code == 200
    assert browser.delete(f"/api/v1/patients/{pid}", headers={"If-Match": "*", "X-CSRF-Token": csrf}
                          ).status_code == 204


def test_openapi_declares_the_new_routes_with_their_errors(world):
    doc = world["c"].get("/openapi.json").json()
    for path, method, codes in (("/api/v1/patients/{patient_id}", "patch", {"401", "403", "404", "412"}),
                                ("/api/v1/patients/{patient_id}", "delete", {"401", "403", "404", "412", "428"}),
                                ("/api/v1/sessions/{session_id}", "patch", {"401", "403", "404", "409", "412"}),
                                ("/api/v1/sessions/{session_id}", "delete", {"401", "403", "404", "409", "428"})):
        assert codes <= set(doc["paths"][path][method]["responses"]), (path, method)


def test_settings_default_leave_retention_off(tmp_path):
    assert make_settings(tmp_path).retention_days == 0
