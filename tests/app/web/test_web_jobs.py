"""Jobs that cannot succeed end ``failed`` with the pipeline's sentence, and the session says so; an uploaded
``session.json`` is honoured (here its MAC → segment map swaps the sensors, which the pipeline detects)."""

from __future__ import annotations

import json

from web_helpers import clinic_token, demo_files, new_session, wait_job


def test_swapped_sensors_fail_the_job_with_a_sentence(client, settings, demo_dir):
    h = clinic_token(settings, "J")
    _, sid = new_session(client, h)
    manifest = {"sensors": {"D4F1A2B3C4E5": "shank", "E8C2B1A0F9D7": "thigh"}}  # the demo's MACs, swapped
    files = demo_files(demo_dir) + [("files", ("session.json", json.dumps(manifest).encode(), "application/json"))]
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files)
    assert r.status_code == 201 and r.json()["ingestion"]["ok"] is True
    assert any("session.json" in m for m in r.json()["ingestion"]["messages"])
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=h).json()["job_id"], h)
    assert job["status"] == "failed" and job["analysis_id"] is None
    # the diagnosis names the cause a clinician can fix (estimators.diagnosis: sensors_swapped), not a guess
    assert "are swapped. Check which recording belongs to which segment" in job["error"], job["error"]
    assert "Traceback" not in " ".join(job["log"])  # a data problem, not a crash
    s = client.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert s["status"] == "failed" and s["analyses"] == []
    assert client.get(f"/api/v1/sessions/{sid}/results", headers=h).status_code == 404


def test_a_broken_manifest_is_an_ingestion_error(client, settings):
    h = clinic_token(settings, "K")
    _, sid = new_session(client, h)
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
                    files=[("files", ("session.json", b"{not json", "application/json")),
                           ("files", ("a.csv", b"time (s),acc_x (g)\n", "text/csv"))])
    assert r.status_code == 201
    ing = r.json()["ingestion"]
    assert ing["ok"] is False and "session.json" in ing["error"] and "JSON" in ing["error"]
