"""Settings, database and migrations, blob storage, security primitives, the CLI set-up commands, and the
non-API routes."""

from __future__ import annotations

import hashlib

import pytest

from app.settings import Settings, SettingsError


# -------------------------------------------------------------------------------------------- settings
def test_production_refuses_a_missing_or_weak_secret(tmp_path):
    with pytest.raises(ValueError, match="CHAKAMO_SECRET_KEY is not set"):
        Settings(CHAKAMO_ENV="production", CHAKAMO_DATA_DIR=tmp_path)
    with pytest.raises(ValueError, match="too weak"):
        Settings(CHAKAMO_ENV="production", CHAKAMO_DATA_DIR=tmp_path, CHAKAMO_SECRET_KEY="short")
    ok = Settings(CHAKAMO_ENV="production", CHAKAMO_DATA_DIR=tmp_path, CHAKAMO_SECRET_KEY="x" * 40)
    assert not ok.development and ok.db_url == f"sqlite:///{tmp_path.as_posix()}/chakamo.db"


def test_job_backends_are_inprocess_or_celery_with_a_redis_broker(tmp_path):
    base = dict(CHAKAMO_ENV="development", CHAKAMO_DATA_DIR=tmp_path)
    assert Settings(**base).job_backend == "inprocess"
    s = Settings(**base, CHAKAMO_JOB_BACKEND="Celery", CHAKAMO_BROKER_URL="redis://broker:6379/1")
    assert (s.job_backend, s.broker_url) == ("celery", "redis://broker:6379/1")
    with pytest.raises(ValueError, match="inprocess"):
        Settings(**base, CHAKAMO_JOB_BACKEND="threads")
    with pytest.raises(ValueError, match="not a Redis URL"):
        Settings(**base, CHAKAMO_JOB_BACKEND="celery", CHAKAMO_BROKER_URL="amqp://guest@localhost//")


def test_get_settings_reads_the_environment_once(monkeypatch, tmp_path):
    from app.settings import get_settings

    monkeypatch.setenv("CHAKAMO_ENV", "production")
    monkeypatch.delenv("CHAKAMO_SECRET_KEY", raising=False)
    get_settings.cache_clear()
    with pytest.raises(SettingsError, match="CHAKAMO_SECRET_KEY"):
        get_settings()
    monkeypatch.setenv("CHAKAMO_ENV", "development")
    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(tmp_path))
    get_settings.cache_clear()
    try:
        assert get_settings() is get_settings() and get_settings().data_dir == tmp_path
    finally:
        get_settings.cache_clear()


# -------------------------------------------------------------------------------------------- database
def test_foreign_keys_are_enforced(tmp_path):
    from sqlalchemy.exc import IntegrityError

    from app.store.database import Database
    from app.store.models import Patient

    db = Database(f"sqlite:///{tmp_path}/f.db")
    db.migrate()
    with pytest.raises(IntegrityError):
        with db.session() as s:
            s.add(Patient(clinic_id=999, external_id="X", side="left"))
    db.dispose()


# -------------------------------------------------------------------------------------------- storage
def test_blob_store_is_content_addressed_and_verified(tmp_path):
    from app.store.blobs import BlobStore, CorruptBlob, TooLarge

    store = BlobStore(tmp_path)
    sha, size = store.put(b"hello")
    assert sha == hashlib.sha256(b"hello").hexdigest() and size == 5
    assert store.path(sha) == tmp_path / sha[:2] / sha[2:]
    assert store.put(b"hello")[0] == sha and store.read(sha) == b"hello"
    w = store.writer(max_bytes=8)
    w.write(b"12345")
    with pytest.raises(TooLarge):
        w.write(b"6789")
    assert list(store.incoming.iterdir()) == []  # the partial file is gone
    store.path(sha).write_bytes(b"hellO")
    with pytest.raises(CorruptBlob, match="checksum"):
        store.read(sha)
    with pytest.raises(CorruptBlob, match="checksum"):
        store.copy_to(sha, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    with pytest.raises(CorruptBlob, match="missing"):
        store.read("0" * 64)


# -------------------------------------------------------------------------------------------- security
def test_passwords_tokens_csrf():
    from app.web import security

    h = security.hash_password("correct horse battery")
    assert h.startswith("$argon2id$") and "correct" not in h
    assert security.hash_password("correct horse battery") != h  # per-password salt
    assert security.verify_password("correct horse battery", h)
    assert not security.verify_password("correct horse batterY", h)
    assert not security.verify_password("x", "garbage")
    with pytest.raises(ValueError, match="at least 12"):
        security.check_password_strength("short")
    t = security.new_token()
    assert t.startswith("chk_") and len(t) > 40 and security.sha256_hex(t) != t
    c = security.csrf_token(b"k" * 32, "sid")
    assert security.csrf_ok(b"k" * 32, "sid", c)
    assert not security.csrf_ok(b"k" * 32, "other", c) and not security.csrf_ok(b"k" * 32, "sid", None)


# -------------------------------------------------------------------------------------------- CLI
def test_cli_setup_commands(monkeypatch, tmp_path, capsys):
    from app.cli.admin import ROLES as CLI_ROLES
    from app.cli.main import main
    from app.store.database import Database
    from app.store.models import ROLES, ApiToken, User
    from app.web.security import sha256_hex
    from app.settings import get_settings

    assert CLI_ROLES == ROLES
    monkeypatch.setenv("CHAKAMO_ENV", "development")
    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(tmp_path))
    get_settings.cache_clear()
    try:
        assert main(["clinics", "create", "Clínica Norte"]) == 0
        assert main(["clinics", "create", "Clínica Norte"]) == 2
        assert "already exists" in capsys.readouterr().err
        assert main(["tokens", "create", "--clinic", "Clínica Norte", "--label", "HIS"]) == 0
        out = capsys.readouterr().out.splitlines()
        token = out[-1]
        assert token.startswith("chk_") and token.strip() == token and token not in " ".join(out[:-1])
        assert main(["tokens", "create", "--clinic", "Nowhere"]) == 2
        assert "no clinic named 'Nowhere'" in capsys.readouterr().err
        monkeypatch.setattr("sys.stdin", __import__("io").StringIO("a strong password\n"))
        assert main(["users", "create", "--clinic", "Clínica Norte", "--email", "Ana@X.org", "--role", "admin",
                     "--password-stdin"]) == 0
        monkeypatch.setattr("sys.stdin", __import__("io").StringIO("short\n"))
        assert main(["users", "create", "--clinic", "Clínica Norte", "--email", "b@x.org", "--role", "admin",
                     "--password-stdin"]) == 2
        db = Database(get_settings().db_url)
        with db.session() as s:
            assert s.query(ApiToken).one().token_sha256 == sha256_hex(token)
            assert [u.email for u in s.query(User)] == ["ana@x.org"]
        db.dispose()
    finally:
        get_settings.cache_clear()


# -------------------------------------------------------------------------------------------- routes
def test_non_api_routes_work_offline(client):
    assert client.get("/healthz").json() == {"status": "ok"}
    docs = client.get("/docs")
    assert docs.status_code == 200 and "cdn" not in docs.text.lower() and "/docs-assets/swagger-ui-bundle.js" in docs.text
    assert client.get("/docs-assets/swagger-ui-bundle.js").status_code == 200
    assert client.get("/openapi.json").json()["paths"]["/api/v1/sessions/{session_id}/recordings"]
    js = client.get("/vendor/plotly.min.js")
    assert js.status_code == 200 and "javascript" in js.headers["content-type"] and len(js.content) > 1_000_000
    viser = client.get("/viser/index.html")
    assert viser.status_code == 200 and "<html" in viser.text.lower()
    ui = client.get("/")  # the repository's static/index.html (503 only where static/ is not installed)
    assert ui.status_code == 200 and "text/html" in ui.headers["content-type"]


def test_roles_and_languages_are_defined_once():
    import typing

    from app.cli import admin as admin_cli
    from app.web import security
    from app.web.api import deps, schemas
    from app.store import models
    from app.pipeline.render import LANGS
    from reports.i18n import LANGUAGES

    assert admin_cli.ROLES is models.ROLES is security.ROLES
    assert typing.get_args(schemas.RoleName) == security.ROLES and deps.ROLE_RANK is security.ROLE_RANK
    assert security.ROLE_RANK["admin"] > security.ROLE_RANK["clinician"] > security.ROLE_RANK["read_only"]
    assert typing.get_args(schemas.Lang) == LANGUAGES and LANGS is LANGUAGES
