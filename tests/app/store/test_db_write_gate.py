"""SQLite's one write lock, queued first come first served inside the server process (issue 16 finding 10h).

Before, a writer that found the lock taken slept in SQLite's busy handler (1, 2, 5 … then 100 ms steps) and
tried again: a writer waiting long retried only every 100 ms while newcomers slipped in, and every waiter held a
pooled connection meanwhile.  ``py-spy dump`` of ``chakamo serve`` at the start of ``benchmarks.load``'s upload
burst found 34 request threads inside SQLite's ``execute``, 25 of them reads whose audit row was being written by
their commit.  Now the writers of one database file wait at :class:`app.store.database.WriteGate`, and the one
that has waited longest is woken as soon as the one before commits."""

from __future__ import annotations

import threading

import pytest
from sqlalchemy import text
from store_world import wait_for


@pytest.fixture
def db(tmp_path):
    from app.store.database import Database

    database = Database(f"sqlite:///{tmp_path}/w.db")
    with database.engine.begin() as conn:
        conn.execute(text("CREATE TABLE t (x INTEGER)"))
    yield database
    database.dispose()


def _writer(db, i: int, order: list[int]) -> threading.Thread:
    def write() -> None:
        with db.session() as s:
            s.execute(text("INSERT INTO t VALUES (:i)"), {"i": i})
            order.append(i)

    t = threading.Thread(target=write)
    t.start()
    return t


def test_queued_writers_are_woken_in_the_order_they_came(db, tmp_path):
    from app.store.database import write_gate

    gate = write_gate(str(tmp_path / "w.db"))
    holder = db.sessions()
    holder.execute(text("INSERT INTO t VALUES (0)"))  # a write transaction open: the gate is held
    order: list[int] = []
    threads = []
    try:
        for i in range(1, 6):
            threads.append(_writer(db, i, order))
            # each writer queues at the gate (before: it slept in SQLite's busy handler, invisible here)
            wait_for(lambda n=i: gate.waiting == n, f"writer {i} queued at the gate")
        assert order == []
    finally:
        holder.commit()
        holder.close()
    for t in threads:
        t.join(30)
    assert order == [1, 2, 3, 4, 5]  # the longest waiter woken first (before: whoever's sleep ended first)
    assert gate.waiting == 0
    with db.session() as s:
        assert s.scalar(text("SELECT count(*) FROM t")) == 6


def test_the_gate_is_given_back_on_rollback_and_close_and_not_taken_by_reads(db, tmp_path):
    from app.store.database import write_gate

    gate = write_gate(str(tmp_path / "w.db"))
    s = db.sessions()
    s.execute(text("SELECT count(*) FROM t"))  # a read takes nothing
    assert not gate._held
    s.execute(text("INSERT INTO t VALUES (1)"))
    assert gate._held
    s.rollback()
    assert not gate._held
    s.execute(text("UPDATE t SET x = 2"))
    s.close()  # closed without a commit: rolled back, the gate given back
    assert not gate._held
    order: list[int] = []
    _writer(db, 7, order).join(30)
    assert order == [7]


def test_every_engine_on_one_file_shares_its_gate(db, tmp_path):
    """The server opens a second engine on its database (the webhook sender): both must queue at one gate, or
    their writers would meet in SQLite's busy handler again."""
    from app.store.database import Database, write_gate

    other = Database(f"sqlite:///{tmp_path}/w.db")
    gate = write_gate(str(tmp_path / "w.db"))
    holder = db.sessions()
    holder.execute(text("INSERT INTO t VALUES (1)"))
    order: list[int] = []
    try:
        t = _writer(other, 2, order)
        wait_for(lambda: gate.waiting == 1, "the other engine's writer queued at the same gate")
    finally:
        holder.commit()
        holder.close()
    t.join(30)
    assert order == [2]
    other.dispose()


def test_a_writer_that_waits_past_the_timeout_gets_database_is_locked(db, tmp_path, monkeypatch):
    import app.store.database as database
    from sqlalchemy.exc import OperationalError

    monkeypatch.setattr(database, "WRITE_WAIT_S", 0.2)
    gate = database.write_gate(str(tmp_path / "w.db"))
    holder = db.sessions()
    holder.execute(text("INSERT INTO t VALUES (1)"))
    try:
        with pytest.raises(OperationalError, match="database is locked"):  # what SQLite's own timeout says
            with db.session() as s:
                s.execute(text("INSERT INTO t VALUES (2)"))
        assert gate.waiting == 0  # the one that gave up left the queue
    finally:
        holder.commit()
        holder.close()
    assert not gate._held


def test_a_connection_collected_inside_the_gate_s_own_lock_gives_the_gate_back(tmp_path):
    """An unclosed writer's connection in a reference cycle gives the gate back from its finaliser, which a
    garbage-collection pass runs wherever it starts — here in a thread that is inside the gate's critical section
    (any allocation in :meth:`WriteGate.acquire` / :meth:`~WriteGate.release` may start one).  With a plain lock
    that thread deadlocked on itself and no writer got the gate again."""
    import gc
    import sqlite3

    from app.store.database import GatedConnection, write_gate

    path = tmp_path / "cycle.db"
    conn = sqlite3.connect(path, factory=GatedConnection, check_same_thread=False)
    conn.execute("CREATE TABLE t (x INTEGER)")
    conn.commit()
    gate = write_gate(str(path))
    conn.cursor().execute("INSERT INTO t VALUES (1)")
    assert gate._held
    cycle = [conn]
    cycle.append(cycle)
    del conn, cycle

    def collect_inside_the_gate():
        with gate._cond:
            gc.collect()

    t = threading.Thread(target=collect_inside_the_gate, daemon=True)
    t.start()
    t.join(60)
    assert not t.is_alive(), "the collecting thread deadlocked on the gate's own lock"
    took = []
    w = threading.Thread(target=lambda: took.append(gate.acquire(5.0)), daemon=True)
    w.start()
    w.join(60)
    assert took == [True]
    gate.release()


def test_a_write_after_a_comment_takes_the_gate_and_a_statement_that_fails_to_prepare_gives_it_back(tmp_path):
    """pysqlite skips leading comments before it decides a statement writes (it then opens the transaction): the
    gate must be taken there too.  A write that cannot even be prepared opens no transaction: the gate goes back
    at once, not at the connection's next commit."""
    import sqlite3

    from app.store.database import GatedConnection, write_gate

    path = tmp_path / "comments.db"
    conn = sqlite3.connect(path, factory=GatedConnection, check_same_thread=False)
    try:
        conn.execute("CREATE TABLE t (x INTEGER)")
        conn.commit()
        gate = write_gate(str(path))
        for sql in ("/* audit */ INSERT INTO t VALUES (1)", "-- audit\nUPDATE t SET x = 2"):
            conn.cursor().execute(sql)
            assert conn.in_transaction and gate._held, sql
            conn.commit()
            assert not gate._held
        with pytest.raises(sqlite3.OperationalError):
            conn.cursor().execute("INSERT INTO no_such_table VALUES (1)")
        assert not conn.in_transaction and not gate._held
    finally:
        conn.close()


def test_executemany_takes_the_gate_and_commit_gives_it_back(tmp_path):
    """A write through a cursor's ``executemany`` (SQLAlchemy's path for one statement over many rows, e.g.
    :func:`app.store.checks.save_ingestion`'s devices) opens a write transaction like ``execute``: it holds the
    gate until the commit."""
    import sqlite3

    from app.store.database import GatedConnection, write_gate

    path = tmp_path / "many.db"
    conn = sqlite3.connect(path, factory=GatedConnection, check_same_thread=False)
    try:
        conn.cursor().execute("CREATE TABLE t (x INTEGER)")
        gate = write_gate(str(path))
        conn.cursor().executemany("INSERT INTO t VALUES (?)", [(1,), (2,)])
        assert conn.in_transaction and gate._held
        conn.commit()
        assert not gate._held
        assert conn.cursor().execute("SELECT count(*) FROM t").fetchone() == (2,)
    finally:
        conn.close()


def test_sqlite_s_own_busy_wait_is_the_gate_s_bound(tmp_path, monkeypatch):
    """Review finding: the connect timeout followed WRITE_WAIT_S but a PRAGMA every pooled connection ran still set
    15 s, overriding it; the PRAGMA is gone (pysqlite's ``timeout`` is SQLite's busy timeout): one definition."""
    import app.store.database as database

    monkeypatch.setattr(database, "WRITE_WAIT_S", 2.5)
    engine = database.make_engine(f"sqlite:///{tmp_path / 'b.db'}")
    try:
        with engine.connect() as conn:
            assert conn.execute(text("PRAGMA busy_timeout")).scalar() == 2500
    finally:
        engine.dispose()


def test_a_writer_going_first_is_woken_before_the_writers_queued_earlier(db, tmp_path):
    """The group commit's batch (the audit rows of every read waiting to answer) goes ahead of uploads and
    creations queued at the lock: ``py-spy dump`` in a burst found 11–26 reads waiting behind 14 such writers."""
    from app.store.database import write_gate, writes_first

    gate = write_gate(str(tmp_path / "w.db"))
    holder = db.sessions()
    holder.execute(text("INSERT INTO t VALUES (0)"))
    order: list[int] = []
    threads = []

    def first_writer() -> None:
        with writes_first(), db.session() as s:
            s.execute(text("INSERT INTO t VALUES (99)"))
            order.append(99)

    try:
        for i in (1, 2):
            threads.append(_writer(db, i, order))
            wait_for(lambda n=i: gate.waiting == n, f"writer {i} queued at the gate")
        threads.append(threading.Thread(target=first_writer))
        threads[-1].start()
        wait_for(lambda: gate.waiting == 3, "the first-going writer queued last")
        threads.append(_writer(db, 3, order))  # arrives after it: waits, the gate is promised
        wait_for(lambda: gate.waiting == 4, "a writer after it queued")
    finally:
        holder.commit()
        holder.close()
    for t in threads:
        t.join(30)
        assert not t.is_alive()
    assert order == [99, 1, 2, 3]
    assert gate.waiting == 0 and not gate._held



def test_a_first_going_writer_interrupted_after_its_wake_up_passes_it_on(tmp_path):
    """A release wakes the first-going writer; if that one is interrupted before it takes the gate, the wake-up
    goes to the next first-going writer (else that one slept its whole wait with the gate free)."""
    from app.store.database import WriteGate

    gate = WriteGate()
    assert gate.acquire(1.0)
    real_wait_for = gate._first.wait_for
    woken = threading.Event()

    def interrupted_wait_for(predicate, timeout):  # the first waiter: woken by the release, then interrupted
        real_wait_for(lambda: woken.is_set() or predicate(), timeout)
        raise KeyboardInterrupt

    got: list[str] = []

    def f1() -> None:
        try:
            gate._first.wait_for = interrupted_wait_for
            gate.acquire(60, first=True)
        except KeyboardInterrupt:
            got.append("f1 interrupted")

    t1 = threading.Thread(target=f1)
    t1.start()
    wait_for(lambda: gate.waiting == 1, "the interrupted writer waiting")
    gate._first.wait_for = real_wait_for  # the second writer waits as usual
    t2 = threading.Thread(target=lambda: got.append("f2" if gate.acquire(60, first=True) else "f2 timed out"))
    t2.start()
    wait_for(lambda: gate.waiting == 2, "a second first-going writer waiting")
    woken.set()
    gate.release()
    t1.join(30)
    t2.join(30)  # 60 s of sleep with the gate free, before the fix
    assert not t2.is_alive() and got == ["f1 interrupted", "f2"]
