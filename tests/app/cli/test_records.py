"""``chakamo patients|sessions correct|erase`` and ``chakamo retention`` (app/cli/records.py), and the retention
policy on a fixed clock (app/store/retention.py): a session is due exactly when its last activity is the
configured number of days old, a dry run changes nothing, and applying it erases the session's files and leaves
the operator's audit event."""

from __future__ import annotations

import datetime as dt
import hashlib

import pytest

pytest.importorskip("fastapi")

DATA = b"acc_x (g),acc_y (g),acc_z (g)\n0.0,0.0,1.0\n# retention\n"


@pytest.fixture
def world(tmp_path):
    """A clinic with a patient and a session holding one recording (made through the API, then closed)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "web"))
    from fastapi.testclient import TestClient
    from web_helpers import clinic_token, make_settings

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "Ret")
    with TestClient(create_app(settings)) as c:
        pid = c.post("/api/v1/patients", json={"external_id": "RET-1", "side": "right"}, headers=h).json()["id"]
        sid = c.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=h).json()["id"]
        files = [("files", ("thigh_task.csv", DATA, "text/csv"))]
        assert c.post(f"/api/v1/sessions/{sid}/recordings", files=files, headers=h).status_code == 201
        created = dt.datetime.fromisoformat(c.get(f"/api/v1/sessions/{sid}", headers=h).json()["recordings"][0]
                                            ["uploaded_at"])
    return {"settings": settings, "pid": pid, "sid": sid, "last": created,
            "path": settings.blob_dir / (h := hashlib.sha256(DATA).hexdigest())[:2] / h[2:]}


def _new_session(world, pid: int) -> int:
    """A new session of patient ``pid`` of clinic "Ret" (through the API, as ``world`` made the first)."""
    from fastapi.testclient import TestClient
    from web_helpers import clinic_token

    from app.web.main import create_app

    with TestClient(create_app(world["settings"])) as c:
        return c.post(f"/api/v1/patients/{pid}/sessions", json={},
                      headers=clinic_token(world["settings"], "Ret")).json()["id"]


def _events(settings, action: str) -> list:
    from sqlalchemy import select

    from app.store.database import Database
    from app.store.models import AuditEvent

    db = Database(settings.db_url)
    with db.session() as s:
        out = [(e.actor_kind, e.actor, e.patient_id, e.session_id, e.resource) for e in
               s.scalars(select(AuditEvent).where(AuditEvent.action == action).order_by(AuditEvent.id))]
    db.dispose()
    return out


def test_retention_is_due_exactly_after_the_days_and_a_dry_run_changes_nothing(world):
    from app.cli.records import retention

    days = 30
    before = world["last"] + dt.timedelta(days=days) - dt.timedelta(seconds=1)
    after = world["last"] + dt.timedelta(days=days) + dt.timedelta(seconds=1)
    assert retention(world["settings"], days=days, now=before).due == []
    due = retention(world["settings"], days=days, now=after).due
    assert [d.session_id for d in due] == [world["sid"]] and due[0].last_activity == world["last"]
    assert world["path"].is_file() and _events(world["settings"], "delete") == []  # a dry run
    report = retention(world["settings"], days=days, now=after, apply=True)
    assert (report.erased_sessions, report.erased_files) == (1, 1)
    assert not world["path"].exists()
    [(kind, actor, pid, sid, resource)] = _events(world["settings"], "delete")
    assert (kind, pid, sid) == ("operator", world["pid"], world["sid"]) and "retention 30 days" in actor
    assert retention(world["settings"], days=days, now=after).due == []


def test_retention_is_off_by_default(world):
    from app.cli.records import retention

    with pytest.raises(ValueError, match="off"):
        retention(world["settings"])


def test_the_embedded_runner_applies_the_configured_policy(world):
    """The housekeeping the server runs (at start and hourly) with CHAKAMO_RETENTION_DAYS set: on a clock a year
    on, the session is erased."""
    from app.store.blobs import open_storage
    from app.store.database import Database
    from app.web.housekeeping import housekeeping

    settings = world["settings"].model_copy(update={"retention_days": 365})
    db = Database(settings.db_url)
    housekeeping(settings, db, open_storage(settings), now=world["last"] + dt.timedelta(days=364))
    assert world["path"].is_file()
    housekeeping(settings, db, open_storage(settings), now=world["last"] + dt.timedelta(days=366))
    db.dispose()
    assert not world["path"].exists()
    assert [e[0] for e in _events(settings, "delete")] == ["operator"]


def test_cli_corrects_and_erases_with_confirmation(world, capsys):
    from app.cli.main import main

    env_settings = world["settings"]
    import os

    os.environ["CHAKAMO_DATA_DIR"] = str(env_settings.data_dir)
    os.environ["CHAKAMO_ENV"] = "development"
    from app.settings import get_settings

    get_settings.cache_clear()
    try:
        pid, sid = world["pid"], world["sid"]
        assert main(["patients", "correct", "--clinic", "Ret", str(pid), "--set", "name=Ana Pérez",
                     "--set", "height_cm=165.5"]) == 0
        assert "corrected name, height_cm" in capsys.readouterr().out
        assert main(["patients", "correct", "--clinic", "Ret", str(pid), "--set", "side=up"]) == 2
        assert "side" in capsys.readouterr().err
        assert main(["sessions", "correct", "--clinic", "Ret", str(sid), "--set", "notes=left knee pain"]) == 0
        assert main(["sessions", "erase", "--clinic", "Ret", str(sid), "--confirm", "RET-2"]) == 2
        assert "not the patient's external id" in capsys.readouterr().err and world["path"].is_file()
        assert main(["patients", "erase", "--clinic", "Other", str(pid), "--confirm", "RET-1"]) == 2
        assert main(["patients", "erase", "--clinic", "Ret", str(pid), "--confirm", "RET-1"]) == 0
        assert "1 session(s), 1 stored file(s) erased" in capsys.readouterr().out
        assert not world["path"].exists()
        assert [e[0] for e in _events(env_settings, "update")] == ["operator", "operator"]
        assert [(e[0], e[2]) for e in _events(env_settings, "delete")] == [("operator", pid)]
    finally:
        get_settings.cache_clear()
        os.environ.pop("CHAKAMO_DATA_DIR")
        os.environ.pop("CHAKAMO_ENV")


@pytest.mark.parametrize("lang, words", [
    ("en", {"corrected": "patient {pid}: corrected name", "unchanged": "patient {pid}: nothing changed",
            "pair": "is not FIELD=VALUE", "field": "cannot be corrected", "date": "is not a date (YYYY-MM-DD)",
            "number": "is not a number", "confirm": "is not the patient's external id",
            "off": "the retention policy is off", "due": "1 session(s) due (dry run",
            "line": "  session {sid} (clinic", "erased": "session(s) erased",
            "files": "1 stored file(s) erased, 0 kept", "gone": "patient {pid} erased: 0 session(s)",
            "session_gone": "session {new} erased: 0 stored file(s)"}),
    ("es", {"corrected": "paciente {pid}: corregidos name", "unchanged": "paciente {pid}: no ha cambiado nada",
            "pair": "no es CAMPO=VALOR", "field": "no se puede corregir", "date": "no es una fecha (AAAA-MM-DD)",
            "number": "no es un número", "confirm": "no es el identificador externo del paciente",
            "off": "la política de conservación está desactivada", "due": "1 sesión(es) vencida(s) (simulación",
            "line": "  sesión {sid} (clínica", "erased": "sesión(es) borrada(s)",
            "files": "1 archivo(s) guardado(s) borrado(s), 0 conservado(s)",
            "gone": "paciente {pid} borrado: 0 sesión(es)", "session_gone": "sesión {new} borrada: 0 archivo(s)"}),
    ("pt", {"corrected": "paciente {pid}: corrigidos name", "unchanged": "paciente {pid}: nada foi alterado",
            "pair": "não é CAMPO=VALOR", "field": "não pode ser corrigido", "date": "não é uma data (AAAA-MM-DD)",
            "number": "não é um número", "confirm": "não é o identificador externo do paciente",
            "off": "a política de conservação está desativada", "due": "1 sessão(ões) vencida(s) (simulação",
            "line": "  sessão {sid} (clínica", "erased": "sessão(ões) apagada(s)",
            "files": "1 ficheiro(s) guardado(s) apagado(s), 0 mantido(s)",
            "gone": "paciente {pid} apagado: 0 sessão(ões)", "session_gone": "sessão {new} apagada: 0 ficheiro(s)"}),
])
def test_cli_records_speak_the_language_of_lang(world, capsys, monkeypatch, lang, words):
    """``chakamo patients|sessions correct|erase`` and ``chakamo retention --lang es|en|pt``: what they print and
    their refusals (their own and the data layer's) in that language (they were English only, with no ``--lang``)."""
    from app.cli.main import main
    from app.settings import get_settings

    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(world["settings"].data_dir))
    monkeypatch.setenv("CHAKAMO_ENV", "development")
    monkeypatch.delenv("CHAKAMO_RETENTION_DAYS", raising=False)
    get_settings.cache_clear()
    pid, sid = world["pid"], world["sid"]
    words = {k: v.format(pid=pid, sid=sid, new="{new}") for k, v in words.items()}

    def said(argv, code=0):
        assert main([*argv, "--lang", lang]) == code, argv
        out = capsys.readouterr()
        return out.out if code == 0 else out.err

    fix = ["patients", "correct", "--clinic", "Ret", str(pid)]
    try:
        assert words["corrected"] in said([*fix, "--set", "name=Ana"])
        assert words["unchanged"] in said([*fix, "--set", "name=Ana"])
        assert words["pair"] in said([*fix, "--set", "name"], 2)
        assert words["field"] in said([*fix, "--set", "colour=red"], 2)
        assert words["date"] in said([*fix, "--set", "birth_date=ayer"], 2)
        assert words["number"] in said([*fix, "--set", "height_cm=alto"], 2)
        from app.cli.records import correct
        from app.store.errors import DomainError

        with pytest.raises(DomainError) as exc:   # the data layer's own refusal, by its catalogue code
            correct(None, "patient", clinic="Ret", row_id=pid, sets=["side=up"])
        assert exc.value.code == "store.unknown_value" and (lang == "en") == (exc.value.message(lang) == str(exc.value))
        assert exc.value.message(lang) in said([*fix, "--set", "side=up"], 2)
        assert words["confirm"] in said(["sessions", "erase", "--clinic", "Ret", str(sid), "--confirm", "X"], 2)
        assert words["off"] in said(["retention"], 2)
        monkeypatch.setattr("app.store.models.utcnow", lambda: world["last"] + dt.timedelta(days=31))
        due = said(["retention", "--days", "30"])
        assert words["due"] in due and words["line"] in due, due
        applied = said(["retention", "--days", "30", "--apply"])
        assert words["erased"] in applied and words["files"] in applied, applied
        new = _new_session(world, pid)   # "sesión 5 borrado": the participle agrees with the kind
        assert words["session_gone"].format(new=new) in said(["sessions", "erase", "--clinic", "Ret", str(new),
                                                              "--confirm", "RET-1"])
        assert words["gone"] in said(["patients", "erase", "--clinic", "Ret", str(pid), "--confirm", "RET-1"])
    finally:
        get_settings.cache_clear()
