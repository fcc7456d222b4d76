"""API tokens: expiry, rotation and scopes (issue 17, §1; :mod:`app.store.tokens`, :mod:`app.web.api.deps`).

Tokens are made by the real ``chakamo tokens`` command (a subprocess, as an operator runs it) and by the
functions behind it; the API then answers them as the rules say: an expired or rotated-out token 401, a scoped
token 403 outside its scopes.
"""

from __future__ import annotations

import datetime as dt
import os
import subprocess
import sys

import pytest
from web_helpers import make_settings


@pytest.fixture
def app_client(tmp_path):
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    with TestClient(create_app(settings)) as c:
        admin_cli.create_clinic(settings, "Hospital Tokens")
        yield c, settings


def _chakamo(settings, *args: str) -> subprocess.CompletedProcess:
    env = os.environ | {"CHAKAMO_DATA_DIR": str(settings.data_dir), "CHAKAMO_ENV": "development"}
    return subprocess.run([sys.executable, "-m", "app.cli.main", *args], env=env, capture_output=True, text=True,
                          timeout=300)


def test_cli_creates_scoped_expiring_tokens_and_rotates_them(app_client):
    client, settings = app_client
    out = _chakamo(settings, "tokens", "create", "--clinic", "Hospital Tokens", "--label", "PACS", "--expires-days",
                   "30", "--scope", "fhir:read", "--scope", "patients:read")
    assert out.returncode == 0, out.stderr
    token = out.stdout.strip().splitlines()[-1]
    h = {"Authorization": f"Bearer {token}"}
    assert client.get("/api/v1/patients", headers=h).status_code == 200
    r = client.post("/api/v1/patients", json={"external_id": "T-1", "side": "left"}, headers=h)
    assert r.status_code == 403 and "patients:write" in r.json()["detail"]
    assert client.get("/api/v1/jobs/1", headers=h).status_code == 403  # jobs:read not granted
    assert client.get("/api/v1/options", headers=h).status_code == 200  # needs no scope

    from app.cli import admin as admin_cli

    (row,) = admin_cli.list_tokens(settings, clinic="Hospital Tokens")
    assert row["scopes"] == "fhir:read patients:read" and row["label"] == "PACS"
    lifetime = row["expires_at"] - row["created_at"]
    assert abs(lifetime - dt.timedelta(days=30)) < dt.timedelta(minutes=1)

    out = _chakamo(settings, "tokens", "rotate", str(row["id"]), "--grace-hours", "2")
    assert out.returncode == 0, out.stderr
    successor = out.stdout.strip().splitlines()[-1]
    h2 = {"Authorization": f"Bearer {successor}"}
    assert client.get("/api/v1/patients", headers=h2).status_code == 200
    assert client.get("/api/v1/patients", headers=h).status_code == 200  # the grace period
    old, new = admin_cli.list_tokens(settings, clinic="Hospital Tokens")
    assert new["scopes"] == old["scopes"] and new["label"] == "PACS"
    assert abs((new["expires_at"] - new["created_at"]) - lifetime) < dt.timedelta(minutes=1)
    assert old["expires_at"] <= old["created_at"] + dt.timedelta(hours=2, minutes=1)

    # rotation without grace: the old token ends now, with a sentence saying so
    _, info = admin_cli.rotate_token(settings, new["id"], grace_hours=0)
    r = client.get("/api/v1/patients", headers=h2)
    assert r.status_code == 401 and "expired" in r.json()["detail"]
    assert r.headers["content-type"] == "application/problem+json"
    from app.store.errors import Invalid

    with pytest.raises(Invalid, match="revoked or expired"):  # the data layer's refusal; main() prints it in --lang
        admin_cli.rotate_token(settings, new["id"])


def test_bad_token_options_are_refused_with_a_sentence(app_client):
    _, settings = app_client
    from app.cli import admin as admin_cli

    from app.store.errors import Invalid

    with pytest.raises(Invalid, match="unknown scope"):  # the data layer's refusals; main() prints them in --lang
        admin_cli.create_token(settings, clinic="Hospital Tokens", scopes=["patients:delete"])
    with pytest.raises(Invalid, match="out of range"):
        admin_cli.create_token(settings, clinic="Hospital Tokens", expires_days=0)
    out = _chakamo(settings, "tokens", "create", "--clinic", "Hospital Tokens", "--scope", "everything")
    assert out.returncode == 2 and "unknown scope everything" in out.stderr


def test_a_scoped_upload_token_cannot_read_patients(app_client, demo_dir):
    client, settings = app_client
    from app.cli import admin as admin_cli

    full = {"Authorization": "Bearer " + admin_cli.create_token(settings, clinic="Hospital Tokens")}
    pid = client.post("/api/v1/patients", json={"external_id": "U-1", "side": "right"}, headers=full).json()["id"]
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=full).json()["id"]
    uploader = {"Authorization": "Bearer " + admin_cli.create_token(
        settings, clinic="Hospital Tokens", scopes=["recordings:write", "jobs:write jobs:read"])}
    files = [("files", (p.name, p.read_bytes(), "text/csv")) for p in sorted(demo_dir.glob("*.csv"))[:3]]
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=files, headers=uploader).status_code == 201
    assert client.get(f"/api/v1/patients/{pid}", headers=uploader).status_code == 403
    assert client.get(f"/api/v1/sessions/{sid}/results", headers=uploader).status_code == 403
    reader = {"Authorization": "Bearer " + admin_cli.create_token(settings, clinic="Hospital Tokens",
                                                                  scopes=["sessions:read"])}
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=files, headers=reader).status_code == 403


def test_a_route_is_guarded_by_what_it_touches_not_by_its_router(app_client):
    """``/patients/{id}/trend`` and ``/compare`` are clinical results (``results:read``); a new session is
    ``sessions:write``: a ``patients:*`` token reads neither nor makes sessions."""
    client, settings = app_client
    from app.cli import admin as admin_cli

    def bearer(*scopes):
        return {"Authorization": "Bearer " + admin_cli.create_token(settings, clinic="Hospital Tokens",
                                                                      scopes=list(scopes) or None)}

    full = bearer()
    pid = client.post("/api/v1/patients", json={"external_id": "S-1", "side": "right"}, headers=full).json()["id"]
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=full).json()["id"]
    patients_only = bearer("patients:read", "patients:write")
    for path in (f"/patients/{pid}/trend", f"/patients/{pid}/compare?a={sid}&b={sid}"):
        r = client.get("/api/v1" + path, headers=patients_only)
        assert r.status_code == 403 and "results:read" in r.text, path
        assert client.get("/api/v1" + path, headers=bearer("results:read")).status_code != 403, path
    assert client.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=patients_only).status_code == 403
    made = client.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=bearer("sessions:write"))
    assert made.status_code == 201, made.text
    assert client.get(f"/api/v1/patients/{pid}", headers=patients_only).status_code == 200


def test_the_event_stream_ends_when_its_token_is_revoked(app_client, monkeypatch):
    """``GET /events`` resolves its caller again while streaming: a token revoked meanwhile ends the stream with
    ``event: end`` carrying the refusal's code and es/en/pt message (it used to stream on for up to 600 s)."""
    import json
    import threading

    from app.cli import admin as admin_cli
    from app.web.api import webhooks as events_api

    client, settings = app_client
    monkeypatch.setattr(events_api, "RECHECK_S", 0.2)
    monkeypatch.setattr(events_api, "STREAM_S", 30.0)
    token = admin_cli.create_token(settings, clinic="Hospital Tokens", label="stream")
    token_id = admin_cli.list_tokens(settings, clinic="Hospital Tokens")[-1]["id"]
    timer = threading.Timer(1.0, admin_cli.revoke_token, (settings, token_id))
    timer.start()
    r = client.get("/api/v1/events", headers={"Authorization": f"Bearer {token}"})
    timer.join()
    assert r.status_code == 200
    blocks = [b for b in r.text.split("\n\n") if b.startswith("event: end")]
    assert blocks, r.text
    end = json.loads(blocks[0].split("data: ", 1)[1])
    assert end["status"] == 401 and end["code"] == "auth.token_unknown" and set(end["message"]) == {"es", "en", "pt"}


def test_the_event_stream_ends_in_the_readers_language_when_its_caller_is_another_clinics(app_client):
    """The stream's re-check finds the credentials now let their bearer into another clinic than the one the
    stream was opened for: its ``event: end`` carries a catalogue refusal (it was a bare ``{"status": 403}``)."""
    from starlette.requests import Request

    from app.cli import admin as admin_cli
    from app.web.api import webhooks as events_api
    from app.web.api.deps import resolve_principal

    client, settings = app_client
    token = admin_cli.create_token(settings, clinic="Hospital Tokens", label="stream")
    clinic_id = None
    for lang, words in (("es", "Este flujo de eventos se abrió para otra clínica"),
                        ("pt", "Este fluxo de eventos foi aberto para outra clínica")):
        scope = {"type": "http", "method": "GET", "path": "/api/v1/events", "app": client.app, "query_string": b"",
                 "headers": [(b"authorization", f"Bearer {token}".encode()), (b"accept-language", lang.encode())]}
        request = Request(scope)
        if clinic_id is None:   # the clinic the token lets in, as the stream resolved it when it opened
            with client.app.state.db.session() as db:
                clinic_id = resolve_principal(request, db, client.app.state.settings).clinic_id
        assert events_api._refused(request, clinic_id) is None   # still its own clinic: the stream goes on
        end = events_api._refused(request, clinic_id + 1000)
        assert end["status"] == 403 and end["code"] == "request.events_other_clinic"
        assert end["detail"].startswith(words) and end["message"][lang] == end["detail"]
