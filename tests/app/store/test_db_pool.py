"""The SQLite database's connection pool (issue 16 finding 10h): writers queued on SQLite's one write lock each
hold a pooled connection while they wait; a plain read (WAL: it never waits for a writer) must still get one.  With
SQLAlchemy's default pool for a SQLite file (5 + 10 connections) 15 such writers left a read waiting for a
connection for 30 s and then failing — what made every read of the embedded server take tens of seconds during
an upload burst (uploads place their files holding the write lock)."""

from __future__ import annotations

import threading

from sqlalchemy import select, text


def test_a_read_gets_a_connection_while_writers_queue_on_the_write_lock(tmp_path):
    from app.store.database import POOL_SIZE, Database
    from app.store.models import Clinic

    db = Database(f"sqlite:///{tmp_path}/p.db")
    db.migrate()
    holder = db.engine.connect()
    holder.exec_driver_sql("BEGIN IMMEDIATE")  # what an upload placing its files holds
    writers, queued = [], threading.Semaphore(0)

    def write(i: int) -> None:
        try:
            conn = db.engine.connect()  # a pooled connection, held while the write waits for the lock
        except Exception:  # noqa: BLE001 — the pool's TimeoutError (before: the pool had 15)
            queued.release()
            return
        with conn:
            queued.release()
            conn.execute(text("INSERT INTO clinics (name, created_at) VALUES (:n, '2026-01-01')"), {"n": f"c{i}"})
            conn.commit()

    try:
        for i in range(POOL_SIZE):
            writers.append(threading.Thread(target=write, args=(i,)))
            writers[-1].start()
        for _ in writers:
            queued.acquire()  # every writer holds its connection and waits for the lock
        with db.session() as s:  # before: no connection left, a TimeoutError after 30 s
            assert s.scalars(select(Clinic.name)).all() == []
    finally:
        holder.rollback()
        holder.close()
        for t in writers:
            t.join()
    with db.session() as s:
        assert len(s.scalars(select(Clinic.name)).all()) == POOL_SIZE
    db.dispose()
