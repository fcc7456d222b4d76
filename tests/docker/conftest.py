"""Fixtures of the deployment tests: a fresh PostgreSQL database and a private redis-server, both on loopback.

The native test runs the compose file's commands on this machine against these two, in place of the
compose file's ``postgres`` and ``redis`` services.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time
import uuid

import pytest
from native_run import free_port


@pytest.fixture
def pg_url():
    """URL of a new empty database on ``CHAKAMO_TEST_POSTGRES_URL``'s server, dropped after the test."""
    server = os.environ.get("CHAKAMO_TEST_POSTGRES_URL")
    if not server:
        pytest.skip("CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")
    from sqlalchemy import create_engine
    from sqlalchemy.engine import make_url

    admin = create_engine(server, isolation_level="AUTOCOMMIT")
    name = f"chakamo_docker_{uuid.uuid4().hex[:12]}"
    with admin.connect() as conn:
        conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    try:
        yield make_url(server).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


@pytest.fixture
def redis_url(tmp_path):
    """``redis://127.0.0.1:PORT/0`` of a redis-server started for this test (append-only file, as in compose),
    in a temporary directory; stopped after the test."""
    binary = shutil.which("redis-server")
    if binary is None:
        pytest.skip("redis-server not installed (apt-get install redis-server)")
    import redis

    port = free_port()
    workdir = tmp_path / "redis"
    workdir.mkdir()
    proc = subprocess.Popen([binary, "--port", str(port), "--bind", "127.0.0.1", "--dir", str(workdir),
                             "--appendonly", "yes", "--save", "", "--daemonize", "no"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"redis://127.0.0.1:{port}/0"
    try:
        client = redis.Redis.from_url(url, socket_timeout=1.0)
        deadline = time.monotonic() + 30.0
        while True:
            try:
                client.ping()
                break
            except redis.ConnectionError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    pytest.fail(f"redis-server on port {port} did not start (exit status {proc.poll()})")
                time.sleep(0.1)
        client.close()
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
