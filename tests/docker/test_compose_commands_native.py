"""The compose file's own commands, run natively: ``migrate``, then ``serve`` and ``worker`` side by side, on
a fresh PostgreSQL database and a private redis-server, until ``/readyz`` answers 200.

No Docker engine runs here, so this is how CI proves the deployment's commands and environment work: the
commands and variables are read from ``docker/compose.yaml`` and the Dockerfile (never retyped), and only
the host names, the data folder and the listening address are adapted to loopback (``native_run.py``).
Every process is started in its own process group and stopped in a ``finally``; every wait is bounded.
"""

from __future__ import annotations

import json
import subprocess
import time
import urllib.error
import urllib.request

import pytest
from deploy_files import TEST_SECRETS, healthcheck_command, load_compose, load_dockerfile, service_environment
from native_run import (chakamo_argv, chakamo_process, free_port, http_status, loopback_environment, run_healthcheck,
                        wait_for_status, with_option)

pytest.importorskip("yaml")


def _environment(tmp_path, pg_url: str, broker_url: str) -> dict[str, str]:
    compose = load_compose()
    envs = {name: service_environment(compose["services"][name]) for name in ("migrate", "api", "worker")}
    assert envs["migrate"] == envs["api"] == envs["worker"]
    env = loopback_environment(load_dockerfile().final.env(), envs["api"], TEST_SECRETS, database_url=pg_url,
                               broker_url=broker_url, data_dir=tmp_path / "data")
    home = tmp_path / "home"
    home.mkdir()
    env["HOME"] = str(home)   # in the image HOME does not exist: nothing may be written there
    return env


def _migrate(argv: list[str], env: dict[str, str], tmp_path, run: int) -> None:
    log = tmp_path / f"migrate-{run}.log"
    with open(log, "wb") as out:
        done = subprocess.run(argv, env=env, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                              timeout=300)
    assert done.returncode == 0, f"`chakamo migrate` (run {run}) exited {done.returncode}:\n{log.read_text()[-3000:]}"


def _alembic_revision(pg_url: str) -> str | None:
    from sqlalchemy import create_engine, inspect, text

    engine = create_engine(pg_url)
    try:
        with engine.connect() as conn:
            if not inspect(conn).has_table("alembic_version"):
                return None
            return conn.execute(text("SELECT version_num FROM alembic_version")).scalar_one()
    finally:
        engine.dispose()


def _wait_for_worker(broker_url: str, worker, timeout_s: float = 180.0) -> list[dict]:
    """Celery's own remote-control ping over the broker until a worker answers (bounded)."""
    from celery import Celery

    client = Celery("chakamo-docker-test", broker=broker_url)
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            if worker.proc.poll() is not None:
                raise AssertionError(f"the worker exited with status {worker.proc.returncode}:\n{worker.tail()}")
            replies = client.control.ping(timeout=2.0)
            if replies:
                return replies
        raise AssertionError(f"no Celery worker answered a ping within {timeout_s:.0f} s:\n{worker.tail()}")
    finally:
        client.close()


def test_compose_commands_run_natively(tmp_path, pg_url, redis_url):
    compose = load_compose()
    services = compose["services"]
    env = _environment(tmp_path, pg_url, redis_url)
    assert _alembic_revision(pg_url) is None

    migrate = chakamo_argv(services["migrate"]["command"])
    _migrate(migrate, env, tmp_path, run=1)
    revision = _alembic_revision(pg_url)
    assert revision, "`chakamo migrate` exited 0 but the database has no Alembic revision"
    _migrate(migrate, env, tmp_path, run=2)   # compose runs it at every `up`: a no-op the second time
    assert _alembic_revision(pg_url) == revision

    port = free_port()
    serve = with_option(with_option(services["api"]["command"], "--host", "127.0.0.1"), "--port", str(port))
    procs = {}
    try:
        procs["api"] = chakamo_process(serve, env, tmp_path / "api.log")
        procs["worker"] = chakamo_process(services["worker"]["command"], env, tmp_path / "worker.log")
        base = f"http://127.0.0.1:{port}"
        wait_for_status(f"{base}/healthz", procs)
        deadline = time.monotonic() + 120.0
        while (status := http_status(f"{base}/readyz")) != 200 and time.monotonic() < deadline:
            time.sleep(1.0)
        assert status == 200, f"/readyz answered {status}:\n{procs['api'].tail()}"
        assert http_status(f"{base}/healthz") == 200
        # the image's HEALTHCHECK, run as the engine would, says healthy
        health = healthcheck_command(load_dockerfile().final.all("HEALTHCHECK")[-1])
        assert run_healthcheck(health, port) == 0
        replies = _wait_for_worker(redis_url, procs["worker"])
        assert len(replies) == 1, replies       # one `chakamo worker` started, one answers
        for name, p in procs.items():
            assert p.proc.poll() is None, f"{name} exited:\n{p.tail()}"
    finally:
        for p in procs.values():
            p.stop()
    assert not any((tmp_path / "home").iterdir()), sorted(p.name for p in (tmp_path / "home").iterdir())


def test_readyz_answers_503_while_the_broker_is_unreachable(tmp_path, pg_url):
    """The compose health check keeps the api out of service while Redis is down: /readyz says 503 (and
    /healthz still 200: the process is alive)."""
    services = load_compose()["services"]
    env = _environment(tmp_path, pg_url, f"redis://127.0.0.1:{free_port()}/0")    # nothing listens there
    _migrate(chakamo_argv(services["migrate"]["command"]), env, tmp_path, run=1)
    port = free_port()
    serve = with_option(with_option(services["api"]["command"], "--host", "127.0.0.1"), "--port", str(port))
    procs = {}
    try:
        procs["api"] = chakamo_process(serve, env, tmp_path / "api.log")
        wait_for_status(f"http://127.0.0.1:{port}/healthz", procs)
        with pytest.raises(urllib.error.HTTPError) as answer:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/readyz", timeout=10)
        assert answer.value.code == 503
        checks = json.loads(answer.value.read())
        assert checks["database"] == "ok" and checks["jobs"] != "ok", checks   # it is the broker that is down
        assert http_status(f"http://127.0.0.1:{port}/healthz") == 200
        health = healthcheck_command(load_dockerfile().final.all("HEALTHCHECK")[-1])
        assert run_healthcheck(health, port) != 0
    finally:
        for p in procs.values():
            p.stop()
