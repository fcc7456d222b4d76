"""Requests give their pooled database connection back between thread hops (issue 16, the upload burst).

A ``def`` dependency and the ``def`` route after it run on different thread-pool threads; a request waiting for
its next thread must hold no connection, or every thread can end up waiting in the pool for a connection held
by a request that waits for a thread (what stalled reads in the 20-clinician burst)."""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

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
    turns = client.app.state.session_turns
    assert REQUEST_SESSIONS < POOL_SIZE + POOL_OVERFLOW
    for _ in range(REQUEST_SESSIONS):  # every turn taken, as by requests parked between two thread hops
        client.portal.call(turns.acquire)
    with ThreadPoolExecutor(1) as pool:
        answer = pool.submit(client.get, "/api/v1/patients", headers=headers)
        deadline = time.monotonic() + 60
        while not turns._waiters and time.monotonic() < deadline:  # the request reached its turn's queue
            time.sleep(0.05)
        assert turns._waiters and not answer.done()
        client.portal.call(_release, turns)
        assert answer.result(timeout=60).status_code == 200
    for _ in range(REQUEST_SESSIONS - 1):
        client.portal.call(_release, turns)


async def _release(turns) -> None:
    turns.release()


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
