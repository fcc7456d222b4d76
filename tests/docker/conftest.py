"""Fixtures of the deployment tests: a private redis-server on loopback (and ``pg_url``, a fresh PostgreSQL
database, from ``tests/conftest.py``).

The native test runs the compose file's commands on this machine against these two, in place of the
compose file's ``postgres`` and ``redis`` services.
"""

from __future__ import annotations

import pytest
from live_fixtures import running_redis


@pytest.fixture
def redis_url(tmp_path):
    """``redis://127.0.0.1:PORT/0`` of a redis-server started for this test (append-only file, as in compose),
    in a temporary directory; stopped after the test."""
    with running_redis(tmp_path / "redis", persistent=True) as server:
        yield server.url
