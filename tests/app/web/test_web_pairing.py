"""Two one-knee sessions paired in the web (issue 15 §2 "two sessions paired"; app.store.pairing): the four-sensor
simulated walk split into a left-knee and a right-knee session of one patient, each uploaded on its own; pairing
them makes each one's processing read both knees — curves of both and the limb symmetry index — as the CLI's
``paired_session`` does.

Truth: the walk's left flexion is 80 % of the right's (``knee_gain``); the patient's side (right) is the involved
knee unless the request names another, so the swing-peak LSI is 125 % (right / left) by default and 80 % with the
left involved, within the pipeline's error (the four-sensor test's tolerance).  Refusals: another patient's
session, the session itself, a job running.  Unpairing gives one knee back; both sessions' earlier analyses are
superseded each time (the facts the reports print changed)."""

from __future__ import annotations

import pytest
from web_helpers import clinic_token, wait_job

from app.pipeline.demo import simulate_walk_knees, write_knees_session


@pytest.fixture(scope="module")
def knee_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pairwalk") / "session"
    write_knees_session(folder, simulate_walk_knees(seed=3, knee_gain={"left": 0.8}))
    return {side: [("files", (p.name, p.read_bytes(), "text/csv")) for p in sorted(folder.glob(f"{word}-*.csv"))]
            for side, word in (("left", "izquierda"), ("right", "derecha"))}


def _lsi(results: dict, name: str) -> float:
    return next(p["lsi_pct"] for p in results["symmetry"]["parameters"] if p["name"] == name)


def _session(client, h, pid: int, files) -> int:
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={"task": "gait", "date": "2026-11-05"},
                      headers=h).json()["id"]
    assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files).status_code == 201
    return sid


def _process(client, h, sid: int, **body) -> dict:
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "en", **body},
                                       headers=h).json()["job_id"], h)
    assert job["status"] == "done", job
    return client.get(f"/api/v1/sessions/{sid}/results", headers=h).json()


def test_two_one_knee_sessions_paired_give_both_knees_and_the_lsi(client, settings, knee_files):
    h = clinic_token(settings, "Pairs")
    pid = client.post("/api/v1/patients", json={"external_id": "P-1", "side": "right"}, headers=h).json()["id"]
    right, left = _session(client, h, pid, knee_files["right"]), _session(client, h, pid, knee_files["left"])
    alone = _process(client, h, right)
    assert "knees" not in alone and alone["side"] == "right"

    r = client.post(f"/api/v1/sessions/{left}/pair", json={"session_id": right, "knee": "left"}, headers=h)
    assert r.status_code == 200, r.text
    assert (r.json()["paired_session_id"], r.json()["knee"]) == (right, "left")
    other = client.get(f"/api/v1/sessions/{right}", headers=h).json()
    assert (other["paired_session_id"], other["knee"]) == (left, "right")
    assert other["ingestion"]["ok"] is True and "Left knee:" in other["ingestion"]["messages"]
    assert other["status"] == "superseded"  # its one-knee analysis no longer describes the session
    assert client.get(f"/api/v1/sessions/{right}/results", headers=h).status_code == 409

    both = _process(client, h, right)  # the patient's side, right, is the involved knee
    assert sorted(both["knees"]) == ["left", "right"] and both["involved_side"] == "right"
    assert both["knees"]["left"]["session"]["folder"] == f"session {right}"  # no server path
    assert _lsi(both, "swing_peak_flexion") == pytest.approx(125.0, abs=7.0)
    from_left = _process(client, h, left, involved="left")
    assert _lsi(from_left, "swing_peak_flexion") == pytest.approx(80.0, abs=4.0)
    assert _lsi(from_left, "swing_peak_flexion") == pytest.approx(10_000.0 / _lsi(both, "swing_peak_flexion"))

    assert from_left["session"]["paired_session_id"] == right  # provenance: where the other knee's files came from

    # a choice of cycles on one side changes what both sessions' reports would say: the partner's is superseded too
    current = client.get(f"/api/v1/sessions/{left}", headers=h).json()["analyses"][0]["id"]
    assert client.get(f"/api/v1/sessions/{right}/results", headers=h).status_code == 200
    _process(client, h, left, based_on_analysis_id=current, exclude_cycles=[{"cycle": 2, "knee": "left"}])
    assert client.get(f"/api/v1/sessions/{right}/results", headers=h).status_code == 409

    admin = clinic_token(settings, "Pairs", role="admin")
    events = client.get("/api/v1/audit", params={"limit": 50}, headers=admin).json()
    assert {(e["session_id"], e["detail"]) for e in events if e["action"] == "update"} >= {
        (left, f"paired with session {right}, left knee"), (right, f"paired with session {left}, right knee")}

    r = client.delete(f"/api/v1/sessions/{left}/pair", headers=h)
    assert r.status_code == 200 and r.json()["paired_session_id"] is None and r.json()["knee"] is None
    events = client.get("/api/v1/audit", params={"limit": 50}, headers=admin).json()
    assert {(e["session_id"], e["detail"]) for e in events if e["action"] == "update"} >= {
        (left, f"pairing undone (was session {right})"), (right, f"pairing undone (was session {left})")}
    assert client.get(f"/api/v1/sessions/{right}", headers=h).json()["paired_session_id"] is None
    assert "knees" not in _process(client, h, right)


def test_pairing_refusals(client, settings, knee_files):
    h = clinic_token(settings, "Pairs refused")
    p1 = client.post("/api/v1/patients", json={"external_id": "P-2", "side": "left"}, headers=h).json()["id"]
    p2 = client.post("/api/v1/patients", json={"external_id": "P-3", "side": "left"}, headers=h).json()["id"]
    a, b = _session(client, h, p1, knee_files["left"]), _session(client, h, p2, knee_files["right"])
    r = client.post(f"/api/v1/sessions/{a}/pair", json={"session_id": b, "knee": "left"}, headers=h)
    assert r.status_code == 409 and r.json()["code"] == "store.pair_other_patient"
    r = client.post(f"/api/v1/sessions/{a}/pair", json={"session_id": a, "knee": "left"}, headers=h)
    assert r.status_code == 409 and r.json()["code"] == "store.pair_itself"
    r = client.post(f"/api/v1/sessions/{a}/pair", json={"session_id": b, "knee": "left"}, headers={**h, "Accept-Language": "es"})
    assert "pacientes distintos" in r.json()["message"]["es"]
    r = client.post(f"/api/v1/sessions/{a}/pair", json={"session_id": b}, headers=h)
    assert r.status_code == 422  # no knee: none is assumed (a default could swap the knees)
    other = clinic_token(settings, "Another clinic")
    assert client.post(f"/api/v1/sessions/{a}/pair", json={"session_id": b, "knee": "left"}, headers=other).status_code == 404
