"""Pairing two one-knee sessions (app.store.pairing) on a real migrated SQLite database: what happens to a pairing
when either side changes or goes.

Truth: the rows as the database holds them after each change — a pairing counts only when both rows point at each
other (same patient), a session whose partner's files or facts change is checked again and its analyses are
superseded, erasing a session unpairs its partner (SQLite reuses the freed id: the partner must not end up paired
with a new session of another patient), and a re-pairing frees the former partner the same way."""

from __future__ import annotations

import datetime as dt

import pytest
from store_world import erasure_world


@pytest.fixture()
def world(tmp_path):
    with erasure_world(f"sqlite:///{tmp_path / 'chakamo.db'}", tmp_path, "Pairs", "PA-1") as w:
        yield w


def _analysis(s, sid: int) -> int:
    """A done job of session ``sid`` with its analysis (current files), as app.jobs.work stores them."""
    from app.store.models import Analysis, Job, KneeSession

    session = s.get(KneeSession, sid)
    job = Job(clinic_id=session.clinic_id, session_id=sid, filter="ekf", status="done")
    s.add(job)
    s.flush()
    a = Analysis(session_id=sid, job_id=job.id, filter="ekf", files_version=session.files_version)
    s.add(a)
    s.flush()
    return a.id


def _add_file(s, sid: int, name: str) -> None:
    from app.store.erasure import reserve_blobs
    from app.store.models import Recording

    sha = f"{abs(hash((sid, name))):064x}"[:64]
    reserve_blobs(s, [(sha, 1)])
    s.add(Recording(session_id=sid, file_name=name, size_bytes=1, sha256=sha))
    s.flush()


def _state(s, sid: int) -> tuple[int | None, int, int]:
    from app.store.models import KneeSession

    row = s.get(KneeSession, sid, populate_existing=True)
    return row.paired_session_id, row.files_version, row.version


def _superseded(s, aid: int) -> bool:
    from app.store.models import Analysis

    return s.get(Analysis, aid, populate_existing=True).superseded_at is not None


def test_erasing_a_partner_unpairs_it_and_a_reused_id_is_no_partner(world):
    from app.store.models import KneeSession
    from app.store.pairing import pair, partner
    from app.store.patients import add_patient
    from app.store.sessions import add_session, delete_session

    a, b = world["sids"]
    with world["db"].session() as s:
        pair(s, world["cid"], a, b, "right")
    with world["db"].session() as s:
        aid = _analysis(s, a)
        _, files_before, _ = _state(s, a)
    with world["db"].session() as s:
        delete_session(s, world["cid"], b)
    with world["db"].session() as s:
        paired, files_after, _ = _state(s, a)
        assert paired is None and files_after == files_before + 1  # checked again: one knee now
        assert _superseded(s, aid)  # its report described both knees
        other = add_patient(s, world["cid"], {"external_id": "PA-2", "side": "left"})
        new = add_session(s, world["cid"], other.id, {})
        assert new.id == b  # SQLite gave the erased id to another patient's session
        assert partner(s, s.get(KneeSession, a)) is None


def test_a_pairing_that_does_not_point_back_is_no_pairing(world):
    from app.store.models import KneeSession
    from app.store.pairing import partner

    a, b = world["sids"]
    with world["db"].session() as s:
        s.get(KneeSession, a).paired_session_id = b  # one side only (as a pairing left by an erased partner)
        s.flush()
        assert partner(s, s.get(KneeSession, a)) is None


def test_changes_to_the_partner_reach_the_paired_session(world):
    from app.store.recordings import set_split
    from app.store.sessions import correct_session

    a, b = world["sids"]
    with world["db"].session() as s:
        from app.store.pairing import pair
        pair(s, world["cid"], a, b, "right")
    for change in (lambda s: set_split(s, world["cid"], b, None),
                   lambda s: correct_session(s, world["cid"], b, {"date": dt.date(2026, 1, 2)})):
        with world["db"].session() as s:
            aid = _analysis(s, a)
            _, files_before, _ = _state(s, a)
        with world["db"].session() as s:
            change(s)
        with world["db"].session() as s:
            paired, files_after, _ = _state(s, a)
            assert paired == b and files_after == files_before + 1  # A's check reads B's files: redone
            assert _superseded(s, aid)


def test_changes_refused_while_the_partner_is_processed(world):
    from app.store.models import Job
    from app.store.pairing import pair
    from app.store.recordings import set_split
    from app.store.sessions import Busy, delete_session

    a, b = world["sids"]
    with world["db"].session() as s:
        pair(s, world["cid"], a, b, "right")
        s.add(Job(clinic_id=world["cid"], session_id=a, filter="ekf", status="running"))
    for change in (lambda s: set_split(s, world["cid"], b, None), lambda s: delete_session(s, world["cid"], b)):
        with world["db"].session() as s, pytest.raises(Busy):
            change(s)


def test_re_pairing_frees_the_former_partner_and_is_refused_while_it_is_processed(world):
    from app.store.models import Job
    from app.store.pairing import pair
    from app.store.sessions import Busy, add_session

    a, b = world["sids"]
    with world["db"].session() as s:
        c = add_session(s, world["cid"], world["pid"], {}).id
        pair(s, world["cid"], a, b, "right")
        job = Job(clinic_id=world["cid"], session_id=b, filter="ekf", status="queued")
        s.add(job)
    with world["db"].session() as s, pytest.raises(Busy):
        pair(s, world["cid"], a, c, "right")
    with world["db"].session() as s:
        s.get(Job, job.id).status = "done"
    with world["db"].session() as s:
        bid = _analysis(s, b)
        _, b_files, b_version = _state(s, b)
    with world["db"].session() as s:
        _, _, previous, _ = pair(s, world["cid"], a, c, "right")
        assert [p.id for p in previous] == [b]
    with world["db"].session() as s:
        assert _state(s, b) == (None, b_files + 1, b_version + 1)
        assert _superseded(s, bid)
        assert _state(s, a)[0] == c and _state(s, c)[0] == a


def test_a_checked_paired_session_can_be_paired_again(world):
    """A paired session's stored check reads both knees (left_* and right_* segments): only its own files count."""
    from app.store.models import KneeSession
    from app.store.pairing import pair
    from app.store.sessions import add_session

    a, b = world["sids"]
    with world["db"].session() as s:
        c = add_session(s, world["cid"], world["pid"], {}).id
        pair(s, world["cid"], a, b, "right")
        row = s.get(KneeSession, a)
        row.ingestion = {"ok": True, "segments": {"a": "right_thigh", "b": "right_shank", "c": "left_thigh",
                                                  "d": "left_shank"}}
        row.ingestion_version = row.files_version
    with world["db"].session() as s:
        pair(s, world["cid"], a, c, "right")
    with world["db"].session() as s:
        assert _state(s, a)[0] == c


def test_refused_for_other_tasks_or_a_knee_the_files_contradict_and_warned_for_other_dates(world):
    from app.store.errors import Conflict
    from app.store.models import KneeSession
    from app.store.pairing import DATE_WARNING, pair
    from app.store.sessions import add_session

    a, b = world["sids"]
    with world["db"].session() as s:
        gait = add_session(s, world["cid"], world["pid"], {"task": "gait"}).id
        for sid in (a, b):
            s.get(KneeSession, sid).task = "step_up"
        _add_file(s, a, "derecha-muslo.csv")
    with world["db"].session() as s, pytest.raises(Conflict) as err:
        pair(s, world["cid"], a, gait, "right")
    assert err.value.code == "store.pair_other_task"
    with world["db"].session() as s, pytest.raises(Conflict) as err:
        pair(s, world["cid"], a, b, "left")  # its files say right
    assert err.value.code == "store.pair_knee_mismatch"
    with world["db"].session() as s:
        from app.store.sessions import correct_session
        correct_session(s, world["cid"], b, {"date": dt.date(2020, 1, 1)})
    with world["db"].session() as s:
        *_, warnings = pair(s, world["cid"], a, b, "right")
        assert [w["code"] for w in warnings] == [DATE_WARNING]
    from app.pipeline.service_messages import CATALOGUE
    for code in ("store.pair_other_task", "store.pair_knee_mismatch", DATE_WARNING):
        assert set(CATALOGUE[code]) == {"es", "en", "pt"}
