"""The user's own account and the security audit trail (issue 16 findings 7, 9, 10c): self-service password
change that ends the other sessions, the password rules (length 12, the shipped common list and zxcvbn's
breached passwords, patterns, the user's own name), the list of one's sessions and ending them, the admins'
role changes, and the audit events of logins, refusals and account changes.  Every refusal speaks es/en/pt."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from web_helpers import clinic_token

EMAIL, PASSWORD, NEW = "ines.castro@clinic.test", "a long enough password", "seven brown owls at dawn"
ADMIN = "jefa@clinic.test"


@pytest.fixture
def world(settings, client):
    from app.cli import admin as admin_cli

    admin_cli.create_clinic(settings, "Oeste")
    uid = admin_cli.create_user(settings, clinic="Oeste", email=EMAIL, role="clinician", password=PASSWORD,
                                name="Inés Castro")
    admin_cli.create_user(settings, clinic="Oeste", email=ADMIN, role="admin", password=PASSWORD)
    return {"uid": uid}


def _browser(client, email=EMAIL, password=PASSWORD, address="192.0.2.1"):
    from fastapi.testclient import TestClient

    c = TestClient(client.app, client=(address, 40000))
    r = c.post("/api/v1/auth/login", json={"email": email, "password": password})
    assert r.status_code == 200, r.text
    c.headers["X-CSRF-Token"] = r.json()["csrf_token"]
    return c


def _events(client, action=None):
    admin = _browser(client, ADMIN, address="192.0.2.99")
    params = {"limit": 1000, **({"action": action} if action else {})}
    return admin.get("/api/v1/audit", params=params).json()


# ------------------------------------------------------------------------------------------- passwords
@pytest.mark.parametrize(("password", "code"), [
    ("aaaaaaaaaa", "password.too_short"), ("password123", "password.too_short"),  # the two examples
    ("elevenchars", "password.too_short"), ("aaaaaaaaaaaa", "password.pattern"), ("123456789012", "password.pattern"),
    ("abcabcabcabc", "password.pattern"), ("password1234", "password.common"), ("P4ssw0rd2024!", "password.common"),
    ("Contraseña2025", "password.common"), ("iloveyou2024!", "password.common"), ("inescastro2024", "password.personal"),
])
def test_weak_passwords_are_refused(password, code):
    from app.web.passwords import WeakPassword, check_password_strength

    with pytest.raises(WeakPassword) as info:
        check_password_strength(password, email=EMAIL, name="Inés Castro")
    assert info.value.code == code


#: passwords of real breach dumps, 12 characters or more, that the curated list alone let through (each passed
#: check_password_strength before the breached list was added): as listed, with case, digits or symbols around
#: them, spaced, or their digits split by dashes
BREACHED = ["leavemealone", "sonyericsson", "finalfantasy", "whosyourdaddy", "LeaveMeAlone2024", "Jamesbond007!",
            "I see dead people", "1234-5665-4321"]


@pytest.mark.parametrize("password", BREACHED)
def test_breached_passwords_are_refused_as_common(password, monkeypatch):
    from app.web import passwords

    with pytest.raises(passwords.WeakPassword) as info:
        passwords.check_password_strength(password, email=EMAIL, name="Inés Castro")
    assert info.value.code == "password.common"
    monkeypatch.setattr(passwords, "breached_passwords", lambda: frozenset())
    passwords.check_password_strength(password, email=EMAIL, name="Inés Castro")  # the breached list refused it


@pytest.mark.parametrize("password", [PASSWORD, NEW, "correct horse battery staple", "Tr0ub4dor&3xyz",
                                      "siete búhos pardos al alba", "Qz7!mountain-Lark-4411",
                                      # a listed word that is only a small part of it: not the listed password
                                      "&(]B7U+}@*Ll", "$00$8!%!weed", "кот-собака-лампа-1234"])
def test_ordinary_passphrases_pass(password):
    from app.web.passwords import check_password_strength

    check_password_strength(password, email=EMAIL, name="Inés Castro")


def test_the_list_ships_with_the_package():
    from app.web.passwords import COMMON_FILE, common_words

    assert COMMON_FILE.is_file() and len(common_words()) > 400
    assert {"password", "qwerty", "contrasena", "senha", "iloveyou", "admin"} <= common_words()


def test_the_breached_list_ships_with_the_installed_package_and_is_loaded_at_first_use():
    """zxcvbn's ranked list comes from the installed package with the network cut off, and importing the
    password rules (as ``chakamo``'s start-up and the web application do) does not import it."""
    code = """if True:
        import socket, sys
        from app.web import passwords, security
        assert "zxcvbn" not in sys.modules, "imported at start-up"
        def no_network(*args, **kwargs):
            raise OSError("no network in this test")
        socket.socket = socket.create_connection = socket.getaddrinfo = no_network
        words = passwords.breached_passwords()
        import zxcvbn
        print(len(words), "password" in words, "leavemealone" in words, zxcvbn.__file__)
    """
    repo = Path(__file__).resolve().parents[3]
    run = subprocess.run([sys.executable, "-c", code], cwd=repo, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    count, has_password, has_leavemealone, module = run.stdout.split()
    assert int(count) >= 10_000 and has_password == has_leavemealone == "True"  # ASVS 2.1.7: the top 10 000 at least
    # the installed package's data (in site-packages, also when the venv lies in the checkout), not a copy in the
    # repository's sources
    installed = Path(module).resolve()
    assert "site-packages" in installed.parts and (repo / "app") not in installed.parents, installed


def test_an_admin_cannot_create_a_user_with_a_weak_password_and_reads_why_in_spanish(client, world):
    admin = _browser(client, ADMIN)
    for weak in ("aaaaaaaaaa", "password123", "password1234"):
        r = admin.post("/api/v1/users", json={"email": "x@clinic.test", "role": "clinician", "password": weak},
                       headers={"Accept-Language": "es-ES,es;q=0.9,en;q=0.5"})
        assert r.status_code == 422 and "contraseña" in r.json()["detail"], r.text
    r = admin.post("/api/v1/users", json={"email": "x@clinic.test", "role": "clinician", "password": "password1234"},
                   headers={"Accept-Language": "pt-BR"})
    assert r.status_code == 422 and "palavra-passe" in r.json()["detail"]


def test_password_change_ends_the_other_sessions_only(client, world):
    here, there = _browser(client), _browser(client, address="198.51.100.2")
    r = here.post("/api/v1/auth/password", json={"current_password": "not my password", "new_password": NEW})
    assert r.status_code == 400 and r.headers["x-chakamo-code"] == "password.wrong_current"
    r = here.post("/api/v1/auth/password", json={"current_password": PASSWORD, "new_password": "inescastro2025!"})
    assert r.status_code == 422 and r.headers["x-chakamo-code"] == "password.personal"
    assert there.get("/api/v1/auth/me").status_code == 200  # nothing changed yet
    r = here.post("/api/v1/auth/password", json={"current_password": PASSWORD, "new_password": NEW})
    assert r.status_code == 200 and r.json()["ended_sessions"] == 1
    assert there.get("/api/v1/auth/me").status_code == 401  # the other browser is logged out
    assert here.get("/api/v1/auth/me").status_code == 200  # this one stays
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 401
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": NEW}).status_code == 200
    changes = _events(client, "password_change")
    assert [(e["status"], e["user_id"]) for e in changes] == [(200, world["uid"]), (400, world["uid"])]


def test_a_token_has_no_password_to_change(client, settings, world):
    h = clinic_token(settings, "Oeste")
    r = client.post("/api/v1/auth/password", json={"current_password": "x", "new_password": NEW}, headers=h)
    assert r.status_code == 400 and r.headers["x-chakamo-code"] == "account.browser_only"
    assert client.get("/api/v1/auth/sessions", headers=h).status_code == 400


# -------------------------------------------------------------------------------------------- sessions
def test_users_list_and_end_their_other_sessions(client, world):
    a, b, c = _browser(client), _browser(client, address="198.51.100.3"), _browser(client, address="203.0.113.4")
    rows = a.get("/api/v1/auth/sessions").json()
    assert len(rows) == 3 and sum(r["current"] for r in rows) == 1
    assert {r["client"] for r in rows} == {"192.0.2.1", "198.51.100.3", "203.0.113.4"}
    current = next(r["id"] for r in rows if r["current"])
    b_id = next(r["id"] for r in rows if r["client"] == "198.51.100.3")
    r = a.delete(f"/api/v1/auth/sessions/{current}")
    assert r.status_code == 400 and r.headers["x-chakamo-code"] == "account.this_session"
    assert a.delete(f"/api/v1/auth/sessions/{b_id}").status_code == 204
    assert b.get("/api/v1/auth/me").status_code == 401 and c.get("/api/v1/auth/me").status_code == 200
    assert a.delete(f"/api/v1/auth/sessions/{b_id}").status_code == 404
    # another user's session id is not this user's to end
    other = _browser(client, ADMIN, address="192.0.2.77")
    other_id = next(r["id"] for r in other.get("/api/v1/auth/sessions").json() if r["current"])
    assert a.delete(f"/api/v1/auth/sessions/{other_id}").status_code == 404
    assert a.post("/api/v1/auth/end-other-sessions").json() == {"ended_sessions": 1}
    assert c.get("/api/v1/auth/me").status_code == 401 and a.get("/api/v1/auth/me").status_code == 200
    assert other.get("/api/v1/auth/me").status_code == 200
    assert len(_events(client, "session_end")) == 2


# ------------------------------------------------------------------------------------------------ audit
def test_logins_failures_and_refusals_are_audited(client, settings, world):
    """Finding 7: logins, failed logins, 401 (bad credentials), 403 (role, CSRF) and account changes leave events."""
    from sqlalchemy import select

    from app.cli import admin as admin_cli
    from app.store.models import AuditEvent

    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": "wrong password!"}).status_code == 401
    assert client.post("/api/v1/auth/login", json={"email": "nobody@x.test", "password": "wrong"}).status_code == 401
    me = _browser(client)
    assert me.post("/api/v1/users", json={"email": "y@clinic.test", "role": "admin",
                                          "password": NEW}).status_code == 403  # a clinician: role too low
    assert me.post("/api/v1/patients", json={"external_id": "Q", "side": "left"},
                   headers={"X-CSRF-Token": "0" * 64}).status_code == 403
    assert client.get("/api/v1/patients", headers={"Authorization": "Bearer chk_made_up"}).status_code == 401
    boss = _browser(client, ADMIN, address="192.0.2.99")
    r = boss.post("/api/v1/users", json={"email": "otra.jefa@clinic.test", "role": "admin", "password": NEW})
    assert r.status_code == 201
    r = boss.patch(f"/api/v1/users/{world['uid']}", json={"role": "admin"})
    assert r.status_code == 200 and r.json()["role"] == "admin"
    assert boss.patch("/api/v1/users/999999", json={"role": "admin"}).status_code == 404
    token = admin_cli.create_token(settings, clinic="Oeste", label="ris")
    assert client.get("/api/v1/patients", headers={"Authorization": f"Bearer {token}"}).status_code == 200

    events = boss.get("/api/v1/audit", params={"limit": 1000}).json()
    got = [(e["action"], e["status"], e["actor"], e["detail"]) for e in reversed(events)]
    assert ("login_failed", 401, EMAIL, "wrong password") in got
    assert ("login", 200, EMAIL, "") in got
    assert ("denied", 403, EMAIL, "role clinician below admin") in got
    assert ("denied", 403, EMAIL, "missing or wrong CSRF header") in got
    assert any(a == "user_create" and s == 201 and who == ADMIN and "role admin" in d for a, s, who, d in got)
    assert ("user_change", 200, ADMIN, f"user {world['uid']}: role clinician -> admin") in got
    assert any(a == "token_create" and who == "operator (command line)" and "(ris)" in d for a, _, who, d in got)
    with client.app.state.db.session() as s:  # the events no clinic can be named for are kept too
        rows = s.scalars(select(AuditEvent).where(AuditEvent.clinic_id.is_(None))).all()
        kinds = {(r.action, r.status, r.detail) for r in rows}
    assert ("login_failed", 401, "unknown email") in kinds
    assert ("denied", 401, "unknown or revoked API token") in kinds


def test_an_admin_cannot_demote_or_deactivate_themselves(client, world):
    boss = _browser(client, ADMIN)
    me = next(u for u in boss.get("/api/v1/users").json() if u["email"] == ADMIN)
    r = boss.patch(f"/api/v1/users/{me['id']}", json={"role": "clinician"})
    assert r.status_code == 400 and r.headers["x-chakamo-code"] == "account.not_yourself"
    r = boss.patch(f"/api/v1/users/{world['uid']}", json={"active": False})
    assert r.status_code == 200 and r.json()["active"] is False
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 401


SAME_IN_ES_AND_PT = {"cli.kind_patient", "cli.stage_accelerometer", "cli.stage_magnetometer", "cli.stage_segments",
                     "cli.argparse_argument", "cli.argparse_ignored", "cli.argparse_expected_n"}
#: the same word in Spanish and English ("error")
SAME_IN_ES_AND_EN = {"cli.argparse_error"}


def test_every_message_exists_in_three_languages():
    from app.web.messages import CATALOGUE, LANGUAGES, placeholders

    for code, texts in CATALOGUE.items():
        assert set(texts) == set(LANGUAGES), code
        assert len({frozenset(placeholders(t)) for t in texts.values()}) == 1, code
        # really translated; a word Spanish and Portuguese write alike is listed
        assert len(set(texts.values())) == (2 if code in SAME_IN_ES_AND_PT | SAME_IN_ES_AND_EN else 3), code
        if code in SAME_IN_ES_AND_EN:
            assert texts["es"] == texts["en"] != texts["pt"], code


def test_the_language_is_negotiated():
    from starlette.requests import Request

    from app.web.messages import language

    def req(value):
        return Request({"type": "http", "headers": [(b"accept-language", value.encode())]})

    assert language(req("pt-BR,pt;q=0.9")) == "pt" and language(req("de-DE,es;q=0.3,en;q=0.7")) == "en"
    assert language(req("fr")) == "en" and language(None) == "en" and language(req("es;q=0,pt")) == "pt"
