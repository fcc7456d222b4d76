"""The data layer the routes call (``app.store.*``, ``app.jobs.queue``), without HTTP: clinic scoping, the
refusals (domain errors carrying the user's sentence) and the processing request's rules, on SQLite."""

from __future__ import annotations

import datetime as dt

import pytest

from app.pipeline.service_messages import message_dict


@pytest.fixture()
def world(tmp_path):
    """Two clinics, one patient and one session in the first; the session's check stored and passing."""
    from app.store.database import Database
    from app.store.models import Clinic, KneeSession, Patient

    db = Database(f"sqlite:///{tmp_path}/s.db")
    db.migrate()
    with db.session() as s:
        a, b = Clinic(name="A"), Clinic(name="B")
        s.add_all([a, b])
        s.flush()
        p = Patient(clinic_id=a.id, external_id="P-1", side="right", name="Ana 50%_x")
        s.add(p)
        s.flush()
        k = KneeSession(clinic_id=a.id, patient_id=p.id, date=dt.date(2026, 1, 2), files_version=1,
                        ingestion={"ok": True, "messages": [], "error": None}, ingestion_version=1)
        s.add(k)
        s.flush()
        ids = {"a": a.id, "b": b.id, "patient": p.id, "session": k.id}
    yield db, ids, tmp_path
    db.dispose()


def _checker(db, tmp_path):
    from app.store.checks import IngestionChecker

    return IngestionChecker(db, None, tmp_path)  # never runs a check here: the stored one is fresh


def test_another_clinics_ids_are_not_found_like_unknown_ones(world):
    from app.store.errors import NotFound
    from app.store.patients import clinic_patient
    from app.store.sessions import clinic_job, clinic_session

    db, ids, _ = world
    with db.session() as s:
        assert clinic_session(s, ids["a"], ids["session"]).id == ids["session"]
        assert clinic_patient(s, ids["a"], ids["patient"]).external_id == "P-1"
        for clinic in (ids["b"],):
            with pytest.raises(NotFound) as other:
                clinic_session(s, clinic, ids["session"])
            with pytest.raises(NotFound) as unknown:
                clinic_session(s, ids["a"], 999)
            assert str(other.value) == f"No session {ids['session']} in your clinic; check the id."
            assert "No session 999 in your clinic" in str(unknown.value)
            with pytest.raises(NotFound, match="No patient"):
                clinic_patient(s, clinic, ids["patient"])
            with pytest.raises(NotFound, match="No job 5 in your clinic"):
                clinic_job(s, clinic, 5)


def test_patients_unique_per_clinic_and_search_takes_wildcards_literally(world):
    from app.store.errors import Conflict
    from app.store.patients import add_patient, search_patients

    db, ids, _ = world
    with db.session() as s:
        with pytest.raises(Conflict, match="'P-1' already exists in your clinic"):
            add_patient(s, ids["a"], {"external_id": "P-1", "side": "left"})
        assert add_patient(s, ids["b"], {"external_id": "P-1", "side": "left"}).clinic_id == ids["b"]
        add_patient(s, ids["a"], {"external_id": "P-2", "side": "left", "name": "Ana 50 x"})
        assert [p.external_id for p in search_patients(s, ids["a"], "50%_")] == ["P-1"]
        assert [p.external_id for p in search_patients(s, ids["a"], "ana")] == ["P-2", "P-1"]  # newest first
        assert search_patients(s, ids["b"], "ana") == []


def test_enqueue_queues_once_then_refuses_while_busy_and_when_up_to_date(world):
    from app.jobs.queue import UpToDate, enqueue
    from app.pipeline.session import PIPELINE_VERSION
    from app.store.models import Analysis, Job
    from app.store.sessions import Busy, active_job_id, refuse_while_processing

    db, ids, tmp = world
    checker = _checker(db, tmp)
    with db.session() as s:
        job = enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="en", checker=checker)
        assert (job.status, job.stage, job.filter, job.lang, job.pipeline_version) == \
               ("queued", "queued", "guo", "en", PIPELINE_VERSION)
    with db.session() as s:
        with pytest.raises(Busy) as busy:
            enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="en", checker=checker)
        assert busy.value.job_id == job.id and "process it again when that job has finished" in str(busy.value)
        with pytest.raises(Busy, match="upload the files when") as upload:
            refuse_while_processing(s, ids["session"], "upload")
        for error, es, pt in ((busy.value, "procésela de nuevo cuando", "processe-a de novo quando"),
                              (upload.value, "suba los archivos cuando", "envie os ficheiros quando")):
            said = message_dict(error.code, error.params)["message"]   # what the API answers, every language
            assert es in said["es"] and pt in said["pt"] and "process it" not in said["es"] + said["pt"]
        done = s.get(Job, job.id)
        done.status = "done"
        s.add(Analysis(session_id=ids["session"], job_id=job.id, filter="guo", lang="en",
                       pipeline_version=PIPELINE_VERSION, files_version=1))
    with db.session() as s:
        assert active_job_id(s, ids["session"]) is None
        with pytest.raises(UpToDate) as current:
            enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="en", checker=checker, unless_current=True)
        assert current.value.analysis_id is not None
        # another language is other work; and without unless_current (the API) the same work is queued again
        assert enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="es", checker=checker,
                       unless_current=True).lang == "es"
        s.rollback()
        assert enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="en", checker=checker).id > job.id


def test_enqueue_refuses_files_that_are_not_ready_or_not_checked(world):
    from app.jobs.queue import NotReady, enqueue
    from app.store.errors import NotFound
    from app.store.models import KneeSession

    db, ids, tmp = world
    checker = _checker(db, tmp)
    with db.session() as s:
        s.get(KneeSession, ids["session"]).ingestion = {"ok": False, "messages": [], "error": "no shank lying file"}
    with db.session() as s:
        with pytest.raises(NotReady) as bad:
            enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="es", checker=checker)
        assert bad.value.reason == "no shank lying file"
        assert str(bad.value) == "The session's recordings are not ready to process: no shank lying file"
        s.get(KneeSession, ids["session"]).files_version = 2  # files changed, none stored: nothing to check
    with db.session() as s:
        with pytest.raises(NotReady) as stale:
            enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="es", checker=checker)
        assert stale.value.reason is None and str(stale.value).endswith("No recordings yet; upload the session's files.")
        said = message_dict(stale.value.code, stale.value.params)["message"]
        assert said["es"].endswith("Todavía no hay grabaciones; suba los archivos de la sesión.")
        assert said["pt"].endswith("Ainda não há gravações; envie os ficheiros da sessão.")
        with pytest.raises(NotFound):
            enqueue(s, ids["b"], ids["session"], filter_name="guo", lang="es", checker=checker)


def test_the_not_ready_refusal_says_the_stored_check_in_the_readers_language(world):
    """The check stores its refusal as a code and params (``error_item``); the "not ready" refusal carries it and
    each language renders it (it embedded the English sentence in es and pt)."""
    from app.jobs.queue import NotReady, enqueue
    from app.pipeline.ingestion.messages import render as ingestion_render
    from app.pipeline.service_messages import item
    from app.store.models import KneeSession

    db, ids, tmp = world
    checker = _checker(db, tmp)
    params = {"file": "thigh_task.csv"}
    stored = item("file.not_found", params, ingestion_render("file.not_found", params, "en"))
    with db.session() as s:
        s.get(KneeSession, ids["session"]).ingestion = {"ok": False, "messages": [], "error": stored["text"],
                                                        "error_item": stored}
    with db.session() as s:
        with pytest.raises(NotReady) as bad:
            enqueue(s, ids["a"], ids["session"], filter_name="guo", lang="es", checker=checker)
    said = message_dict(bad.value.code, bad.value.params)["message"]
    assert str(bad.value) == said["en"] == f"The session's recordings are not ready to process: {stored['text']}"
    for lang in ("es", "pt"):
        assert said[lang].endswith(ingestion_render("file.not_found", params, lang)) and stored["text"] not in said[lang]


def test_superseded_results_say_the_tail_in_the_readers_language():
    from types import SimpleNamespace

    from app.store.analyses import SupersededResults

    analysis = SimpleNamespace(id=41, superseded_at=dt.datetime(2026, 11, 2, 9, 30))
    error = SupersededResults(7, analysis)
    said = message_dict(error.code, error.params)["message"]
    assert said["en"].endswith("process the session again, or ask for analysis_id=41 to see the superseded report.")
    assert said["es"].endswith("procese la sesión de nuevo, o pida analysis_id=41 para ver el informe reemplazado.")
    assert said["pt"].endswith("processe a sessão de novo, ou peça analysis_id=41 para ver o relatório substituído.")
    plain = SupersededResults(7, analysis, readable_by_id=False)
    assert message_dict(plain.code, plain.params)["message"]["pt"].endswith("processe a sessão de novo.")


def test_session_status_and_shown_check():
    from app.store.models import Job, KneeSession
    from app.store.sessions import BEING_CHECKED, session_status, stored_ingestion
    from app.store.workspace import NO_RECORDINGS

    assert session_status(0, True, Job(status="done")) == "empty"
    assert session_status(2, False, Job(status="running")) == "processing"
    assert session_status(2, True, Job(status="failed")) == "failed"
    assert session_status(2, True, None) == "ready" and session_status(2, False, None) == "incomplete"
    stale = KneeSession(ingestion={"ok": True}, ingestion_version=1, files_version=2)
    assert stored_ingestion(stale, 0) == NO_RECORDINGS and stored_ingestion(stale, 3) == BEING_CHECKED
    fresh = KneeSession(ingestion={"ok": True}, ingestion_version=2, files_version=2)
    assert stored_ingestion(fresh, 3) == {"ok": True}
