"""Files are made durable before the transaction that stores them (issue 16 finding 10h).

On SQLite every writing request waits for the database's one write lock; an upload or a job's store step that
fsynced each file while holding it made a burst of uploads stall every clinician's audited reads.  Now the files
are written and fsynced first (:meth:`app.store.blobs.BlobWriter.seal`) and only renamed under the locks.  The test
records, in order, each ``os.fsync`` (of a regular file or of a folder) and each SQL statement that reserves a blob
row (:func:`app.store.erasure.reserve_blobs`, the point from which the blob's lock — and on SQLite the write lock —
is held): no regular file may be fsynced after the first reservation, in an upload and in a job's store step."""

from __future__ import annotations

import os
import stat

import pytest
from sqlalchemy import event

from web_helpers import clinic_token, demo_files, new_session, wait_job


@pytest.fixture
def sequence(client, monkeypatch):
    """The ordered list of ``file`` / ``dir`` fsyncs and blob ``reserve`` statements made while the test runs."""
    seq: list[str] = []
    real = os.fsync

    def fsync(fd):
        seq.append("dir" if stat.S_ISDIR(os.fstat(fd).st_mode) else "file")
        return real(fd)

    def statement(conn, cursor, sql, params, context, executemany):
        text = " ".join(sql.split()).lower()
        if text.startswith(("insert", "update")) and " blobs " in f" {text.replace('(', ' ')} ":
            seq.append("reserve")

    monkeypatch.setattr(os, "fsync", fsync)
    engine = client.app.state.db.engine
    event.listen(engine, "before_cursor_execute", statement)
    try:
        yield seq
    finally:
        event.remove(engine, "before_cursor_execute", statement)


def _no_file_fsync_after_reserving(seq: list[str], files: int) -> None:
    assert seq.count("file") >= files and "reserve" in seq, seq
    first = seq.index("reserve")
    assert "file" not in seq[first:], seq  # every file fsync came before the locks


def test_upload_and_job_fsync_their_files_before_reserving_blobs(client, settings, demo_dir, sequence):
    h = clinic_token(settings, "Clinic fsync")
    _, sid = new_session(client, h)
    seq = sequence
    seq.clear()
    files = demo_files(demo_dir)
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files)
    assert r.status_code == 201, r.text
    _no_file_fsync_after_reserving(seq, len(files))

    seq.clear()
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "en"}, headers=h)
                   .json()["job_id"], h)
    assert job["status"] == "done", job
    _no_file_fsync_after_reserving(seq, 3)  # results.json, the PDF, the workbooks…


def test_under_the_lock_an_upload_reserves_once_fsyncs_each_folder_once_and_reads_no_stored_file(
        client, settings, demo_dir, sequence, monkeypatch):
    """What an upload does while it holds the blobs' locks (on SQLite the database's one write lock, which the reads'
    audit batches wait for: 260–850 ms per upload of 24 files in the 20-clinician burst) is bounded by the upload,
    not by its number of files: one reserving statement (was one per file), each receiving folder fsynced once, in
    parallel; and an upload of content already stored reads no stored file there (it was verified before)."""
    import app.store.blobs as blobs

    real_hash = blobs._file_sha256
    monkeypatch.setattr(blobs, "_file_sha256", lambda path: sequence.append("read") or real_hash(path))
    h = clinic_token(settings, "Clinic lock work")
    _, first = new_session(client, h)
    _, second = new_session(client, h, external_id="P-2")
    files = demo_files(demo_dir)
    seq = sequence
    for sid in (first, second):
        seq.clear()
        r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files)
        assert r.status_code == 201, r.text
        under_lock = seq[seq.index("reserve"):]
        assert under_lock.count("reserve") == 1, seq
        assert "read" not in under_lock, seq
        shas = {rec["sha256"] for rec in r.json()["recordings"]}
        folders = {sha[:2] for sha in shas}
        # the first upload places every file (each folder fsynced once); the second finds them stored, intact
        assert under_lock.count("dir") == (len(folders) if sid == first else 0), seq
