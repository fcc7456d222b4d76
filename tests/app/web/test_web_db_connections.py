"""Requests give their pooled database connection back between thread hops (issue 16, the upload burst).

A ``def`` dependency and the ``def`` route after it run on different thread-pool threads; a request waiting for
its next thread must hold no connection, or every thread can end up waiting in the pool for a connection held
by a request that waits for a thread (what stalled reads in the 20-clinician burst)."""

from __future__ import annotations

import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor

import pytest
from sqlalchemy import event

from starlette.requests import Request
from web_helpers import clinic_token

from app.store.database import POOL_OVERFLOW, POOL_SIZE
from app.web.api.deps import REQUEST_SESSIONS, get_principal


def _request(app, headers: dict[str, str], path: str = "/api/v1/patients") -> Request:
    return Request({"type": "http", "method": "GET", "path": path, "raw_path": path.encode(), "query_string": b"",
                    "headers": [(k.lower().encode(), v.encode()) for k, v in headers.items()], "app": app,
                    "client": ("127.0.0.1", 1), "server": ("testserver", 80), "scheme": "http"})


def test_authenticating_ends_the_transaction_before_the_route_runs(client, settings):
    headers = clinic_token(settings, "A")
    database = client.app.state.db
    with database.session() as db:
        principal = get_principal(_request(client.app, headers), db, settings)
        assert not db.in_transaction()  # no transaction: the session holds no pooled connection
        assert principal.clinic_name == "A" and principal.role == "clinician"  # still loaded, usable by the route
    assert client.get("/api/v1/patients", headers=headers).status_code == 200


def test_requests_past_the_bound_wait_for_a_turn_without_a_session(client, settings):
    """At most ``REQUEST_SESSIONS`` requests hold a request session at once, fewer than the pool's connections; the
    next waits on the event loop (no thread, no connection) and goes on when a turn is given back."""
    headers = clinic_token(settings, "A")
    turns, pool_of_connections = client.app.state.session_turns, client.app.state.db.engine.pool
    for _ in range(REQUEST_SESSIONS):  # every turn taken, as by requests parked between two thread hops
        client.portal.call(turns.acquire)
    connections = pool_of_connections.checkedout()
    with ThreadPoolExecutor(1) as pool:
        answer = pool.submit(client.get, "/api/v1/patients", headers=headers)
        deadline = time.monotonic() + 60
        while not turns._waiters and time.monotonic() < deadline:  # the request reached its turn's queue
            time.sleep(0.05)
        assert turns._waiters and not answer.done()
        assert pool_of_connections.checkedout() == connections  # it waits holding no connection
        client.portal.call(_release, turns)
        assert answer.result(timeout=60).status_code == 200
    for _ in range(REQUEST_SESSIONS - 1):
        client.portal.call(_release, turns)


async def _release(turns) -> None:
    turns.release()


@pytest.mark.parametrize("who", ["unknown token", "malformed header", "closed browser session"])
@pytest.mark.parametrize("what", ["read", "upload"])
def test_a_refused_caller_never_holds_two_connections(client, settings, who, what):
    """A refusal is recorded in a session of its own (app.web.audit.record_refusal): the look-up's transaction
    ends first.  A thread holding one connection while it waits for a second breaks the turns' progress argument
    (a flood of wrong credentials on the upload route, which takes no turn, could hold every connection and wait
    for one more).  Before, an unknown token and a closed session held two; a malformed header is refused before any
    look-up (one before too: it guards the order, it did not fail)."""
    clinic_token(settings, "A")  # a clinic, so the refusal has somewhere to be recorded
    held, most, lock = Counter(), Counter(), threading.Lock()

    def checkout(*_):
        with lock:
            me = threading.get_ident()
            held[me] += 1
            most[me] = max(most[me], held[me])

    def checkin(*_):
        with lock:
            held[threading.get_ident()] -= 1

    headers, cookies = {"unknown token": ({"Authorization": "Bearer not-a-token"}, {}),
                        "malformed header": ({"Authorization": "Basic abc"}, {}),
                        "closed browser session": ({}, {"chakamo_session": "closed"})}[who]
    client.cookies.clear()
    client.cookies.update(cookies)
    pool = client.app.state.db.engine.pool
    event.listen(pool, "checkout", checkout)
    event.listen(pool, "checkin", checkin)
    try:
        if what == "read":
            answer = client.get("/api/v1/patients", headers=headers)
        else:
            answer = client.post("/api/v1/sessions/1/recordings", headers=headers,
                                 files=[("files", ("a.csv", b"t,x\n", "text/csv"))])
    finally:
        event.remove(pool, "checkout", checkout)
        event.remove(pool, "checkin", checkin)
        client.cookies.clear()
    assert answer.status_code == 401, answer.text
    assert most and max(most.values()) == 1, dict(most)


def test_many_parallel_reads_all_answer(client, settings):
    """Three times as many parallel reads as there are pooled connections: each answers 200 (none waits out the
    pool's timeout, as when every thread waited for a connection held by a request waiting for a thread)."""
    headers = clinic_token(settings, "A")
    n = 3 * (POOL_SIZE + POOL_OVERFLOW)
    with ThreadPoolExecutor(n) as pool:
        codes = list(pool.map(lambda _: client.get("/api/v1/patients", headers=headers).status_code, range(n)))
    assert codes == [200] * n


def test_the_liveness_probe_answers_while_every_request_thread_is_busy(client):
    """``/healthz`` says the process answers: it needs no thread of the request pool (during the upload burst it
    waited for one behind the reads, p95 116 ms to minutes)."""
    limiter = client.portal.call(_default_limiter)
    holders = [object() for _ in range(int(limiter.total_tokens))]
    for h in holders:
        client.portal.call(limiter.acquire_on_behalf_of, h)
    pool = ThreadPoolExecutor(1)
    try:
        answer = pool.submit(client.get, "/healthz")
        assert answer.result(timeout=60).status_code == 200
    finally:  # the threads given back first: a probe still waiting for one then ends too
        for h in holders:
            client.portal.call(_give_back, limiter, h)
        pool.shutdown()


async def _default_limiter():
    import anyio.to_thread

    return anyio.to_thread.current_default_thread_limiter()


async def _give_back(limiter, holder) -> None:
    limiter.release_on_behalf_of(holder)
