"""Offboarding: ``chakamo tokens list|revoke`` and ``users deactivate|set-password``, checked through the CLI
functions, through ``app.cli.main.main`` and through the API (a revoked token, a deactivated user's open browser,
an old password after a reset)."""

from __future__ import annotations

import io

import pytest

CLINIC, EMAIL, PASSWORD = "Clínica Este", "ana@clinic.test", "a long enough password"
NEW_PASSWORD = "another long password"


@pytest.fixture
def cli_env(monkeypatch, settings):
    """``app.cli.main.main`` on the same data dir (hence database) as the ``client`` fixture's app."""
    from app.settings import get_settings

    monkeypatch.setenv("CHAKAMO_ENV", "development")
    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(settings.data_dir))
    if settings.database_url:
        monkeypatch.setenv("DATABASE_URL", settings.database_url)
    monkeypatch.setenv("CHAKAMO_WORKERS", "1")
    get_settings.cache_clear()
    yield
    get_settings.cache_clear()


@pytest.fixture
def user(settings):
    from app.cli import admin as admin_cli

    admin_cli.create_clinic(settings, CLINIC)
    admin_cli.create_user(settings, clinic=CLINIC, email=EMAIL, role="clinician", password=PASSWORD, name="Ana")


def login(client, email=EMAIL, password=PASSWORD):
    return client.post("/api/v1/auth/login", json={"email": email, "password": password})


def _sessions_of(settings, email: str) -> tuple[bool, int]:
    """(active, number of browser sessions) of the user ``email``, read from the database."""
    from sqlalchemy import func, select

    from app.store.database import Database
    from app.store.models import BrowserSession, User

    db = Database(settings.db_url)
    try:
        with db.session() as s:
            u = s.scalar(select(User).where(User.email == email))
            n = s.scalar(select(func.count()).select_from(BrowserSession).where(BrowserSession.user_id == u.id))
            return u.active, n
    finally:
        db.dispose()


# ------------------------------------------------------------------------------------------------ tokens
def test_revoked_token_gets_401_and_the_others_still_work(client, settings, cli_env, capsys):
    from web_helpers import clinic_token

    from app.cli import admin as admin_cli
    from app.cli.main import main

    his = clinic_token(settings, CLINIC)
    lab = clinic_token(settings, CLINIC, role="read_only")
    other_clinic = clinic_token(settings, "Otra")
    for h in (his, lab, other_clinic):
        assert client.get("/api/v1/patients", headers=h).status_code == 200

    rows = admin_cli.list_tokens(settings, clinic=CLINIC)
    assert [(r["role"], r["label"], r["revoked_at"]) for r in rows] == [("clinician", "tests", None),
                                                                        ("read_only", "tests", None)]
    assert rows[0]["created_at"].tzinfo is not None
    his_id = rows[0]["id"]

    # the listing shows ids, roles and dates but never a token
    assert main(["tokens", "list", "--clinic", CLINIC]) == 0
    out = capsys.readouterr().out
    assert "revoked" in out.splitlines()[0] and str(his_id) in out and "read_only" in out
    for h in (his, lab, other_clinic):
        assert h["Authorization"].removeprefix("Bearer ") not in out
    assert "chk_" not in out

    assert main(["tokens", "revoke", str(his_id)]) == 0
    assert "revoked" in capsys.readouterr().out
    r = client.get("/api/v1/patients", headers=his)
    assert r.status_code == 401 and "revoked" in r.json()["detail"]
    assert client.get("/api/v1/auth/me", headers=his).status_code == 401
    assert client.get("/api/v1/patients", headers=lab).status_code == 200  # only that one
    assert client.get("/api/v1/patients", headers=other_clinic).status_code == 200

    rows = admin_cli.list_tokens(settings, clinic=CLINIC)
    assert rows[0]["revoked_at"] is not None and rows[1]["revoked_at"] is None
    first = rows[0]["revoked_at"]
    # revoking again changes nothing (scripts may run twice) and says so
    assert main(["tokens", "revoke", str(his_id)]) == 0
    assert "already revoked" in capsys.readouterr().out
    assert admin_cli.list_tokens(settings, clinic=CLINIC)[0]["revoked_at"] == first
    assert client.get("/api/v1/patients", headers=his).status_code == 401

    assert len(admin_cli.list_tokens(settings, clinic="Otra")) == 1  # each clinic sees its own


def test_token_errors_are_one_clear_sentence(settings, cli_env, capsys):
    from app.cli import admin as admin_cli
    from app.cli.main import main

    admin_cli.create_clinic(settings, CLINIC)
    assert main(["tokens", "list", "--clinic", CLINIC]) == 0
    assert "no API tokens" in capsys.readouterr().out
    assert main(["tokens", "revoke", "999"]) == 2
    assert "no API token with id 999" in capsys.readouterr().err
    assert main(["tokens", "list", "--clinic", "Nowhere"]) == 2
    assert "no clinic named 'Nowhere'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="no API token with id 5"):
        admin_cli.revoke_token(settings, 5)
    with pytest.raises(SystemExit):  # argparse: an id must be a number
        main(["tokens", "revoke", "abc"])
    # the existing command is untouched
    assert main(["tokens", "create", "--clinic", CLINIC, "--label", "HIS"]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith("chk_")


# ------------------------------------------------------------------------------------------------- users
def test_deactivated_user_is_logged_out_at_once_and_cannot_log_in(client, settings, user, cli_env, capsys):
    from app.cli import admin as admin_cli
    from app.cli.main import main

    assert login(client).status_code == 200
    assert client.get("/api/v1/auth/me").status_code == 200
    assert _sessions_of(settings, EMAIL) == (True, 1)

    assert main(["users", "deactivate", "--email", " Ana@Clinic.TEST "]) == 0
    assert "1 browser session(s) closed" in capsys.readouterr().out
    assert _sessions_of(settings, EMAIL) == (False, 0)
    # the open browser (it still sends its cookie) is out at its next request
    assert client.cookies.get("chakamo_session")
    assert client.get("/api/v1/auth/me").status_code == 401
    assert client.get("/api/v1/patients").status_code == 401
    # and cannot log in again, not even with the right password
    r = login(client)
    assert r.status_code == 401 and "Wrong email or password" in r.json()["detail"]

    assert admin_cli.deactivate_user(settings, email=EMAIL) == 0  # twice: nothing left to close
    assert main(["users", "deactivate", "--email", "nobody@clinic.test"]) == 2
    assert "no user with the email 'nobody@clinic.test'" in capsys.readouterr().err


def test_deactivation_closes_every_browser_of_that_user_only(client, settings, user):
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli

    admin_cli.create_user(settings, clinic=CLINIC, email="bea@clinic.test", role="clinician", password=PASSWORD)
    # more browsers on the same app: separate cookie jars (no `with`: the app's lifespan already runs)
    second, colleague = TestClient(client.app), TestClient(client.app)
    assert login(client).status_code == 200
    assert login(second).status_code == 200
    assert login(colleague, email="bea@clinic.test").status_code == 200
    assert admin_cli.deactivate_user(settings, email=EMAIL) == 2
    assert client.get("/api/v1/auth/me").status_code == 401
    assert second.get("/api/v1/auth/me").status_code == 401
    assert colleague.get("/api/v1/auth/me").status_code == 200


def test_set_password_from_stdin(client, settings, user, cli_env, capsys, monkeypatch):
    from app.cli.main import main

    assert login(client).status_code == 200
    monkeypatch.setattr("sys.stdin", io.StringIO(NEW_PASSWORD + "\n"))
    assert main(["users", "set-password", "--email", EMAIL, "--password-stdin"]) == 0
    assert "1 browser session(s) closed" in capsys.readouterr().out
    assert client.get("/api/v1/auth/me").status_code == 401  # the session opened with the old password is gone
    client.cookies.clear()
    assert login(client).status_code == 401
    r = login(client, password=NEW_PASSWORD)
    assert r.status_code == 200 and r.json()["user"]["email"] == EMAIL
    assert client.get("/api/v1/auth/me").status_code == 200
    assert _sessions_of(settings, EMAIL) == (True, 1)

    # too short: refused with the users-create rule, nothing changes (the new session stays open)
    monkeypatch.setattr("sys.stdin", io.StringIO("short\n"))
    assert main(["users", "set-password", "--email", EMAIL, "--password-stdin"]) == 2
    assert "at least 12 characters" in capsys.readouterr().err
    assert client.get("/api/v1/auth/me").status_code == 200
    client.cookies.clear()
    assert login(client, password=NEW_PASSWORD).status_code == 200


def test_set_password_prompts_twice(client, settings, user, cli_env, capsys, monkeypatch):
    import getpass

    from app.cli import admin as admin_cli
    from app.cli.main import main

    answers = iter([NEW_PASSWORD, NEW_PASSWORD + "x"])
    monkeypatch.setattr(getpass, "getpass", lambda prompt="": next(answers))
    assert main(["users", "set-password", "--email", EMAIL]) == 2
    assert "the two passwords differ" in capsys.readouterr().err
    assert login(client).status_code == 200  # unchanged

    answers = iter([NEW_PASSWORD, NEW_PASSWORD])
    assert main(["users", "set-password", "--email", EMAIL]) == 0
    client.cookies.clear()
    assert login(client).status_code == 401 and login(client, password=NEW_PASSWORD).status_code == 200

    # an unknown email is said before any prompt
    def no_prompt(prompt=""):
        raise AssertionError("asked for a password of an unknown user")

    monkeypatch.setattr(getpass, "getpass", no_prompt)
    assert main(["users", "set-password", "--email", "nobody@clinic.test"]) == 2
    assert "no user with the email" in capsys.readouterr().err
    with pytest.raises(ValueError, match="no user with the email"):
        admin_cli.set_password(settings, email="nobody@clinic.test", password=NEW_PASSWORD)


def test_set_password_keeps_a_deactivated_account_closed(client, settings, user):
    from app.cli import admin as admin_cli

    admin_cli.deactivate_user(settings, email=EMAIL)
    assert admin_cli.set_password(settings, email=EMAIL, password=NEW_PASSWORD) == 0
    assert login(client, password=NEW_PASSWORD).status_code == 401


@pytest.mark.parametrize("lang, words", [
    ("es", {"none": "no hay tokens de API en", "created": "Solo se muestra ahora", "header": "creado",
            "revoked": "revocado: la API ahora le responde 401", "again": "ya se revocó el",
            "unknown": "no hay ningún token de API con id 999", "clinic": "no hay ninguna clínica llamada 'Nowhere'",
            "scope": "ámbito desconocido"}),
    ("pt", {"none": "não há tokens de API em", "created": "Só é mostrado agora", "header": "criado",
            "revoked": "revogado: a API agora responde 401", "again": "já foi revogado em",
            "unknown": "não há nenhum token de API com id 999", "clinic": "não há nenhuma clínica chamada 'Nowhere'",
            "scope": "âmbito desconhecido"}),
])
def test_chakamo_tokens_speaks_the_language_of_lang(settings, cli_env, capsys, lang, words):
    """``chakamo tokens create|rotate|list|revoke --lang es|pt``: every line it prints, and its refusals (its own,
    and the store's, e.g. an unknown scope), in that language (they were English whatever ``--lang``)."""
    from app.cli import admin as admin_cli
    from app.cli.main import main

    admin_cli.create_clinic(settings, CLINIC)
    assert main(["tokens", "list", "--clinic", CLINIC, "--lang", lang]) == 0
    assert words["none"] in capsys.readouterr().out
    assert main(["tokens", "create", "--clinic", CLINIC, "--label", "HIS", "--expires-days", "30", "--lang", lang]) == 0
    out = capsys.readouterr().out.splitlines()
    assert words["created"] in out[0] and out[-1].startswith("chk_")
    token_id = admin_cli.list_tokens(settings, clinic=CLINIC)[0]["id"]
    assert main(["tokens", "rotate", str(token_id), "--lang", lang]) == 0
    assert f"{token_id}" in capsys.readouterr().out.splitlines()[0]
    assert main(["tokens", "list", "--clinic", CLINIC, "--lang", lang]) == 0
    assert words["header"] in capsys.readouterr().out.splitlines()[0]
    assert main(["tokens", "revoke", str(token_id), "--lang", lang]) == 0
    assert words["revoked"] in capsys.readouterr().out
    assert main(["tokens", "revoke", str(token_id), "--lang", lang]) == 0
    assert words["again"] in capsys.readouterr().out
    for argv, key in ((["tokens", "revoke", "999"], "unknown"), (["tokens", "list", "--clinic", "Nowhere"], "clinic"),
                      (["tokens", "create", "--clinic", CLINIC, "--scope", "everything"], "scope")):
        assert main([*argv, "--lang", lang]) == 2
        assert words[key] in capsys.readouterr().err, argv


@pytest.mark.parametrize("lang, words", [
    ("es", {"clinic": "clínica 'Clínica Este' creada", "exists": "ya existe una clínica llamada",
            "empty": "el nombre de la clínica está vacío", "user": "usuario ana@clinic.test (clinician) creado en",
            "taken": "ya tiene una cuenta en", "email": "no es una dirección de correo",
            "short": "La contraseña debe tener al menos", "off": "desactivado: inicios de sesión rechazados",
            "changed": "contraseña de ana@clinic.test cambiada", "unknown": "no hay ningún usuario con el correo",
            "differ": "las dos contraseñas no coinciden", "prompt": "Contraseña (al menos"}),
    ("pt", {"clinic": "clínica 'Clínica Este' criada", "exists": "já existe uma clínica chamada",
            "empty": "o nome da clínica está vazio", "user": "utilizador ana@clinic.test (clinician) criado em",
            "taken": "já tem uma conta em", "email": "não é um endereço de e-mail",
            "short": "A palavra-passe deve ter pelo menos", "off": "desativado: inícios de sessão recusados",
            "changed": "palavra-passe de ana@clinic.test alterada", "unknown": "não há nenhum utilizador com o e-mail",
            "differ": "as duas palavras-passe não coincidem", "prompt": "Palavra-passe (pelo menos"}),
])
def test_chakamo_clinics_and_users_speak_the_language_of_lang(settings, cli_env, capsys, monkeypatch, lang, words):
    """``chakamo clinics create`` and ``chakamo users create|deactivate|set-password --lang es|pt``: what they
    print, their prompts and their refusals (their own and the password rules') in that language (they were
    English whatever the clinic's language, and had no ``--lang``)."""
    import getpass
    import io

    from app.cli.main import main

    def said(argv, code=0, stdin=None):
        if stdin is not None:
            monkeypatch.setattr("sys.stdin", io.StringIO(stdin))
        assert main([*argv, "--lang", lang]) == code, argv
        out = capsys.readouterr()
        return out.out if code == 0 else out.err

    assert words["clinic"] in said(["clinics", "create", CLINIC])
    assert words["exists"] in said(["clinics", "create", CLINIC], 2)
    assert words["empty"] in said(["clinics", "create", "  "], 2)
    new_user = ["users", "create", "--clinic", CLINIC, "--email", EMAIL, "--role", "clinician", "--password-stdin"]
    assert words["short"] in said(new_user, 2, "short\n")
    assert words["user"] in said(new_user, 0, PASSWORD + "\n")
    assert words["taken"] in said(new_user, 2, PASSWORD + "\n")
    assert words["email"] in said([*new_user[:4], "--email", "ana", *new_user[6:]], 2, PASSWORD + "\n")
    prompts = []
    answers = iter([NEW_PASSWORD, NEW_PASSWORD + "x"])
    monkeypatch.setattr(getpass, "getpass", lambda prompt="": prompts.append(prompt) or next(answers))
    assert words["differ"] in said(["users", "set-password", "--email", EMAIL], 2)
    assert words["prompt"] in prompts[0]
    assert words["changed"] in said(["users", "set-password", "--email", EMAIL, "--password-stdin"], 0,
                                    NEW_PASSWORD + "\n")
    assert words["off"] in said(["users", "deactivate", "--email", EMAIL])
    assert words["unknown"] in said(["users", "deactivate", "--email", "nobody@clinic.test"], 2)
