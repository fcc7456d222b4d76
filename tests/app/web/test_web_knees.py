"""Both knees through the web API (issue 15 §2 and §4): four sensors uploaded to one session and processed with the
involved knee chosen in the process request; the LSI in results.json and as FHIR Observations; two sessions
compared (before/after); the ROM trend of one filter and pipeline version only, each point naming its analysis.

Truth: the simulated walk's left flexion is 80 % (then 90 %) of the right's (``knee_gain``): with the left knee
involved the swing-peak LSI is 80 % (90 %) within the pipeline's error, so the comparison's change is +10 points."""

from __future__ import annotations

import pytest
from web_helpers import clinic_token, wait_job

from app.pipeline.demo import simulate_walk_knees, write_knees_session


@pytest.fixture(scope="module")
def walks(tmp_path_factory):
    out = {}
    for gain in (0.8, 0.9):
        folder = tmp_path_factory.mktemp(f"walk{gain}") / "session"
        write_knees_session(folder, simulate_walk_knees(seed=3, knee_gain={"left": gain}))
        (folder / "session.json").unlink()  # the API writes its own (the patient's side: the involved knee)
        out[gain] = [("files", (p.name, p.read_bytes(), "text/csv")) for p in sorted(folder.glob("*.csv"))]
    return out


def _lsi(results: dict, name: str) -> float:
    return next(p["lsi_pct"] for p in results["symmetry"]["parameters"] if p["name"] == name)


def _processed_session(client, h, pid: int, files, date: str, **process) -> int:
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={"task": "gait", "date": date}, headers=h).json()["id"]
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files)
    assert r.status_code == 201 and r.json()["ingestion"]["ok"] is True, r.text
    messages = r.json()["ingestion"]["messages"]
    assert messages.index("Left knee:") < messages.index("Right knee:")  # each knee's recordings under its header
    assert sum(m.startswith("thigh task") for m in messages) == 2
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "en", **process},
                                       headers=h).json()["job_id"], h)
    assert job["status"] == "done", job
    return sid


def test_four_sensors_lsi_fhir_comparison_and_trend(client, settings, walks):
    h = clinic_token(settings, "Knees")
    pid = client.post("/api/v1/patients", json={"external_id": "K-1", "side": "right"}, headers=h).json()["id"]
    # the patient's side is right; the clinician chooses the left knee as involved for this analysis
    before = _processed_session(client, h, pid, walks[0.8], "2026-11-01", involved="left")
    r = client.get(f"/api/v1/sessions/{before}/results", headers=h).json()
    assert r["involved_side"] == "left" and r["side"] == "left" and sorted(r["knees"]) == ["left", "right"]
    assert r["knees"]["right"]["session"]["folder"] == f"session {before}"  # no server path in either knee
    assert _lsi(r, "swing_peak_flexion") == pytest.approx(80.0, abs=4.0)

    fhir = client.get(f"/api/v1/fhir/DiagnosticReport/{before}", headers=h).json()
    lsi = {o["id"]: o for o in fhir["contained"] if o["id"].startswith("lsi-")}
    assert len(lsi) == len(r["symmetry"]["parameters"])
    swing = lsi["lsi-swing-peak-flexion"]
    assert swing["valueQuantity"]["value"] == round(_lsi(r, "swing_peak_flexion"), 1)  # FHIR values rounded to 0.1
    assert swing["valueQuantity"]["code"] == "%" and swing["bodySite"]["text"] == "Left knee joint"
    assert {"reference": "#lsi-swing-peak-flexion"} in [{"reference": x["reference"]} for x in fhir["result"]]

    after = _processed_session(client, h, pid, walks[0.9], "2026-11-20", involved="left")
    cmp = client.get(f"/api/v1/patients/{pid}/compare?a={before}&b={after}", headers=h)
    assert cmp.status_code == 200, cmp.text
    c = cmp.json()
    assert c["comparable"] and c["a"]["session_id"] == before and c["b"]["session_id"] == after
    rows = {row["key"]: row for row in c["rows"]}
    change = rows["symmetry.swing_peak_flexion.lsi_pct"]["change"]
    assert change == pytest.approx(10.0, abs=5.0)
    assert rows["gait.parameters.swing_peak_flexion_deg.mean"]["a"] == \
        r["gait"]["parameters"]["swing_peak_flexion_deg"]["mean"]

    # the first session processed once more with Madgwick: the trend keeps one series (the default filter's), and
    # names each point's analysis; the Madgwick one is a series of its own
    again = wait_job(client, client.post(f"/api/v1/sessions/{before}/process", json={"filter": "madgwick"},
                                         headers=h).json()["job_id"], h)
    assert again["status"] == "done"
    trend = client.get(f"/api/v1/patients/{pid}/trend", headers=h).json()
    assert trend["filter"] != "madgwick" and [p["session_id"] for p in trend["points"]] == [before, after]
    assert trend["points"][0]["analysis_id"] != again["analysis_id"]
    assert {(s["filter"], s["sessions"]) for s in trend["series"]} >= {("madgwick", 1)}
    mad = client.get(f"/api/v1/patients/{pid}/trend?filter=madgwick", headers=h).json()
    assert [p["analysis_id"] for p in mad["points"]] == [again["analysis_id"]]
    assert [x["session_id"] for x in mad["left_out"]] == [after]
    # compared again: the earlier session's latest is now Madgwick's; its default-filter analysis is used instead
    c2 = client.get(f"/api/v1/patients/{pid}/compare?a={before}&b={after}", headers=h).json()
    assert c2["comparable"] and c2["a"]["analysis_id"] == trend["points"][0]["analysis_id"]
    forced = client.get(f"/api/v1/patients/{pid}/compare?a={before}&b={after}&a_analysis={again['analysis_id']}",
                        headers=h).json()
    # that Madgwick run chose no involved knee: the patient's (right) one is its top level, the other run's the left
    assert not forced["comparable"] and forced["mismatch"] == ["filter", "side"]


def test_comparing_another_patients_session_is_refused(client, settings, walks):
    h = clinic_token(settings, "Knees2")
    p1 = client.post("/api/v1/patients", json={"external_id": "A", "side": "left"}, headers=h).json()["id"]
    p2 = client.post("/api/v1/patients", json={"external_id": "B", "side": "left"}, headers=h).json()["id"]
    s1 = client.post(f"/api/v1/patients/{p1}/sessions", json={}, headers=h).json()["id"]
    s2 = client.post(f"/api/v1/patients/{p2}/sessions", json={}, headers=h).json()["id"]
    r = client.get(f"/api/v1/patients/{p1}/compare?a={s1}&b={s2}", headers=h)
    assert r.status_code == 404 and "not one of patient" in r.json()["detail"]
    assert client.get(f"/api/v1/patients/{p1}/compare?a={s1}&b={s1}", headers=h).status_code == 404  # no analysis


def test_the_patients_side_is_the_default_involved_knee_and_the_trend_keeps_to_it(client, settings, walks):
    """A right-sided patient, the process request's ``involved`` left out (as the browser sends it): the right knee
    is the involved one (its swing-peak LSI 1/0.8 = 125 %); a second session processed with the left knee involved
    is compared as another knee (``mismatch`` names the side), and the ROM trend stays on the right knee."""
    h = clinic_token(settings, "KneesRight")
    pid = client.post("/api/v1/patients", json={"external_id": "K-R", "side": "right"}, headers=h).json()["id"]
    first = _processed_session(client, h, pid, walks[0.8], "2026-11-01", involved=None)
    r = client.get(f"/api/v1/sessions/{first}/results", headers=h).json()
    assert r["involved_side"] == "right" and r["side"] == "right" and r["rom_deg"] == r["knees"]["right"]["rom_deg"]
    assert _lsi(r, "swing_peak_flexion") == pytest.approx(100 / 0.8, abs=6.0)
    fhir = client.get(f"/api/v1/fhir/DiagnosticReport/{first}", headers=h).json()
    swing = next(o for o in fhir["contained"] if o["id"] == "lsi-swing-peak-flexion")
    assert swing["bodySite"]["text"] == "Right knee joint"

    second = _processed_session(client, h, pid, walks[0.9], "2026-11-20", involved="left")
    r2 = client.get(f"/api/v1/sessions/{second}/results", headers=h).json()
    assert r2["side"] == "left"
    c = client.get(f"/api/v1/patients/{pid}/compare?a={first}&b={second}", headers=h).json()
    assert not c["comparable"] and c["mismatch"] == ["side"]
    trend = client.get(f"/api/v1/patients/{pid}/trend", headers=h).json()
    assert [p["session_id"] for p in trend["points"]] == [first, second]
    assert [p["side"] for p in trend["points"]] == ["right", "right"]
    assert trend["points"][1]["rom_deg"] == r2["knees"]["right"]["rom_deg"] != r2["rom_deg"]


def test_a_side_for_both_knees_is_refused_in_the_webs_words(client, settings, walks):
    h = clinic_token(settings, "KneesSide")
    pid = client.post("/api/v1/patients", json={"external_id": "K-S", "side": "right"}, headers=h).json()["id"]
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={"task": "gait"}, headers=h).json()["id"]
    assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=walks[0.8]).status_code == 201
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={"side": "left"},
                                       headers=h).json()["job_id"], h)
    assert job["status"] == "failed" and job["error_code"] == "pipeline.side_with_two_knees.web", job
    assert "Involved knee" in job["error"] and "--" not in job["error"]
