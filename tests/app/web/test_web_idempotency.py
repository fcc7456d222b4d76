"""``Idempotency-Key`` on every creating POST and ``Location`` on every 201/202 (issue 17, §1).

The issue's finding: the same ``Idempotency-Key`` sent after the job completed created a second analysis (the
header was ignored; only a job still running had refused the repeat).  Here each creating POST is sent twice
with one key — the second time after the first's work is over — and the second answer must be the first's
resource, marked replayed, with nothing new in the database.
"""

from __future__ import annotations

import threading

from web_helpers import clinic_token, demo_files, wait_job


def _counts(client, h, pid: int) -> tuple[int, int]:
    patients = int(client.get("/api/v1/patients", headers=h).headers["x-total-count"])
    sessions = int(client.get(f"/api/v1/patients/{pid}/sessions", headers=h).headers["x-total-count"])
    return patients, sessions


def test_each_creating_post_happens_once_per_key(client, settings, demo_dir):
    h = clinic_token(settings, "Hospital Retry")
    k = lambda name: h | {"Idempotency-Key": f"key-{name}"}  # noqa: E731

    first = client.post("/api/v1/patients", json={"external_id": "R-1", "side": "right"}, headers=k("p"))
    assert first.status_code == 201 and first.headers["location"] == f"/api/v1/patients/{first.json()['id']}"
    assert "idempotent-replayed" not in first.headers
    again = client.post("/api/v1/patients", json={"external_id": "R-1", "side": "right"}, headers=k("p"))
    assert again.status_code == 201 and again.json() == first.json()
    assert again.headers["idempotent-replayed"] == "true" and again.headers["location"] == first.headers["location"]
    pid = first.json()["id"]
    assert client.get(first.headers["location"], headers=h).json()["external_id"] == "R-1"
    # without a key the same body is a new request: the external id is taken
    assert client.post("/api/v1/patients", json={"external_id": "R-1", "side": "right"}, headers=h).status_code == 409
    # the same key with another body is refused, and creates nothing
    other = client.post("/api/v1/patients", json={"external_id": "R-2", "side": "right"}, headers=k("p"))
    assert other.status_code == 409 and "Idempotency-Key" in other.json()["detail"]
    assert _counts(client, h, pid)[0] == 1

    s1 = client.post(f"/api/v1/patients/{pid}/sessions", json={"step_height_m": 0.17}, headers=k("s"))
    s2 = client.post(f"/api/v1/patients/{pid}/sessions", json={"step_height_m": 0.17}, headers=k("s"))
    assert s1.status_code == s2.status_code == 201 and s1.json()["id"] == s2.json()["id"]
    sid = s1.json()["id"]
    assert s1.headers["location"] == s2.headers["location"] == f"/api/v1/sessions/{sid}"
    assert _counts(client, h, pid) == (1, 1)

    files = demo_files(demo_dir)
    u1 = client.post(f"/api/v1/sessions/{sid}/recordings", files=files, headers=k("u"))
    assert u1.status_code == 201 and u1.headers["location"] == f"/api/v1/sessions/{sid}", u1.text
    u2 = client.post(f"/api/v1/sessions/{sid}/recordings", files=files, headers=k("u"))
    assert u2.status_code == 201 and u2.headers["idempotent-replayed"] == "true"  # not 409 "already stored"
    assert [r["id"] for r in u2.json()["recordings"]] == [r["id"] for r in u1.json()["recordings"]]
    assert u2.json()["ingestion"]["ok"] is True
    assert len(client.get(f"/api/v1/sessions/{sid}", headers=h).json()["recordings"]) == 24

    j1 = client.post(f"/api/v1/sessions/{sid}/process", json={"filter": "chakamo"}, headers=k("j"))
    assert j1.status_code == 202 and j1.headers["location"] == f"/api/v1/jobs/{j1.json()['job_id']}"
    assert wait_job(client, j1.json()["job_id"], h)["status"] == "done"
    j2 = client.post(f"/api/v1/sessions/{sid}/process", json={"filter": "chakamo"}, headers=k("j"))
    assert j2.status_code == 202 and j2.json() == j1.json() and j2.headers["idempotent-replayed"] == "true"
    session = client.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert len(session["jobs"]) == 1 and len(session["analyses"]) == 1  # no duplicate analysis

    bad = client.post("/api/v1/patients", json={"external_id": "R-3", "side": "right"},
                      headers=h | {"Idempotency-Key": "x" * 201})
    assert bad.status_code == 400 and bad.json()["code"] == "request.idempotency_key_invalid"


def test_keys_belong_to_their_clinic(client, settings):
    a, b = clinic_token(settings, "A"), clinic_token(settings, "B")
    key = {"Idempotency-Key": "shared-key"}
    ra = client.post("/api/v1/patients", json={"external_id": "X", "side": "left"}, headers=a | key)
    rb = client.post("/api/v1/patients", json={"external_id": "X", "side": "left"}, headers=b | key)
    assert ra.status_code == rb.status_code == 201 and ra.json()["id"] != rb.json()["id"]
    assert "idempotent-replayed" not in rb.headers


def test_concurrent_requests_with_one_key_create_one_patient(client, settings):
    h = clinic_token(settings, "Hospital Race") | {"Idempotency-Key": "race"}
    answers, start = [], threading.Barrier(6)

    def post():
        start.wait()
        answers.append(client.post("/api/v1/patients", json={"external_id": "RACE", "side": "left"}, headers=h))

    threads = [threading.Thread(target=post) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    created = {r.json()["id"] for r in answers if r.status_code == 201}
    assert len(created) == 1, [(r.status_code, r.text) for r in answers]
    # the others replay the winner's patient, or (not seen on SQLite/PostgreSQL, allowed) say "still running,
    # retry" — never "external id taken", which is what a request without the key machinery answers
    assert all(r.status_code == 201 or (r.status_code == 409 and "Idempotency-Key" in r.json()["detail"])
               for r in answers), [(r.status_code, r.text) for r in answers]
    assert int(client.get("/api/v1/patients", headers=h).headers["x-total-count"]) == 1


def test_an_upload_key_is_bound_to_its_files(client, settings, demo_dir):
    """The same key with other files is another request: 409 with its code in three languages, and the other
    files are neither stored nor dropped silently (it used to answer 201 "replayed" and drop them)."""
    h = clinic_token(settings, "Hospital Upload Keys")
    pid = client.post("/api/v1/patients", json={"external_id": "UK-1", "side": "right"}, headers=h).json()["id"]
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=h).json()["id"]
    files = demo_files(demo_dir)
    k = h | {"Idempotency-Key": "upload-1"}
    first = client.post(f"/api/v1/sessions/{sid}/recordings", files=files[:3], headers=k)
    assert first.status_code == 201, first.text
    again = client.post(f"/api/v1/sessions/{sid}/recordings", files=files[:3], headers=k)
    assert again.status_code == 201 and again.headers["idempotent-replayed"] == "true"
    other = client.post(f"/api/v1/sessions/{sid}/recordings", files=files[3:6], headers=k)
    assert other.status_code == 409, other.text
    body = other.json()
    assert body["code"] == "store.key_reused" and set(body["message"]) == {"es", "en", "pt"}
    assert "upload-1" in body["message"]["es"] and other.headers["x-chakamo-code"] == "store.key_reused"
    assert len(client.get(f"/api/v1/sessions/{sid}", headers=h).json()["recordings"]) == 3
