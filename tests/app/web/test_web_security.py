"""Security boundaries found in review: the 3D viewer plays only this server's scenes, the UI carries a
Content-Security-Policy, and an uploaded session.json cannot point the ingestion at other files."""

from __future__ import annotations

import json

from web_helpers import clinic_token, demo_files, new_session


def test_viewer_plays_only_this_servers_scenes(client):
    bad = ("http://127.0.0.1:9/evil.viser", "//evil.example/x.viser", "/api/v1/sessions/../../etc/passwd",
           "/static/app.js")
    for path in bad:
        r = client.get("/viser/index.html", params={"playbackPath": path})
        assert r.status_code == 400, path
    for path in ("/api/v1/sessions/%2e%2e/%2e%2e/auth/me", "/api/v1/sessions/%252e%252e/%252e%252e/x"):
        r = client.get("/viser/index.html", params={"playbackPath": path})  # a fetch decodes the dots
        assert r.status_code == 400, path
    r = client.get("/viser/index.html?playbackPath=/static/app.js&playbackPath=/api/v1/sessions/3/scene.viser")
    assert r.status_code == 400  # given twice: viser's client reads the first, a check of the last would pass
    r = client.get("/viser/index.html", params={"playbackPath": "/api/v1/sessions/3/scene.viser"})
    assert r.status_code == 200
    csp = r.headers["content-security-policy"]
    assert "connect-src 'self' data: blob:;" in csp and "frame-ancestors 'self'" in csp


def test_ui_has_security_headers(client):
    for url in ("/", "/static/app.js"):
        r = client.get(url)
        assert r.status_code == 200
        assert "script-src 'self';" in r.headers["content-security-policy"]
        assert r.headers["x-content-type-options"] == "nosniff"
        assert r.headers["x-frame-options"] == "SAMEORIGIN"
    assert client.get("/healthz").headers["x-content-type-options"] == "nosniff"


def test_uploaded_manifest_cannot_name_files_outside_the_session(client, settings, demo_dir, tmp_path):
    secret = tmp_path / "outside" / "secret-data.csv"
    secret.parent.mkdir()
    secret.write_text("secret_col_a,secret_col_b\n1,2\n")
    h = clinic_token(settings, "M")
    _, sid = new_session(client, h)
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    for name in (str(secret), "../../outside/secret-data.csv", "not-uploaded.csv"):
        manifest = {"recordings": [{"files": [name], "segment": "thigh", "role": "task"}]}
        r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
                        files=[("files", ("session.json", json.dumps(manifest).encode(), "application/json"))])
        assert r.status_code == 201, r.text
        ing = r.json()["ingestion"]
        assert ing["ok"] is False and "not one of this session's uploaded files" in ing["error"]
        assert "secret_col" not in json.dumps(r.json())  # the outside file was never read
        rid = [x["id"] for x in r.json()["recordings"] if x["file_name"] == "session.json"][0]
        assert client.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=h).status_code == 204
    assert client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=h).status_code == 202
