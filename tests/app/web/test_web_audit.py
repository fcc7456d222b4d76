"""The audit log (app/web/audit.py, GET /api/v1/audit): every read, download, export and change of a patient's data
leaves exactly one event naming the actor, the action and the patient; admins of the clinic alone can list it,
another clinic never sees it, no route changes it, and a read whose event cannot be written fails."""

from __future__ import annotations

import datetime as dt
import os
import re
from pathlib import Path

import pytest

from test_web_asvs import app_routes
from web_helpers import demo_files, make_settings, wait_job

PG = os.environ.get("CHAKAMO_TEST_POSTGRES_URL")
APP_DIR = Path(__file__).resolve().parents[3] / "app"
ADMIN_EMAIL, ADMIN_PASSWORD = "audit-admin@a.test", "a long enough password"


def _token(settings, clinic: str, role: str, label: str) -> tuple[dict[str, str], int]:
    """A bearer header of a new token and the token's id."""
    from sqlalchemy import select

    from app.cli import admin as admin_cli
    from app.store.database import Database
    from app.store.models import ApiToken
    from app.web.security import sha256_hex

    token = admin_cli.create_token(settings, clinic=clinic, role=role, label=label)
    db = Database(settings.db_url)
    with db.session() as s:
        token_id = s.scalar(select(ApiToken.id).where(ApiToken.token_sha256 == sha256_hex(token)))
    db.dispose()
    return {"Authorization": f"Bearer {token}"}, token_id


@pytest.fixture(scope="module")
def world(tmp_path_factory, demo_dir):
    """Clinic A: an admin user, a clinician token ("lab system"), a read-only token, two patients, one processed
    session; clinic B: an admin token and a patient of its own."""
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path_factory.mktemp("audit") / "data")
    admin_cli.create_clinic(settings, "Audit A")
    admin_cli.create_clinic(settings, "Audit B")
    user_id = admin_cli.create_user(settings, clinic="Audit A", email=ADMIN_EMAIL, role="admin",
                                    password=ADMIN_PASSWORD)
    a, a_token = _token(settings, "Audit A", "clinician", "lab system")
    a_admin, _ = _token(settings, "Audit A", "admin", "audit reader")
    a_ro, _ = _token(settings, "Audit A", "read_only", "viewer")
    b_admin, _ = _token(settings, "Audit B", "admin", "other clinic")
    with TestClient(create_app(settings)) as c:
        pid = c.post("/api/v1/patients", json={"external_id": "AUD-1", "side": "right"}, headers=a).json()["id"]
        pid2 = c.post("/api/v1/patients", json={"external_id": "AUD-2", "side": "left"}, headers=a).json()["id"]
        sid = c.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=a).json()["id"]
        assert c.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=a).status_code == 201
        job = wait_job(c, c.post(f"/api/v1/sessions/{sid}/process", json={}, headers=a).json()["job_id"], a)
        assert job["status"] == "done", job
        bpid = c.post("/api/v1/patients", json={"external_id": "B-1", "side": "right"}, headers=b_admin).json()["id"]
        yield {"c": c, "a": a, "a_token": a_token, "a_admin": a_admin, "a_ro": a_ro, "b_admin": b_admin,
               "pid": pid, "pid2": pid2, "sid": sid, "bpid": bpid, "user_id": user_id, "settings": settings,
               "demo_dir": demo_dir}


def _last_id(w) -> int:
    events = w["c"].get("/api/v1/audit", params={"limit": 1}, headers=w["a_admin"]).json()
    return events[0]["id"] if events else 0


def _new_events(w, after_id: int) -> list[dict]:
    r = w["c"].get("/api/v1/audit", params={"limit": 1000}, headers=w["a_admin"])
    assert r.status_code == 200, r.text
    return [e for e in r.json() if e["id"] > after_id]


# (method, path, action, patient key or None, session key or None); the path's {…} come from the world
READ_ROUTES = [
    ("GET", "/api/v1/patients", "list", None, None),
    ("GET", "/api/v1/patients?q=aud-1", "search", "pid", None),  # one match: that patient
    ("GET", "/api/v1/patients?q=AUD", "search", None, None),  # two matches: no single patient
    ("GET", "/api/v1/patients/{pid}", "view", "pid", None),
    ("GET", "/api/v1/patients/{pid}/sessions", "view", "pid", None),
    ("GET", "/api/v1/patients/{pid}/trend", "view", "pid", None),
    ("GET", "/api/v1/sessions/{sid}", "view", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/results", "view", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/report.pdf?lang=en", "download", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/angles.xlsx", "download", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/quaternions.xlsx", "download", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/report.html", "download", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/scene.viser", "download", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/scene.png", "download", "pid", "sid"),
    ("GET", "/api/v1/sessions/{sid}/timeseries.npz", "download", "pid", "sid"),
    ("GET", "/api/v1/fhir/DiagnosticReport/{sid}", "export", "pid", "sid"),
]


def _check_one(w, before: int, action: str, patient_id, session_id, resource: str) -> dict:
    events = _new_events(w, before)
    assert len(events) == 1, events
    e = events[0]
    assert (e["action"], e["patient_id"], e["session_id"]) == (action, patient_id, session_id), e
    assert e["actor_kind"] == "token" and e["token_id"] == w["a_token"] and e["user_id"] is None
    assert e["actor"] == f"token {w['a_token']} (lab system)"
    assert e["resource"] == resource and e["client"] == "testclient"
    return e


@pytest.mark.parametrize(("method", "path", "action", "patient", "session"), READ_ROUTES,
                         ids=[f"{m} {p}" for m, p, *_ in READ_ROUTES])
def test_each_read_leaves_exactly_its_event(world, method, path, action, patient, session):
    url = path.format(**world)
    before = _last_id(world)
    r = world["c"].request(method, url, headers=world["a"])
    assert r.status_code == 200, r.text[:300]
    _check_one(world, before, action, world[patient] if patient else None, world[session] if session else None,
               f"{method} {url.split('?')[0]}")  # the query string (a search term) is not stored


def test_creates_uploads_and_deletes_leave_their_events(world):
    w, c, a = world, world["c"], world["a"]
    before = _last_id(w)
    pid = c.post("/api/v1/patients", json={"external_id": "AUD-NEW", "side": "left"}, headers=a).json()["id"]
    _check_one(w, before, "create", pid, None, "POST /api/v1/patients")

    before = _last_id(w)
    sid = c.post(f"/api/v1/patients/{pid}/sessions", json={}, headers=a).json()["id"]
    _check_one(w, before, "create", pid, sid, f"POST /api/v1/patients/{pid}/sessions")

    before = _last_id(w)
    files = demo_files(w["demo_dir"])[:2]
    r = c.post(f"/api/v1/sessions/{sid}/recordings", files=files, headers=a)
    assert r.status_code == 201, r.text
    _check_one(w, before, "upload", pid, sid, f"POST /api/v1/sessions/{sid}/recordings")

    before = _last_id(w)
    rid = r.json()["recordings"][0]["id"]
    assert c.delete(f"/api/v1/sessions/{sid}/recordings/{rid}", headers=a).status_code == 204
    _check_one(w, before, "delete", pid, sid, f"DELETE /api/v1/sessions/{sid}/recordings/{rid}")


def test_refused_writes_leave_no_event(world):
    """A 409 (duplicate patient, duplicate file) rolls its event back with its work."""
    w, c, a = world, world["c"], world["a"]
    before = _last_id(w)
    assert c.post("/api/v1/patients", json={"external_id": "AUD-1", "side": "left"}, headers=a).status_code == 409
    files = demo_files(w["demo_dir"])[:1]
    assert c.post(f"/api/v1/sessions/{w['sid']}/recordings", files=files, headers=a).status_code == 409
    assert _new_events(w, before) == []


def test_a_processing_request_leaves_its_event(world):
    w, c, a = world, world["c"], world["a"]
    before = _last_id(w)
    r = c.post(f"/api/v1/sessions/{w['sid']}/process", json={"filter": "madgwick"}, headers=a)
    assert r.status_code == 202, r.text
    try:
        events = [e for e in _new_events(w, before) if e["action"] == "process"]
        assert len(events) == 1 and events[0]["patient_id"] == w["pid"] and events[0]["session_id"] == w["sid"]
    finally:
        assert wait_job(c, r.json()["job_id"], a)["status"] == "done"


def test_a_browser_user_is_named_by_id_and_email_and_can_be_filtered(world):
    w, c = world, world["c"]
    before = _last_id(w)
    from fastapi.testclient import TestClient  # a second client: its own cookie jar

    browser = TestClient(c.app)
    me = browser.post("/api/v1/auth/login", json={"email": ADMIN_EMAIL, "password": ADMIN_PASSWORD})
    assert me.status_code == 200, me.text
    assert browser.get(f"/api/v1/patients/{w['pid2']}").status_code == 200
    events = _new_events(w, before)
    assert [(e["actor_kind"], e["user_id"], e["actor"], e["action"], e["patient_id"]) for e in events] == \
        [("user", w["user_id"], ADMIN_EMAIL, "view", w["pid2"]),
         ("user", w["user_id"], ADMIN_EMAIL, "login", None)]  # newest first; the login names no patient
    mine = browser.get("/api/v1/audit", params={"user_id": w["user_id"]}).json()  # the admin user reads the log
    assert mine and {e["user_id"] for e in mine} == {w["user_id"]}


def test_another_clinics_ids_leave_a_denied_event_in_the_owners_log_only(world):
    """Finding 7: a cross-clinic 404 discloses nothing, and the clinic that owns the id sees the attempt
    (``denied``, 404); the caller's clinic's log gets nothing it could probe ids with."""
    w, c, b = world, world["c"], world["b_admin"]
    before = _last_id(w)
    b_before = max([e["id"] for e in c.get("/api/v1/audit", params={"limit": 1}, headers=b).json()] or [0])
    assert c.get(f"/api/v1/patients/{w['pid']}", headers=b).status_code == 404
    assert c.get(f"/api/v1/sessions/{w['sid']}/report.pdf", headers=b).status_code == 404
    assert c.get("/api/v1/patients/999999", headers=b).status_code == 404  # nobody's id: nobody's log
    events = _new_events(w, before)
    assert [(e["action"], e["status"], e["resource"], e["patient_id"]) for e in events] == \
        [("denied", 404, f"GET /api/v1/sessions/{w['sid']}/report.pdf", None),
         ("denied", 404, f"GET /api/v1/patients/{w['pid']}", None)]
    theirs = c.get("/api/v1/audit", params={"limit": 1000}, headers=b).json()
    assert [e for e in theirs if e["id"] > b_before] == []
    assert theirs and {e["patient_id"] for e in theirs} <= {w["bpid"], None}
    assert all(e["actor"] == f"token {e['token_id']} (other clinic)" for e in theirs if e["actor_kind"] == "token")
    assert c.get("/api/v1/audit", params={"patient_id": w["pid"]}, headers=b).json() == []
    ours = c.get("/api/v1/audit", params={"limit": 1000}, headers=w["a_admin"]).json()
    assert w["bpid"] not in {e["patient_id"] for e in ours}


def test_only_admins_read_the_log(world):
    c = world["c"]
    for h in (world["a"], world["a_ro"]):
        r = c.get("/api/v1/audit", headers=h)
        assert r.status_code == 403 and "admin" in r.json()["detail"]
    assert c.get("/api/v1/audit").status_code == 401


def test_filters_order_and_limit(world):
    w, c, h = world, world["c"], world["a_admin"]
    # a download of its own: the module's tests may run on other workers (pytest-xdist), so none may have happened
    assert c.get(f"/api/v1/sessions/{w['sid']}/angles.xlsx", headers=w["a"]).status_code == 200
    all_events = c.get("/api/v1/audit", params={"limit": 1000}, headers=h).json()
    ids = [e["id"] for e in all_events]
    assert ids == sorted(ids, reverse=True) and len(ids) > 5  # newest first
    by_patient = c.get("/api/v1/audit", params={"patient_id": w["pid2"], "limit": 1000}, headers=h).json()
    assert by_patient and {e["patient_id"] for e in by_patient} == {w["pid2"]}
    assert len(by_patient) == sum(e["patient_id"] == w["pid2"] for e in all_events)
    downloads = c.get("/api/v1/audit", params={"action": "download", "limit": 1000}, headers=h).json()
    assert downloads and {e["action"] for e in downloads} == {"download"}
    assert len(c.get("/api/v1/audit", params={"limit": 2}, headers=h).json()) == 2
    page2 = c.get("/api/v1/audit", params={"limit": 2, "before_id": ids[1]}, headers=h).json()
    assert [e["id"] for e in page2] == ids[2:4]
    future = (dt.datetime.now(dt.timezone.utc) + dt.timedelta(hours=1)).isoformat()
    assert c.get("/api/v1/audit", params={"since": future}, headers=h).json() == []
    past = (dt.datetime.now(dt.timezone.utc) - dt.timedelta(hours=1)).replace(tzinfo=None).isoformat()
    assert len(c.get("/api/v1/audit", params={"since": past, "limit": 1000}, headers=h).json()) == len(ids)
    for bad in ({"limit": 1001}, {"limit": 0}, {"action": "erase"}):
        assert c.get("/api/v1/audit", params=bad, headers=h).status_code == 422, bad


def test_the_log_is_append_only_from_the_api(world):
    """No route but GET reaches the audit log, and no product code but app/web/audit.py writes AuditEvent (its
    rows are built by app/store/audit.py, which only app/web/audit.py calls to add one)."""
    c, h = world["c"], world["a_admin"]
    audit_routes = [(m, p) for m, p, _ in app_routes(c.app) if "audit" in p]
    assert audit_routes == [("GET", "/api/v1/audit")]
    some_id = c.get("/api/v1/audit", params={"limit": 1}, headers=h).json()[0]["id"]
    for method in ("PUT", "PATCH", "DELETE", "POST"):
        assert c.request(method, "/api/v1/audit", headers=h).status_code == 405
        assert c.request(method, f"/api/v1/audit/{some_id}", headers=h).status_code in (404, 405)
    writers = []
    for path in APP_DIR.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        rel = path.relative_to(APP_DIR).as_posix()
        if re.search(r"(update|delete)\(\s*AuditEvent|AuditEvent\.__table__\.(update|delete)", text):
            writers.append(rel)
        if "AuditEvent(" in text and rel not in ("store/audit.py", "store/models.py"):
            writers.append(rel)
        if "add_event(" in text and rel not in ("web/audit.py", "store/audit.py"):
            writers.append(rel)
    assert writers == []


def _fail_closed(settings, create_trigger: list[str]) -> None:
    """With audit inserts refused by the database, a read of a patient answers 500 without the patient."""
    from fastapi.testclient import TestClient
    from sqlalchemy import text

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    with TestClient(create_app(settings), raise_server_exceptions=False) as c:
        admin_cli.create_clinic(settings, "Closed")
        h = {"Authorization": f"Bearer {admin_cli.create_token(settings, clinic='Closed')}"}
        pid = c.post("/api/v1/patients", json={"external_id": "SECRET-77", "side": "right", "name": "Ana Secreta"},
                     headers=h).json()["id"]
        with c.app.state.db.engine.begin() as conn:
            for statement in create_trigger:  # a database that refuses the audit row (as a full disk would)
                conn.execute(text(statement))
        for url in (f"/api/v1/patients/{pid}", "/api/v1/patients", "/api/v1/patients?q=secret"):
            r = c.get(url, headers=h)
            assert r.status_code == 500, (url, r.status_code)
            assert "Secreta" not in r.text and "SECRET-77" not in r.text
        r = c.post("/api/v1/patients", json={"external_id": "X-2", "side": "right"}, headers=h)
        assert r.status_code == 500
        with c.app.state.db.session() as s:  # the write was rolled back with its event
            assert s.scalar(text("SELECT count(*) FROM patients WHERE external_id = 'X-2'")) == 0


def test_a_read_writes_its_event_only_inside_its_commit(tmp_path):
    """Issue 16 finding 2: an audited read takes the database's write lock only inside its commit.  Before, its
    event was flushed in the route (the lock taken there); FastAPI then validates a ``def`` route's answer on a
    thread-pool thread it must queue for, and commits after that, so the read held SQLite's one write lock while
    it queued for a pool thread — and when every pool thread was a request waiting for that lock (a flood of
    logins), nothing moved until SQLite's busy timeout: reads timed out at 30 s.  Observed on the real engine's
    events: each audit ``INSERT`` runs inside the session dependency's exit, which waits for no pool thread — in
    the group commit (:mod:`app.store.group_commit`, a read's event is all its transaction writes), after the
    request's session has closed."""
    import traceback

    from fastapi.testclient import TestClient
    from sqlalchemy import event

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    admin_cli.create_clinic(settings, "Locks")
    h = {"Authorization": f"Bearer {admin_cli.create_token(settings, clinic='Locks')}"}
    with TestClient(create_app(settings)) as c:
        pid = c.post("/api/v1/patients", json={"external_id": "LOCK-1", "side": "right"}, headers=h).json()["id"]
        engine, inserts = c.app.state.db.engine, []

        def on_execute(conn, cursor, statement, *args):
            if statement.lstrip().upper().startswith("INSERT INTO AUDIT_EVENTS"):
                stack = traceback.extract_stack()
                inserts.append(any(f.name == "get_db" for f in stack)
                               and any(f.name == "_insert" and f.filename.endswith(("store/group_commit.py", "store\\group_commit.py")) for f in stack))

        event.listen(engine, "before_cursor_execute", on_execute)
        try:
            for url in (f"/api/v1/patients/{pid}", "/api/v1/patients", f"/api/v1/patients/{pid}/sessions"):
                assert c.get(url, headers=h).status_code == 200
        finally:
            event.remove(engine, "before_cursor_execute", on_execute)
    assert inserts == [True] * 3, inserts


def test_a_read_whose_event_cannot_be_written_fails(tmp_path):
    _fail_closed(make_settings(tmp_path / "data"),
                 ["CREATE TRIGGER no_audit BEFORE INSERT ON audit_events BEGIN SELECT RAISE(ABORT, 'disk full'); END"])


@pytest.mark.skipif(not PG, reason="CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")
def test_a_read_whose_event_cannot_be_written_fails_on_postgresql(tmp_path, pg_url):
    _fail_closed(make_settings(tmp_path / "data", DATABASE_URL=pg_url),
                 ["CREATE FUNCTION no_audit() RETURNS trigger LANGUAGE plpgsql AS "
                  "$$ BEGIN RAISE EXCEPTION 'disk full'; END $$",
                  "CREATE TRIGGER no_audit BEFORE INSERT ON audit_events FOR EACH ROW EXECUTE FUNCTION no_audit()"])


@pytest.mark.skipif(not PG, reason="CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")
def test_events_and_their_listing_on_postgresql(tmp_path, pg_url):
    from fastapi.testclient import TestClient

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", DATABASE_URL=pg_url)
    with TestClient(create_app(settings)) as c:
        admin_cli.create_clinic(settings, "PG A")
        admin_cli.create_clinic(settings, "PG B")
        a, token_id = _token(settings, "PG A", "clinician", "ris")
        admin, _ = _token(settings, "PG A", "admin", "")
        b, _ = _token(settings, "PG B", "admin", "")
        pid = c.post("/api/v1/patients", json={"external_id": "PG-1", "side": "right"}, headers=a).json()["id"]
        assert c.get(f"/api/v1/patients/{pid}", headers=a).status_code == 200
        assert c.get("/api/v1/patients", headers=a).status_code == 200
        # (the command line's token creations are events of their own: the operator's, left out here)
        events = [e for e in c.get("/api/v1/audit", headers=admin).json() if e["actor_kind"] != "operator"]
        assert [(e["action"], e["patient_id"], e["token_id"]) for e in events] == \
            [("list", None, token_id), ("view", pid, token_id), ("create", pid, token_id)]
        since = events[1]["at"]
        assert [e["action"] for e in c.get("/api/v1/audit", params={"since": since}, headers=admin).json()] == \
            ["list", "view"]
        assert [e["action"] for e in c.get("/api/v1/audit", headers=b).json()] == ["token_create"]
