"""Group commit of the reads' audit events (issue 16: the 20-clinician upload burst).

Every audited read was a one-row write transaction; on SQLite they all queued for the file's one write lock, each
holding it across its commit's flush to disk.  Now the events that are all their transaction writes go to
:class:`app.store.group_commit.GroupCommit`: those that arrive while one batch is written go in the next, one
transaction for all of them.  A transaction that writes anything else keeps its event in its own commit (the
event and the data commit together or not at all), and a refused event fails its own caller only."""

from __future__ import annotations

import threading

import pytest
from sqlalchemy import event, func, select, text
from store_world import wait_for


@pytest.fixture
def db(tmp_path):
    from app.store.database import Database

    database = Database(f"sqlite:///{tmp_path}/g.db")
    database.migrate()
    with database.engine.begin() as conn:
        conn.execute(text("CREATE TABLE other (x INTEGER)"))
    yield database
    database.dispose()


def _event(actor: str):
    from app.store.models import AuditEvent

    return AuditEvent(clinic_id=None, actor_kind="anonymous", actor=actor, action="view", resource="GET /x",
                      client="127.0.0.1")


def _read(db, actor: str, errors: dict) -> threading.Thread:
    """A read's transaction: a query, then its audit event queued for the commit (as ``app.web.audit.record``)."""
    from app.store.audit import add_event

    def run() -> None:
        try:
            with db.session() as s:
                s.execute(text("SELECT count(*) FROM other"))
                add_event(s, at_commit=True, clinic_id=None, actor_kind="anonymous", actor=actor, action="view",
                          resource="GET /x", client="127.0.0.1")
        except Exception as exc:  # noqa: BLE001 — the test looks at it
            errors[actor] = exc

    t = threading.Thread(target=run)
    t.start()
    return t


def _audit_inserts(db) -> list[str]:
    """The stack's name of each INSERT into audit_events from now on (``group`` or ``own``)."""
    import traceback

    seen: list[str] = []

    def on_execute(conn, cursor, statement, *args):
        if statement.lstrip().upper().startswith("INSERT INTO AUDIT_EVENTS"):
            grouped = any(f.filename.endswith(("store/group_commit.py", "store\\group_commit.py")) for f in traceback.extract_stack())
            seen.append("group" if grouped else "own")

    event.listen(db.engine, "before_cursor_execute", on_execute)
    return seen


def _actors(db) -> list[str]:
    from app.store.models import AuditEvent

    with db.session() as s:
        return sorted(s.scalars(select(AuditEvent.actor)))


def _leader_waits_at_the_lock(db) -> None:
    """Wait until a leader has taken its batch and waits for the write lock (the gate's queue holds it)."""
    from app.store.database import write_gate

    gate = write_gate(db.engine.url.database)
    wait_for(lambda: gate.waiting == 1, "a leader waiting for the write lock")


def _hold_the_write_lock(db):
    """A writer that holds the database's write lock until ``release()`` (as an upload's transaction would)."""
    holder = db.sessions()
    holder.execute(text("INSERT INTO other VALUES (1)"))
    return holder


@pytest.fixture
def patient_lock(monkeypatch):
    """The write lock's wait made longer than any wait of these tests (a slow machine must not give up first)."""
    import app.store.database as database

    monkeypatch.setattr(database, "WRITE_WAIT_S", 120.0)


def _join(threads) -> None:
    for t in threads:
        t.join(60)
        assert not t.is_alive(), "a read still waiting"


def test_events_that_arrive_while_one_is_written_are_written_together(db, patient_lock):
    from app.store.models import AuditEvent

    inserts = _audit_inserts(db)
    holder = _hold_the_write_lock(db)
    errors: dict = {}
    threads = [_read(db, "first", errors)]  # leads; waits at the write lock
    _leader_waits_at_the_lock(db)
    threads += [_read(db, f"r{i}", errors) for i in range(9)]
    wait_for(lambda: len(db.group._queue) == 9, "nine more events queued behind it")
    from app.store.models import utcnow

    queued_by = utcnow()
    holder.commit()
    holder.close()
    _join(threads)
    assert errors == {}
    assert _actors(db) == sorted(["first"] + [f"r{i}" for i in range(9)])
    assert inserts == ["group", "group"]  # the first alone, then the nine in one statement — not ten transactions
    with db.session() as s:
        ids = list(s.scalars(select(AuditEvent.id).order_by(AuditEvent.id)))
        assert ids == list(range(1, 11)) and s.scalar(select(func.count()).select_from(AuditEvent)) == 10
        # each event's time is when its read added it, not when the group wrote it (after the lock was freed)
        assert all(at <= queued_by for at in s.scalars(select(AuditEvent.at)))


def test_an_event_beside_other_writes_commits_with_them_or_not_at_all(db):
    from app.store.database import add_at_commit

    inserts = _audit_inserts(db)
    with db.session() as s:
        s.execute(text("INSERT INTO other VALUES (7)"))
        add_at_commit(s, _event("with data"))
    assert inserts == ["own"] and _actors(db) == ["with data"]

    with db.engine.begin() as conn:  # a database that refuses audit rows (as a full disk would)
        conn.execute(text("CREATE TRIGGER no_audit BEFORE INSERT ON audit_events "
                          "BEGIN SELECT RAISE(ABORT, 'disk full'); END"))
    with pytest.raises(Exception, match="disk full"):
        with db.session() as s:
            s.execute(text("INSERT INTO other VALUES (8)"))
            add_at_commit(s, _event("refused"))
    with db.session() as s:  # the data went with its event
        assert s.scalar(text("SELECT count(*) FROM other WHERE x = 8")) == 0


def test_a_refused_event_fails_its_own_read_only(db, patient_lock):
    from app.store.group_commit import GroupWriteFailed

    with db.engine.begin() as conn:
        conn.execute(text("CREATE TRIGGER no_bad BEFORE INSERT ON audit_events WHEN NEW.actor LIKE 'bad%' "
                          "BEGIN SELECT RAISE(ABORT, 'refused'); END"))
    holder = _hold_the_write_lock(db)
    errors: dict = {}
    threads = [_read(db, "lead", errors)]
    _leader_waits_at_the_lock(db)
    threads += [_read(db, actor, errors) for actor in ("good1", "bad", "good2")]
    wait_for(lambda: len(db.group._queue) == 3, "three events queued behind it")
    holder.commit()
    holder.close()
    _join(threads)
    assert set(errors) == {"bad"} and isinstance(errors["bad"], GroupWriteFailed)
    assert "refused" in str(errors["bad"].__cause__)
    assert _actors(db) == ["good1", "good2", "lead"]
    assert not db.group._writing and db.group._queue == []  # nobody left waiting


def test_a_read_alone_is_written_at_once(db):
    """No batch to wait for: the leader writes its own event and returns (what a quiet server does)."""
    errors: dict = {}
    _join([_read(db, "alone", errors)])
    assert errors == {} and _actors(db) == ["alone"] and not db.group._writing


def test_a_database_that_cannot_write_fails_the_batch_at_once(db, monkeypatch):
    """Locked past the write wait (or a full disk): every caller of the batch gets the error from one attempt —
    not one more wait per caller, as writing each alone would."""
    from app.store.database import WriteGate
    from app.store.group_commit import GroupWriteFailed

    entered, give_up = [], threading.Event()

    def acquire(self, timeout_s, first=False):  # a write lock that stays taken until the test gives up on it
        entered.append(timeout_s)
        give_up.wait(30)
        return False  # what the gate answers past its wait: "database is locked"

    monkeypatch.setattr(WriteGate, "acquire", acquire)
    inserts = _audit_inserts(db)
    errors: dict = {}
    threads = [_read(db, "lead", errors)]
    wait_for(lambda: len(entered) == 1, "the leader waiting for the write lock")
    threads += [_read(db, f"r{i}", errors) for i in range(3)]
    wait_for(lambda: len(db.group._queue) == 3, "three events queued behind it")
    give_up.set()
    _join(threads)
    assert sorted(errors) == ["lead", "r0", "r1", "r2"]
    assert all(isinstance(e, GroupWriteFailed) and "locked" in str(e.__cause__) for e in errors.values())
    assert inserts == ["group", "group"]  # the three queued failed together (one attempt), not once each
    assert not db.group._writing and db.group._queue == []


def _own(db, write) -> list[str]:
    """Where the event of a transaction that also ran ``write(session)`` was written."""
    from app.store.database import add_at_commit

    inserts = _audit_inserts(db)
    with db.session() as s:
        write(s)
        s.execute(text("SELECT 1"))
        add_at_commit(s, _event("beside a write"))
    return inserts


def test_every_kind_of_write_keeps_the_event_in_its_own_commit(db):
    """The group commit takes an event only when nothing else was written: a flushed row, an autoflushed one, a
    pending one, an ORM ``update()``, a statement on the session's connection, one before a savepoint."""
    from sqlalchemy import update

    from app.store.models import Clinic

    def flushed(s):
        s.add(Clinic(name="A"))
        s.flush()

    def autoflushed(s):
        s.add(Clinic(name="B"))
        s.scalar(select(func.count()).select_from(Clinic))

    def pending(s):
        s.add(Clinic(name="C"))

    def orm_update(s):
        s.execute(update(Clinic).where(Clinic.name == "A").values(name="A2"))

    def on_connection(s):
        s.connection().execute(text("INSERT INTO other VALUES (3)"))

    def before_savepoint(s):
        s.execute(text("INSERT INTO other VALUES (4)"))
        with s.begin_nested():
            s.execute(text("SELECT 1"))

    for write in (flushed, autoflushed, pending, orm_update, on_connection, before_savepoint):
        assert _own(db, write) == ["own"], write.__name__
    assert _own(db, lambda s: s.execute(text("SELECT count(*) FROM other"))) == ["group"]  # a read: grouped


def test_an_interrupted_follower_passes_on_the_lead(db):
    """A caller interrupted while it waits in the queue leaves it; handed the lead, it hands it on — nobody
    behind it waits for ever."""
    from app.store.group_commit import _Caller

    group = db.group
    me = _Caller([])
    with group._lock:  # as if a leader had just handed ``me`` the lead, with another caller queued behind
        behind = _Caller([])
        group._queue[:] = [me, behind]
        group._writing = True
        me.lead = True
    group._abandon(me)
    assert group._queue == [behind] and behind.lead and behind.woken.is_set() and group._writing
    group._abandon(behind)
    assert group._queue == [] and not group._writing


def test_a_follower_interrupted_while_queued_leaves_the_queue(db, patient_lock, monkeypatch):
    """An interruption (KeyboardInterrupt, SystemExit) of a queued caller reaches it as it is and takes it out of the
    queue: the leader's batch and the next callers go on without it."""
    import app.store.group_commit as group_commit

    class Interrupted(threading.Event):
        def wait(self, timeout=None):
            raise KeyboardInterrupt

    holder = _hold_the_write_lock(db)
    errors: dict = {}
    leader = _read(db, "lead", errors)
    _leader_waits_at_the_lock(db)
    real = group_commit._Caller
    monkeypatch.setattr(group_commit, "_Caller", lambda rows: real(rows, woken=Interrupted()))
    with pytest.raises(KeyboardInterrupt):
        db.group.write([_event("interrupted")])
    monkeypatch.setattr(group_commit, "_Caller", real)
    assert db.group._queue == [] and db.group._writing  # the leader still writes its batch
    holder.commit()
    holder.close()
    _join([leader])
    after = _read(db, "after", errors)
    _join([after])
    assert errors == {} and _actors(db) == ["after", "lead"] and not db.group._writing


def test_a_batch_goes_ahead_of_the_writers_waiting_for_the_lock(db, patient_lock):
    """The reads' batch holds every waiting read's answer: it is written before the uploads and creations that
    queued for the write lock earlier (in a burst's first seconds 11–26 reads waited behind 14 of them)."""
    from app.store.database import write_gate

    written: list[str] = []

    def on_execute(conn, cursor, statement, *args):
        words = statement.split()
        if words[:2] == ["INSERT", "INTO"]:
            written.append(words[2])

    event.listen(db.engine, "after_cursor_execute", on_execute)  # run: the gate was taken
    gate = write_gate(db.engine.url.database)
    holder = _hold_the_write_lock(db)
    written.clear()

    def data_writer() -> None:
        with db.session() as s:
            s.execute(text("INSERT INTO other VALUES (2)"))

    errors: dict = {}
    threads = [threading.Thread(target=data_writer)]
    threads[0].start()
    wait_for(lambda: gate.waiting == 1, "a data writer queued at the lock")
    threads.append(_read(db, "read", errors))
    wait_for(lambda: gate.waiting == 2, "the read's batch queued after it")
    holder.commit()
    holder.close()
    _join(threads)
    assert errors == {} and _actors(db) == ["read"]
    assert written == ["audit_events", "other"]  # the batch first, then the writer that queued before it
