"""The distributed engine for real: Redis (``redis-server``), real ``chakamo worker`` subprocesses (Celery,
prefork) and PostgreSQL, with faults a hospital deployment meets — a worker killed mid-job, Redis restarted
empty, PostgreSQL restarted during a run.  Nothing is mocked: the API is the application in-process (its
``CeleryJobRunner`` publishes to the real broker), the workers are separate processes.

Runs when ``redis-server`` and the PostgreSQL server binaries are installed (``.ci/run`` installs both);
short leases (``CHAKAMO_JOB_LEASE_S``) and re-dispatch delays keep the recoveries within seconds.
"""

from __future__ import annotations

import time

import pytest

from benchmarks.live_services import ChakamoProcess, Missing, PostgresServer, RedisServer, chakamo_env, wait_until
from live_fixtures import fresh_database, running_redis
from web_helpers import clinic_token, demo_files, make_settings, new_session, wait_job


FAST = {"CHAKAMO_JOB_LEASE_S": "4", "CHAKAMO_REDISPATCH_S": "3", "CHAKAMO_BROKER_VISIBILITY_TIMEOUT_S": "3600"}


@pytest.fixture(scope="module")
def postgres():
    try:
        server = PostgresServer().start()
    except Missing as exc:
        pytest.skip(str(exc))
    try:
        yield server
    finally:
        server.remove()


@pytest.fixture
def database(postgres):
    """A fresh database on the private server, its URL."""
    with fresh_database(postgres.url) as url:
        yield url


@pytest.fixture
def redis(tmp_path):
    with running_redis(tmp_path / "redis") as server:
        yield server


class Deployment:
    """The API in-process on the celery backend, plus real worker processes started on demand."""

    def __init__(self, tmp_path, database: str, redis: RedisServer, lease_s: float | None = None) -> None:
        self.tmp_path, self.database, self.redis = tmp_path, database, redis
        self.data = tmp_path / "data"
        timing = FAST | ({"CHAKAMO_JOB_LEASE_S": str(lease_s)} if lease_s else {})
        self.env = chakamo_env(self.data, DATABASE_URL=database, CHAKAMO_JOB_BACKEND="celery",
                               CHAKAMO_BROKER_URL=redis.url, **timing)
        self.settings = make_settings(self.data, DATABASE_URL=database, CHAKAMO_JOB_BACKEND="celery",
                                      CHAKAMO_BROKER_URL=redis.url, **timing)
        self.workers: list[ChakamoProcess] = []

    def worker(self, concurrency: int = 1) -> ChakamoProcess:
        w = ChakamoProcess(["worker", "--concurrency", str(concurrency)], self.env,
                           self.tmp_path / f"worker-{len(self.workers)}.log").start()
        self.workers.append(w)
        return w

    def close(self) -> None:
        for w in self.workers:
            w.stop()


@pytest.fixture
def deployment(request, tmp_path, database, redis):
    """The deployment; ``@pytest.mark.lease(S)`` gives its jobs a lease of S seconds instead of FAST's 4 s."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    marker = request.node.get_closest_marker("lease")
    dep = Deployment(tmp_path, database, redis, lease_s=marker.args[0] if marker else None)
    try:
        with TestClient(create_app(dep.settings)) as client:
            dep.client = client
            dep.headers = clinic_token(dep.settings, "Hospital Norte")
            yield dep
    finally:
        dep.close()


def _upload_session(dep, demo_dir, external_id: str) -> int:
    _, session_id = new_session(dep.client, dep.headers, external_id)
    r = dep.client.post(f"/api/v1/sessions/{session_id}/recordings", files=demo_files(demo_dir), headers=dep.headers)
    assert r.status_code == 201 and r.json()["ingestion"]["ok"], r.text
    return session_id


def _process(dep, session_id: int, **body) -> int:
    r = dep.client.post(f"/api/v1/sessions/{session_id}/process", json=body, headers=dep.headers)
    assert r.status_code == 202, r.text
    return r.json()["job_id"]


def _worker_log(dep) -> str:
    return "".join(w.output() for w in dep.workers)


def _analyses(dep, session_id: int) -> int:
    from sqlalchemy import func, select

    from app.store.models import Analysis

    with dep.client.app.state.db.session() as s:  # the API's own database (one engine, not one per look)
        return s.scalar(select(func.count()).select_from(Analysis).where(Analysis.session_id == session_id))


def _stored_files(dep, session_id: int) -> int:
    r = dep.client.get(f"/api/v1/sessions/{session_id}", headers=dep.headers)
    assert r.status_code == 200, r.text
    return len(r.json()["recordings"])


def _artefacts(dep, analysis_id: int) -> dict[tuple[str, str], str]:
    from sqlalchemy import select

    from app.store.models import Artefact

    with dep.client.app.state.db.session() as s:
        return {(a.name, a.lang): a.sha256 for a in s.scalars(select(Artefact).where(Artefact.analysis_id == analysis_id))}


def _job_row(dep, job_id: int):
    from app.store.models import Job

    with dep.client.app.state.db.session() as s:
        job = s.get(Job, job_id)
        s.expunge(job)
        return job


def test_jobs_run_on_celery_workers_and_readyz_sees_the_broker(deployment, demo_dir):
    dep = deployment
    assert dep.client.get("/readyz").json() == {"status": "ready", "backend": "celery", "database": "ok",
                                                "jobs": "ok"}
    dep.worker(concurrency=2)
    session_id = _upload_session(dep, demo_dir, "CEL-1")
    job = wait_job(dep.client, _process(dep, session_id), dep.headers, timeout_s=180)
    assert job["status"] == "done", job
    results = dep.client.get(f"/api/v1/sessions/{session_id}/results", headers=dep.headers).json()
    assert results["cycles"]["detected"] >= 6
    row = _job_row(dep, job["id"])
    assert row.attempts == 1 and row.pipeline_version and row.dispatched_at is not None

    # the same job delivered twice more (a duplicate, a re-dispatch).  Counted from here: on a loaded machine the
    # sweeper may already have re-sent the job while the worker was starting (queue empty, job still queued after
    # CHAKAMO_REDISPATCH_S) — a delivery that found it running or finished, as designed
    finished = _worker_log(dep).count(": 'finished'")
    runner = dep.client.app.state.runner
    assert runner.publish(job["id"]) and runner.publish(job["id"])
    wait_until(lambda: _worker_log(dep).count(": 'finished'") >= finished + 2, 30, "the duplicates delivered",
               every_s=0.2)
    assert _worker_log(dep).count(": 'done'") == 1  # each duplicate found the job finished: it ran once
    assert _job_row(dep, job["id"]).attempts == 1  # not run again
    assert _analyses(dep, session_id) == 1

    dep.redis.stop()
    r = dep.client.get("/readyz")
    assert r.status_code == 503 and r.json()["jobs"].startswith("the job broker is unreachable"), r.json()


def test_a_worker_killed_mid_job_is_retried_and_yields_identical_artefacts(deployment, demo_dir):
    dep = deployment
    session_id = _upload_session(dep, demo_dir, "CEL-KILL")
    first = dep.worker()
    reference = wait_job(dep.client, _process(dep, session_id), dep.headers, timeout_s=180)
    assert reference["status"] == "done", reference
    first.stop()

    victim = dep.worker()
    job_id = _process(dep, session_id)
    wait_until(lambda: dep.client.get(f"/api/v1/jobs/{job_id}", headers=dep.headers).json()["status"] == "running",
               120, "the job running on the worker", every_s=0.02)
    victim.kill()  # the worker and its pool processes die mid-job; the message was not acknowledged
    assert dep.client.get(f"/api/v1/jobs/{job_id}", headers=dep.headers).json()["status"] == "running"

    dep.worker()  # a fresh worker: the lost job is queued again (lease) and delivered again
    job = wait_job(dep.client, job_id, dep.headers, timeout_s=180)
    assert job["status"] == "done", job
    row = _job_row(dep, job_id)
    assert row.attempts == 2, row.log
    assert any("worker lost" in line for line in row.log), row.log
    new, old = _artefacts(dep, job["analysis_id"]), _artefacts(dep, reference["analysis_id"])
    assert len(new) >= 8 and new == old  # byte-identical artefacts (content addresses), nothing missing


def test_redis_restarted_empty_loses_no_upload_and_the_jobs_resume(deployment, demo_dir):
    dep = deployment
    # 1. a job handed to Redis while no worker runs, then Redis restarted with no persistence: the message is gone
    published = _process(dep, _upload_session(dep, demo_dir, "CEL-R0"))
    wait_until(lambda: _job_row(dep, published).dispatched_at is not None, 30, "the job handed to the broker")
    import redis as redis_client

    assert redis_client.Redis.from_url(dep.redis.url).llen("chakamo") == 1  # its message waits in the queue
    dep.redis.stop()
    dep.redis.start()
    assert redis_client.Redis.from_url(dep.redis.url).llen("chakamo") == 0  # and is gone

    # 2. the broker down: uploads and process requests must still be taken
    dep.redis.stop()
    session_ids = [_upload_session(dep, demo_dir, f"CEL-R{i}") for i in (1, 2)]
    job_ids = [published] + [_process(dep, sid) for sid in session_ids]
    assert dep.client.get("/readyz").status_code == 503
    time.sleep(1.0)
    assert all(dep.client.get(f"/api/v1/jobs/{j}", headers=dep.headers).json()["status"] == "queued" for j in job_ids)

    dep.redis.start()  # back, empty again; now a worker: the sweeper sends every job again
    dep.worker()
    jobs = [wait_job(dep.client, j, dep.headers, timeout_s=180) for j in job_ids]
    assert [j["status"] for j in jobs] == ["done", "done", "done"], jobs
    for sid in session_ids:
        assert _stored_files(dep, sid) == len(demo_files(demo_dir))


@pytest.mark.lease(60)  # the outage and the retries' back-off stay inside the lease: the same run resumes
def test_postgresql_restarted_during_a_run_loses_nothing(deployment, demo_dir, postgres):
    dep = deployment
    dep.worker()
    session_id = _upload_session(dep, demo_dir, "CEL-PG")
    job_id = _process(dep, session_id)
    wait_until(lambda: dep.client.get(f"/api/v1/jobs/{job_id}", headers=dep.headers).json()["status"] == "running",
               120, "the job running", every_s=0.02)
    postgres.stop()  # the database goes away mid-job (fast shutdown: every connection is cut)
    time.sleep(2.0)
    r = dep.client.get(f"/api/v1/jobs/{job_id}", headers=dep.headers)
    assert r.status_code == 503 and "try again" in r.json()["detail"], r.text  # honest, and says what to do
    r = dep.client.post(f"/api/v1/sessions/{session_id}/recordings", files=demo_files(demo_dir)[:1],
                        headers=dep.headers)
    assert r.status_code == 503, r.text  # an upload is refused, never acknowledged and then lost
    assert dep.client.get("/readyz").json()["database"] == "unreachable"
    postgres.start()

    job = wait_job(dep.client, job_id, dep.headers, timeout_s=240)
    assert job["status"] == "done", job
    assert "database unreachable; retrying" in _worker_log(dep)  # the outage reached the running job
    assert _job_row(dep, job_id).attempts == 1  # and the retry resumed that run: an outage is not an attempt
    assert dep.client.get(f"/api/v1/sessions/{session_id}/results", headers=dep.headers).status_code == 200
    assert _stored_files(dep, session_id) == len(demo_files(demo_dir))
    # and a new upload after the restart is taken as usual
    assert _upload_session(dep, demo_dir, "CEL-PG-2")
