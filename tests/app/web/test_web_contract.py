"""DESIGN §4's hospital API minimum, exactly as written there, end to end on a real demo session.

clinics create → tokens create (the CLI functions) → POST patient → POST session → POST recordings
(MetaBase files named as the ingestion rules say) → POST process → poll the job → GET results →
GET report.pdf?lang=pt; then every artefact, and reprocessing with another filter keeps the first analysis.
"""

from __future__ import annotations

import io
import zipfile

import pytest

from web_helpers import demo_files, make_settings, wait_job


@pytest.fixture
def pooled_client(tmp_path):
    """The production-like app: the jobs computed in warm helper processes (app.jobs.compute)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_RENDER_PROCESSES=1)
    app = create_app(settings)
    with TestClient(app) as c:
        assert all(helper.wait_warm() for helper in app.state.runner.helpers)
        yield c, settings


def test_minimal_hospital_contract(pooled_client, demo_dir):
    from app.cli import admin as admin_cli

    client, settings = pooled_client
    admin_cli.create_clinic(settings, "Hospital Norte")
    token = admin_cli.create_token(settings, clinic="Hospital Norte")
    h = {"Authorization": f"Bearer {token}"}

    r = client.post("/api/v1/patients", json={"external_id": "HN-0042", "side": "right"}, headers=h)
    assert r.status_code == 201
    patient_id = r.json()["id"]
    r = client.post(f"/api/v1/patients/{patient_id}/sessions", json={"step_height_m": 0.17}, headers=h)
    assert r.status_code == 201
    session_id = r.json()["id"]

    r = client.post(f"/api/v1/sessions/{session_id}/recordings", files=demo_files(demo_dir), headers=h)
    assert r.status_code == 201, r.text
    body = r.json()
    assert len(body["recordings"]) == 24
    assert body["ingestion"]["ok"] is True and body["ingestion"]["error"] is None
    assert any(m.startswith("thigh task:") for m in body["ingestion"]["messages"])

    r = client.post(f"/api/v1/sessions/{session_id}/process", json={"filter": "chakamo"}, headers=h)
    assert r.status_code == 202
    job_id = r.json()["job_id"]
    job = wait_job(client, job_id, h)
    assert job["status"] == "done", job
    assert job["progress"] == 1.0 and job["error"] is None and job["analysis_id"] is not None
    assert any("orientation thigh" in line for line in job["log"])
    assert any("scene.viser" in line for line in job["log"])  # the helper process's progress, relayed

    r = client.get(f"/api/v1/sessions/{session_id}/results", headers=h)
    assert r.status_code == 200
    results = r.json()
    assert results["side"] == "right" and results["task"] == "step_up"
    assert results["filter"]["name"] == "chakamo"
    assert results["cycles"]["accepted"] >= 4
    assert len(results["curves"]["flexion"]["mean"]) == 101
    assert "/" not in results["session"]["folder"]  # no server path leaks

    r = client.get(f"/api/v1/sessions/{session_id}/report.pdf", params={"lang": "pt"}, headers=h)
    assert r.status_code == 200
    assert r.headers["content-type"] == "application/pdf"
    assert r.headers["content-disposition"].startswith("attachment")
    assert r.content.startswith(b"%PDF")

    # every artefact of the analysis, the three languages of the report
    pdfs = {lang: client.get(f"/api/v1/sessions/{session_id}/report.pdf?lang={lang}", headers=h).content
            for lang in ("es", "en", "pt")}
    assert len(set(pdfs.values())) == 3
    for name in ("angles.xlsx", "quaternions.xlsx"):
        r = client.get(f"/api/v1/sessions/{session_id}/{name}", headers=h)
        assert r.status_code == 200 and zipfile.is_zipfile(io.BytesIO(r.content))
    r = client.get(f"/api/v1/sessions/{session_id}/report.html", headers=h)
    assert r.status_code == 200 and "<html" in r.text.lower()
    assert r.headers["content-security-policy"].startswith("sandbox allow-scripts")
    r = client.get(f"/api/v1/sessions/{session_id}/scene.viser", headers=h)
    assert r.status_code == 200 and len(r.content) > 1000

    # the session and patient views
    s = client.get(f"/api/v1/sessions/{session_id}", headers=h).json()
    assert s["status"] == "done" and s["n_recordings"] == 24 and len(s["analyses"]) == 1
    sessions = client.get(f"/api/v1/patients/{patient_id}/sessions", headers=h).json()
    assert [x["id"] for x in sessions] == [session_id] and sessions[0]["status"] == "done"

    # reprocessing with another filter adds an analysis and keeps the first
    first = job["analysis_id"]
    job2 = wait_job(client, client.post(f"/api/v1/sessions/{session_id}/process",
                                        json={"filter": "madgwick", "lang": "en"}, headers=h).json()["job_id"], h)
    assert job2["status"] == "done", job2
    assert client.get(f"/api/v1/sessions/{session_id}/results", headers=h).json()["filter"]["name"] == "madgwick"
    old = client.get(f"/api/v1/sessions/{session_id}/results", params={"analysis_id": first}, headers=h).json()
    assert old["filter"]["name"] == "chakamo"
    r = client.get(f"/api/v1/sessions/{session_id}/report.pdf", headers=h)  # default: the job's language
    assert 'en-report.pdf' in r.headers["content-disposition"]
    trend = client.get(f"/api/v1/patients/{patient_id}/trend", headers=h).json()["points"]
    assert len(trend) == 1 and trend[0]["analysis_id"] == job2["analysis_id"] and trend[0]["filter"] == "madgwick"
    assert trend[0]["rom_deg"]["flexion"]["range"]["mean"] > 30


def test_unknown_filter_and_results_before_processing(client, settings):
    from web_helpers import clinic_token, new_session

    h = clinic_token(settings, "C")
    _, sid = new_session(client, h)
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"filter": "kalman9000"}, headers=h)
    from app.choices import FILTER_NAMES

    # the schema's enum is app.choices' filter list: 422 naming the bad value and every valid one
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert "filter" in detail and all(repr(name) in detail for name in FILTER_NAMES), detail
    assert r.json()["errors"][0]["input"] == "kalman9000"
    r = client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=h)
    assert r.status_code == 409 and "no recordings" in r.json()["detail"].lower()
    r = client.get(f"/api/v1/sessions/{sid}/results", headers=h)
    assert r.status_code == 404 and "process it first" in r.json()["detail"]


def test_fhir_diagnostic_report(client, settings, demo_dir):
    """GET /fhir/DiagnosticReport/{session_id}: the PDF in presentedForm, one Observation per knee angle."""
    import base64

    from web_helpers import clinic_token, new_session

    h = clinic_token(settings, "F")
    _, sid = new_session(client, h, "F-7", side="left")
    assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir)).status_code == 201
    assert client.get(f"/api/v1/fhir/DiagnosticReport/{sid}", headers=h).status_code == 404  # nothing processed
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "pt"}, headers=h).json()["job_id"], h)
    assert job["status"] == "done", job
    r = client.get(f"/api/v1/fhir/DiagnosticReport/{sid}", headers=h)
    assert r.status_code == 200, r.text[:500]
    assert r.headers["content-type"].startswith("application/fhir+json")
    doc = r.json()
    text = r.text
    assert doc["resourceType"] == "DiagnosticReport" and doc["status"] in ("final", "preliminary")
    pdf = client.get(f"/api/v1/sessions/{sid}/report.pdf", headers=h).content
    forms = doc["presentedForm"]
    assert any(base64.b64decode(f["data"]) == pdf for f in forms)
    assert '"deg"' in text and "F-7" in text
    observations = [c for c in doc["contained"] if c["resourceType"] == "Observation"]
    assert len(observations) == 3 and len(doc["result"]) == 3
    assert doc["id"] == str(sid) and "Left" in text  # the patient's side reached the report


def test_validation_errors_are_one_sentence(client, settings):
    from web_helpers import clinic_token

    h = clinic_token(settings, "V")
    r = client.post("/api/v1/patients", json={"external_id": "X", "side": "up", "colour": 1}, headers=h)
    assert r.status_code == 422
    detail = r.json()["detail"]
    assert isinstance(detail, str) and "side" in detail and "colour" in detail and detail.endswith("again.")
