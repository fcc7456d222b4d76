"""Races between the reference-counted erasure (app/store/erasure.py) and the writers of the same bytes: a job
storing its artefacts, an upload; retention against an upload; a blob's removal against a writer sharing its
folder.  Each interleaving is forced by a hook at the point the race needs (no sleeps), on SQLite and, with
CHAKAMO_TEST_POSTGRES_URL, on PostgreSQL."""

from __future__ import annotations

import contextlib
import datetime as dt
import threading

import pytest
from store_world import erasure_world

pytest.importorskip("sqlalchemy")

DATA = b"t_s,acc_x\n0,1\n" * 10


@pytest.fixture(params=["sqlite", "postgresql"])
def env(request, tmp_path):
    url = f"sqlite:///{tmp_path / 'chakamo.db'}" if request.param == "sqlite" else request.getfixturevalue("pg_url")
    with erasure_world(url, tmp_path, "Races", "R-1") as world:
        yield world | {"kind": request.param}


def _writer(env, data: bytes = DATA):
    w = env["store"].writer()
    w.write(data)
    return w


def _upload(env, session_id: int, name: str, data: bytes = DATA) -> int:
    from app.store.recordings import store_upload

    with env["db"].session() as s:
        _, rows = store_upload(s, env["cid"], session_id, [(name, _writer(env, data))], segment=None, role=None,
                               max_files=40)
        return rows[0].id


def _delete_and_mark(env, session_id: int, rec_id: int) -> list[int]:
    from app.store.erasure import mark
    from app.store.recordings import delete_recording

    with env["db"].session() as s:
        _, sha, _ = delete_recording(s, env["cid"], session_id, rec_id)
        return mark(s, [sha], reason="session", actor="test", clinic_id=env["cid"])


def test_a_job_whose_artefact_equals_content_being_erased_keeps_its_file(env, monkeypatch):
    """Finding 1: session B's job stores an artefact whose bytes equal session A's only other copy; A is deleted
    and erased after B's job rendered but before it committed; B's artefact must still be readable."""
    import hashlib
    import os
    import types

    import app.jobs.compute as compute
    import app.jobs.work as work
    import app.pipeline.ingestion as ingestion
    import app.pipeline.knees as knees
    import app.pipeline.render as render
    import app.pipeline.results as results
    import app.store.workspace as workspace
    from app.store.erasure import erase_pending
    from app.store.models import Artefact, Job

    db, store = env["db"], env["store"]
    sa, sb = env["sids"]
    rec_a = _upload(env, sa, "a.csv")
    _upload(env, sb, "b.csv", b"other bytes\n")
    with db.session() as s:
        job = Job(clinic_id=env["cid"], session_id=sb, filter="guo", lang="en", log=[])
        s.add(job)
        s.flush()
        job_id = job.id
    # the pipeline is not what is tested: it renders one artefact, equal to A's recording
    monkeypatch.setattr(workspace, "materialise", lambda *a, **k: contextlib.nullcontext(env["store"].root))
    monkeypatch.setattr(ingestion, "load_knees", lambda folder: None)
    monkeypatch.setattr(knees, "process_knees", lambda loaded, options, progress, web=False: types.SimpleNamespace(primary=None))
    monkeypatch.setattr(results, "build_knees_results", lambda outcome: {"cycles": {"accepted": 3},
                                                                          "quality": {"warnings": []}})
    monkeypatch.setattr(compute, "public_results", lambda res, sid, paired_id=None: res)
    monkeypatch.setattr(render, "render_all", lambda *a, **k: {("quaternions.xlsx", None): DATA})
    owned = work._owned

    def stage() -> str:
        with db.session() as other:
            return other.get(Job, job_id).stage

    def erase_a_first(s, *a):  # the admin deletes session A, the eraser runs, before B's job records its analysis
        if not getattr(erase_a_first, "done", False) and stage() == "store":  # (progress writes go through here too)
            erase_a_first.done = True
            path = store.path(hashlib.sha256(DATA).hexdigest())  # written a while ago (a job runs for minutes)
            os.utime(path, (path.stat().st_mtime - 600,) * 2)
            erase_pending(db, store, _delete_and_mark(env, sa, rec_a))
        return owned(s, *a)

    monkeypatch.setattr(work, "_owned", erase_a_first)
    assert work.run_job(job_id, db, store, store.root) == "done" and erase_a_first.done
    sha = hashlib.sha256(DATA).hexdigest()
    with db.session() as s:
        assert s.query(Artefact).filter_by(sha256=sha).count() == 1
    assert store.read(sha) == DATA  # CorruptBlob (missing) before the fix


@pytest.mark.parametrize("env", ["postgresql"], indirect=True)
def test_an_upload_racing_the_erasure_of_its_bytes_is_stored(env, monkeypatch):
    """Finding 2 (PostgreSQL): the upload ensured the blob row while the eraser held it locked, the eraser then
    deleted it; the upload must add it again, not fail on the foreign key as a name conflict."""
    import app.store.database as database
    import app.store.erasure as erasure
    from app.store.models import Blob, Recording

    sa, sb = env["sids"]
    ids = _delete_and_mark(env, sa, _upload(env, sa, "thigh_task.csv"))
    counted, ensured = threading.Event(), threading.Event()
    real_refs, real_ensure = erasure.references, database.ensure_blobs

    def refs(db, sha):  # the eraser, holding the blob row's lock, waits for the upload's ensure_blobs
        n = real_refs(db, sha)
        counted.set()
        assert ensured.wait(30)
        return n

    def ensure(db, blobs):
        real_ensure(db, blobs)
        ensured.set()

    monkeypatch.setattr(erasure, "references", refs)
    monkeypatch.setattr(database, "ensure_blobs", ensure)
    out = {}
    eraser = threading.Thread(target=lambda: out.update(counts=erasure.erase_pending(env["db"], env["store"], ids)))
    eraser.start()
    assert counted.wait(30)
    rid = _upload(env, sb, "thigh_task.csv")  # Conflict before the fix
    eraser.join(30)
    assert out["counts"].erased == 1
    with env["db"].session() as s:
        sha = s.get(Recording, rid).sha256
        assert s.get(Blob, sha) is not None
    assert env["store"].read(sha) == DATA


def test_retention_locks_the_session_before_deciding_it_is_due(env, monkeypatch):
    """Finding 3: between retention's re-check and its deletion an upload must not be able to commit (on
    PostgreSQL it would be acknowledged, then deleted); the session row is locked by then."""
    import app.store.retention as retention
    from app.store.models import KneeSession
    from sqlalchemy import select
    from sqlalchemy.exc import OperationalError

    sa, _ = env["sids"]
    now = dt.datetime.now(dt.timezone.utc) + dt.timedelta(days=400)
    real = retention.delete_sessions
    seen = []

    def delete(db, ids):
        if env["kind"] == "postgresql":  # another connection cannot lock the row now
            with env["db"].session() as other:
                with pytest.raises(OperationalError):
                    other.execute(select(KneeSession.id).where(KneeSession.id == ids[0]).with_for_update(nowait=True))
        seen.append(ids)
        return real(db, ids)

    monkeypatch.setattr(retention, "delete_sessions", delete)
    report = retention.apply_retention(env["db"], env["store"], 30, now=now, dry_run=False,
                                       record=lambda db, **kw: None)
    assert report.erased_sessions == 2 and seen


def test_removing_a_blob_keeps_the_folder_another_writer_is_placing_into(tmp_path, monkeypatch):
    """Finding 4: a writer made the two-hex-digit folder, then a blob of the same prefix was removed; the
    writer's rename must still find the folder."""
    import hashlib
    import os

    import app.store.blobs as blobs

    store = blobs.BlobStore(tmp_path / "blobs")
    seen: dict[str, bytes] = {}
    i = 0
    while True:  # two contents whose sha256 share the first two hex digits
        d = b"x%d" % i
        prefix = hashlib.sha256(d).hexdigest()[:2]
        if prefix in seen:
            first, second = seen[prefix], d
            break
        seen[prefix] = d
        i += 1
    sha_first, _ = store.put(first)
    real_replace = os.replace

    def replace(src, dst):  # the other blob is erased between the writer's mkdir and its rename
        store.remove(sha_first)
        return real_replace(src, dst)

    monkeypatch.setattr(blobs.os, "replace", replace)
    sha_second, _ = store.put(second)  # FileNotFoundError before the fix
    monkeypatch.undo()
    assert store.read(sha_second) == second
