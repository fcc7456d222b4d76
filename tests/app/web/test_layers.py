"""The layers of ``app/`` (issue 12 §3): routes build no queries and never run the pipeline; nothing outside
``app/web`` imports the web layer.

Read from the source (``ast``), so a violation fails here whether or not a test happens to run the line:

* a router (``app/web/api/*.py`` other than ``deps.py`` and ``schemas.py``) imports nothing of
  ``sqlalchemy`` (so it cannot build ``select`` / ``update`` / ``delete`` / ``insert``) nor of
  ``app.pipeline``, and calls no query method of a database session (``db.execute``, ``db.add``, …): its
  data comes from :mod:`app.store` and :mod:`app.jobs`;
* ``deps.py`` and ``schemas.py`` build no statements either (they call the store);
* no module outside ``app/web`` imports ``app.web`` (at the top or inside a function), except the CLI,
  which sits above it (``chakamo serve`` starts the web app).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

APP_DIR = Path(__file__).resolve().parents[3] / "app"
API_DIR = APP_DIR / "web" / "api"
SHARED = {"deps.py", "schemas.py", "__init__.py"}
#: statement builders of sqlalchemy
BUILDERS = {"select", "update", "delete", "insert"}
#: methods of a SQLAlchemy Session that run or stage SQL (``commit`` / ``rollback`` are transaction control)
QUERY_METHODS = {"execute", "scalar", "scalars", "get", "add", "add_all", "delete", "merge", "query", "flush",
                 "refresh", "exec_driver_sql"}
#: names a router's database session goes by
DB_NAMES = {"db", "s", "session_db"}


def _imports(tree: ast.AST) -> list[tuple[int, str, list[str]]]:
    """``(line, module, names)`` of every import in ``tree`` (also inside functions)."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.lineno, node.module, [a.name for a in node.names]))
    return out


def violations_of_router(source: str, name: str = "router.py") -> list[str]:
    """What in a router's ``source`` breaks "routes build no queries and never run the pipeline"."""
    tree = ast.parse(source)
    found = []
    for line, module, _ in _imports(tree):
        if module == "sqlalchemy" or module.startswith("sqlalchemy."):
            found.append(f"{name}:{line}: imports {module} (build queries in app/store)")
        if module == "app.pipeline" or module.startswith("app.pipeline."):
            found.append(f"{name}:{line}: imports {module} (run the pipeline through app/jobs or app/store)")
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        if isinstance(f, ast.Name) and f.id in BUILDERS:
            found.append(f"{name}:{node.lineno}: calls {f.id}(...) (a query: move it to app/store)")
        if isinstance(f, ast.Attribute) and f.attr in QUERY_METHODS and isinstance(f.value, ast.Name) \
                and f.value.id in DB_NAMES:
            found.append(f"{name}:{node.lineno}: calls {f.value.id}.{f.attr}(...) (a query: move it to app/store)")
    return found


def violations_of_shared(source: str, name: str) -> list[str]:
    """``deps.py`` / ``schemas.py``: no statement builders imported or called."""
    found = []
    tree = ast.parse(source)
    for line, module, names in _imports(tree):
        if (module == "sqlalchemy" or module.startswith("sqlalchemy.")) and set(names) & BUILDERS:
            found.append(f"{name}:{line}: imports {sorted(set(names) & BUILDERS)} from {module}")
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in BUILDERS:
            found.append(f"{name}:{node.lineno}: calls {node.func.id}(...)")
    return found


def test_the_router_check_sees_queries_and_pipeline_imports():
    """The checker itself, on a sample that breaks every rule once (and a clean one)."""
    bad = '''
from sqlalchemy import select
from app.pipeline.session import PIPELINE_VERSION

def route(db):
    from app.pipeline import process
    db.add(object())
    rows = db.scalars(select(Patient))
    db.execute(update(Patient).values(x=1))
    db.commit()
'''
    found = violations_of_router(bad)
    assert len(found) == 8, found  # 3 imports, select, update, db.add, db.scalars, db.execute
    assert any("select(...)" in v for v in found) and any("update(...)" in v for v in found)
    assert any("db.add" in v for v in found) and any("db.scalars" in v for v in found)
    assert not any("db.commit" in v for v in found)
    clean = "from app.store import patients\n\ndef route(db, principal):\n    return patients.search_patients(db, 1)\n"
    assert violations_of_router(clean) == []


ROUTERS = sorted(p for p in API_DIR.glob("*.py") if p.name not in SHARED)


def test_there_are_routers_to_check():
    assert {"patients.py", "jobs.py", "recordings.py"} <= {p.name for p in ROUTERS}


@pytest.mark.parametrize("path", ROUTERS, ids=lambda p: p.name)
def test_routes_build_no_queries_and_never_run_the_pipeline(path):
    assert violations_of_router(path.read_text(encoding="utf-8"), f"app/web/api/{path.name}") == []


@pytest.mark.parametrize("name", ["deps.py", "schemas.py"])
def test_deps_and_schemas_build_no_statements(name):
    assert violations_of_shared((API_DIR / name).read_text(encoding="utf-8"), f"app/web/api/{name}") == []


def test_nothing_outside_app_web_imports_it():
    """store, jobs, pipeline, research, settings, choices: none imports ``app.web`` (not even lazily); the CLI
    may (it is the one layer above the web)."""
    found = []
    for path in sorted(APP_DIR.rglob("*.py")):
        rel = path.relative_to(APP_DIR).as_posix()
        if rel.startswith(("web/", "cli/")):
            continue
        for line, module, _ in _imports(ast.parse(path.read_text(encoding="utf-8"))):
            if module == "app.web" or module.startswith("app.web."):
                found.append(f"app/{rel}:{line}: imports {module}")
    assert found == []


def test_no_module_imports_a_router():
    """Routers are leaves: only :func:`app.web.api.api_router` assembles them (tests may still call in)."""
    routers = {f"app.web.api.{p.stem}" for p in ROUTERS}
    found = []
    for path in sorted(APP_DIR.rglob("*.py")):
        rel = path.relative_to(APP_DIR).as_posix()
        if rel == "web/api/__init__.py":
            continue
        for line, module, names in _imports(ast.parse(path.read_text(encoding="utf-8"))):
            targets = {module} | {f"{module}.{n}" for n in names}
            if targets & routers:
                found.append(f"app/{rel}:{line}: imports {sorted(targets & routers)}")
    assert found == []


def test_domain_errors_get_their_status_codes_in_one_place():
    """Every refusal class of the services maps to one code (subclasses take their base's), detail unchanged."""
    from app.jobs.queue import NotReady, UpToDate
    from app.store.errors import Conflict, Invalid, LimitExceeded, NotFound
    from app.store.sessions import Busy
    from app.web.api.deps import http_error

    cases = [(NotFound("No session 3 in your clinic; check the id."), 404), (Conflict("taken"), 409),
             (Busy(3, 7, "upload"), 409), (NotReady("no lying file"), 409), (UpToDate(4), 409),
             (Invalid("a.csv sent twice"), 400), (LimitExceeded("at most 40 files"), 413)]
    for error, status in cases:
        http = http_error(error)
        assert (http.status_code, http.detail) == (status, str(error))
    assert http_error(Busy(3, 7, "upload")).detail == \
        "Session 3 is being processed (job 7); upload the files when that job has finished."
