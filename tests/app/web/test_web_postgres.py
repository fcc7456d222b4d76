"""The web application on a real PostgreSQL server through ``DATABASE_URL`` (SQLite is the embedded default).

Runs when ``CHAKAMO_TEST_POSTGRES_URL`` names a server and a role allowed to create databases, e.g.
``postgresql+psycopg://chakamo:chakamo@127.0.0.1:5432/postgres``; ``.ci/run`` installs Debian's
``postgresql``, starts it and sets the variable.  Skipped otherwise.  Each test gets a fresh database,
dropped afterwards (the ``pg_url`` fixture of ``conftest.py``).
"""

from __future__ import annotations

import os

import pytest

from web_helpers import demo_files, make_settings, wait_job

PG = os.environ.get("CHAKAMO_TEST_POSTGRES_URL")
pytestmark = pytest.mark.skipif(not PG, reason="CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")


def test_migrations_match_the_models_on_postgresql(pg_url):
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from app.store.database import Database
    from app.store.models import Base

    db = Database(pg_url)
    db.migrate()
    db.migrate()  # idempotent
    with db.engine.connect() as conn:
        assert conn.dialect.name == "postgresql"
        diff = compare_metadata(MigrationContext.configure(conn, opts={"compare_type": True}), Base.metadata)
        assert diff == [], diff
    db.dispose()


def test_hospital_contract_and_clinic_isolation_on_postgresql(tmp_path, pg_url, demo_dir):
    """DESIGN §4's minimum on PostgreSQL: upload, process, results, report; another clinic gets 404."""
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", DATABASE_URL=pg_url)
    with TestClient(create_app(settings)) as client:
        admin_cli.create_clinic(settings, "Hospital Sur")
        admin_cli.create_clinic(settings, "Otra")
        h = {"Authorization": f"Bearer {admin_cli.create_token(settings, clinic='Hospital Sur')}"}
        other = {"Authorization": f"Bearer {admin_cli.create_token(settings, clinic='Otra')}"}

        patient_id = client.post("/api/v1/patients", json={"external_id": "HS-7", "side": "right"}, headers=h).json()["id"]
        assert client.post("/api/v1/patients", json={"external_id": "HS-7", "side": "left"}, headers=h).status_code == 409
        session_id = client.post(f"/api/v1/patients/{patient_id}/sessions", json={}, headers=h).json()["id"]
        r = client.post(f"/api/v1/sessions/{session_id}/recordings", files=demo_files(demo_dir), headers=h)
        assert r.status_code == 201 and r.json()["ingestion"]["ok"], r.text
        job = wait_job(client, client.post(f"/api/v1/sessions/{session_id}/process", json={}, headers=h)
                       .json()["job_id"], h)
        assert job["status"] == "done", job
        results = client.get(f"/api/v1/sessions/{session_id}/results", headers=h).json()
        assert results["cycles"]["accepted"] >= 4
        assert client.get(f"/api/v1/sessions/{session_id}/report.pdf?lang=es", headers=h).content.startswith(b"%PDF")
        assert [p["external_id"] for p in client.get("/api/v1/patients?q=hs-", headers=h).json()] == ["HS-7"]

        for url in (f"/api/v1/patients/{patient_id}", f"/api/v1/sessions/{session_id}",
                    f"/api/v1/sessions/{session_id}/results", f"/api/v1/sessions/{session_id}/report.pdf",
                    f"/api/v1/jobs/{job['id']}"):
            assert client.get(url, headers=other).status_code == 404, url
        assert client.get("/api/v1/patients", headers=other).json() == []
