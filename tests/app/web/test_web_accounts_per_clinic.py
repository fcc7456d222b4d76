"""Accounts per clinic (issue 16 finding 10b) and the login's leftovers of the second review: an admin learns
nothing about other clinics' accounts; an email with accounts in two clinics logs in to the one it names; one
clinic's unlock never lifts the limit on another clinic's account; a throttled or failed login costs the same
statements whether its email has an account or not; a login without a client address (a unix socket) shares
no per-address counter or slot with every other one.  Each runs on SQLite and on PostgreSQL (``settings``)."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import replace

import pytest

EMAIL, PASSWORD_A, PASSWORD_B = "ana@hospital.test", "first long password", "second long password"


@pytest.fixture
def two_clinics(settings):
    """Clinics Norte and Sur, each with an admin; Ana has an account in Norte only."""
    from app.cli import admin as admin_cli

    for clinic in ("Norte", "Sur"):
        admin_cli.create_clinic(settings, clinic)
        admin_cli.create_user(settings, clinic=clinic, email=f"admin@{clinic.lower()}.test", role="admin",
                              password=PASSWORD_A)
    return admin_cli.create_user(settings, clinic="Norte", email=EMAIL, role="clinician", password=PASSWORD_A)


@contextmanager
def _client(app, address):
    from fastapi.testclient import TestClient

    c = TestClient(app, client=address)
    try:
        yield c
    finally:
        c.close()


def _login(c, email=EMAIL, password=PASSWORD_A, **extra):
    return c.post("/api/v1/auth/login", json={"email": email, "password": password, **extra})


def _admin(c, clinic: str) -> dict:
    r = _login(c, f"admin@{clinic.lower()}.test")
    assert r.status_code == 200, r.text
    return {"X-CSRF-Token": r.json()["csrf_token"]}


def _slow(app, **changes):
    throttle = app.state.login_throttle
    throttle.policy = replace(throttle.policy, base_s=60.0, **changes)
    return throttle.policy


def test_an_admin_learns_nothing_about_another_clinics_accounts(client, two_clinics):
    """Finding 10b: Sur's admin creates an account for an email Norte uses — 201, as for any new email (before:
    409, which told them that Norte has that person); the same email twice in Sur is still refused."""
    h = _admin(client, "Sur")
    new = {"email": EMAIL, "name": "Ana", "role": "clinician", "password": PASSWORD_B}
    r = client.post("/api/v1/users", json=new, headers=h)
    assert r.status_code == 201, r.text
    r = client.post("/api/v1/users", json=new, headers=h)
    assert r.status_code == 409 and r.headers["x-chakamo-code"] == "account.email_unavailable"
    assert "your clinic" in r.json()["detail"]
    assert EMAIL in [u["email"] for u in client.get("/api/v1/users").json()]


def test_an_email_with_two_accounts_logs_in_to_the_clinic_it_names(client, two_clinics):
    """Each clinic's account has its own password and opens its own clinic; without a clinic an email with two
    accounts is refused exactly like a wrong password (the same 401 sentence, which says to name the clinic)."""
    from app.cli import admin as admin_cli

    assert _login(client).status_code == 200  # one account: no clinic needed
    client.cookies.clear()
    admin_cli.create_user(client.app.state.settings, clinic="Sur", email=EMAIL, role="read_only",
                          password=PASSWORD_B)
    wrong = _login(client, password="not the password")
    ambiguous = _login(client)
    assert ambiguous.status_code == wrong.status_code == 401
    assert ambiguous.json() == wrong.json() and "clinic" in wrong.json()["detail"]
    for clinic, password, role in (("Norte", PASSWORD_A, "clinician"), ("Sur", PASSWORD_B, "read_only")):
        r = _login(client, password=password, clinic=clinic)
        assert r.status_code == 200 and r.json()["user"]["role"] == role, r.text
        assert client.get("/api/v1/auth/me").json()["user"]["clinic"]["name"] == clinic
        client.cookies.clear()
    assert _login(client, password=PASSWORD_B, clinic="Norte").status_code == 401  # the other clinic's password
    assert _login(client, clinic="Nowhere").status_code == 401


def test_one_clinics_unlock_does_not_lift_the_limit_on_anothers_account(client, two_clinics):
    """An admin of Sur can give Ana's email an account there and unlock it; that clears the email's counters
    and Sur's account counter, never Norte's: guesses at Norte's account stay limited."""
    from app.cli import admin as admin_cli

    sur_id = admin_cli.create_user(client.app.state.settings, clinic="Sur", email=EMAIL, role="clinician",
                                   password=PASSWORD_B)
    policy = _slow(client.app, free_per_pair=100, free_per_address=100)
    for i in range(policy.free_per_email):  # guesses at Norte's account from many addresses
        with _client(client.app, (f"198.51.100.{i + 1}", 40000)) as guesser:
            assert _login(guesser, password="a guess a guess", clinic="Norte").status_code == 401
    with _client(client.app, ("198.51.100.200", 40000)) as guesser:
        assert _login(guesser, password="a guess a guess", clinic="Norte").status_code == 429
        with _client(client.app, ("192.0.2.1", 40000)) as boss:
            r = boss.post(f"/api/v1/users/{sur_id}/unlock", headers=_admin(boss, "Sur"))
            assert r.status_code == 200
        r = _login(guesser, password="a guess a guess", clinic="Norte")
        assert r.status_code == 429 and r.headers["x-chakamo-code"] == "login.throttled"
        # Norte's own admin can unlock it
        with _client(client.app, ("192.0.2.2", 40000)) as boss:
            assert boss.post(f"/api/v1/users/{two_clinics}/unlock", headers=_admin(boss, "Norte")).status_code == 200
        assert _login(guesser, clinic="Norte").status_code == 200


class _Statements:
    """The SQL statements the app's engine runs while active (texts only: their parameters differ)."""

    def __init__(self, engine) -> None:
        self.engine, self.seen, self.on = engine, [], False

    def __call__(self, conn, cursor, statement, parameters, context, executemany):
        if self.on and threading.current_thread().name not in ("chakamo-sweeper", "chakamo-housekeeping"):
            self.seen.append(" ".join(statement.split()))

    @contextmanager
    def recording(self):
        from sqlalchemy import event

        self.seen, self.on = [], True
        event.listen(self.engine, "before_cursor_execute", self)
        try:
            yield self.seen
        finally:
            self.on = False
            event.remove(self.engine, "before_cursor_execute", self)


def _same_work(client, email_a: str, email_b: str, password: str) -> tuple[list, list]:
    spy = _Statements(client.app.state.db.engine)
    out = []
    for email in (email_a, email_b):
        with spy.recording() as seen:
            r = _login(client, email, password)
        out.append((r.status_code, [s for s in seen if "job" not in s.lower()]))
    return out[0], out[1]


def test_a_throttled_login_costs_the_same_whether_its_email_has_an_account(client, two_clinics):
    """Second review: a refused (429) login of an email with an account wrote an audit event and one of an unknown
    email did not — about 1.3 ms that told a guesser which emails exist.  Now both run the same statements; and
    a failed (401) login runs the same statements for a wrong password as for an unknown email."""
    known, unknown = _same_work(client, EMAIL, "nobody@hospital.test", "a wrong password")
    assert known[0] == unknown[0] == 401
    assert known[1] == unknown[1] and any("audit_events" in s for s in known[1])
    _slow(client.app, free_per_email=0, free_per_pair=0, free_per_address=1000)
    _login(client, EMAIL, "wrong again, now delayed")
    _login(client, "nobody@hospital.test", "wrong again, now delayed")
    known, unknown = _same_work(client, EMAIL, "nobody@hospital.test", "a wrong password")
    assert known[0] == unknown[0] == 429
    assert known[1] == unknown[1] and any("INSERT INTO audit_events" in s for s in known[1]), known[1]


def test_logins_without_a_client_address_share_no_per_address_counter_or_slot(client, two_clinics, monkeypatch):
    """Behind a unix socket there is no client address.  Every such login used to be keyed as the one address
    "-": the ``pair:`` counter (5 free) then delayed the email for everybody after 5 failures (the lock-out of
    finding 10a), and 4 logins in flight held every login slot of the server.  Now nothing is kept per address:
    the email's own counter (20 free) and the hashing queue still bound them."""
    from app.web import security

    monkeypatch.setattr(security, "HASH_QUEUE", 200)  # room for every login of the burst
    policy = _slow(client.app)
    with _client(client.app, None) as anon:
        for _ in range(policy.free_per_pair + 1):
            assert _login(anon, password="somebody else guessing").status_code == 401
        assert _login(anon).status_code == 200  # before: 429, the shared "-" pair counter was delayed
        anon.cookies.clear()
        release = threading.Event()
        busy = [security._submit(release.wait, 60) for _ in range(security.HASH_CONCURRENCY)]
        try:
            n = policy.max_in_flight + 1
            with ThreadPoolExecutor(n) as pool:
                waiting = [pool.submit(_login, anon, f"u{i}@hospital.test", "wrong password!") for i in range(n)]
                for _ in range(600):
                    if security.hashes_admitted() >= security.HASH_CONCURRENCY + n:
                        break
                    release.wait(0.05)
                assert security.hashes_admitted() == security.HASH_CONCURRENCY + n  # all five inside
                release.set()
                assert [f.result().status_code for f in waiting] == [401] * n
        finally:
            release.set()
            for f in busy:
                f.result()
