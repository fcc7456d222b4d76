"""Requests give their pooled database connection back between thread hops (issue 16, the upload burst).

A ``def`` dependency and the ``def`` route after it run on different thread-pool threads; a request waiting for
its next thread must hold no connection, or every thread can end up waiting in the pool for a connection held
by a request that waits for a thread (what stalled reads in the 20-clinician burst)."""

from __future__ import annotations

from starlette.requests import Request
from web_helpers import clinic_token

from app.web.api.deps import get_principal


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

