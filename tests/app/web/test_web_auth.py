"""Browser login: cookie flags, CSRF on every cookie-authenticated unsafe request, logout, users (admin)."""

from __future__ import annotations

import pytest

from web_helpers import hash_slots_held

EMAIL, PASSWORD = "admin@clinic.test", "a long enough password"


@pytest.fixture
def admin(settings):
    from app.cli import admin as admin_cli

    admin_cli.create_clinic(settings, "Clínica Sur")
    admin_cli.create_user(settings, clinic="Clínica Sur", email=EMAIL, role="admin", password=PASSWORD, name="Ana")


def login(client, email=EMAIL, password=PASSWORD):
    return client.post("/api/v1/auth/login", json={"email": email, "password": password})


def test_login_sets_a_strict_httponly_cookie_and_returns_csrf(client, admin):
    r = login(client)
    assert r.status_code == 200
    body = r.json()
    assert body["user"]["email"] == EMAIL and body["user"]["role"] == "admin"
    assert body["user"]["clinic"]["name"] == "Clínica Sur" and body["csrf_token"]
    cookie = r.headers["set-cookie"]
    assert cookie.startswith("chakamo_session=") and "HttpOnly" in cookie and "SameSite=strict" in cookie
    assert "Secure" not in cookie  # development: plain-http localhost
    me = client.get("/api/v1/auth/me").json()
    assert me["user"]["email"] == EMAIL and me["csrf_token"] == body["csrf_token"]


def test_secure_cookie_outside_development(tmp_path):
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli
    from app.web.main import create_app
    from app.settings import Settings

    settings = Settings(CHAKAMO_ENV="production", CHAKAMO_DATA_DIR=tmp_path, CHAKAMO_SECRET_KEY="k" * 40,
                        CHAKAMO_WORKERS=1)
    admin_cli.create_clinic(settings, "P")
    admin_cli.create_user(settings, clinic="P", email=EMAIL, role="admin", password=PASSWORD)
    with TestClient(create_app(settings), base_url="https://testserver") as c:
        r = login(c)
        assert r.status_code == 200 and "Secure" in r.headers["set-cookie"]


def test_wrong_credentials(client, admin):
    assert login(client, password="wrong password!").status_code == 401
    r = login(client, email="nobody@clinic.test")
    assert r.status_code == 401 and "Wrong email or password" in r.json()["detail"]


def slow_throttle(client, **policy):
    """The app's throttle with a delay base of 60 s (so no delay expires during a test on a slow machine)."""
    from dataclasses import replace

    throttle = client.app.state.login_throttle
    throttle.policy = replace(throttle.policy, base_s=60.0, **policy)
    return throttle.policy


def test_repeated_failures_are_delayed_even_for_the_right_password(client, admin):
    policy = slow_throttle(client)
    for _ in range(policy.free_per_pair):
        assert login(client, password="wrong password!").status_code == 401
    r = login(client)  # even the right password, until the delay passes
    assert r.status_code == 429 and "wait" in r.json()["detail"] and int(r.headers["retry-after"]) >= 30
    assert r.headers["x-chakamo-code"] == "login.throttled"
    assert login(client, email="other@clinic.test").status_code == 401  # other emails unaffected


def test_csrf_required_for_cookie_writes(client, admin):
    csrf = login(client).json()["csrf_token"]
    body = {"external_id": "P-9", "side": "left"}
    r = client.post("/api/v1/patients", json=body)
    assert r.status_code == 403 and "X-CSRF-Token" in r.json()["detail"]
    r = client.post("/api/v1/patients", json=body, headers={"X-CSRF-Token": "0" * 64})
    assert r.status_code == 403
    r = client.post("/api/v1/patients", json=body, headers={"X-CSRF-Token": csrf})
    assert r.status_code == 201
    assert client.get("/api/v1/patients").status_code == 200  # reads need no header
    # a 409 for the same external id, with a sentence
    r = client.post("/api/v1/patients", json=body, headers={"X-CSRF-Token": csrf})
    assert r.status_code == 409 and "already exists" in r.json()["detail"]
    # uploads too
    r = client.post("/api/v1/sessions/1/recordings", files=[("files", ("a.csv", b"x", "text/csv"))])
    assert r.status_code == 403


def test_logout_needs_csrf_and_closes_the_session(client, admin):
    csrf = login(client).json()["csrf_token"]
    assert client.post("/api/v1/auth/logout").status_code == 403
    r = client.post("/api/v1/auth/logout", headers={"X-CSRF-Token": csrf})
    assert r.status_code == 204 and 'chakamo_session=""' in r.headers["set-cookie"]
    assert client.get("/api/v1/auth/me").status_code == 401


def test_stolen_cookie_after_logout_is_dead(client, admin):
    csrf = login(client).json()["csrf_token"]
    sid = client.cookies.get("chakamo_session")
    client.post("/api/v1/auth/logout", headers={"X-CSRF-Token": csrf})
    client.cookies.set("chakamo_session", sid)
    assert client.get("/api/v1/auth/me").status_code == 401


def test_users_admin_only(client, admin, settings):
    csrf = login(client).json()["csrf_token"]
    h = {"X-CSRF-Token": csrf}
    r = client.post("/api/v1/users", json={"email": "Clin@Clinic.test", "name": "Carlos", "role": "clinician",
                                           "password": "another long one"}, headers=h)
    assert r.status_code == 201 and r.json()["email"] == "clin@clinic.test"
    r = client.post("/api/v1/users", json={"email": "clin@clinic.test", "name": "X", "role": "clinician",
                                           "password": "another long one"}, headers=h)
    assert r.status_code == 409 and r.headers["x-chakamo-code"] == "account.email_unavailable"
    r = client.post("/api/v1/users", json={"email": "x@clinic.test", "name": "X", "role": "clinician",
                                           "password": "short"}, headers=h)
    assert r.status_code == 422
    assert [u["email"] for u in client.get("/api/v1/users").json()] == [EMAIL, "clin@clinic.test"]
    # the clinician logs in and is refused the users list
    client.cookies.clear()
    login(client, "clin@clinic.test", "another long one")
    assert client.get("/api/v1/users").status_code == 403


def test_bearer_me_has_no_user_and_no_csrf(client, settings):
    from web_helpers import clinic_token

    h = clinic_token(settings, "Z")
    assert client.get("/api/v1/auth/me", headers=h).json() == {"user": None, "csrf_token": None}


def test_failures_from_one_address_are_throttled_across_emails(client, admin):
    """Guessing over many emails from one machine: past 30 attempts that address waits (429)."""
    policy = slow_throttle(client)
    for i in range(policy.free_per_address):
        assert login(client, email=f"guess{i}@clinic.test", password="wrong password!").status_code == 401
    r = login(client)  # a fresh email, right password, same address
    assert r.status_code == 429 and "from this computer" in r.json()["detail"]


def test_too_many_password_checks_at_once_answer_503(client, admin):
    """Every hashing thread and queue place busy (held here): a login answers 503 with Retry-After at once."""
    with hash_slots_held() as held:
        assert held >= 1
        r = login(client)
        assert r.status_code == 503 and "try again" in r.json()["detail"] and r.headers["retry-after"]
    assert login(client).status_code == 200
