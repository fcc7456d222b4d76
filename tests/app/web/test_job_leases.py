"""Leases, the sweeper and cohort reprocessing (``app.jobs.work``, ``app.jobs.reprocess``), on the embedded engine and
both databases: a job whose worker stopped beating is queued again (failed after MAX_ATTEMPTS), a job left
queued is handed over again, a cohort is queued once (idempotent) and the running server picks it up."""

from __future__ import annotations

import datetime as dt

import pytest

from web_helpers import clinic_token, demo_files, new_session, wait_job


def _job(db, session_id: int, **values):
    from app.store.models import Job

    with db.session() as s:
        job = Job(clinic_id=1, session_id=session_id, filter="guo", lang="es", log=[], **values)
        s.add(job)
        s.flush()
        return job.id


@pytest.fixture
def world(client, settings, demo_dir):
    h = clinic_token(settings, "Leases")
    _, session_id = new_session(client, h, "LEASE-1")
    r = client.post(f"/api/v1/sessions/{session_id}/recordings", files=demo_files(demo_dir), headers=h)
    assert r.status_code == 201, r.text
    return client, h, session_id


@pytest.fixture
def stopped(world):
    """The world with its server's job runner stopped: the function under test is called by hand."""
    world[0].app.state.runner.shutdown()
    return world


def test_sweep_requeues_lost_jobs_fails_them_after_max_attempts_and_redispatches_stale_ones(settings, stopped):
    from app.store.database import Database
    from app.store.models import Job, utcnow
    from app.jobs.work import MAX_ATTEMPTS, mark_dispatched, sweep

    client, _, session_id = stopped
    db = Database(settings.db_url)
    old = utcnow() - dt.timedelta(seconds=120)
    lost = _job(db, session_id, status="running", attempts=1, started_at=old, heartbeat_at=old)
    doomed = _job(db, session_id, status="running", attempts=MAX_ATTEMPTS, started_at=old, heartbeat_at=old)
    alive = _job(db, session_id, status="running", attempts=1, started_at=old, heartbeat_at=utcnow())
    stale = _job(db, session_id, status="queued", dispatched_at=old)
    fresh = _job(db, session_id, status="queued", dispatched_at=utcnow())
    never = _job(db, session_id, status="queued")

    due = sweep(db, lease_s=60, redispatch_s=60)
    assert due == sorted([lost, stale, never])  # the lost one is queued again and due at once
    with db.session() as s:
        rows = {j.id: j for j in s.query(Job)}
        assert rows[lost].status == "queued" and "worker lost" in rows[lost].log[-1]
        assert rows[doomed].status == "failed" and f"interrupted {MAX_ATTEMPTS} times" in rows[doomed].error
        assert rows[alive].status == "running"
        assert rows[fresh].status == "queued"
    assert sweep(db, lease_s=60, redispatch_s=None) == sorted([lost, never])  # a broker with a backlog: no re-send
    mark_dispatched(db, due)
    assert sweep(db, lease_s=60, redispatch_s=60) == []  # handed over now: not due again before redispatch_s
    db.dispose()


def test_a_run_taken_over_by_the_sweeper_writes_nothing(settings, stopped):
    """A worker that only looked lost (its lease expired): the sweeper gives its job to a new run; the old run's
    progress, failure and results are refused, so the new run's state stands."""
    from app.store.database import Database
    from app.store.models import Job
    from app.jobs.work import Superseded, _fail, _Progress, claim

    client, _, session_id = stopped
    db = Database(settings.db_url)
    job_id = _job(db, session_id, status="queued")
    first = claim(db, job_id)
    with db.session() as s:  # what sweep() does to a stale run, then a second worker claims it
        s.get(Job, job_id).status = "queued"
    second = claim(db, job_id)
    assert (first, second) == (1, 2)
    with pytest.raises(Superseded):
        _Progress(db, job_id, first)("orientation", 0.5)
    _fail(db, job_id, first, "the old run's failure")
    _Progress(db, job_id, second)("orientation", 0.4)
    with db.session() as s:
        job = s.get(Job, job_id)
        assert (job.status, job.attempts, job.stage, job.error) == ("running", 2, "orientation", None)
    db.dispose()


def test_a_run_cut_short_by_a_database_outage_resumes_without_using_an_attempt(settings, stopped):
    from app.store.database import Database
    from app.store.models import Job
    from app.jobs.work import claim, run_job
    from app.store.blobs import open_storage

    client, _, session_id = stopped
    db = Database(settings.db_url)
    job_id = _job(db, session_id, status="queued")
    assert claim(db, job_id) == 1  # the run the outage cut short: still 'running' under attempt 1
    assert run_job(job_id, db, open_storage(settings), settings.tmp_dir) == "busy"  # a new run may not take it
    assert run_job(job_id, db, open_storage(settings), settings.tmp_dir, resume_attempt=1) == "done"
    with db.session() as s:
        job = s.get(Job, job_id)
        assert (job.status, job.attempts) == ("done", 1) and job.analysis_id is not None
    assert run_job(job_id, db, open_storage(settings), settings.tmp_dir, resume_attempt=1) == "finished"
    db.dispose()


def test_run_job_says_busy_or_finished_for_a_job_it_cannot_claim(settings, stopped):
    from app.store.database import Database
    from app.store.models import utcnow
    from app.jobs.work import run_job
    from app.store.blobs import open_storage

    client, _, session_id = stopped
    db = Database(settings.db_url)
    running = _job(db, session_id, status="running", attempts=1, heartbeat_at=utcnow())
    done = _job(db, session_id, status="done", attempts=1)
    store = open_storage(settings)
    assert run_job(running, db, store, settings.tmp_dir) == "busy"
    assert run_job(done, db, store, settings.tmp_dir) == "finished"
    assert run_job(10_000, db, store, settings.tmp_dir) == "finished"
    db.dispose()


def test_reprocess_queues_a_cohort_once_and_the_running_server_takes_it(settings, world):
    from app.jobs.reprocess import reprocess
    from app.pipeline.service_messages import render_item
    from app.store.errors import NotFound

    client, h, session_id = world
    job = wait_job(client, client.post(f"/api/v1/sessions/{session_id}/process", json={"filter": "guo"},
                                       headers=h).json()["job_id"], h)
    assert job["status"] == "done"
    since = dt.date.today() - dt.timedelta(days=1)

    outcomes, summary = reprocess(settings, filter_name="guo", since=since)
    assert [(o.session_id, o.status) for o in outcomes] == [(session_id, "current")], outcomes
    assert summary == {"code": "jobs.reprocess_none", "params": {}}

    outcomes, summary = reprocess(settings, filter_name="madgwick", since=since, clinic="Leases")
    assert [o.status for o in outcomes] == ["queued"] and "chakamo serve" in render_item(summary)
    assert "`chakamo serve` em execução" in render_item(summary, "pt")
    job = wait_job(client, outcomes[0].job_id, h, timeout_s=120)  # found by the server's sweeper
    assert job["status"] == "done" and job["filter"] == "madgwick", job

    again, _ = reprocess(settings, filter_name="madgwick", since=since)
    assert [o.status for o in again] == ["current"]  # idempotent: nothing new the second time
    forced, _ = reprocess(settings, filter_name="madgwick", since=since, force=True)
    assert [o.status for o in forced] == ["queued"]
    busy, _ = reprocess(settings, filter_name="valenti_cf", since=since, force=True)
    assert [o.status for o in busy] == ["busy"]  # one job per session at a time
    # the note says it in every language (it was English only): the API's own refusal of a busy session
    assert busy[0].note["code"] == "store.busy"
    assert "está a ser processada" in render_item(busy[0].note, "pt") and "processe-a de novo" in \
        render_item(busy[0].note, "pt")
    assert "se está procesando" in render_item(busy[0].note, "es")
    # stored as every message is (service_messages.item): with its English text for older readers
    assert busy[0].note["text"] == render_item(busy[0].note, "en") and "being processed" in busy[0].note["text"]
    assert reprocess(settings, filter_name="guo", since=dt.date.today() + dt.timedelta(days=1))[0] == []
    with pytest.raises(NotFound) as unknown:
        reprocess(settings, filter_name="guo", since=since, clinic="Nowhere")
    assert unknown.value.code == "store.clinic_unknown" and "'Leases'" in str(unknown.value)
    from app.cli.admin import create_token

    with pytest.raises(NotFound) as same:   # one lookup (app.store.accounts.clinic_named) for the operator's commands
        create_token(settings, clinic="Nowhere")
    assert (same.value.code, same.value.params) == (unknown.value.code, unknown.value.params)
    with pytest.raises(ValueError, match="unknown filter"):
        reprocess(settings, filter_name="kalman9000", since=since)


def test_cli_reprocess_and_worker_messages(settings, world, monkeypatch, capsys):
    from app.cli.main import main
    from app.settings import get_settings

    monkeypatch.setenv("CHAKAMO_ENV", "development")
    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(settings.data_dir))
    if settings.database_url:
        monkeypatch.setenv("DATABASE_URL", settings.database_url)
    get_settings.cache_clear()
    try:
        assert main(["reprocess", "--filter", "guo", "--since", "2000-01-01"]) == 0
        out = capsys.readouterr().out
        assert "LEASE-1" in out and "queued" in out and out.strip().splitlines()[-1].startswith("1 sessions: 1 queued")
        # --lang: the table, its notes and the hand-over in that language (the job queued just now is busy, or done)
        assert main(["reprocess", "--filter", "guo", "--since", "2000-01-01", "--lang", "pt"]) == 0
        out = capsys.readouterr().out
        assert ("ocupada" in out or "em dia" in out) and out.strip().splitlines()[-1].startswith("1 sessões: ")
        assert ("está a ser processada" in out or "análise" in out) and "nenhuma tarefa em fila" in out
        assert main(["reprocess", "--filter", "guo", "--since", "2000-01-01", "--clinic", "Nowhere",
                     "--lang", "es"]) == 2
        assert "no hay ninguna clínica llamada 'Nowhere'" in capsys.readouterr().err
        assert main(["worker"]) == 2  # the embedded engine needs no worker: one sentence says what to set
        assert "CHAKAMO_JOB_BACKEND=celery" in capsys.readouterr().err
        with pytest.raises(SystemExit):
            main(["reprocess", "--filter", "guo", "--since", "1st of May"])
        assert "YYYY-MM-DD" in capsys.readouterr().err
        assert main(["migrate"]) == 0 and "schema up to date" in capsys.readouterr().out
    finally:
        get_settings.cache_clear()


def test_readyz_on_the_embedded_engine(client):
    r = client.get("/readyz")
    assert r.status_code == 200 and r.json() == {"status": "ready", "backend": "inprocess", "database": "ok",
                                                 "jobs": "ok"}
    client.app.state.runner.shutdown()
    r = client.get("/readyz")
    assert r.status_code == 503 and r.json()["jobs"] == "the job workers are not running"
