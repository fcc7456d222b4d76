"""Issue 16's low findings 10d–10f: a spoofed Host never reaches the FHIR identifiers (allowed hosts and a
public URL from the settings), ``/docs`` cannot be framed, and ``report.html`` may reach no network."""

from __future__ import annotations

import re

import pytest
from fastapi import Request  # at module level: the probe route's annotation is resolved here

from web_helpers import clinic_token, demo_files, make_settings, new_session, wait_job

PUBLIC = "https://chakamo.hospital.example"


@pytest.fixture(scope="module")
def processed(tmp_path_factory, demo_dir):
    """(client, headers, session id) of one processed demo session; Host checked, public URL set."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path_factory.mktemp("hosts") / "data", CHAKAMO_PUBLIC_URL=PUBLIC + "/",
                             CHAKAMO_ALLOWED_HOSTS="testserver, chakamo.hospital.example, *.ward.example")
    h = clinic_token(settings, "Hosts")
    with TestClient(create_app(settings)) as client:
        _, sid = new_session(client, h, "H-1")
        r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir))
        assert r.status_code == 201, r.text
        job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=h).json()["job_id"], h)
        assert job["status"] == "done", job
        yield client, h, sid


def test_a_spoofed_host_is_refused_and_never_written_into_fhir(processed):
    client, h, sid = processed
    url = f"/api/v1/fhir/DiagnosticReport/{sid}"
    r = client.get(url, headers=h | {"host": "evil.example"})
    assert r.status_code == 400 and r.json()["code"] == "request.host_not_allowed", r.text
    assert set(r.json()["message"]) == {"es", "en", "pt"}
    for host in ("testserver", "a.ward.example", "chakamo.hospital.example:443"):
        r = client.get(url, headers=h | {"host": host})
        assert r.status_code == 200, (host, r.text[:300])
        systems = re.findall(r'"system":\s*"(https?://[^"]+)"', r.text)
        ours = [s for s in systems if "/api/v1/" in s]
        assert ours and all(s.startswith(PUBLIC + "/api/v1/") for s in ours), ours  # never the request's Host
    assert client.get("/healthz", headers={"host": "10.0.0.7:8000"}).status_code == 200  # probes by address


def test_report_html_may_reach_no_network(processed):
    client, h, sid = processed
    r = client.get(f"/api/v1/sessions/{sid}/report.html", headers=h)
    assert r.status_code == 200
    csp = {d.split()[0]: d.split()[1:] for d in (x.strip() for x in r.headers["content-security-policy"].split(";")) if d}
    assert csp["sandbox"] and "allow-same-origin" not in csp["sandbox"]
    assert csp["default-src"] == ["'none'"] and csp["connect-src"] == ["'none'"]
    assert csp["form-action"] == ["'none'"] and csp["frame-src"] == ["'none'"]
    # the report is self-contained, so the policy costs it nothing: no script, style, image or frame from a URL
    assert not re.search(r'<(script|img|link|iframe)[^>]+(src|href)="(https?:)?//', r.text, re.I)


def test_docs_cannot_be_framed_and_no_server_banner(tmp_path):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    with TestClient(create_app(make_settings(tmp_path / "data"))) as client:
        r = client.get("/docs")
        assert r.status_code == 200
        assert r.headers["x-frame-options"] == "DENY"
        assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
        assert "script-src 'self' 'unsafe-inline'" in r.headers["content-security-policy"]  # swagger's own start-up
        assert client.get("/docs-assets/swagger-ui-bundle.js").headers["x-frame-options"] == "DENY"


def test_production_without_a_public_url_does_not_trust_the_host(tmp_path):
    """Any Host allowed and no CHAKAMO_PUBLIC_URL: the FHIR export refuses (503, what to set) rather than write
    whatever Host a caller sent into a clinical document."""
    from fastapi import FastAPI
    from fastapi.testclient import TestClient

    from app.settings import Settings
    from app.web.api.fhir import fhir_base_url
    from app.web.refusals import Refusal

    prod = Settings(CHAKAMO_ENV="production", CHAKAMO_DATA_DIR=tmp_path, CHAKAMO_SECRET_KEY="k" * 40)
    probe = FastAPI()
    probe.state.settings = prod

    @probe.get("/base")
    def base(request: Request):
        try:
            return {"base": fhir_base_url(request)}
        except Refusal as exc:
            return {"refused": exc.status_code, "code": exc.code}

    with TestClient(probe) as c:
        assert c.get("/base", headers={"host": "evil.example"}).json() == {"refused": 503,
                                                                           "code": "request.public_url_missing"}
    probe.state.settings = Settings(CHAKAMO_ENV="production", CHAKAMO_DATA_DIR=tmp_path, CHAKAMO_SECRET_KEY="k" * 40,
                                    CHAKAMO_PUBLIC_URL=PUBLIC)
    with TestClient(probe) as c:
        assert c.get("/base", headers={"host": "evil.example"}).json() == {"base": PUBLIC + "/api/v1"}
