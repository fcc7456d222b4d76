"""OWASP ASVS level 2 checks that guard the whole application, not one route: authentication on every route
(walked from the real app, so a route added without it fails here), roles on every unsafe method, password
storage (argon2id, legacy scrypt upgraded at login), SQL only through the ORM (a static scan of app/), hostile
patient text through the whole pipeline, and the cache and transport headers."""

from __future__ import annotations

import ast
import base64
import hashlib
import io
import re
import secrets
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

from web_helpers import clinic_token, demo_files, hash_slots_held, make_settings, new_session, wait_job

APP_DIR = Path(__file__).resolve().parents[3] / "app"
EMAIL, PASSWORD = "asvs@clinic.test", "a long enough password"

#: routes anyone may call, each with its reason; every other route must refuse a caller without credentials
PUBLIC = {
    ("POST", "/api/v1/auth/login"): "the login itself",
    ("GET", "/healthz"): "liveness probe of the orchestrator: no data",
    ("GET", "/readyz"): "readiness probe: database and broker reachable, no data",
    ("GET", "/"): "the single-page UI shell (static HTML, no data)",
    ("GET", "/vendor/plotly.min.js"): "a static library",
    ("GET", "/viser/"): "viser's client page (unpacked from the installed package, no data)",
    ("GET", "/viser/index.html"): "viser's client page (unpacked from the installed package, no data)",
    ("GET", "/viser/{name}"): "viser's client files (unpacked from the installed package, no data)",
    ("GET", "/docs"): "the API documentation page",
    ("GET", "/openapi.json"): "the API description (no data)",
}
#: mounted static folders (no data; files of the repository and of installed packages)
PUBLIC_MOUNTS = {"/docs-assets", "/static", "/viser"}
#: unsafe routes a read-only caller may use, each with its reason
READ_ONLY_MAY = {
    ("POST", "/api/v1/auth/login"): "anyone may log in",
    ("POST", "/api/v1/auth/logout"): "everyone may close their own session",
    ("POST", "/api/v1/auth/password"): "everyone may change their own password",
    ("DELETE", "/api/v1/auth/sessions/{session_id}"): "everyone may end their own other sessions",
    ("POST", "/api/v1/auth/end-other-sessions"): "everyone may end their own other sessions",
}
UNSAFE = {"POST", "PUT", "PATCH", "DELETE"}


# --------------------------------------------------------------------------------------- route walk
def app_routes(app) -> list[tuple[str, str | None, str]]:
    """``(method, path, kind)`` of every route of ``app``, included routers expanded (FastAPI ≥ 0.137 keeps an
    included router as one ``_IncludedRouter`` entry of ``app.routes``; its routes are under
    ``original_router`` with the include prefix in ``include_context``).  Mounts give ``(None, path, "mount")``."""
    out: list[tuple[str | None, str, str]] = []

    def walk(routes, prefix: str) -> None:
        for r in routes:
            sub = getattr(r, "original_router", None)
            if sub is not None:
                walk(sub.routes, prefix + r.include_context.prefix)
            elif getattr(r, "methods", None):
                out.extend((m, prefix + r.path, type(r).__name__) for m in sorted(r.methods - {"HEAD"}))
            else:
                out.append((None, prefix + r.path, "mount"))

    walk(app.routes, "")
    return out


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """An app with a clinic, a read-only token and a patient (ids for the paths)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path_factory.mktemp("asvs") / "data")
    ro = clinic_token(settings, "ASVS", role="read_only")
    clinician = clinic_token(settings, "ASVS")
    with TestClient(create_app(settings)) as client:
        pid, sid = new_session(client, clinician, "ASVS-1")
        yield {"c": client, "ro": ro, "clinician": clinician, "pid": pid, "sid": sid,
               "routes": app_routes(client.app)}


def _url(path: str, w) -> str:
    """``path`` with its parameters filled: the world's own ids (so a 404 cannot hide a missing check)."""
    return re.sub(r"\{(\w+)\}", lambda m: str({"patient_id": w["pid"], "session_id": w["sid"]}.get(m[1], 1)), path)


def test_the_route_walk_sees_every_documented_route(world):
    """The walk must not go quiet (FastAPI changed how included routers appear once): every operation of the
    OpenAPI document is in it, and so are the undocumented probes and pages."""
    walked = {(m, p) for m, p, _ in world["routes"] if m}
    documented = {(m.upper(), p) for p, ops in world["c"].app.openapi()["paths"].items() for m in ops}
    assert len(documented) >= 25 and documented <= walked, documented - walked
    assert set(PUBLIC) <= walked | {("GET", "/openapi.json")}, set(PUBLIC) - walked


def open_routes(client, routes, w) -> list[str]:
    """The routes of ``routes`` that do not answer 401 to a caller without credentials (public ones aside)."""
    bad = []
    for method, path, _ in routes:
        if method is None:
            if path not in PUBLIC_MOUNTS:
                bad.append(f"mount {path}: neither public nor checked")
        elif (method, path) not in PUBLIC:
            r = client.request(method, _url(path, w), json={} if method in UNSAFE else None)
            if r.status_code != 401:
                bad.append(f"{method} {path}: {r.status_code}")
    return bad


def unsafe_for_read_only(client, routes, w) -> list[str]:
    """The unsafe routes of ``routes`` that a read-only token is not refused (403) on."""
    bad = []
    for method, path, _ in routes:
        if method in UNSAFE and (method, path) not in READ_ONLY_MAY:
            r = client.request(method, _url(path, w), json={}, headers=w["ro"])
            if r.status_code != 403 or "role" not in r.json().get("detail", ""):
                bad.append(f"{method} {path}: {r.status_code}")
    return bad


def test_every_route_refuses_a_caller_without_credentials(world):
    assert sum(m is not None and (m, p) not in PUBLIC for m, p, _ in world["routes"]) >= 25
    assert open_routes(world["c"], world["routes"], world) == []


def test_methods_a_route_does_not_have_are_refused_too(world):
    """The other methods on every API path answer 404 or 405 even to a clinician who may call the path's own
    methods — never data, never a change (without credentials the router's 405 would say nothing of auth)."""
    c = world["c"]
    paths = {p for m, p, _ in world["routes"] if m and p.startswith("/api/")}
    for path in paths:
        mine = {m for m, p, _ in world["routes"] if p == path}
        for method in {"GET", "POST", "PUT", "PATCH", "DELETE"} - mine:
            r = c.request(method, _url(path, world), headers=world["clinician"])
            assert r.status_code in (404, 405), (method, path, r.status_code)


def test_a_read_only_token_may_not_use_any_unsafe_method(world):
    assert sum(m in UNSAFE for m, _, _ in world["routes"]) >= 8
    assert unsafe_for_read_only(world["c"], world["routes"], world) == []
    assert world["c"].get(f"/api/v1/patients/{world['pid']}", headers=world["ro"]).status_code == 200  # reads ok


def test_the_checks_catch_a_route_added_without_auth(world, settings):
    """The two walks above on an app with one careless route each: both are reported."""
    from fastapi import APIRouter, Depends
    from fastapi.testclient import TestClient

    from app.web.api.deps import require
    from app.web.main import create_app

    app = create_app(settings)
    careless = APIRouter(prefix="/api/v1")

    @careless.get("/patients-export")
    def export_without_auth():
        return []

    @careless.delete("/patients-everything")
    def delete_by_any_reader(principal=Depends(require("read_only"))):  # should have been clinician
        return {}

    app.include_router(careless)
    with TestClient(app) as c:
        routes = app_routes(app)
        assert open_routes(c, routes, world) == ["GET /api/v1/patients-export: 200"]
        assert unsafe_for_read_only(c, routes, world | {"ro": clinic_token(settings, "Careless", "read_only")}) \
            == ["DELETE /api/v1/patients-everything: 200"]


# ----------------------------------------------------------------------------------------- passwords
def _legacy_scrypt_hash(password: str) -> str:
    """A hash in the format earlier versions stored (``scrypt$n$r$p$salt$hash``), made here by hand."""
    salt = secrets.token_bytes(16)
    digest = hashlib.scrypt(password.encode(), salt=salt, n=2 ** 14, r=8, p=1, dklen=32)
    return f"scrypt$16384$8$1${base64.b64encode(salt).decode()}${base64.b64encode(digest).decode()}"


def _stored_hash(client) -> str:
    from sqlalchemy import select

    from app.store.models import User

    with client.app.state.db.session() as s:
        return s.scalar(select(User.password_hash).where(User.email == EMAIL))


def _set_hash(client, value: str) -> None:
    from sqlalchemy import update

    from app.store.models import User

    with client.app.state.db.session() as s:
        s.execute(update(User).where(User.email == EMAIL).values(password_hash=value))


def test_new_hashes_are_argon2id_with_the_documented_cost():
    from app.web import security

    h = security.hash_password(PASSWORD)
    assert h.startswith("$argon2id$v=19$m=65536,t=2,p=1$") and PASSWORD not in h
    assert security.hash_password(PASSWORD) != h  # a salt per hash
    assert security.verify_password(PASSWORD, h) and not security.verify_password(PASSWORD + "!", h)
    assert not security.needs_rehash(h)
    for damaged in ("$argon2id$v=19$m=65536,t=2,p=1$", "$argon2id$garbage", "scrypt$1$2$3", "", "plain"):
        assert not security.verify_password(PASSWORD, damaged), damaged


def test_legacy_and_weaker_hashes_verify_and_ask_for_a_rehash():
    from argon2 import PasswordHasher

    from app.web import security

    legacy = _legacy_scrypt_hash(PASSWORD)
    assert security.verify_password(PASSWORD, legacy) and not security.verify_password("wrong password!", legacy)
    weak = PasswordHasher(time_cost=1, memory_cost=8192, parallelism=1).hash(PASSWORD)
    assert security.verify_password(PASSWORD, weak)
    assert security.needs_rehash(legacy) and security.needs_rehash(weak) and security.needs_rehash("junk")


def test_login_upgrades_a_legacy_hash_once_the_password_is_right(settings, client):
    from app.cli import admin as admin_cli

    admin_cli.create_clinic(settings, "Legacy")
    admin_cli.create_user(settings, clinic="Legacy", email=EMAIL, role="clinician", password=PASSWORD)
    legacy = _legacy_scrypt_hash(PASSWORD)
    _set_hash(client, legacy)
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": "wrong password!"}).status_code == 401
    assert _stored_hash(client) == legacy  # a failed login changes nothing
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 200
    upgraded = _stored_hash(client)
    assert upgraded.startswith("$argon2id$") and upgraded != legacy
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 200
    assert _stored_hash(client) == upgraded  # current parameters: no new hash at every login


def test_login_upgrades_an_argon2_hash_with_weaker_parameters(settings, client):
    from argon2 import PasswordHasher

    from app.cli import admin as admin_cli

    admin_cli.create_clinic(settings, "Weak")
    admin_cli.create_user(settings, clinic="Weak", email=EMAIL, role="clinician", password=PASSWORD)
    _set_hash(client, PasswordHasher(time_cost=1, memory_cost=8192, parallelism=1).hash(PASSWORD))
    assert client.post("/api/v1/auth/login", json={"email": EMAIL, "password": PASSWORD}).status_code == 200
    assert _stored_hash(client).startswith("$argon2id$v=19$m=65536,t=2,p=1$")


def test_hashing_is_bounded_in_concurrency():
    """With every hashing thread and queue place taken, a new hash raises Busy (no waiting in line)."""
    from app.web import security

    with hash_slots_held() as held:
        assert held == security.HASH_CONCURRENCY + security.HASH_QUEUE
        with pytest.raises(security.Busy, match="try again"):
            security.hash_password(PASSWORD)
        with pytest.raises(security.Busy):
            security.verify_password(PASSWORD, _legacy_scrypt_hash(PASSWORD))
    assert security.hash_password(PASSWORD).startswith("$argon2id$")


# ------------------------------------------------------------------------------------ SQL via the ORM
#: the places of app/ that run SQL text, each with its reason.  Key: (file under app/, the SQL).
RAW_SQL_ALLOWED = {
    ("store/database.py", "PRAGMA journal_mode=WAL"): "SQLite connection setting on connect; no ORM equivalent",
    ("store/database.py", "PRAGMA foreign_keys=ON"): "SQLite connection setting on connect",
    ("store/database.py", "PRAGMA synchronous=FULL"): "SQLite connection setting on connect",
    ("web/main.py", "SELECT 1"): "/readyz: is the database reachable (no data, no input)",
    ("jobs/inprocess.py", "SELECT pg_try_advisory_lock(:k)"): "PostgreSQL advisory lock: one in-process runner "
                                                          "per database (a bound key, no ORM equivalent)",
    ("jobs/inprocess.py", "SELECT pg_advisory_unlock(:k)"): "its release",
    ("jobs/inprocess.py", "SELECT 1"): "is the lock's own connection (and the lock with it) still there (no data, "
                                       "no input)",
    ("store/models.py", "kind = 'fhir'"): "a partial unique index's constant predicate (one FHIR push per clinic); "
                                          "DDL, no input",
}
#: migrations are written by developers and run before any request: constant SQL there is allowed
MIGRATIONS = "store/migrations/"
_SQL_CALLS = {"execute", "exec_driver_sql", "executescript", "executemany", "scalar", "scalars"}


def raw_sql_places(source: str) -> list[tuple[int, str | None, str]]:
    """``(line, sql or None, how)`` of every SQL text in ``source``: ``text(...)`` / ``literal_column(...)``
    calls and string arguments of ``execute``-like calls.  ``sql`` is None when the SQL is not one constant
    string (an f-string, ``%``, ``+``, ``.format``, a variable: something could be formatted into it)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call) or not node.args:
            continue
        f = node.func
        name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
        arg = node.args[0]
        if isinstance(arg, ast.Constant) and not isinstance(arg.value, str):
            continue  # e.g. rows.scalar(0): no SQL text
        if name in ("text", "literal_column") and not (isinstance(f, ast.Attribute) and f.attr == "text"
                                                          and isinstance(f.value, ast.Name)
                                                          and f.value.id not in ("sa", "sqlalchemy")):
            how = name
        elif name in _SQL_CALLS and not isinstance(arg, ast.Call):
            if isinstance(arg, (ast.Name, ast.Attribute, ast.Subscript)) and name in ("scalar", "scalars"):
                continue  # db.scalar(stmt): an ORM statement in a variable
            if isinstance(arg, (ast.Name, ast.Attribute, ast.Subscript)) and name == "execute" \
                    and not (isinstance(f, ast.Attribute) and "cursor" in ast.unparse(f.value)):
                continue  # session.execute(stmt) with an ORM statement built above
            if isinstance(arg, ast.Name) and isinstance(f, ast.Attribute) and ast.unparse(f.value) == "super()":
                continue  # a cursor's override passing its caller's SQL on (the caller's own call is scanned)
            how = name
        else:
            continue
        sql = arg.value if isinstance(arg, ast.Constant) and isinstance(arg.value, str) else None
        found.append((node.lineno, sql, how))
    return sorted(found)


def test_the_sql_scan_finds_formatted_sql():
    """The scanner itself: it sees each way of writing SQL text and tells constants from formatted strings."""
    sample = '''
from sqlalchemy import text, select
db.execute(text("SELECT 1"))
db.execute(text(f"SELECT * FROM patients WHERE name = '{name}'"))
conn.exec_driver_sql("DELETE FROM x WHERE id = %s" % ident)
cursor.execute("PRAGMA foreign_keys=ON")
cursor.execute(query)
db.scalar(select(Patient).where(Patient.id == 3))
db.execute(stmt)
path.read_text()
'''
    places = raw_sql_places(sample)
    assert [(line, sql) for line, sql, _ in places] == [(3, "SELECT 1"), (4, None), (5, None),
                                                         (6, "PRAGMA foreign_keys=ON"), (7, None)]


def test_sql_only_through_the_orm():
    """Every SQL text in app/ is a listed constant (parameters bound, never formatted in); migrations may hold
    constant SQL.  A new place fails here: use the ORM, or list it with its reason."""
    unlisted, formatted, seen = [], [], set()
    for path in sorted(APP_DIR.rglob("*.py")):
        rel = path.relative_to(APP_DIR).as_posix()
        for line, sql, how in raw_sql_places(path.read_text(encoding="utf-8")):
            if sql is None:
                formatted.append(f"app/{rel}:{line} ({how}): SQL built from a non-constant string")
            elif rel.startswith(MIGRATIONS):
                continue
            elif (rel, sql) in RAW_SQL_ALLOWED:
                seen.add((rel, sql))
            else:
                unlisted.append(f"app/{rel}:{line} ({how}): {sql!r}")
    assert formatted == [] and unlisted == [], formatted + unlisted
    assert seen == set(RAW_SQL_ALLOWED), f"listed but gone (remove from the list): {set(RAW_SQL_ALLOWED) - seen}"


# ---------------------------------------------------------------------------------------- hostile text
HOSTILE_NAME = "<script>alert(1)</script>"
HOSTILE_FORMULA = '=HYPERLINK("http://x")'
HOSTILE_SQL = "'); DROP TABLE patients;--"


def _pdf_text(pdf: bytes, tmp_path: Path) -> str:
    path = tmp_path / "report.pdf"
    path.write_bytes(pdf)
    out = subprocess.run(["pdftotext", "-layout", "-enc", "UTF-8", str(path), "-"], check=True, capture_output=True)
    return re.sub(r"\s+", " ", out.stdout.decode("utf-8"))


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler-utils (pdftotext) not installed")
def test_hostile_patient_text_through_the_api_into_every_output(client, settings, demo_dir, tmp_path):
    """A patient named like a script, a formula and an SQL injection: stored and searched as plain data,
    escaped in report.html, literal in the PDF, inert text in the workbook; the patients table survives."""
    from openpyxl import load_workbook
    from sqlalchemy import inspect

    h = clinic_token(settings, "Hostile")
    r = client.post("/api/v1/patients", headers=h, json={"external_id": HOSTILE_SQL, "side": "right",
                                                          "name": HOSTILE_NAME})
    assert r.status_code == 201, r.text
    pid = r.json()["id"]
    assert [p["id"] for p in client.get("/api/v1/patients", params={"q": HOSTILE_SQL}, headers=h).json()] == [pid]
    assert client.get("/api/v1/patients", params={"q": "%"}, headers=h).json() == []  # LIKE wildcard is literal
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={"professional": HOSTILE_FORMULA,
                                                                 "notes": HOSTILE_SQL}, headers=h).json()["id"]
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "en"}, headers=h)
                   .json()["job_id"], h)
    assert job["status"] == "done", job

    html = client.get(f"/api/v1/sessions/{sid}/report.html", headers=h).text
    assert HOSTILE_NAME not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "=HYPERLINK(&quot;http://x&quot;)" in html and "&#x27;); DROP TABLE patients;--" in html

    text = _pdf_text(client.get(f"/api/v1/sessions/{sid}/report.pdf", headers=h).content, tmp_path)
    for s in (HOSTILE_NAME, HOSTILE_FORMULA, HOSTILE_SQL):
        assert s in text, s

    xlsx = client.get(f"/api/v1/sessions/{sid}/angles.xlsx", headers=h).content
    with zipfile.ZipFile(io.BytesIO(xlsx)) as z:
        sheets = [z.read(n).decode("utf-8") for n in z.namelist() if n.startswith("xl/worksheets/")]
    assert sheets and not any("<f>" in s or "<f " in s for s in sheets)  # no formula anywhere
    cells = [cell for ws in load_workbook(io.BytesIO(xlsx)).worksheets for row in ws.iter_rows() for cell in row
             if cell.value == HOSTILE_FORMULA]
    assert cells and all(c.data_type == "s" and c.quotePrefix for c in cells)

    with client.app.state.db.engine.connect() as conn:
        assert "patients" in inspect(conn).get_table_names()
    assert client.get(f"/api/v1/patients/{pid}", headers=h).json()["external_id"] == HOSTILE_SQL


# ------------------------------------------------------------------------------------------- headers
def test_api_answers_are_not_cached(world):
    c, h = world["c"], world["clinician"]
    for url in ("/api/v1/patients", f"/api/v1/patients/{world['pid']}", f"/api/v1/sessions/{world['sid']}",
                "/api/v1/patients/999999", "/api/v1/auth/me"):
        r = c.get(url, headers=h)
        assert r.headers["cache-control"] == "no-store", (url, r.status_code)
    assert c.get("/api/v1/patients").headers["cache-control"] == "no-store"  # the 401 too
    assert "no-store" not in c.get("/vendor/plotly.min.js").headers.get("cache-control", "")  # static: cacheable
    assert "strict-transport-security" not in c.get("/healthz").headers  # development: plain-http localhost


def test_production_answers_carry_hsts(tmp_path):
    from fastapi.testclient import TestClient

    from app.web.main import create_app
    from app.settings import Settings

    settings = Settings(CHAKAMO_ENV="production", CHAKAMO_DATA_DIR=tmp_path, CHAKAMO_SECRET_KEY="k" * 40,
                        CHAKAMO_WORKERS=1)
    with TestClient(create_app(settings), base_url="https://testserver") as c:
        for url in ("/healthz", "/", "/api/v1/patients", "/viser/index.html?playbackPath=http://evil/x"):
            hsts = c.get(url).headers.get("strict-transport-security", "")
            assert re.fullmatch(r"max-age=(\d+); includeSubDomains", hsts), (url, hsts)
            assert int(hsts.split("=")[1].split(";")[0]) >= 180 * 86400
