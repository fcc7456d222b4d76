"""Fixtures of the web application tests: a temporary data dir + database per test, and the demo session's
real MetaBase files (simulated once per run).  Helpers live in ``web_helpers.py``."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("fastapi")


@pytest.fixture
def settings(tmp_path):
    from web_helpers import make_settings

    return make_settings(tmp_path / "data")


@pytest.fixture
def client(settings):
    """A TestClient on a fresh app (lifespan run: migrations applied, job runner started)."""
    from fastapi.testclient import TestClient

    from app.main import create_app

    with TestClient(create_app(settings)) as c:
        yield c


@pytest.fixture(scope="session")
def demo_dir(tmp_path_factory) -> Path:
    """The demo session written as MetaBase CSV files (24 files; its session.json left out: the API builds one)."""
    from app.demo import simulate_session, write_session

    folder = tmp_path_factory.mktemp("demo") / "session"
    write_session(folder, simulate_session(seed=7, side="right", n_cycles=6))
    (folder / "session.json").unlink()
    return folder


@pytest.fixture
def pg_url():
    """URL of a new empty PostgreSQL database (``CHAKAMO_TEST_POSTGRES_URL``'s server; dropped after the test)."""
    import os
    import uuid

    from sqlalchemy import create_engine
    from sqlalchemy.engine import make_url

    server = os.environ.get("CHAKAMO_TEST_POSTGRES_URL")
    if not server:
        pytest.skip("CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")
    admin = create_engine(server, isolation_level="AUTOCOMMIT")
    name = f"chakamo_test_{uuid.uuid4().hex[:12]}"
    with admin.connect() as conn:
        conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    try:
        yield make_url(server).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()
