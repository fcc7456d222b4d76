"""Files and jobs never change under each other (409 while a job of the session is queued or running), the
stored ingestion check always belongs to the current files (a versioned check; a missing one is redone),
and patient fields the exports depend on are validated at input."""

from __future__ import annotations

import pytest

from app.web.api.schemas import ingestion_out
from web_helpers import clinic_token, new_session

F = [("files", ("a.csv", b"time,acc_x\n", "text/csv"))]


def _db(settings):
    from app.store.database import Database

    return Database(settings.db_url)


def test_uploads_deletes_and_processing_wait_for_the_running_job(client, settings):
    from app.store.models import Job, KneeSession

    h = clinic_token(settings, "Q")
    _, sid = new_session(client, h)
    rid = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=F).json()["recordings"][0]["id"]
    db = _db(settings)
    with db.session() as s:  # a job row as the API queues it (not handed to this runner: it stays queued)
        job = Job(clinic_id=s.get(KneeSession, sid).clinic_id, session_id=sid, filter="chakamo", log=[])
        s.add(job)
        s.flush()
        job_id = job.id
    try:
        for status in ("queued", "running"):
            with db.session() as s:
                s.get(Job, job_id).status = status
            other = [("files", ("b.csv", b"time,acc_x\n", "text/csv"))]
            r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=other)
            assert r.status_code == 409 and f"job {job_id}" in r.json()["detail"], r.text
            r = client.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=h)
            assert r.status_code == 409 and "being processed" in r.json()["detail"]
            r = client.post(f"/api/v1/sessions/{sid}/process", headers=h, json={})
            assert r.status_code == 409 and "being processed" in r.json()["detail"]
        assert client.get(f"/api/v1/sessions/{sid}", headers=h).json()["n_recordings"] == 1
        with db.session() as s:
            s.get(Job, job_id).status = "failed"
        assert client.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=h).status_code == 204
    finally:
        db.dispose()


def test_a_check_of_older_files_never_overwrites_a_newer_one(client, settings):
    """Delete one file and upload another (the count stays 1): a check computed for the first file, stored
    late, is refused; the session shows the check of its current file."""
    from app.store.checks import save_ingestion
    from app.store.models import KneeSession

    h = clinic_token(settings, "V")
    _, sid = new_session(client, h)
    rid = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=F).json()["recordings"][0]["id"]
    db = _db(settings)
    with db.session() as s:
        old_version = s.get(KneeSession, sid).files_version
    assert client.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=h).status_code == 204
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
                    files=[("files", ("b.csv", b"time,acc_x\n", "text/csv"))])
    assert r.status_code == 201
    stale = {"ok": True, "messages": ["from a.csv"], "error": None}
    assert save_ingestion(db, sid, old_version, stale) is False
    s = client.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert s["ingestion"] == r.json()["ingestion"] and s["ingestion"]["ok"] is False
    assert client.post(f"/api/v1/sessions/{sid}/process", headers=h, json={}).status_code == 409
    db.dispose()


def test_a_lost_check_is_redone_not_reported_as_no_recordings(client, settings, demo_dir):
    """The request that should have stored the check died: reading the session checks its files again."""
    from web_helpers import demo_files

    from app.store.models import KneeSession

    h = clinic_token(settings, "L")
    _, sid = new_session(client, h)
    assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir)).status_code == 201
    db = _db(settings)
    with db.session() as s:
        row = s.get(KneeSession, sid)
        row.ingestion, row.ingestion_version = None, None
    s = client.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert s["ingestion"]["ok"] is True and s["status"] == "ready", s["ingestion"]
    with db.session() as s2:
        assert s2.get(KneeSession, sid).ingestion_version == s2.get(KneeSession, sid).files_version
    db.dispose()


def test_processing_a_session_whose_check_was_lost_checks_it_again(client, settings):
    """POST /process on a stale check redoes it before deciding: the 409 gives the files' real problem, and
    the check is stored for the current files."""
    from app.store.models import KneeSession

    h = clinic_token(settings, "R")
    _, sid = new_session(client, h)
    up = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=F)
    assert up.status_code == 201 and up.json()["ingestion"]["ok"] is False
    db = _db(settings)
    with db.session() as s:
        row = s.get(KneeSession, sid)
        row.ingestion, row.ingestion_version = None, None
    r = client.post(f"/api/v1/sessions/{sid}/process", headers=h, json={})
    assert r.status_code == 409, r.text
    assert r.json()["detail"].endswith(up.json()["ingestion"]["error"])
    with db.session() as s:
        row = s.get(KneeSession, sid)
        # the stored check is the one answered (rendered per language by app.web.api.schemas.ingestion_out)
        assert ingestion_out(row.ingestion, row.split) == up.json()["ingestion"]
        assert row.ingestion_version == row.files_version
    db.dispose()


def test_a_second_process_request_waits_for_the_first(client, settings, demo_dir):
    from web_helpers import demo_files, wait_job

    h = clinic_token(settings, "Z")
    _, sid = new_session(client, h)
    assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir)).status_code == 201
    first = client.post(f"/api/v1/sessions/{sid}/process", headers=h, json={})
    assert first.status_code == 202
    # right after: the first job is queued or running (a job takes seconds: pipeline, PDFs, Excel, scene)
    second = client.post(f"/api/v1/sessions/{sid}/process", headers=h, json={"filter": "madgwick"})
    assert second.status_code == 409 and "being processed" in second.json()["detail"]
    job = wait_job(client, first.json()["job_id"], h)
    assert job["status"] == "done", job
    assert len(client.get(f"/api/v1/sessions/{sid}", headers=h).json()["jobs"]) == 1
    third = client.post(f"/api/v1/sessions/{sid}/process", headers=h, json={"filter": "madgwick"})
    assert third.status_code == 202  # once it has finished, processing again is fine
    assert wait_job(client, third.json()["job_id"], h)["status"] == "done"


@pytest.mark.parametrize("sex, code", [("female", 201), ("unknown", 201), ("M", 422), ("mujer", 422)])
def test_sex_is_one_of_the_fhir_genders(client, settings, sex, code):
    h = clinic_token(settings, "S")
    r = client.post("/api/v1/patients", json={"external_id": f"S-{sex}", "side": "left", "sex": sex}, headers=h)
    assert r.status_code == code, r.text
    if code == 422:
        assert "sex" in r.json()["detail"]
