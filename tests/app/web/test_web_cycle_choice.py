"""The clinician's choice of cycles over the API (POST /sessions/{id}/process with exclude_cycles; app.jobs.queue):
tied to the analysis it was made on, with that analysis' options, and kept by later ordinary processing.

Truth: the simulated demo session (6 step-up cycles, seed 7) processed with non-default options (functional
calibration, the thesis' ZYX angles, the madgwick filter); the job rows and results.json the server stores."""

from __future__ import annotations

from web_helpers import clinic_token, demo_files, new_session, wait_job


def _done(client, h, sid: int, body: dict) -> dict:
    r = client.post(f"/api/v1/sessions/{sid}/process", json=body, headers=h)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["job_id"], h)
    assert job["status"] == "done", job
    return job


def test_a_choice_of_cycles_keeps_the_analysis_options_and_is_tied_to_it(client, settings, demo_dir):
    h = clinic_token(settings, "Cycle choice")
    _, sid = new_session(client, h, "CC-1")
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    options = {"filter": "madgwick", "calibration": "functional", "angle_convention": "thesis_zyx", "heading": "magnetometer"}
    base = _done(client, h, sid, {"lang": "en", **options})

    # named without the analysis it was chosen on: refused
    r = client.post(f"/api/v1/sessions/{sid}/process", headers=h,
                    json={"lang": "en", "exclude_cycles": [{"cycle": 2, "reason": "stumbled"}]})
    assert r.status_code == 400 and r.json()["code"] == "store.exclusions_need_base"

    # the request's own options (the defaults, as cycles.js sends none) give way to the analysis'
    first = _done(client, h, sid, {"lang": "en", "based_on_analysis_id": base["analysis_id"],
                                   "exclude_cycles": [{"cycle": 2, "reason": "stumbled"}]})
    assert (first["filter"], first["calibration"], first["angle_convention"], first["heading"]) == (
        "madgwick", "functional", "thesis_zyx", "magnetometer")
    (was,) = first["cycle_exclusions"]

    # an older analysis is no longer the one to choose on: 409 in es/en/pt
    r = client.post(f"/api/v1/sessions/{sid}/process", headers=h,
                    json={"lang": "en", "based_on_analysis_id": base["analysis_id"], "exclude_cycles": []})
    assert r.status_code == 409 and r.json()["code"] == "store.exclusions_stale"
    assert set(r.json()["message"]) == {"es", "en", "pt"}

    # a second choice keeps who excluded cycle 2 and when; cycle 4 is new
    second = _done(client, h, sid, {"lang": "en", "based_on_analysis_id": first["analysis_id"],
                                    "exclude_cycles": [{"cycle": 2, "reason": "stumbled"},
                                                       {"cycle": 4, "reason": "talked"}]})
    kept = {e["cycle"]: e for e in second["cycle_exclusions"]}
    assert (kept[2]["by"], kept[2]["at"]) == (was["by"], was["at"]) and kept[4]["reason"] == "talked"

    # an ordinary processing afterwards keeps the clinician's exclusions (same files and pipeline)
    plain = _done(client, h, sid, {"lang": "es", "filter": "madgwick"})
    assert plain["cycle_exclusions"] == second["cycle_exclusions"]
    assert any("carried over" in line for line in plain["log"])
    results = client.get(f"/api/v1/sessions/{sid}/results", headers=h).json()
    assert sorted(e["cycle"] for e in results["cycles"]["excluded"]) == [2, 4]

    # after the facts changed the cycles may be others: not carried over, and the job's log says so
    assert client.patch(f"/api/v1/sessions/{sid}", json={"step_height_m": 0.18}, headers=h).status_code == 200
    fresh = _done(client, h, sid, {"lang": "en"})
    assert fresh["cycle_exclusions"] is None
    assert any("not carried over" in line for line in fresh["log"])


def test_another_convention_neither_supersedes_nor_blocks_a_choice_of_cycles(client, settings, demo_dir):
    """A ZYX run after cycles were chosen on the Grood & Suntay analysis leaves that analysis current (it supersedes
    only analyses of its own calibration and convention), and cycles may be chosen on the ZYX analysis itself,
    though the session's current result is the Grood & Suntay one (review of the merged branches: the ZYX run
    superseded it, the results answered 409, and a choice on the newest analysis was refused as stale)."""
    h = clinic_token(settings, "Cycle choice conventions")
    _, sid = new_session(client, h, "CC-2")
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    clinical = _done(client, h, sid, {"lang": "en"})
    chosen = _done(client, h, sid, {"lang": "en", "based_on_analysis_id": clinical["analysis_id"],
                                    "exclude_cycles": [{"cycle": 2, "reason": "stumbled"}]})
    zyx = _done(client, h, sid, {"lang": "en", "angle_convention": "thesis_zyx"})
    results = client.get(f"/api/v1/sessions/{sid}/results", headers=h)
    assert results.status_code == 200, results.text
    assert results.json()["angle_method"] == "grood_suntay"
    assert client.get(f"/api/v1/sessions/{sid}/results", params={"analysis_id": chosen["analysis_id"]},
                      headers=h).status_code == 200
    on_zyx = _done(client, h, sid, {"lang": "en", "based_on_analysis_id": zyx["analysis_id"],
                                    "exclude_cycles": [{"cycle": 3, "reason": "talked"}]})
    assert on_zyx["angle_convention"] == "thesis_zyx"
    after = client.get(f"/api/v1/sessions/{sid}/results", headers=h)
    assert after.status_code == 200 and sorted(e["cycle"] for e in after.json()["cycles"]["excluded"]) == [2]
