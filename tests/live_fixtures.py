"""Context managers behind the fixtures that need a real server (``tests/conftest.py`` ``pg_url``, the
Celery tests' databases and the Redis servers of the Celery and deployment tests)."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from benchmarks.live_services import Missing, RedisServer


@contextmanager
def fresh_database(server_url: str, prefix: str = "chakamo_test") -> Iterator[str]:
    """The URL of a new empty database on the PostgreSQL server of ``server_url``; dropped afterwards."""
    from sqlalchemy import create_engine
    from sqlalchemy.engine import make_url
    from sqlalchemy.pool import NullPool

    # no pool: a test may restart the server meanwhile, and the drop must not reuse a connection it cut
    admin = create_engine(server_url, isolation_level="AUTOCOMMIT", poolclass=NullPool)
    name = f"{prefix}_{uuid.uuid4().hex[:12]}"
    with admin.connect() as conn:
        conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    try:
        yield make_url(server_url).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


@contextmanager
def running_redis(folder: Path, persistent: bool = False) -> Iterator[RedisServer]:
    """A ``redis-server`` of its own in ``folder`` (skips the test when it is not installed); stopped after."""
    try:
        server = RedisServer(folder, persistent=persistent).start()
    except Missing as exc:
        pytest.skip(str(exc))
    try:
        yield server
    finally:
        server.stop()


__all__ = ["fresh_database", "running_redis"]
