"""The housekeeping (erasure sweep, retention policy) runs in the API servers whatever the job backend, one server
at a time (app/web/housekeeping.py; issue 16, finding 8: with ``CHAKAMO_JOB_BACKEND=celery`` it never ran, so a
configured ``CHAKAMO_RETENTION_DAYS`` erased nothing).

Real components: two applications on the Celery backend with a real ``redis-server`` broker, on the embedded
SQLite file and on a fresh database of a real PostgreSQL server (``CHAKAMO_TEST_POSTGRES_URL``; skipped when
unset), sharing one data folder as the servers of a scaled-out deployment share their volume.  The session is
made old by moving its dates back in the database (the policy reads them against the real clock).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import time

import pytest

from live_fixtures import running_redis
from web_helpers import clinic_token, make_settings

DATA = b"acc_x (g),acc_y (g),acc_z (g)\n0.0,0.0,1.0\n# housekeeping\n"


@pytest.fixture
def redis(tmp_path):
    with running_redis(tmp_path / "redis") as server:
        yield server


@pytest.fixture
def fast(monkeypatch):
    """Housekeeping every half second, the lock tried every 0.2 s (an hour and a minute in production)."""
    from app.web.housekeeping import Housekeeper

    monkeypatch.setattr(Housekeeper, "EVERY_S", 0.5)
    monkeypatch.setattr(Housekeeper, "TRY_EVERY_S", 0.2)


def _old_session(client, headers, external_id: str, days: int) -> tuple[int, str]:
    """A session with one recording whose every date is ``days`` days back; its id and its blob's sha256."""
    from sqlalchemy import update

    from app.store.models import KneeSession, Recording

    pid = client.post("/api/v1/patients", json={"external_id": external_id, "side": "right"},
                      headers=headers).json()["id"]
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=headers).json()["id"]
    data = DATA + external_id.encode()
    r = client.post(f"/api/v1/sessions/{sid}/recordings", files=[("files", ("thigh_task.csv", data, "text/csv"))],
                    headers=headers)
    assert r.status_code == 201, r.text
    then = dt.datetime.now(dt.timezone.utc) - dt.timedelta(days=days)
    with client.app.state.db.session() as db:
        db.execute(update(KneeSession).where(KneeSession.id == sid).values(created_at=then, updated_at=then))
        db.execute(update(Recording).where(Recording.session_id == sid).values(uploaded_at=then))
        db.commit()
    return sid, hashlib.sha256(data).hexdigest()


def _wait_erased(client, headers, sid: int, blob, timeout_s: float = 60.0) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if client.get(f"/api/v1/sessions/{sid}", headers=headers).status_code == 404 and not blob.exists():
            return
        time.sleep(0.1)
    raise AssertionError(f"session {sid} older than CHAKAMO_RETENTION_DAYS not erased within {timeout_s} s")


def _retention_events(client) -> list[tuple[str, int | None]]:
    from sqlalchemy import select

    from app.store.models import AuditEvent

    with client.app.state.db.session() as db:
        return [(e.actor, e.session_id) for e in db.scalars(select(AuditEvent).where(AuditEvent.action == "delete"))]


def test_servers_on_the_celery_backend_apply_the_retention_policy_one_at_a_time(tmp_path, database_url, redis,
                                                                                fast):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    extra = {"DATABASE_URL": database_url} if database_url else {}
    settings = make_settings(tmp_path / "data", CHAKAMO_JOB_BACKEND="celery", CHAKAMO_BROKER_URL=redis.url,
                             CHAKAMO_RETENTION_DAYS=30, **extra)
    headers = clinic_token(settings, "Ret")
    running: list[TestClient] = []
    try:
        for _ in range(2):  # two API servers of one deployment
            running.append(TestClient(create_app(settings)).__enter__())
        a, b = running
        recent, _ = _old_session(a, headers, "RECENT", days=29)
        sid, sha = _old_session(b, headers, "OLD", days=31)
        _wait_erased(b, headers, sid, settings.blob_dir / sha[:2] / sha[2:])
        assert a.get(f"/api/v1/sessions/{recent}", headers=headers).status_code == 200  # not due yet
        assert _retention_events(a) == [("retention policy (30 days)", sid)]

        # one server housekeeps (at start, then every half second); the other never did
        time.sleep(1.0)
        runs = [c.app.state.housekeeper.runs for c in running]
        assert min(runs) == 0 and max(runs) >= 2, runs
        leader, other = (a, b) if runs[0] else (b, a)
        assert not other.app.state.housekeeper.lock.held()  # not taken: answered without its connection

        # the server that housekeeps stops: the other takes over within a try and erases the next session due
        running.remove(leader)
        leader.__exit__(None, None, None)
        sid2, sha2 = _old_session(other, headers, "OLD-2", days=31)
        _wait_erased(other, headers, sid2, settings.blob_dir / sha2[:2] / sha2[2:])
        # it took the lock (it runs only while holding it); its held() is not asked from this thread: on PostgreSQL it
        # queries the lock's connection, which the housekeeping thread uses
        assert other.app.state.housekeeper.runs >= 1
    finally:
        for c in reversed(running):
            c.__exit__(None, None, None)


def test_a_housekeeping_lock_lost_with_its_connection_passes_to_another_server(pg_url):
    """PostgreSQL: the lock is a session-level advisory lock on a connection of its own; when the database cuts that
    connection (a restart, an idle timeout) its holder sees it has lost the lock and another server can take it.
    The job runner's lock is another key: a server holds both."""
    from sqlalchemy import text

    from app.jobs.inprocess import RunnerLock, RunnerLocked
    from app.store.database import Database
    from app.web.housekeeping import HOUSEKEEPING_LOCK_KEY

    db = Database(pg_url)
    first, second = (RunnerLock(db, key=HOUSEKEEPING_LOCK_KEY, name="housekeeping") for _ in range(2))
    runner = RunnerLock(db)
    try:
        first.acquire()
        runner.acquire()
        with pytest.raises(RunnerLocked):
            second.acquire()
        assert first.held() and not second.held()
        with db.engine.connect() as conn:
            cut = conn.scalar(text("SELECT count(pg_terminate_backend(pid)) FROM pg_locks WHERE locktype = 'advisory' "
                                   "AND classid::bigint = :hi AND objid::bigint = :lo"),
                              {"hi": HOUSEKEEPING_LOCK_KEY >> 32, "lo": HOUSEKEEPING_LOCK_KEY & 0xFFFFFFFF})
        assert cut == 1
        deadline = time.monotonic() + 10.0
        while first.held() and time.monotonic() < deadline:  # the backend exits a moment after the signal
            time.sleep(0.05)
        assert not first.held()
        second.acquire()
        assert second.held() and runner.held()
    finally:
        for lock in (first, second, runner):
            lock.release()
        db.dispose()


def test_a_housekeeping_run_holds_none_of_the_requests_connections(tmp_path, monkeypatch):
    """A run uses an engine of the housekeeper's own: while it is inside a transaction, the requests' pool has
    nothing checked out (the run at start-up once held one of them: a half-sent-upload test counted it)."""
    import threading

    from fastapi.testclient import TestClient
    from sqlalchemy import func, select

    from app.store.models import KneeSession
    from app.web import housekeeping
    from app.web.main import create_app

    inside, leave = threading.Event(), threading.Event()

    def run(settings, database, store, now=None):  # a run's transaction, held open until the test has looked
        with database.session() as db:
            db.scalar(select(func.count()).select_from(KneeSession))
            inside.set()
            leave.wait(30)

    monkeypatch.setattr(housekeeping, "housekeeping", run)
    with TestClient(create_app(make_settings(tmp_path / "data"))) as client:
        try:
            assert inside.wait(30)
            assert client.app.state.db.engine.pool.checkedout() == 0
        finally:
            leave.set()
