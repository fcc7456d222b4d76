"""Reference-counted, crash-safe blob erasure (app/store/erasure.py) on the embedded SQLite database.

Each crash is reproduced by stopping after the step it interrupts — the database and the disk are then in the
state that crash leaves — and the next step or the sweep must finish the erasure without losing a byte that a
row still names.  Truth: the files on disk (their names are the sha256 of the bytes written, computed here)."""

from __future__ import annotations

import datetime as dt
import hashlib
import os
import time

import pytest
from store_world import erasure_world

pytest.importorskip("sqlalchemy")


@pytest.fixture
def env(tmp_path):
    with erasure_world(f"sqlite:///{tmp_path / 'chakamo.db'}", tmp_path, "Erasure", "E-1") as world:
        yield world


def _upload(env, session_id: int, name: str, data: bytes) -> int:
    from app.store.recordings import store_upload

    w = env["store"].writer()
    w.write(data)
    with env["db"].session() as s:
        _, rows = store_upload(s, env["cid"], session_id, [(name, w)], segment=None, role=None, max_files=40)
        return rows[0].id


def _delete(env, session_id: int, rec_id: int) -> list[int]:
    """Steps 1 (the request's transaction): delete the recording and mark its blob; committed on return."""
    from app.store.erasure import mark
    from app.store.recordings import delete_recording

    with env["db"].session() as s:
        _, sha, _ = delete_recording(s, env["cid"], session_id, rec_id)
        return mark(s, [sha], reason="recording", actor="test", clinic_id=env["cid"])


def _states(env) -> list[tuple[str, str]]:
    from sqlalchemy import select

    from app.store.models import BlobErasure

    with env["db"].session() as s:
        return [(e.state, e.reason) for e in s.scalars(select(BlobErasure).order_by(BlobErasure.id))]


def _blob_row(env, sha: str) -> bool:
    from app.store.models import Blob

    with env["db"].session() as s:
        return s.get(Blob, sha) is not None


DATA = b"acc_x (g),acc_y (g),acc_z (g)\n0.0,0.0,1.0\n" * 20


def test_a_blob_shared_by_two_recordings_survives_one_deletion(env):
    from app.store.erasure import erase_pending

    sha = hashlib.sha256(DATA).hexdigest()
    r1 = _upload(env, env["sids"][0], "a.csv", DATA)
    r2 = _upload(env, env["sids"][1], "b.csv", DATA)  # the same content, uploaded again
    erase_pending(env["db"], env["store"], _delete(env, env["sids"][0], r1))
    assert env["store"].read(sha) == DATA and _states(env) == [("kept", "recording")]
    counts = erase_pending(env["db"], env["store"], _delete(env, env["sids"][1], r2))
    assert counts.erased == 1 and counts.bytes_erased == len(DATA)
    assert not env["store"].path(sha).exists() and not _blob_row(env, sha)
    assert _states(env) == [("kept", "recording"), ("erased", "recording")]


def test_a_crash_after_the_mark_is_finished_by_the_sweep(env):
    from app.store.erasure import sweep

    sha = hashlib.sha256(DATA).hexdigest()
    _delete(env, env["sids"][0], _upload(env, env["sids"][0], "a.csv", DATA))  # crash: no erase step
    assert env["store"].path(sha).is_file() and _states(env) == [("pending", "recording")]
    assert sweep(env["db"], env["store"]).erased == 1
    assert not env["store"].path(sha).exists() and _states(env) == [("erased", "recording")]


def test_a_crash_between_the_unlink_and_its_commit_is_finished_too(env):
    """The file is gone, the blob row and the pending mark are still there (the commit never happened)."""
    from app.store.erasure import erase_pending

    sha = hashlib.sha256(DATA).hexdigest()
    ids = _delete(env, env["sids"][0], _upload(env, env["sids"][0], "a.csv", DATA))
    os.unlink(env["store"].path(sha))  # what the interrupted transaction had done to the disk
    assert _blob_row(env, sha)
    assert erase_pending(env["db"], env["store"], ids).erased == 1
    assert not _blob_row(env, sha) and _states(env) == [("erased", "recording")]


def test_content_uploaded_again_before_the_erase_step_is_kept(env):
    from app.store.erasure import erase_pending

    sha = hashlib.sha256(DATA).hexdigest()
    ids = _delete(env, env["sids"][0], _upload(env, env["sids"][0], "a.csv", DATA))
    _upload(env, env["sids"][1], "again.csv", DATA)  # between the mark and the erasure
    assert erase_pending(env["db"], env["store"], ids).kept == 1
    assert env["store"].read(sha) == DATA and _states(env) == [("kept", "recording")]


def test_uploading_erased_content_again_stores_it_again(env):
    from app.store.erasure import erase_pending

    sha = hashlib.sha256(DATA).hexdigest()
    erase_pending(env["db"], env["store"], _delete(env, env["sids"][0], _upload(env, env["sids"][0], "a.csv", DATA)))
    assert not env["store"].path(sha).exists()
    _upload(env, env["sids"][0], "a.csv", DATA)
    assert env["store"].read(sha) == DATA and _blob_row(env, sha)


def test_the_sweep_removes_old_unnamed_files_and_unreferenced_rows_but_not_fresh_ones(env):
    """A file no row names (a writer that crashed before committing its row) goes after the grace period; a
    fresh one may still get its row and stays.  A blob row nothing references (a recording deleted before
    erasure existed) goes with its file."""
    from sqlalchemy import delete

    from app.store.erasure import sweep
    from app.store.models import Recording

    old_sha, _ = env["store"].put(b"orphan from a crash")
    old = time.time() - 7200
    os.utime(env["store"].path(old_sha), (old, old))
    fresh_sha, _ = env["store"].put(b"a job's artefact, row not committed yet")
    sha = hashlib.sha256(DATA).hexdigest()
    _upload(env, env["sids"][0], "a.csv", DATA)
    with env["db"].session() as s:  # the old code's deletion: the row goes, the blob row and file stay
        s.execute(delete(Recording))
    counts = sweep(env["db"], env["store"], now=dt.datetime.now(dt.timezone.utc) + dt.timedelta(hours=2))
    assert counts.erased == 2
    assert not env["store"].path(old_sha).exists() and not env["store"].path(sha).exists()
    assert env["store"].path(fresh_sha).is_file()
    assert sorted(_states(env)) == [("erased", "orphan"), ("erased", "orphan")]


def test_the_record_holds_the_hash_and_never_the_content(env):
    from sqlalchemy import select

    from app.store.erasure import erase_pending
    from app.store.models import BlobErasure

    secret = b"patient=Ana Perez;MRN=778899\n" * 3
    erase_pending(env["db"], env["store"], _delete(env, env["sids"][0], _upload(env, env["sids"][0], "x.csv", secret)))
    with env["db"].session() as s:
        row = s.scalars(select(BlobErasure)).one()
        values = [str(getattr(row, c.name)) for c in BlobErasure.__table__.columns]
    assert row.sha256 == hashlib.sha256(secret).hexdigest() and row.size_bytes == len(secret)
    assert not any("Ana" in v or "778899" in v or "x.csv" in v for v in values)
