"""The knee-angle convention and the sensor-to-segment calibration belong to an analysis (real database, real
pipeline): a session processed again with the thesis' ZYX angles "just to compare" does not become its current
result (results, PDF, FHIR), is a series of its own in the ROM trend, and is not comparable with a Grood & Suntay
analysis; neither is one with another calibration.

Truth: the same knee pose reads other angles in the two conventions (tests/app/pipeline/test_comparison.py: at
90/5/15° the ZYX adduction is 10.1° higher, its rotation 19.8° lower), so mixing them is a change of method."""

from __future__ import annotations

from web_helpers import clinic_token, demo_files, new_session, wait_job


def _process(client, h, sid: int, **body) -> dict:
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "en", **body}, headers=h)
    assert r.status_code in (200, 201, 202), r.text
    job = wait_job(client, r.json()["job_id"], h)
    assert job["status"] == "done", job
    return job


def test_convention_and_calibration_keep_analyses_apart(client, settings, demo_dir):
    h = clinic_token(settings, "Conventions")
    pid, first = new_session(client, h, "AC-1")
    second = client.post(f"/api/v1/patients/{pid}/sessions", json={"step_height_m": 0.17, "date": "2026-12-01"},
                         headers=h).json()["id"]
    for sid in (first, second):
        assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir)).status_code == 201
    clinical = _process(client, h, first)
    _process(client, h, second)
    zyx = _process(client, h, first, angle_convention="thesis_zyx")

    # the ZYX run is newer, but the session's current result stays the Grood & Suntay one (results, PDF, FHIR)
    analyses = {a["id"]: a for a in client.get(f"/api/v1/sessions/{first}", headers=h).json()["analyses"]}
    assert analyses[zyx["analysis_id"]]["angle_method"] == "thesis_zyx"
    assert analyses[clinical["analysis_id"]]["angle_method"] == "grood_suntay"
    current = client.get(f"/api/v1/sessions/{first}/results", headers=h).json()
    assert current["angle_method"] == "grood_suntay" and current["calibration_method"] == "static"
    asked = client.get(f"/api/v1/sessions/{first}/results?analysis_id={zyx['analysis_id']}", headers=h).json()
    assert asked["angle_method"] == "thesis_zyx"
    fhir = client.get(f"/api/v1/fhir/DiagnosticReport/{first}", headers=h).json()
    assert str(clinical["analysis_id"]) in fhir["identifier"][0]["value"]

    # the trend: the Grood & Suntay series covers both sessions; the ZYX run is a series of its own
    trend = client.get(f"/api/v1/patients/{pid}/trend", headers=h).json()
    assert trend["angle_method"] == "grood_suntay" and trend["calibration"] == "static"
    assert {p["session_id"]: p["analysis_id"] for p in trend["points"]}[first] == clinical["analysis_id"]
    assert {(s["angle_method"], s["sessions"]) for s in trend["series"]} == {("grood_suntay", 2), ("thesis_zyx", 1)}
    other = client.get(f"/api/v1/patients/{pid}/trend?angle_method=thesis_zyx", headers=h).json()
    assert [p["analysis_id"] for p in other["points"]] == [zyx["analysis_id"]]
    assert [x["session_id"] for x in other["left_out"]] == [second]

    # compared: by default the two Grood & Suntay analyses; the ZYX one named is not comparable
    c = client.get(f"/api/v1/patients/{pid}/compare?a={first}&b={second}", headers=h).json()
    assert c["comparable"] and c["a"]["analysis_id"] == clinical["analysis_id"], c["mismatch"]
    forced = client.get(f"/api/v1/patients/{pid}/compare?a={first}&b={second}&a_analysis={zyx['analysis_id']}",
                        headers=h).json()
    assert not forced["comparable"] and forced["mismatch"] == ["angle_method"]

    # the later session processed with the functional calibration: the earlier has no such analysis, so the pair
    # compared differs in calibration, and says so
    _process(client, h, second, calibration="functional")
    c = client.get(f"/api/v1/patients/{pid}/compare?a={first}&b={second}", headers=h).json()
    assert not c["comparable"] and c["mismatch"] == ["calibration"]
    assert c["b"]["calibration"] == "functional" and c["a"]["calibration"] == "static"
