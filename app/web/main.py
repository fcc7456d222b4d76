"""The web application: :func:`create_app` assembles API v1, the UI's static files and the job runner.

``create_app(settings)`` builds a fresh app (nothing global: tests make one per temporary data dir).
Start-up (the lifespan): create the data folders, apply the Alembic migrations, start the job runner
(``CHAKAMO_JOB_BACKEND``: the embedded :class:`app.jobs.inprocess.ThreadJobRunner`, which refuses to start when
another server runs this database's jobs, clears a crashed run's temporary files and resumes the jobs a
previous run left queued or running; or :class:`app.jobs.celery_engine.CeleryJobRunner`, which hands jobs to the
Celery workers), and when the database has no user yet print how
to create the first admin (in ``create_app``'s ``lang``: ``chakamo serve --lang``) (there are no default accounts or passwords).  It also starts the webhook sender (:class:`app.web.webhooks.WebhookSender`).  Shutdown stops the runner after
its current jobs (the database is disposed only when they have all stopped).  Errors that would show server
internals (a damaged stored file) answer a sentence with a reference id; the details go to the server log.
Middleware (plain ASGI), outermost first: :class:`app.web.headers.SecurityHeaders`,
:class:`app.web.headers.AllowedHosts` (``CHAKAMO_ALLOWED_HOSTS``), :class:`app.web.limits.BodyLimit` (no request body above
``CHAKAMO_MAX_BODY_KB`` but the recordings upload's); a :class:`app.web.refusals.Refusal`
answers its sentence in es/en/pt.  Every error answer is an RFC 7807 problem (``application/problem+json``,
:mod:`app.web.problems`), and the OpenAPI document declares each operation's error answers with its schema.

Routes besides ``/api/v1`` (see ``app.web.api``): ``/`` (``static/index.html``, the single-page UI), ``/static``
(the repository's ``static/`` folder), ``/vendor/plotly.min.js`` (from the installed ``plotly`` package),
``/viser/`` (viser's built client, which plays ``scene.viser``, served unpacked: :mod:`app.web.viser_client`), ``/docs`` (Swagger UI 5 from the
``fastapi-offline`` package's static folder: no CDN, clinics are often offline; Swagger UI 4 cannot read the
OpenAPI 3.1 document FastAPI writes), ``/healthz`` (the process answers: for
a liveness probe) and ``/readyz`` (200 only when the database answers and the job engine can take jobs —
the broker is reachable, or the embedded workers run; else 503 naming what is down: for a load balancer).
"""

from __future__ import annotations

import asyncio
import logging
import secrets
import sys
import threading
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from fastapi.staticfiles import StaticFiles
from sqlalchemy import func, select, text
from sqlalchemy.exc import OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeout

import app as _app_pkg
from app.web.api import api_router
from app.web.api.deps import REQUEST_SESSIONS
from app.store.database import Database
from app.store.models import User
from app.web.headers import AllowedHosts, SecurityHeaders
from app.web.limits import BodyLimit
from app.web.problems import document_errors, problem_response
from app.web.messages import CODE_HEADER, render
from app.web.refusals import Refusal, members as refusal_members
from app.web.throttle import InFlight, LoginGate, LoginThrottle
from app.web.fhir_push import FhirPush
from app.web.housekeeping import Housekeeper
from app.web.webhooks import WebhookSender
from app.settings import Settings, get_settings
from app.store.blobs import CorruptBlob, Storage, open_storage
from app.web.viser_client import unpack_in_background, viser_router
from estimators import __version__

log = logging.getLogger("chakamo")

STATIC_DIR = Path(_app_pkg.__file__).resolve().parents[1] / "static"
def _plotly_js() -> Path:
    import plotly

    return Path(plotly.__file__).resolve().parent / "package_data" / "plotly.min.js"


def _viser_client_dir() -> Path:
    from reports.scene import static_client_path

    return static_client_path().parent


def _swagger_dir() -> Path:
    """The folder of Swagger UI 5's built files (``swagger-ui-bundle.js``, ``swagger-ui.css``, ``favicon.png``)
    inside the installed ``fastapi-offline`` package: only its files are used, not its code."""
    import importlib.util

    spec = importlib.util.find_spec("fastapi_offline")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("the fastapi-offline package (Swagger UI for /docs) is not installed")
    return Path(next(iter(spec.submodule_search_locations))) / "static"


#: uvicorn options of ``chakamo serve``: no ``server: uvicorn`` banner (issue 16, finding 10e: it names the
#: server software to a scanner, and nobody needs it)
UVICORN_OPTIONS = {"server_header": False}

#: an unfinished upload file untouched this long was left by a crashed server (scaled-out deployment)
INCOMING_STALE_S = 24 * 3600.0


def make_runner(settings: Settings, db: Database, store: Storage):
    """The job engine ``CHAKAMO_JOB_BACKEND`` names (an :class:`app.jobs.work.JobRunner`)."""
    if settings.job_backend == "celery":
        from app.jobs.celery_engine import CeleryJobRunner

        return CeleryJobRunner(db, settings)
    from app.jobs.inprocess import ThreadJobRunner

    return ThreadJobRunner(db, store, settings.tmp_dir, workers=settings.workers,
                           render_processes=settings.render_processes, lease_s=settings.job_lease_s)


def create_app(settings: Settings | None = None, lang: str | None = None) -> FastAPI:
    """A new ChakaMo application for ``settings`` (default: :func:`app.settings.get_settings`); ``lang``: the
    language of its start-up words to the operator (``chakamo serve --lang``; English when None)."""
    settings = settings or get_settings()
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    settings.tmp_dir.mkdir(parents=True, exist_ok=True)
    db = Database(settings.db_url)
    store = open_storage(settings)
    runner = make_runner(settings, db, store)

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        unpack_in_background(_viser_client_dir() / "index.html")  # viser's client unpacked beside the migrations
        db.migrate(settings.sealing_key)
        with db.session() as s:
            if not s.scalar(select(func.count()).select_from(User)):
                print(render("cli.first_admin", lang or "en"), file=sys.stderr, flush=True)
        try:
            runner.start()  # refuses (RunnerLocked) when another server runs this database's jobs
        except Exception:
            db.dispose()
            raise
        # app/web/webhooks.py: signed job notifications, on an engine of their own (their rounds never take a
        # connection the requests' pool counts on)
        sender = WebhookSender(Database(settings.db_url), settings.webhook_retry_s,
                               settings.webhook_host_patterns, settings.key,
                               FhirPush(settings, store) if settings.fhir_push_url else None)
        # the erasure sweep and the retention policy, whatever the job backend, one server at a time, on an engine
        # of its own like the sender's (a run never takes a connection the requests' pool counts on)
        app.state.housekeeper = housekeeper = Housekeeper(settings, Database(settings.db_url), store)
        check_pool = None
        try:  # a start-up failing from here on stops what it started (threads, the housekeeping lock, helpers)
            sender.start()
            housekeeper.start()
            if settings.job_backend == "celery":  # servers share the store: only a crashed upload's old leftovers
                store.clear_incoming(older_than_s=INCOMING_STALE_S)
            if settings.render_processes > 0 and settings.check_processes > 0:  # uploads checked off this GIL
                from app.store.checks import CheckPool

                app.state.check_pool = check_pool = CheckPool(settings.check_processes)
            yield
        finally:
            app.state.check_pool = None
            sender.stop()
            housekeeper.stop()
            if check_pool is not None:
                check_pool.shutdown()
            if runner.shutdown(wait=True):  # a job thread still running keeps its database
                db.dispose()

    app = FastAPI(title="ChakaMo", version=__version__, lifespan=lifespan, docs_url=None, redoc_url=None,
                  description="Clinical 3D knee kinematics from two IMUs: patients, sessions, uploads, processing, "
                              "reports. Authenticate with `Authorization: Bearer <token>` (`chakamo tokens "
                              "create`) or the browser login.")
    app.state.settings, app.state.db, app.state.store, app.state.runner = settings, db, store, runner
    #: the helper processes running the uploads' ingestion checks off this process' GIL when
    #: CHAKAMO_RENDER_PROCESSES > 0 (CHAKAMO_CHECK_PROCESSES of them, :class:`app.store.checks.CheckPool`;
    #: None: checks run in the request thread)
    app.state.check_pool = None
    #: login counters in the database (every server shares them) and this server's logins per address (app.web.throttle)
    app.state.login_throttle = LoginThrottle(db)
    app.state.login_in_flight = InFlight(app.state.login_throttle)
    #: uploads streaming at the same time (non-blocking acquire: a full server answers 503 at once)
    app.state.upload_slots = threading.BoundedSemaphore(settings.max_uploads)
    #: turns to hold a request session (app/web/api/deps.py, _session_turn): waited for on the event loop
    app.state.session_turns = asyncio.Semaphore(REQUEST_SESSIONS)
    app.include_router(api_router())

    # inner first: the body limit's 413 gets the security headers too
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_kb * 1024)  # app/web/limits.py
    app.add_middleware(LoginGate, in_flight=app.state.login_in_flight)  # app/web/throttle.py: flood refusals
    if settings.host_patterns != ("*",):  # a foreign Host is answered before anything but the headers
        app.add_middleware(AllowedHosts, patterns=settings.host_patterns)
    app.add_middleware(SecurityHeaders, development=settings.development)  # app/web/headers.py

    @app.exception_handler(Refusal)
    async def refusal(request: Request, exc: Refusal):
        """A refusal the user caused: its sentence in English and in es/en/pt (:mod:`app.web.refusals`)."""
        return exc.response(instance=request.url.path)

    @app.exception_handler(StarletteHTTPException)
    async def http_problem(request: Request, exc: StarletteHTTPException):
        """Any other HTTP error as an RFC 7807 problem (:mod:`app.web.problems`)."""
        return problem_response(exc.status_code, str(exc.detail), headers=exc.headers, instance=request.url.path)

    @app.exception_handler(RequestValidationError)
    async def validation_error(request: Request, exc: RequestValidationError):
        """422 with one sentence (the contract's error shape), the pydantic details kept under ``errors``; like
        every refusal it carries ``code`` (``request.invalid``), ``params`` (the fields) and ``message`` in
        es/en/pt (:data:`app.pipeline.service_messages.CATALOGUE`; pydantic's own words are English only, so the
        es/pt sentences name the fields and say the value is missing or invalid)."""
        parts, fields = [], []
        for err in exc.errors()[:3]:
            where = ".".join(str(x) for x in err.get("loc", ()) if x not in ("body", "query", "path"))
            parts.append(f"{where or 'request'}: {err.get('msg', 'invalid')}")
            fields.append(where or "request")
        detail = "; ".join(parts) + ". Correct the request and send it again."
        params = {"fields": ", ".join(dict.fromkeys(fields))}
        return problem_response(422, detail, instance=request.url.path, errors=jsonable_encoder(exc.errors()),
                                headers={CODE_HEADER: "request.invalid"},
                                **refusal_members("request.invalid", params))

    @app.exception_handler(OperationalError)
    async def database_unreachable(request: Request, exc: OperationalError):
        """503 while the database is away (a restart, a fail-over): nothing was changed; the client retries."""
        log.warning("database unreachable during %s %s: %s", request.method, request.url.path, exc.orig)
        return problem_response(503, "The database is not reachable at the moment (nothing was changed); try "
                                     "again in a minute.", headers={"Retry-After": "30"}, instance=request.url.path)

    @app.exception_handler(PoolTimeout)
    async def database_busy(request: Request, exc: PoolTimeout):
        """503 when every database connection stayed busy too long (an overload): nothing was changed."""
        log.warning("no database connection free for %s %s", request.method, request.url.path)
        return problem_response(503, "The server is too busy at the moment (nothing was changed); try again in "
                                     "a minute.", headers={"Retry-After": "10"}, instance=request.url.path)

    @app.exception_handler(CorruptBlob)
    async def corrupt_blob(request: Request, exc: CorruptBlob):
        """500 with a sentence and a reference id; the details (which file, where) go to the server log only."""
        ref = secrets.token_hex(4)
        log.error("corrupt blob (reference %s) under %s: %s", ref, store.root, exc)
        return problem_response(500, f"A stored file is damaged or missing (reference {ref}); give the reference "
                                     "to your ChakaMo administrator, who can restore it from a backup.",
                                instance=request.url.path)

    def openapi() -> dict:
        """FastAPI's document with every error answer described (:func:`app.web.problems.document_errors`)."""
        if app.openapi_schema is None:
            app.openapi_schema = document_errors(FastAPI.openapi(app))
        return app.openapi_schema

    app.openapi = openapi

    @app.get("/healthz", include_in_schema=False)
    async def healthz():  # async: the process answers even while every request thread is busy (no thread hop)
        return {"status": "ok"}

    @app.get("/readyz", include_in_schema=False)
    def readyz():
        """200 when the database answers and the job engine can take jobs, else 503 saying what is down."""
        checks: dict[str, str] = {}
        try:
            with db.engine.connect() as conn:
                conn.execute(text("SELECT 1"))
            checks["database"] = "ok"
        except Exception as exc:  # noqa: BLE001 — any failure means not ready; the reason is logged
            log.warning("readiness: database unreachable: %s", exc)
            checks["database"] = "unreachable"
        engine_problem = runner.problem()
        checks["jobs"] = engine_problem or "ok"
        ready = all(v == "ok" for v in checks.values())
        return JSONResponse({"status": "ready" if ready else "not ready", "backend": settings.job_backend, **checks},
                            status_code=200 if ready else 503)

    @app.get("/", include_in_schema=False)
    def index():
        page = STATIC_DIR / "index.html"
        if page.is_file():
            return FileResponse(page, media_type="text/html", headers={"Cache-Control": "no-cache"})
        return HTMLResponse("<!doctype html><title>ChakaMo</title><p>The ChakaMo user interface is not installed "
                            "(static/index.html is missing). The API is at <a href='/docs'>/docs</a>.</p>",
                            status_code=503)

    @app.get("/vendor/plotly.min.js", include_in_schema=False)
    def plotly_js():
        return FileResponse(_plotly_js(), media_type="text/javascript",
                            headers={"Cache-Control": "public, max-age=86400"})

    swagger = _swagger_dir()
    app.mount("/docs-assets", StaticFiles(directory=swagger), name="docs-assets")

    @app.get("/docs", include_in_schema=False)
    def docs():
        return get_swagger_ui_html(openapi_url=app.openapi_url, title="ChakaMo API",
                                   swagger_js_url="/docs-assets/swagger-ui-bundle.js",
                                   swagger_css_url="/docs-assets/swagger-ui.css",
                                   swagger_favicon_url="/docs-assets/favicon.png")

    app.mount("/static", StaticFiles(directory=STATIC_DIR, check_dir=False), name="static")
    # viser's client unpacked once per process (app.web.viser_client); the shipped build folder behind it
    app.include_router(viser_router(_viser_client_dir() / "index.html"))
    app.mount("/viser", StaticFiles(directory=_viser_client_dir(), html=True), name="viser")
    return app


__all__ = ["STATIC_DIR", "UVICORN_OPTIONS", "create_app", "make_runner"]
