"""Static checks of the deployment files: ``docker/compose.yaml``, ``docker/Dockerfile``, ``.dockerignore``.

No Docker engine runs on our machines, so what an engine would refuse or run wrongly is checked here by
reading the files against the real code: every chakamo ``command`` must parse with the real CLI parser,
every ``CHAKAMO_*``/``DATABASE_URL`` variable must be a real setting and the whole compose environment must
be accepted by :class:`app.settings.Settings`; the image's health check is run against small loopback HTTP
servers.  ``test_compose_commands_native.py`` runs the same commands for real.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import threading
from fnmatch import fnmatch
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import PurePosixPath

import pytest
from deploy_files import (CHAKAMO_SERVICES, COMPOSE_FILE, TEST_SECRETS, DOCKER_DIR, REPO, InterpolationError,
                          dockerignore_patterns, exec_form, healthcheck_command, interpolate, load_compose,
                          load_dockerfile, service_environment, variables_used, volume_mounts)
from native_run import free_port, run_healthcheck

pytest.importorskip("yaml")

#: variables the image sets that are not :class:`Settings` fields, and the module that reads each
NON_SETTINGS_VARIABLES = {"CHAKAMO_FONT_CACHE": REPO / "reports" / "fonts.py"}
#: test values for the compose file's required variables (never real secrets)


@pytest.fixture(scope="module")
def compose() -> dict:
    return load_compose()


@pytest.fixture(scope="module")
def dockerfile():
    return load_dockerfile()


def _settings_aliases() -> set[str]:
    """The environment variable names :class:`app.settings.Settings` reads (its validation aliases)."""
    from app.settings import Settings

    names = set()
    for info in Settings.model_fields.values():
        alias = info.validation_alias
        if isinstance(alias, str):
            names.add(alias)
        elif alias is not None:   # AliasChoices / AliasPath
            for choice in getattr(alias, "choices", [alias]):
                names.update(p for p in getattr(choice, "path", [choice]) if isinstance(p, str))
    return names


def _is_setting_name(name: str) -> bool:
    return name.startswith("CHAKAMO_") or name == "DATABASE_URL"


# --- compose.yaml ------------------------------------------------------------------------------------------

def test_compose_has_the_services_and_named_volumes(compose):
    assert set(compose["services"]) >= {"postgres", "redis", "migrate", "api", "worker"}
    assert set(compose["volumes"]) >= {"pgdata", "redisdata", "chakamo-data"}
    services = compose["services"]
    assert volume_mounts(services["postgres"]) == {"/var/lib/postgresql/data": "pgdata"}
    assert volume_mounts(services["redis"]) == {"/data": "redisdata"}
    for name in CHAKAMO_SERVICES:   # one data volume shared by the api and every worker
        env = service_environment(services[name])
        assert volume_mounts(services[name]).get(env["CHAKAMO_DATA_DIR"]) == "chakamo-data", name
    for service in services.values():  # every named volume a service uses is declared
        for source in volume_mounts(service).values():
            assert source in compose["volumes"], source


def test_postgres_and_redis_are_health_checked_and_redis_persists_its_queue(compose):
    services = compose["services"]
    assert "pg_isready" in services["postgres"]["healthcheck"]["test"]
    assert services["redis"]["healthcheck"]["test"][-2:] == ["redis-cli", "ping"]
    command = services["redis"]["command"]
    assert command[0] == "redis-server"
    assert command[command.index("--appendonly") + 1] == "yes"


def test_start_order_waits_for_health_and_for_the_migration(compose):
    services = compose["services"]
    assert services["migrate"]["depends_on"]["postgres"]["condition"] == "service_healthy"
    assert services["migrate"].get("restart", "no") == "no"
    for name in ("api", "worker"):
        depends = services[name]["depends_on"]
        assert depends["migrate"]["condition"] == "service_completed_successfully", name
        assert depends["redis"]["condition"] == "service_healthy", name


def test_workers_run_two_replicas(compose):
    worker = compose["services"]["worker"]
    assert worker.get("deploy", {}).get("replicas", worker.get("scale", 1)) >= 2


@pytest.mark.parametrize("service", CHAKAMO_SERVICES)
def test_every_chakamo_command_parses_with_the_real_cli(compose, service):
    """Needs ``chakamo migrate`` and ``chakamo worker`` in app/cli/main.py (issue 8, item 1)."""
    from app.cli.main import _build_parser

    command = compose["services"][service]["command"]
    assert isinstance(command, list) and command[0] == "chakamo", command
    try:
        args = _build_parser().parse_args(command[1:])
    except SystemExit as exc:
        pytest.fail(f"{service}: `{' '.join(command)}` is refused by the chakamo CLI (exit {exc.code})")
    assert args.command == {"migrate": "migrate", "api": "serve", "worker": "worker"}[service]


def test_api_serves_on_all_interfaces_of_the_published_port_and_checks_readyz(compose):
    from app.cli.main import _build_parser

    api = compose["services"]["api"]
    args = _build_parser().parse_args(api["command"][1:])
    assert args.host == "0.0.0.0"             # inside the container: reachable through the published port
    published = [interpolate(str(p), {}) for p in api["ports"]]
    assert [p.rsplit(":", 1)[1] for p in published] == [str(args.port)]
    assert all(p.startswith("127.0.0.1:") for p in published)   # default: loopback, behind a TLS proxy
    test = " ".join(api["healthcheck"]["test"])
    assert f"http://127.0.0.1:{args.port}/readyz" in test


def test_services_without_http_disable_the_images_healthcheck(compose):
    """The image's HEALTHCHECK asks /readyz on port 8000, which only the api serves: inherited by migrate or
    a worker it would mark them unhealthy forever."""
    for name in ("migrate", "worker"):
        assert compose["services"][name]["healthcheck"] == {"disable": True}, name


def test_every_chakamo_variable_is_a_real_setting(compose):
    aliases = _settings_aliases()
    for name in CHAKAMO_SERVICES:
        for var in service_environment(compose["services"][name]):
            if _is_setting_name(var):
                assert var in aliases, f"{name} sets {var}, which app.settings.Settings does not read"


def test_compose_environment_is_accepted_by_the_settings(compose, monkeypatch):
    """The production environment as compose passes it (secrets filled with test values) builds valid
    :class:`Settings`: needs ``CHAKAMO_JOB_BACKEND=celery`` and ``CHAKAMO_BROKER_URL`` (issue 8, item 1)."""
    from app.settings import Settings

    for var in list(os.environ):
        if _is_setting_name(var):
            monkeypatch.delenv(var)
    env = {k: interpolate(v, TEST_SECRETS) for k, v in service_environment(compose["services"]["api"]).items()}
    settings = Settings(**env)
    assert settings.env == "production" and settings.job_backend == "celery"
    assert settings.db_url.startswith("postgresql+psycopg://chakamo:")


def test_the_chakamo_services_share_one_environment(compose):
    envs = [service_environment(compose["services"][name]) for name in CHAKAMO_SERVICES]
    assert envs[0] == envs[1] == envs[2]


def test_secrets_come_only_from_required_variables(compose):
    """No password or key is written in the file: each is a ``${VAR:?message}`` that stops compose when unset."""
    secret_words = ("PASSWORD", "SECRET", "KEY")
    for name, service in compose["services"].items():
        for var, value in service_environment(service).items():
            if any(w in var for w in secret_words):
                assert re.fullmatch(r"\$\{[A-Z_]+:\?[^}]+\}", value), f"{name}.{var} = {value!r}"
        url = service_environment(service).get("DATABASE_URL")
        if url:
            password = url.split("://", 1)[1].split("@", 1)[0].split(":", 1)[1]
            assert [op for _, op in variables_used(password)] == [":?"], url
    with pytest.raises(InterpolationError, match="docker/README.md"):
        interpolate(service_environment(compose["services"]["api"])["CHAKAMO_SECRET_KEY"], {"CHAKAMO_SECRET_KEY": ""})


def test_env_example_names_the_required_variables_without_values(compose):
    required = {var for service in compose["services"].values()
                for value in service_environment(service).values()
                for var, op in variables_used(value) if op == ":?"}
    assert required == set(TEST_SECRETS)
    lines = [ln for ln in (DOCKER_DIR / "env.example").read_text().splitlines() if ln and not ln.startswith("#")]
    assert sorted(lines) == sorted(f"{var}=" for var in required)
    assert ".env" in (DOCKER_DIR / ".gitignore").read_text().split()


def test_images_are_pinned(compose):
    for name, service in compose["services"].items():
        image = service["image"]
        repo, _, tag = image.rpartition(":")
        assert repo and tag and tag != "latest" and "/" not in tag, f"{name}: image {image!r} is not pinned"


# --- Dockerfile --------------------------------------------------------------------------------------------

def test_dockerfile_is_multi_stage_with_a_compiler_only_in_the_builder(dockerfile):
    assert len(dockerfile.stages) >= 2
    builder = dockerfile.stages[0]
    assert any("gcc" in run for run in builder.all("RUN"))
    assert not any("gcc" in run for run in dockerfile.final.all("RUN"))
    assert any(a.startswith(f"--from={builder.name} ") for a in dockerfile.final.all("COPY"))


def test_base_images_are_pinned(dockerfile):
    names = {s.name for s in dockerfile.stages}
    for stage in dockerfile.stages:
        base = dockerfile.resolve(stage.base)
        if base in names:
            continue
        assert ":" in base and not base.endswith(":latest"), f"FROM {stage.base} -> {base} is not pinned"
    assert "latest" not in (DOCKER_DIR / "Dockerfile").read_text()


def test_final_stage_runs_as_a_numeric_non_root_user(dockerfile):
    users = dockerfile.final.all("USER")
    assert users, "the final stage has no USER: it would run as root"
    uid, _, gid = users[-1].partition(":")
    assert uid.isdigit() and int(uid) > 0, users[-1]
    assert not gid or (gid.isdigit() and int(gid) > 0), users[-1]
    env = dockerfile.final.env()
    owned = [run for run in dockerfile.final.all("RUN") if f"-o {uid}" in run or f"chown {uid}" in run]
    assert len(owned) == 1 and env["CHAKAMO_DATA_DIR"] in owned[0]   # the user owns its data dir, nothing else


def test_final_stage_environment_writes_only_under_data(dockerfile, compose):
    env = dockerfile.final.env()
    assert env["PYTHONDONTWRITEBYTECODE"] == "1"
    data = PurePosixPath(env["CHAKAMO_DATA_DIR"])
    for var in ("NUMBA_CACHE_DIR", "CHAKAMO_FONT_CACHE", "MPLCONFIGDIR", "XDG_CACHE_HOME"):
        assert data in PurePosixPath(env[var]).parents, f"{var}={env[var]} is not under {data}"
    # read-only containers: the data dir is a volume of every chakamo service, /tmp a tmpfs
    for name in CHAKAMO_SERVICES:
        service = compose["services"][name]
        assert str(data) in volume_mounts(service), name
        assert service.get("read_only") is True, name
        assert "/tmp" in service.get("tmpfs", []), name
        assert service_environment(service)["CHAKAMO_DATA_DIR"] == str(data)


def test_image_variables_are_read_by_the_code(dockerfile):
    aliases = _settings_aliases()
    for var in dockerfile.final.env():
        if not _is_setting_name(var) or var in aliases:
            continue
        reader = NON_SETTINGS_VARIABLES.get(var)
        assert reader is not None, f"the image sets {var}, which no code reads"
        assert f'os.environ.get("{var}")' in reader.read_text(), f"{reader} no longer reads {var}"


def test_default_command_is_the_api_command_of_compose(dockerfile, compose):
    assert exec_form(dockerfile.final.all("CMD")[-1]) == compose["services"]["api"]["command"]


def test_ui_stays_beside_the_app_package_in_the_image(dockerfile):
    """app/web/main.py serves ``Path(app.__file__).parents[1] / "static"``: the builder puts app/ and static/ in
    one folder, installs it editable there, and the runtime stage copies that folder to the same path."""
    builder = dockerfile.stages[0]
    workdir = builder.all("WORKDIR")[-1]
    copies = {a.split()[0]: a.split()[1] for a in builder.all("COPY") if not a.startswith("--")}
    assert copies.get("app") == "./app" and copies.get("static") == "./static"
    assert any("pip install" in run and "-e ." in run for run in builder.all("RUN"))
    assert f"--from={builder.name} {workdir} {workdir}" in dockerfile.final.all("COPY")


def test_copied_sources_exist_and_are_in_the_build_context(dockerfile):
    patterns = dockerignore_patterns()
    for stage in dockerfile.stages:
        for args in stage.all("COPY"):
            if args.startswith("--from="):
                continue
            for source in args.split()[:-1]:
                assert (REPO / source).exists(), f"COPY {source}: no such file in the repository"
                assert not any(fnmatch(source, p) for p in patterns), f"COPY {source} is excluded by .dockerignore"


class _Readyz(BaseHTTPRequestHandler):
    status = 200

    def do_GET(self):  # noqa: N802 (http.server's name)
        self.send_response(self.status if self.path == "/readyz" else 404)
        self.end_headers()

    def log_message(self, *args):
        pass


@pytest.mark.parametrize("status, healthy", [(200, True), (503, False)])
def test_image_healthcheck_follows_readyz(dockerfile, compose, status, healthy):
    command = healthcheck_command(dockerfile.final.all("HEALTHCHECK")[-1])
    assert command == compose["services"]["api"]["healthcheck"]["test"][1:]
    handler = type("Handler", (_Readyz,), {"status": status})
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        assert (run_healthcheck(command, server.server_address[1]) == 0) is healthy
    finally:
        server.shutdown()
        server.server_close()


def test_image_healthcheck_fails_when_nothing_listens(dockerfile):
    command = healthcheck_command(dockerfile.final.all("HEALTHCHECK")[-1])
    assert run_healthcheck(command, free_port()) != 0


# --- .dockerignore -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("path", [".venv", ".git", "out", "app/__pycache__", "app/x.pyc", ".pytest_cache",
                                  ".hypothesis", "chakamo.egg-info", "docker/.env", "tests"])
def test_dockerignore_keeps_local_files_out_of_the_context(path):
    assert any(fnmatch(path, p) or fnmatch(path, p.removeprefix("**/")) for p in dockerignore_patterns()), path


# --- with a compose CLI, when one happens to be installed ---------------------------------------------------

def _compose_cli() -> list[str] | None:
    if shutil.which("docker-compose"):
        return ["docker-compose"]
    if shutil.which("docker"):
        probe = subprocess.run(["docker", "compose", "version"], capture_output=True, timeout=30)
        if probe.returncode == 0:
            return ["docker", "compose"]
    return None


def test_compose_config_is_valid_for_docker_compose():
    cli = _compose_cli()
    if cli is None:
        pytest.skip("neither `docker compose` nor `docker-compose` is installed")
    env = {k: v for k, v in os.environ.items() if k not in TEST_SECRETS} | TEST_SECRETS
    argv = [*cli, "--env-file", os.devnull, "-f", str(COMPOSE_FILE), "config", "-q"]
    done = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    missing = subprocess.run(argv, capture_output=True, text=True, timeout=120,
                             env={k: v for k, v in env.items() if k != "POSTGRES_PASSWORD"})
    assert missing.returncode != 0 and "POSTGRES_PASSWORD" in missing.stderr
