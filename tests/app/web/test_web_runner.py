"""The embedded job runner: one per database (a second server refuses to start), a crashed server's
leftovers are cleared at start-up, an unexpected error reaches the job row as a sentence with a reference
(the traceback only in the server log), and concurrent jobs storing identical artefacts both finish."""

from __future__ import annotations

import logging
import threading

import pytest

from web_helpers import clinic_token, demo_files, new_session, wait_job


def _runner_pair(url, tmp_path):
    from app.store.database import Database
    from app.jobs.inprocess import ThreadJobRunner
    from app.store.blobs import BlobStore

    db = Database(url)
    db.migrate()
    return db, [ThreadJobRunner(db, BlobStore(tmp_path / "blobs"), tmp_path / "tmp", workers=1) for _ in range(2)]


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_a_second_runner_on_the_same_database_is_refused(tmp_path, backend, request):
    from app.jobs.inprocess import RunnerLocked

    url = f"sqlite:///{tmp_path}/r.db" if backend == "sqlite" else request.getfixturevalue("pg_url")
    db, (first, second) = _runner_pair(url, tmp_path)
    first.start()
    try:
        with pytest.raises(RunnerLocked, match="Another ChakaMo server is already running the jobs"):
            second.start()
    finally:
        assert first.shutdown() is True  # idle: every thread stopped
    second.start()  # the first one has gone: the lock is free
    assert second.shutdown() is True
    db.dispose()


def test_a_second_app_on_the_same_data_dir_does_not_start(settings):
    from fastapi.testclient import TestClient

    from app.jobs.inprocess import RunnerLocked
    from app.web.main import create_app

    with TestClient(create_app(settings)) as c:
        assert c.get("/healthz").status_code == 200
        with pytest.raises(RunnerLocked), TestClient(create_app(settings)):
            pass
        assert c.get("/healthz").status_code == 200  # the first one is unaffected


def test_start_up_clears_a_crashed_servers_temporary_files(settings):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    leftover = settings.tmp_dir / "session-3-abcd"
    (leftover / "sub").mkdir(parents=True)
    (leftover / "sub" / "a.csv").write_text("x")
    upload = settings.blob_dir / ".incoming" / "up-xyz"
    upload.parent.mkdir(parents=True)
    upload.write_bytes(b"half an upload")
    other = settings.tmp_dir / "keep-me.txt"  # not ours: stays
    other.write_text("x")
    with TestClient(create_app(settings)) as c:
        assert c.get("/healthz").status_code == 200
    assert not leftover.exists() and not upload.exists() and other.exists()


def test_an_internal_error_shows_a_reference_not_a_traceback(client, settings, demo_dir, caplog):
    """A stored file vanishes before processing: the job fails with a sentence and a reference id; the
    traceback and the server's paths are only in the server log."""
    from app.store.database import Database
    from app.store.models import Recording

    h = clinic_token(settings, "E")
    ro = clinic_token(settings, "E", role="read_only")
    _, sid = new_session(client, h)
    assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir)).status_code == 201
    db = Database(settings.db_url)
    with db.session() as s:
        sha = s.query(Recording).filter_by(session_id=sid).first().sha256
    db.dispose()
    client.app.state.store.path(sha).unlink()
    with caplog.at_level(logging.ERROR, logger="chakamo.jobs"):
        job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={}, headers=h).json()["job_id"], h)
    assert job["status"] == "failed"
    seen = client.get(f"/api/v1/jobs/{job['id']}", headers=ro).json()  # what a read-only caller sees
    text = seen["error"] + " ".join(seen["log"])
    assert "reference" in seen["error"]
    assert "Traceback" not in text and str(settings.data_dir) not in text and "CorruptBlob" not in text
    ref = seen["error"].split("reference ")[1][:8]
    logged = [r for r in caplog.records if ref in r.getMessage()]
    assert logged and logged[0].exc_info is not None  # the details went to the server log


def test_concurrent_jobs_storing_identical_artefacts_both_finish(client, settings, demo_dir):
    """Two jobs of one session run at the same time (the API allows one at a time; a second server or a
    distributed engine may not): their identical artefacts must not collide in the blobs table."""
    from app.store.database import Database
    from app.store.models import Job, KneeSession
    from app.jobs.work import run_job

    h = clinic_token(settings, "P")
    _, sid = new_session(client, h)
    assert client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir)).status_code == 201
    db = Database(settings.db_url)
    with db.session() as s:
        clinic_id = s.get(KneeSession, sid).clinic_id
        jobs = [Job(clinic_id=clinic_id, session_id=sid, filter="chakamo", lang="en", log=[]) for _ in range(2)]
        s.add_all(jobs)
        s.flush()
        ids = [j.id for j in jobs]
    store, tmp = client.app.state.store, settings.tmp_dir
    barrier = threading.Barrier(2)

    def go(job_id):
        barrier.wait()
        run_job(job_id, db, store, tmp)

    threads = [threading.Thread(target=go, args=(i,)) for i in ids]
    for t in threads:
        t.start()
    for t in threads:
        t.join(600)
    with db.session() as s:
        states = [(s.get(Job, i).status, s.get(Job, i).error) for i in ids]
    db.dispose()
    assert states == [("done", None), ("done", None)], states


def test_a_hung_helper_process_is_replaced():
    """A helper process is stuck (a check that never ends): :meth:`RenderPool.restart` stops it and a fresh,
    warm one takes over (the upload checks' helpers, app.store.checks.CheckPool)."""
    import concurrent.futures
    import time
    from concurrent.futures.process import BrokenProcessPool

    from app.pipeline.render import RenderPool
    from helper_processes import ended

    pool = RenderPool(1)
    try:
        assert pool.wait_warm()
        (stuck,) = pool._pool._processes.values()
        hung = pool.submit(time.sleep, 600)  # the only helper is now busy for ten minutes
        pool.restart()
        assert ended(stuck) is not None  # the stuck helper was stopped, not left sleeping beside the new one
        # The abandoned work ends for whoever waits on it, not ten minutes later: cancelled if restart() came before
        # the executor's thread handed it to the process, else failed (BrokenProcessPool) once that thread sees the
        # process gone, a moment after restart() returns on a loaded machine. So wait, as a caller's result() does
        # (concurrent.futures.wait would not wake for a cancelled future: only the executor notifies its waiters).
        try:
            assert isinstance(hung.exception(60), BrokenProcessPool)
        except concurrent.futures.CancelledError:
            pass
        assert pool.wait_warm()  # the replacement is up
        assert stuck.pid not in pool._pool._processes
        assert pool.submit(sum, [1, 2]).result(60) == 3
    finally:
        pool.shutdown()
