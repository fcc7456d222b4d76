"""The database and the file store: migrations equal the models, durable settings, Blob rows inserted
without races (SQLite, and PostgreSQL when ``CHAKAMO_TEST_POSTGRES_URL`` is set), a damaged stored file
repaired by storing it again, and files made durable before they are acknowledged."""

from __future__ import annotations

import hashlib
import os
import threading
import time

import pytest

PG = os.environ.get("CHAKAMO_TEST_POSTGRES_URL")


def test_migrations_match_the_models(tmp_path):
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from app.store.database import Database
    from app.store.models import Base

    db = Database(f"sqlite:///{tmp_path}/m.db")
    db.migrate()
    db.migrate()  # idempotent
    with db.engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn, opts={"compare_type": True}), Base.metadata)
        assert diff == [], diff
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert conn.exec_driver_sql("PRAGMA synchronous").scalar() == 2  # FULL: commits survive a power cut
    db.dispose()


def test_upgrade_from_0001_keeps_sessions_and_their_checks(tmp_path):
    """A database of revision 0001 upgrades; its sessions get files_version 0 and their stored check counts
    as made from that version; a session without a check has none."""
    import datetime as dt

    from alembic import command

    from app.store.database import Database, alembic_config
    from app.store.models import Clinic, KneeSession, Patient

    db = Database(f"sqlite:///{tmp_path}/u.db")
    cfg = alembic_config(db.engine)
    command.upgrade(cfg, "0001")
    with db.engine.begin() as conn:
        conn.exec_driver_sql("INSERT INTO clinics (id, name, created_at) VALUES (1, 'C', '2026-01-01')")
        conn.exec_driver_sql("INSERT INTO patients (id, clinic_id, external_id, side, created_at) "
                             "VALUES (1, 1, 'P', 'left', '2026-01-01')")
        conn.exec_driver_sql("INSERT INTO sessions (id, clinic_id, patient_id, date, task, created_at, ingestion) "
                             "VALUES (1, 1, 1, '2026-01-01', 'step_up', '2026-01-01', '{\"ok\": true}')")
        conn.exec_driver_sql("INSERT INTO sessions (id, clinic_id, patient_id, date, task, created_at) "
                             "VALUES (2, 1, 1, '2026-01-02', 'step_up', '2026-01-01')")
    db.migrate()
    with db.session() as s:
        k = s.get(KneeSession, 1)
        assert k.files_version == 0 and k.ingestion_version == 0 and k.ingestion == {"ok": True}
        assert s.get(KneeSession, 2).ingestion_version is None
        assert s.get(Patient, 1).external_id == "P" and s.get(Clinic, 1).name == "C"
        assert k.date == dt.date(2026, 1, 1)
    db.dispose()


def _blob_race(url: str) -> None:
    """Two transactions record the same blob at the same time: both commit, one row remains."""
    from sqlalchemy import func, select

    from app.store.database import Database, ensure_blobs
    from app.store.models import Blob

    db = Database(url)
    db.migrate()
    sha = hashlib.sha256(b"same artefact").hexdigest()
    errors: list[BaseException] = []

    def second() -> None:
        try:
            with db.session() as s2:
                ensure_blobs(s2, [(sha, 13)])
        except BaseException as exc:  # noqa: BLE001 — reported below
            errors.append(exc)

    with db.session() as s1:
        ensure_blobs(s1, [(sha, 13)])  # inserted, not committed yet
        t = threading.Thread(target=second)
        t.start()
        time.sleep(0.2)  # let the second transaction reach its insert (it waits for this one, or finds the row)
    t.join(30)
    assert not t.is_alive() and errors == []
    with db.session() as s:
        assert s.scalar(select(func.count()).select_from(Blob).where(Blob.sha256 == sha)) == 1
    db.dispose()


def test_concurrent_blob_rows_do_not_collide_on_sqlite(tmp_path):
    _blob_race(f"sqlite:///{tmp_path}/b.db")


@pytest.mark.skipif(not PG, reason="CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")
def test_concurrent_blob_rows_do_not_collide_on_postgresql(pg_url):
    _blob_race(pg_url)


def test_a_damaged_stored_file_is_repaired_by_storing_it_again(tmp_path):
    from app.store.blobs import BlobStore, CorruptBlob

    store = BlobStore(tmp_path)
    sha, _ = store.put(b"hello")
    store.path(sha).write_bytes(b"hellO")  # same size, other content
    with pytest.raises(CorruptBlob, match="checksum") as info:
        store.read(sha)
    assert str(tmp_path) not in str(info.value)  # the message names the blob, not where the store is
    assert store.put(b"hello")[0] == sha
    assert store.read(sha) == b"hello"
    assert list(store.incoming.iterdir()) == []


def test_a_stored_file_and_its_folder_are_fsynced_before_it_is_acknowledged(tmp_path, monkeypatch):
    """``os.fsync`` is watched (the real one still runs): the temporary file and the folder of the target."""
    import stat

    from app.store.blobs import BlobStore

    synced: list[str] = []
    real = os.fsync

    def watch(fd):
        synced.append("dir" if stat.S_ISDIR(os.fstat(fd).st_mode) else "file")
        return real(fd)

    monkeypatch.setattr(os, "fsync", watch)
    store = BlobStore(tmp_path)
    store.put(b"durable")
    assert synced == ["file", "dir"]


def test_clearing_unfinished_uploads_can_spare_the_recent_ones(tmp_path):
    """A scaled-out API server at start-up removes only old leftovers: another server's upload in progress stays."""
    import os
    import time

    from app.store.blobs import BlobStore

    store = BlobStore(tmp_path / "blobs")
    old, fresh = store.incoming / "up-old", store.incoming / "up-fresh"
    old.write_bytes(b"x")
    fresh.write_bytes(b"y")
    past = time.time() - 2 * 86400
    os.utime(old, (past, past))
    assert store.clear_incoming(older_than_s=86400) == 1
    assert not old.exists() and fresh.exists()
    assert store.clear_incoming() == 1 and not fresh.exists()  # the embedded server: everything
