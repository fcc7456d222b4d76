"""A failed ingestion check still says which zone each file's name points to (``ingestion.recognised``, real
database and check): files dropped together on the wizard's "other files" were all listed there when the check
failed, so the file it rejected was not shown red in its own zone (the zones are placed by this map)."""

from __future__ import annotations

from web_helpers import clinic_token, new_session


def test_a_failed_check_keeps_the_zones_the_names_say(client, settings):
    h = clinic_token(settings, "Named zones")
    _, sid = new_session(client, h, "NZ-1")
    files = [("files", ("step-muslo-NZ1-01012026-1.csv", b"this,is\nnot,a recording\n", "text/csv")),
             ("files", ("notes.csv", b"a,b\n1,2\n", "text/csv")),                       # no segment, no role
             ("files", ("muslo-pierna-step.csv", b"a,b\n1,2\n", "text/csv"))]           # two segments: undecided
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files)
    assert r.status_code == 201, r.text
    assert r.json()["ingestion"]["ok"] is False
    ingestion = client.get(f"/api/v1/sessions/{sid}", headers=h).json()["ingestion"]
    assert ingestion["ok"] is False
    assert ingestion["recognised"] == {"step-muslo-NZ1-01012026-1.csv": {"segment": "thigh", "role": "task"}}
