"""Job failures in the reader's language (issue 14 §5) and the web's side override (§4): a session whose files say
the other leg fails with the provenance check's code and values, rendered in es/en/pt; processed again with the
side chosen, it goes ahead and the results keep the warning."""

from __future__ import annotations

from web_helpers import clinic_token, new_session, wait_job


def _left_thigh_task(demo_dir):
    """The demo's files, the thigh's task recording labelled as the left leg (the patient's knee is the right)."""
    out = []
    for p in sorted(demo_dir.glob("*.csv")):
        name = p.name.replace("step-muslo-", "step-muslo-izquierda-") if p.name.startswith("step-muslo-") else p.name
        out.append(("files", (name, p.read_bytes(), "text/csv")))
    return out


def test_a_left_leg_recording_fails_in_every_language_and_the_side_override_processes_it(client, settings, demo_dir):
    h = clinic_token(settings, "M")
    _, sid = new_session(client, h, side="right")
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=_left_thigh_task(demo_dir))
    assert r.status_code == 201 and r.json()["ingestion"]["ok"] is True, r.text
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=h).json()["job_id"], h)
    assert job["status"] == "failed" and job["error_code"] == "check.side_mismatch", job
    assert "/tmp" not in str(job["error_params"]) and "session-" not in str(job["error_params"])
    msg = job["error_message"]
    assert "left leg" in msg["en"] and msg["en"] == job["error"]
    assert "izquierda" in msg["es"] and "clínico" in msg["es"]
    assert "esquerda" in msg["pt"] and "clínico" in msg["pt"]

    r = client.post(f"/api/v1/sessions/{sid}/process", json={"side": "right"}, headers=h)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["job_id"], h)
    assert job["status"] == "done" and job["side"] == "right", job
    results = client.get(f"/api/v1/sessions/{sid}/results", headers=h).json()
    assert results["side"] == "right"
    assert any(w["code"] == "check.side_mismatch" for w in results["quality"]["warnings"])


def test_an_unknown_side_is_refused_with_the_valid_ones(client, settings):
    h = clinic_token(settings, "N")
    _, sid = new_session(client, h)
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"side": "middle"}, headers=h)
    assert r.status_code == 422 and "right" in r.text and "left" in r.text
