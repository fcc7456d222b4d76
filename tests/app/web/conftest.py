"""Fixtures of the web application tests: a temporary data dir + database per test, and the demo session's
real MetaBase files (simulated once per run).  Helpers live in ``web_helpers.py``.

Every test built on the ``settings`` / ``client`` fixtures runs twice: on the embedded SQLite file and on a
fresh database of a real PostgreSQL server (``CHAKAMO_TEST_POSTGRES_URL``, which ``.ci/run`` sets; the
PostgreSQL run skips when it is unset), so the suite proves both databases the product supports."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("fastapi")


@pytest.fixture(params=["sqlite", "postgresql"])
def database_url(request):
    """None (the embedded SQLite file of the data dir) or the URL of a new empty PostgreSQL database."""
    if request.param == "sqlite":
        return None
    return request.getfixturevalue("pg_url")


@pytest.fixture
def settings(tmp_path, database_url):
    from web_helpers import make_settings

    extra = {"DATABASE_URL": database_url} if database_url else {}
    # the tests' webhook receivers listen on loopback: named exactly, as an operator would allow an internal host
    return make_settings(tmp_path / "data", CHAKAMO_WEBHOOK_ALLOWED_HOSTS="127.0.0.1", **extra)


@pytest.fixture
def client(settings):
    """A TestClient on a fresh app (lifespan run: migrations applied, job runner started)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    with TestClient(create_app(settings)) as c:
        yield c


@pytest.fixture(scope="session")
def demo_dir(tmp_path_factory) -> Path:
    """The demo session written as MetaBase CSV files (24 files; its session.json left out: the API builds one)."""
    from app.pipeline.demo import simulate_session, write_session

    folder = tmp_path_factory.mktemp("demo") / "session"
    write_session(folder, simulate_session(seed=7, side="right", n_cycles=6))
    (folder / "session.json").unlink()
    return folder
