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


def _answers_as(server: RedisServer) -> bool:
    """Whether the server listening on ``server.port`` is ``server``'s own process (its pid in ``INFO``)."""
    import redis

    if server.proc is None or server.proc.poll() is not None:
        return False
    client = redis.Redis.from_url(server.url, socket_timeout=5)
    try:
        return int(client.info("server")["process_id"]) == server.proc.pid
    except redis.RedisError:
        return False
    finally:
        client.close()


@contextmanager
def running_redis(folder: Path, persistent: bool = False) -> Iterator[RedisServer]:
    """A ``redis-server`` of its own in ``folder`` (skips the test when it is not installed); stopped after.

    The port is free when chosen but bound only when the server starts; the server that answers there must be
    this one (another worker's could have taken the port meanwhile), else it starts again on another port."""
    for _ in range(5):
        try:
            server = RedisServer(folder, persistent=persistent).start()
        except Missing as exc:
            pytest.skip(str(exc))
        if _answers_as(server):
            break
        server.stop()       # lost the free port to another process (a parallel test worker) before binding it
    else:
        raise AssertionError(f"no redis-server of this test came up in {folder}")
    try:
        yield server
    finally:
        server.stop()


__all__ = ["fresh_database", "running_redis"]
