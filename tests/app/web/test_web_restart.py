"""A server killed in the middle of a job: the next start resumes the job and finishes it.

The first server runs in a child process (the real app, lifespan and job thread); the test kills it with
SIGKILL as soon as the job row says ``running``, then starts a new app on the same data dir.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

from web_helpers import clinic_token, demo_files, new_session, wait_job

CHILD = textwrap.dedent("""
    import sys, time
    from fastapi.testclient import TestClient
    from app.web.main import create_app
    sid, token = int(sys.argv[1]), sys.argv[2]
    with TestClient(create_app()) as c:
        r = c.post(f"/api/v1/sessions/{sid}/process", json={"lang": "en"}, headers={"Authorization": f"Bearer {token}"})
        print(r.json()["job_id"], flush=True)
        time.sleep(600)
""")


def test_restart_in_the_middle_of_a_job_resumes_it(settings, demo_dir):
    from fastapi.testclient import TestClient

    from app.store.database import Database
    from app.store.models import Job
    from app.web.main import create_app

    h = clinic_token(settings, "R")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
        assert c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=demo_files(demo_dir)).status_code == 201

    env = dict(os.environ, CHAKAMO_ENV="development", CHAKAMO_DATA_DIR=str(settings.data_dir), CHAKAMO_WORKERS="1")
    if settings.database_url:
        env["DATABASE_URL"] = settings.database_url
    token = h["Authorization"].split()[1]
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(sid), token], env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL, text=True)
    db = Database(settings.db_url)
    try:
        job_id = int(child.stdout.readline())
        end = time.monotonic() + 300
        status = None
        while time.monotonic() < end:
            with db.session() as s:
                status = s.get(Job, job_id).status
            if status != "queued":
                break
            time.sleep(0.02)
        assert status == "running", f"the job should be caught running, was {status}"
        child.send_signal(signal.SIGKILL)
        child.wait(30)
        with db.session() as s:
            job = s.get(Job, job_id)
            assert job.status == "running" and job.analysis_id is None  # left behind by the dead server
    finally:
        if child.poll() is None:
            child.kill()
        db.dispose()

    with TestClient(create_app(settings)) as c:  # the restart
        job = wait_job(c, job_id, h)
        assert job["status"] == "done", job
        assert any("interrupted" in line for line in job["log"])
        assert any("attempt 2" in line for line in job["log"])
        assert c.get(f"/api/v1/sessions/{sid}/report.pdf", headers=h).content.startswith(b"%PDF")
        assert len(c.get(f"/api/v1/sessions/{sid}", headers=h).json()["analyses"]) == 1


def test_a_job_interrupted_too_often_is_failed_not_resumed(settings, tmp_path):
    import datetime as dt

    from app.store.database import Database
    from app.store.models import Clinic, Job, KneeSession, Patient
    from app.jobs.inprocess import ThreadJobRunner
    from app.jobs.work import MAX_ATTEMPTS
    from app.store.blobs import BlobStore

    db = Database(settings.db_url)
    db.migrate()
    with db.session() as s:
        c = Clinic(name="X")
        s.add(c)
        s.flush()
        p = Patient(clinic_id=c.id, external_id="X1", side="left")
        s.add(p)
        s.flush()
        k = KneeSession(clinic_id=c.id, patient_id=p.id, date=dt.date(2026, 1, 1))
        s.add(k)
        s.flush()
        s.add(Job(clinic_id=c.id, session_id=k.id, filter="chakamo", status="running", attempts=MAX_ATTEMPTS, log=[]))
    runner = ThreadJobRunner(db, BlobStore(tmp_path / "blobs"), tmp_path / "tmp", workers=1)
    runner.start()
    runner.shutdown()
    with db.session() as s:
        job = s.query(Job).one()
        assert job.status == "failed" and "interrupted 3 times" in job.error
    db.dispose()
