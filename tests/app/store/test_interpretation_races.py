"""Two people writing one interpretation at once (app/store/interpretations.py): two real sessions on the app's
:class:`~app.store.database.Database`, interleaved by hand at the point each race needs, on SQLite and, with
CHAKAMO_TEST_POSTGRES_URL, on PostgreSQL.  ``SELECT … FOR UPDATE`` does nothing on SQLite (and the ORM kept its
stale copy of the row on PostgreSQL): the writes themselves must say what they saw, so the loser gets a
:class:`~app.store.errors.Conflict` (409) and the signed text is never changed without an amendment."""

from __future__ import annotations

import threading
import time

import pytest
from store_world import erasure_world

pytest.importorskip("sqlalchemy")

TEXT = "Flexión máxima reducida; revisar en 6 semanas."


@pytest.fixture(params=["sqlite", "postgresql"])
def env(request, tmp_path):
    from app.store.models import Analysis, Job, User

    url = f"sqlite:///{tmp_path / 'chakamo.db'}" if request.param == "sqlite" else request.getfixturevalue("pg_url")
    with erasure_world(url, tmp_path, "Races", "R-1") as world:
        with world["db"].session() as s:
            sid = world["sids"][0]
            job = Job(clinic_id=world["cid"], session_id=sid, filter="madgwick", status="done")
            s.add(job)
            s.flush()
            analysis = Analysis(session_id=sid, job_id=job.id, filter="madgwick")
            users = [User(clinic_id=world["cid"], email=f"{n}@races.test", name=n, role="clinician",
                          password_hash="x") for n in ("Ana", "Beto")]
            s.add_all([analysis, *users])
            s.flush()
            ids = {"aid": analysis.id, "users": [u.id for u in users]}
        yield world | ids | {"kind": request.param}


def _rows(s, env):
    """The session, analysis and the two users as session ``s`` reads them."""
    from app.store.models import Analysis, KneeSession, User

    return (s.get(KneeSession, env["sids"][0]), s.get(Analysis, env["aid"]),
            *(s.get(User, uid) for uid in env["users"]))


def _draft(env, text: str = TEXT) -> None:
    from app.store import interpretations

    with env["db"].session() as s:
        session, analysis, ana, _ = _rows(s, env)
        interpretations.save_draft(s, session, analysis, text, "Ana")


def _stored(env):
    from app.store import interpretations

    with env["db"].session() as s:
        row = interpretations.find(s, env["aid"])
        return row.text, row.signed_by, len(row.amendments)


def test_a_draft_saved_on_a_stale_read_does_not_change_a_signed_text(env):
    """A reads the unsigned interpretation; B signs and commits; A's draft save must be refused, not written."""
    from app.store import interpretations
    from app.store.errors import Conflict

    _draft(env)
    with env["db"].sessions() as a:
        session, analysis, _, _ = _rows(a, env)
        assert interpretations.find(a, env["aid"]).signed_at is None  # A has read it unsigned
        with env["db"].session() as b:
            b_session, b_analysis, _, beto = _rows(b, env)
            interpretations.sign(b, b_session, b_analysis, beto, TEXT)
        with pytest.raises(Conflict) as err:
            interpretations.save_draft(a, session, analysis, "otro texto", "Ana")
        assert err.value.code == "store.interpretation_signed"
        a.rollback()
    assert _stored(env) == (TEXT, "Beto", 0)


def test_two_signers_only_one_signs(env):
    """A and B both read the unsigned text; B signs first; A's signature is refused (B's stands)."""
    from app.store import interpretations
    from app.store.errors import Conflict

    _draft(env)
    with env["db"].sessions() as a:
        session, analysis, ana, _ = _rows(a, env)
        assert interpretations.find(a, env["aid"]).signed_at is None
        with env["db"].session() as b:
            b_session, b_analysis, _, beto = _rows(b, env)
            interpretations.sign(b, b_session, b_analysis, beto, TEXT)
        with pytest.raises(Conflict):
            interpretations.sign(a, session, analysis, ana, TEXT)
        a.rollback()
    assert _stored(env) == (TEXT, "Beto", 0)


def test_two_amendments_of_one_text_the_second_is_refused(env):
    """A and B both read the signed text T and amend it; B commits first; A's amendment would record T as the text
    it replaced while the text is B's: refused, B's amendment alone in the history."""
    from app.store import interpretations
    from app.store.errors import Conflict

    _draft(env)
    with env["db"].session() as s:
        session, analysis, ana, _ = _rows(s, env)
        interpretations.sign(s, session, analysis, ana, TEXT)
    with env["db"].sessions() as a:
        session, analysis, ana, _ = _rows(a, env)
        assert interpretations.find(a, env["aid"]).text == TEXT
        with env["db"].session() as b:
            b_session, b_analysis, _, beto = _rows(b, env)
            interpretations.amend(b, b_session, b_analysis, beto, "texto de Beto", "motivo B")
        with pytest.raises(Conflict):
            interpretations.amend(a, session, analysis, ana, "texto de Ana", "motivo A", expected=TEXT)
        a.rollback()
    assert _stored(env) == ("texto de Beto", "Ana", 1)


def test_two_first_saves_at_once_answer_a_conflict_not_an_integrity_error(env):
    """A and B both find no interpretation and insert one; A commits first: B's insert breaks the unique
    analysis_id — a Conflict (409), never the database's IntegrityError (500).  B runs in a thread: its insert
    waits for A's lock (SQLite's write lock, PostgreSQL's unique index entry) until A commits."""
    from app.store import interpretations
    from app.store.errors import Conflict

    seen: dict[str, BaseException | None] = {}
    ready, go = threading.Event(), threading.Event()

    def b_saves() -> None:
        try:
            with env["db"].session() as b:
                b_session, b_analysis, _, _ = _rows(b, env)  # B's connection open (its pragmas run) before A writes
                ready.set()
                go.wait(30)
                interpretations.save_draft(b, b_session, b_analysis, "texto de Beto", "Beto")
            seen["b"] = None
        except BaseException as exc:  # noqa: BLE001 — the test reads what B got
            seen["b"] = exc

    thread = threading.Thread(target=b_saves)
    thread.start()
    assert ready.wait(30)
    a = env["db"].sessions()
    session, analysis, _, _ = _rows(a, env)
    interpretations.save_draft(a, session, analysis, "texto de Ana", "Ana")  # inserted, not committed
    go.set()
    time.sleep(1.0)  # B finds none and waits in its insert for A's lock (not a timing assertion: the order is forced)
    a.commit()
    a.close()
    thread.join(30)
    assert not thread.is_alive()
    assert isinstance(seen["b"], Conflict), repr(seen["b"])
    assert seen["b"].code == "store.interpretation_changed"
    assert _stored(env) == ("texto de Ana", None, 0)
