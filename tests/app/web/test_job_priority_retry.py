"""Background work under CPU starvation (issue 16 finding 10h): the jobs' computation, the render and the
upload-check helper processes run at a lower CPU priority than the API, outside its process, and a job whose database connection could not be had in time
(SQLAlchemy's pool ``TimeoutError``, seen under load) waits and runs the same attempt again instead of failing.
The pool-timeout tests run on SQLite and on PostgreSQL (``settings``)."""

from __future__ import annotations

import logging
import os
import threading

import test_job_leases as leases

#: the fixtures and the job-row builder of the lease tests: a server with an uploaded session, its runner stopped
world, stopped, _job = leases.world, leases.stopped, leases._job


def test_helper_processes_run_below_the_api_s_priority():
    from app.pipeline.render import BACKGROUND_NICE, RenderPool
    from app.store.checks import warm_checks

    mine = os.nice(0)
    pool = RenderPool(1, warm=warm_checks)  # as a check helper is made (app.store.checks.CheckPool)
    try:
        assert pool.wait_warm()
        assert pool.submit(os.nice, 0).result(60) == min(19, mine + BACKGROUND_NICE)
    finally:
        pool.shutdown()


def test_a_job_is_computed_in_a_helper_process_below_the_api_s_priority(settings, stopped, monkeypatch):
    """``py-spy record --gil`` of ``chakamo serve`` during ``benchmarks.load``: the job threads' reading,
    processing and rendering held the interpreter's lock for about half of the samples, and every request thread
    queued behind them.  The embedded engine now computes each job in a warm helper process at the background
    priority (:class:`app.jobs.compute.JobProcess`); the job thread only writes to the database.  Here the server
    process' own :func:`app.jobs.compute.compute` refuses to run: the job must still be done."""
    import app.jobs.compute as compute
    from app.jobs.inprocess import ThreadJobRunner
    from app.pipeline.render import BACKGROUND_NICE
    from app.store.models import Job

    client, _, session_id = stopped

    def not_here(*args, **kwargs):
        raise AssertionError("the job was computed in the server process")

    monkeypatch.setattr(compute, "compute", not_here)
    old = client.app.state.runner
    job_id = _job(old.db, session_id)  # queued before the start: the runner hands it over at once
    runner = ThreadJobRunner(old.db, old.store, old.tmp_root, workers=1, render_processes=1)
    runner.start()
    try:
        (helper,) = runner.helpers
        assert helper.wait_warm()
        assert os.getpriority(os.PRIO_PROCESS, helper.pid) == min(19, os.nice(0) + BACKGROUND_NICE)
        status, log_lines = None, []
        for _ in range(1200):
            with old.db.session() as s:
                job = s.get(Job, job_id)
                status, log_lines = job.status, list(job.log)
            if status in ("done", "failed"):
                break
            threading.Event().wait(0.25)
        assert status == "done", log_lines
        assert any("orientation thigh" in line for line in log_lines)  # the helper's progress, relayed
    finally:
        runner.shutdown()


def _tight_pool(settings):
    """The server's database with a pool of one connection that waits 0.3 s for it (SQLite's pragmas kept)."""
    from sqlalchemy import create_engine, event
    from sqlalchemy.orm import sessionmaker

    from app.store.database import Database, _sqlite_pragmas

    db = Database(settings.db_url)
    db.engine.dispose()
    sqlite = db.engine.url.get_backend_name() == "sqlite"
    db.engine = create_engine(db.engine.url, pool_size=1, max_overflow=0, pool_timeout=0.3,
                              connect_args={"check_same_thread": False, "timeout": 15} if sqlite else {})
    if sqlite:
        event.listen(db.engine, "connect", _sqlite_pragmas)
    db.sessions = sessionmaker(db.engine, expire_on_commit=False)
    return db


def _runner(client, db):
    from app.jobs.inprocess import ThreadJobRunner

    old = client.app.state.runner
    runner = ThreadJobRunner(db, old.store, old.tmp_root, workers=1)
    runner.RETRY_S = 0.2
    return runner


def test_a_job_waits_for_a_connection_instead_of_failing(settings, stopped, caplog):
    """Every connection busy when the job starts (the test holds the only one for a while): before, the claim's
    pool ``TimeoutError`` escaped the job path and the job stayed queued, handed to nobody, until a restart;
    now the worker waits and runs it, on its first attempt."""
    from app.store.models import Job

    client, _, session_id = stopped
    db = _tight_pool(settings)
    job_id = _job(db, session_id, status="queued")
    held = db.engine.connect()
    retried = threading.Event()

    class _OnRetry(logging.Handler):
        def emit(self, record):
            if "running it again" in record.getMessage():
                retried.set()

    def give_back():  # once the job has met the busy pool (not after a fixed time: a loaded machine may be slower)
        retried.wait(60)
        held.close()

    on_retry = _OnRetry()
    logging.getLogger("chakamo.jobs").addHandler(on_retry)
    threading.Thread(target=give_back, daemon=True).start()
    try:
        with caplog.at_level(logging.WARNING, logger="chakamo.jobs"):
            assert _runner(client, db).run(job_id) == "done"
    finally:
        logging.getLogger("chakamo.jobs").removeHandler(on_retry)
        retried.set()
    assert "running it again" in caplog.text
    with db.session() as s:
        job = s.get(Job, job_id)
        assert (job.status, job.attempts) == ("done", 1) and job.analysis_id is not None
    db.dispose()


def test_a_job_cut_short_by_a_pool_timeout_mid_way_runs_again_not_failed(settings, stopped, caplog):
    """Once the job runs, another thread takes the only connection and holds it 1.5 s: the job's next write
    times out mid-way.  Before, that failed the job ("internal error"); now the same attempt runs again."""
    from sqlalchemy import event

    from app.store.models import Job

    client, _, session_id = stopped
    db = _tight_pool(settings)
    job_id = _job(db, session_id, status="queued")
    started, done = threading.Event(), threading.Event()

    def on_checkout(*_):
        if threading.current_thread().name == "job-under-test":
            started.set()

    def hold():  # waits for the job's connection to come back, then keeps it 1.5 s
        started.wait(60)
        while not done.is_set():
            try:
                conn = db.engine.connect()
            except Exception:  # noqa: BLE001 — the pool's TimeoutError: the job has it; try again
                continue
            done.wait(1.5)
            conn.close()
            return

    event.listen(db.engine, "checkout", on_checkout)
    holder = threading.Thread(target=hold)
    holder.start()
    out = {}
    worker = threading.Thread(target=lambda: out.setdefault("r", _runner(client, db).run(job_id)),
                              name="job-under-test")
    with caplog.at_level(logging.WARNING, logger="chakamo.jobs"):
        worker.start()
        worker.join(600)
    done.set()
    holder.join()
    assert out["r"] == "done", caplog.text
    assert "running it again" in caplog.text
    with db.session() as s:
        job = s.get(Job, job_id)
        assert (job.status, job.attempts) == ("done", 1) and job.analysis_id is not None
    db.dispose()

