"""Login under attack (issue 16 findings 1, 2, 10a): attempts reserved before the password check, counted in the
database across servers, progressive delays instead of a lock-out, an admin's unlock, and logins that wait for
the hashing pool without holding a request thread.  Each runs on SQLite and on PostgreSQL (``settings``)."""

from __future__ import annotations

import threading
from contextlib import contextmanager
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import pytest

from web_helpers import clinic_token

EMAIL, PASSWORD = "owner@clinic.test", "a long enough password"
ADMIN_EMAIL = "boss@clinic.test"


@pytest.fixture
def accounts(settings):
    from app.cli import admin as admin_cli

    admin_cli.create_clinic(settings, "Norte")
    uid = admin_cli.create_user(settings, clinic="Norte", email=EMAIL, role="clinician", password=PASSWORD)
    admin_cli.create_user(settings, clinic="Norte", email=ADMIN_EMAIL, role="admin", password=PASSWORD)
    return uid


@contextmanager
def _client(app, address: str):
    """A client of the running ``app`` from ``address`` (the app's lifespan is the ``client`` fixture's)."""
    from fastapi.testclient import TestClient

    c = TestClient(app, client=(address, 40000))
    try:
        yield c
    finally:
        c.close()


def _slow(app, **changes):
    """Delays that cannot expire during the test (base 60 s), other numbers as given."""
    throttle = app.state.login_throttle
    throttle.policy = replace(throttle.policy, base_s=60.0, **changes)
    return throttle.policy


def _burst(clients, passwords, email=EMAIL) -> list[int]:
    """The status codes of ``len(passwords)`` logins sent at once (a barrier releases them together)."""
    barrier = threading.Barrier(len(passwords))

    def one(i):
        barrier.wait()
        r = clients[i % len(clients)].post("/api/v1/auth/login", json={"email": email, "password": passwords[i]})
        return r.status_code if r.status_code != 429 or r.headers.get("x-chakamo-code") == "login.throttled" \
            else f"429 {r.headers.get('x-chakamo-code')}"

    with ThreadPoolExecutor(len(passwords)) as pool:
        return list(pool.map(one, range(len(passwords))))


@pytest.fixture
def roomy_queue(monkeypatch):
    """A hashing queue long enough for a whole burst (so no login of it is answered 503 before its reservation)."""
    from app.web import security

    monkeypatch.setattr(security, "HASH_QUEUE", 200)


def test_a_parallel_burst_checks_no_more_passwords_than_allowed(client, accounts, roomy_queue):
    """Finding 1: 40 logins at once on one account — at most ``free_per_pair`` passwords are checked (each check
    answers 401), the others are refused unchecked (429); the right password after that is refused too, also
    inside a second burst."""
    policy = _slow(client.app, max_in_flight=100)
    codes = _burst([client], ["wrong password!"] * 40)
    assert codes.count(401) == policy.free_per_pair and codes.count(429) == 40 - policy.free_per_pair, codes
    codes = _burst([client], ["wrong password!"] * 9 + [PASSWORD])
    assert codes == [429] * 10, codes


def test_the_count_holds_across_two_servers(settings, accounts, roomy_queue):
    """Two API servers on one database (the scaled-out deployment): a burst split between them is counted once.
    (The second app's lifespan is not run: the embedded job runner allows one server per database, and the
    login needs only the app's own database engine and throttle.)"""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    app_a, app_b = create_app(settings), create_app(settings)
    with TestClient(app_a, client=("10.1.1.1", 40000)) as a:
        b = TestClient(app_b, client=("10.1.1.1", 40001))
        policy = _slow(app_a, max_in_flight=100)
        _slow(app_b, max_in_flight=100)
        codes = _burst([a, b], ["wrong password!"] * 30)
        assert set(codes) == {401, 429} and codes.count(401) == policy.free_per_pair, sorted(codes)
        assert a.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 429
        assert b.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 429
        app_b.state.db.dispose()


def test_someone_who_knows_the_email_does_not_lock_its_owner_out(client, accounts):
    """Finding 10a: an attacker's failures from their address delay that address only; the owner, from another
    address, logs in (the old throttle refused the email everywhere for 15 minutes after 10 failures)."""
    policy = _slow(client.app)
    with _client(client.app, "198.51.100.7") as attacker, _client(client.app, "192.0.2.10") as owner:
        for _ in range(policy.free_per_pair):
            assert attacker.post("/api/v1/auth/login", json={"email": EMAIL, "password": "guess guess guess"}) \
                .status_code == 401
        for _ in range(5):
            r = attacker.post("/api/v1/auth/login", json={"email": EMAIL, "password": "guess guess guess"})
            assert r.status_code == 429 and int(r.headers["retry-after"]) >= 30
        assert owner.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 200


def test_the_delay_grows_with_each_attempt_and_an_admin_unlocks(client, accounts):
    """After the free attempts each one doubles the wait (1 s, 2 s, 4 s … capped); an admin clears it at once."""
    from sqlalchemy import select

    from app.store.models import LoginAttempts

    policy = client.app.state.login_throttle.policy
    throttle = client.app.state.login_throttle
    waits = []
    for _ in range(policy.free_per_pair + 3):  # reserved directly: the wait each reservation leaves behind
        assert throttle.reserve(EMAIL, "203.0.113.5") == 0.0
        with client.app.state.db.session() as s:
            row = s.get(LoginAttempts, f"pair:{EMAIL} 203.0.113.5")
            waits.append(row.delay_s)
        with client.app.state.db.session() as s:  # make the next attempt due now
            s.execute(LoginAttempts.__table__.update().where(LoginAttempts.key == row.key).values(next_s=0.0))
    assert waits == [0.0] * (policy.free_per_pair - 1) + [1.0, 2.0, 4.0, 8.0]
    _slow(client.app)
    with _client(client.app, "203.0.113.5") as victim:
        r = victim.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD})
        assert r.status_code == 200  # the last reservation's delay was cleared above
        for _ in range(policy.free_per_pair):
            victim.post("/api/v1/auth/login", json={"email": EMAIL, "password": "mistyped it again"})
        assert victim.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 429
        with _client(client.app, "192.0.2.50") as boss:
            csrf = boss.post("/api/v1/auth/login", json={"email": ADMIN_EMAIL, "password": PASSWORD}).json()["csrf_token"]
            r = boss.post(f"/api/v1/users/{accounts}/unlock", headers={"X-CSRF-Token": csrf})
            assert r.status_code == 200 and r.json()["cleared"] >= 2
            assert boss.post("/api/v1/users/999999/unlock", headers={"X-CSRF-Token": csrf}).status_code == 404
            events = boss.get("/api/v1/audit", params={"action": "unlock"}).json()
            assert len(events) == 1 and events[0]["actor"] == ADMIN_EMAIL
        assert victim.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 200
    with client.app.state.db.session() as s:
        assert s.scalar(select(LoginAttempts.attempts).where(LoginAttempts.key == f"email:{EMAIL}")) == 0


def test_logins_per_address_are_capped_and_refused_at_once(client, accounts):
    """Finding 2: with the hashing threads busy, logins wait inside the server (awaiting, queued); one address
    gets at most ``max_in_flight`` in — the next is answered 429 while the others still wait."""
    from app.web import security

    policy = _slow(client.app, max_in_flight=3)
    release = threading.Event()
    busy = [security._submit(release.wait, 60) for _ in range(security.HASH_CONCURRENCY)]
    try:
        with ThreadPoolExecutor(policy.max_in_flight) as pool:
            inside = [pool.submit(client.post, "/api/v1/auth/login",
                                  json={"email": f"u{i}@clinic.test", "password": "wrong password!"})
                      for i in range(policy.max_in_flight)]
            deadline = 600
            while security.hashes_admitted() < security.HASH_CONCURRENCY + policy.max_in_flight and deadline:
                release.wait(0.05)
                deadline -= 1
            r = client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD})
            assert r.status_code == 429 and r.headers["x-chakamo-code"] == "login.too_many_at_once"
            assert not any(f.done() for f in inside)  # the three are still waiting for a hash thread
            release.set()
            assert [f.result().status_code for f in inside] == [401] * policy.max_in_flight
    finally:
        release.set()
        for f in busy:
            f.result()


def test_waiting_logins_hold_no_request_thread(client, settings, accounts):
    """Finding 2: more logins wait for the hashing pool than the server has request threads (40), and a
    clinician's read is answered meanwhile — before any of the waiting logins is.  (Before: each waiting login
    held one of the threads, and the read queued behind them.)"""
    from app.web import security

    _slow(client.app, max_in_flight=1000, free_per_address=1000)
    reader = clinic_token(settings, "Norte")
    n = 60
    old_queue = security.HASH_QUEUE
    security.HASH_QUEUE = n + 10  # (restored below)
    release = threading.Event()
    busy = [security._submit(release.wait, 120) for _ in range(security.HASH_CONCURRENCY)]
    try:
        with ThreadPoolExecutor(n) as pool:
            waiting = [pool.submit(client.post, "/api/v1/auth/login",
                                   json={"email": f"flood{i}@clinic.test", "password": "wrong password!"})
                       for i in range(n)]
            deadline = 1200
            while security.hashes_admitted() < security.HASH_CONCURRENCY + n and deadline:
                release.wait(0.05)
                deadline -= 1
            done = [f.result().status_code for f in waiting if f.done()]
            assert security.hashes_admitted() == security.HASH_CONCURRENCY + n, done  # all 60 inside, waiting
            assert client.get("/api/v1/patients", headers=reader).status_code == 200
            assert not any(f.done() for f in waiting)
            release.set()
            assert {f.result().status_code for f in waiting} == {401}
    finally:
        security.HASH_QUEUE = old_queue
        release.set()
        for f in busy:
            f.result()


@contextmanager
def _writes_held(db):
    """The login counters' table locked against writes by another connection until the block ends (a writer
    holding SQLite's one write lock; on PostgreSQL an EXCLUSIVE table lock, plain reads still pass)."""
    raw = db.engine.raw_connection()
    try:
        cursor = raw.cursor()
        if db.engine.dialect.name == "sqlite":
            cursor.execute("BEGIN IMMEDIATE")
        else:
            cursor.execute("LOCK TABLE login_attempts IN EXCLUSIVE MODE")
        yield
    finally:
        raw.rollback()
        raw.close()


def test_logins_beyond_the_servers_capacity_are_refused_at_once(client, accounts):
    """Finding 2 with many addresses (the per-address cap refuses nobody): at most as many logins as the hashing
    pool holds are inside the server at once — the next are answered 503 at once, while those inside still wait
    for the database.  (Before: the gate counted only hashes, so every login of a flood went in, each held a
    request thread waiting for SQLite's write lock to reserve its attempt, and a clinician's reads waited behind
    them for a thread: reads timed out at 30 s under 120 parallel logins from 120 addresses.)"""
    from app.web import security

    _slow(client.app, free_per_address=1000)
    capacity = security.HASH_CONCURRENCY + security.HASH_QUEUE
    extra = 3
    with ThreadPoolExecutor(capacity + extra) as pool, _writes_held(client.app.state.db):
        def one(i):
            with _client(client.app, f"198.51.100.{10 + i}") as c:  # one address each
                return c.post("/api/v1/auth/login", json={"email": f"flood{i}@clinic.test", "password": "wrong!"})

        logins = [pool.submit(one, i) for i in range(capacity + extra)]
        deadline = 200  # 10 s, within SQLite's busy timeout (15 s)
        while sum(f.done() for f in logins) < extra and deadline:
            threading.Event().wait(0.05)
            deadline -= 1
        refused = [f.result() for f in logins if f.done()]
        assert len(refused) == extra and {(r.status_code, r.headers["x-chakamo-code"]) for r in refused} \
            == {(503, "login.busy")}, [r.status_code for r in refused]
        assert "retry-after" in refused[0].headers
        inside = [f for f in logins if not f.done()]
        assert len(inside) == capacity  # still waiting for the database, each counted
    assert {f.result().status_code for f in inside} == {401}


def test_a_clinic_behind_one_address_is_not_slowed_by_its_own_successes(client, accounts):
    """Review finding: once an address had used its free failures, each *successful* login behind it doubled the
    address's delay (the refund gave the attempt back but kept the doubled delay), so a clinic behind one NAT
    address ended at one login per 15 min.  A success now restores the address counter as it was."""
    from app.store.models import LoginAttempts

    throttle = client.app.state.login_throttle
    policy = _slow(client.app, free_per_address=3)
    address = "203.0.113.77"
    with client.app.state.db.session() as s:  # the morning's typos from the clinic's address (other emails)
        for i in range(policy.free_per_address):
            assert throttle.reserve(f"typo{i}@clinic.test", address) == 0.0
        s.execute(LoginAttempts.__table__.update().where(LoginAttempts.key == f"ip:{address}").values(next_s=0.0))
        s.commit()
    with _client(client.app, address) as clinic:
        for _ in range(6):  # successful logins by the clinic's staff, one after another
            assert clinic.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 200
    with client.app.state.db.session() as s:
        row = s.get(LoginAttempts, f"ip:{address}")
        assert row.attempts == policy.free_per_address and row.next_s == 0.0
        assert row.delay_s <= policy.base_s  # before the fix: 60 s doubled six times


def test_a_password_reset_during_a_login_wins(client, accounts, monkeypatch):
    """Review finding: a login checked against the old hash while an operator reset the password opened a session
    with the old password (and its rehash could overwrite the new hash).  The hash must still be the one checked."""
    from app.cli import admin as admin_cli
    from app.web.api import auth

    real_finish = auth._finish

    def reset_then_finish(*args, **kwargs):
        admin_cli.set_password(client.app.state.settings, email=EMAIL, password="Qz7!mountain-Lark-4411")
        return real_finish(*args, **kwargs)

    monkeypatch.setattr(auth, "_finish", reset_then_finish)
    r = client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD})
    assert r.status_code == 401 and r.headers["x-chakamo-code"] == "login.wrong"
    monkeypatch.setattr(auth, "_finish", real_finish)
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 401
    assert client.post("/api/v1/auth/login",
                       json={"email": EMAIL, "password": "Qz7!mountain-Lark-4411"}).status_code == 200


def test_an_ipv6_host_cannot_multiply_its_address_counters(client, accounts):
    """Review finding: a host given a /64 has 2^64 addresses; its counters are kept per /64 network, so guesses
    from many of its addresses share one address counter (IPv4 and IPv4-mapped addresses stay as they are)."""
    from app.web.throttle import client_key

    assert client_key("2001:db8:1:2::1") == client_key("2001:db8:1:2:ffff:abcd::9") == "2001:db8:1:2::/64"
    assert client_key("2001:db8:1:3::1") != client_key("2001:db8:1:2::1")
    assert client_key("::ffff:192.0.2.7") == client_key("192.0.2.7") == "192.0.2.7"
    assert client_key(None) is None and client_key("testclient") == "testclient"
    policy = _slow(client.app)
    for i in range(policy.free_per_pair):
        with _client(client.app, f"2001:db8:1:2::{i + 1:x}") as c:
            assert c.post("/api/v1/auth/login", json={"email": EMAIL, "password": "guess guess guess"}).status_code == 401
    with _client(client.app, "2001:db8:1:2::ff") as c:  # another address of the same /64: that pair is spent
        r = c.post("/api/v1/auth/login", json={"email": EMAIL, "password": "guess guess guess"})
        assert r.status_code == 429 and r.headers["x-chakamo-code"] == "login.throttled"
