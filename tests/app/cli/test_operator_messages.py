"""The operator's messages in ``--lang`` (issue 14 §5): the first-admin hint ``chakamo serve`` prints when the
database has no user, and the refusals of the environment (:class:`app.settings.SettingsError`), as an operator
meets them: a fresh ``chakamo`` process, or ``main()``.  The English hint is the one ChakaMo printed before it
spoke other languages, word for word."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading

import pytest

from app.cli.language import say
from app.cli.main import main
from app.settings import MESSAGES, get_settings

LANGS = ("es", "en", "pt")
CHAKAMO = [sys.executable, "-c", "from app.cli.main import console; console()"]

#: the hint as ``app/web/main.py`` printed it, in English only, before issue 14 §5
ENGLISH_HINT = (
    "ChakaMo has no user yet. Create a clinic and its first admin:\n"
    "  chakamo clinics create \"My clinic\"\n"
    "  chakamo users create --clinic \"My clinic\" --email you@example.org --role admin --name \"Your Name\"\n"
    "(the second command asks for the password; use the same CHAKAMO_DATA_DIR / DATABASE_URL as the server)")


def _env(**extra: str) -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if not k.startswith("CHAKAMO_")} | extra


def _error(prog: str, message: str, lang: str) -> str:
    return (say("cli.argparse_error", lang) % {"prog": prog, "message": message}).rstrip("\n")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_english_hint_is_the_one_printed_before():
    assert say("cli.first_admin", "en") == ENGLISH_HINT


@pytest.mark.parametrize("lang", [*LANGS, None])
def test_serve_tells_how_to_create_the_first_admin_in_lang(lang, tmp_path):
    """A real server on a free port and an empty database: its first lines, up to the end of the hint."""
    port = _free_port()
    args = [*CHAKAMO, "serve", "--port", str(port)] + (["--lang", lang] if lang else [])
    proc = subprocess.Popen(args, env=_env(CHAKAMO_DATA_DIR=str(tmp_path), CHAKAMO_ENV="development"),
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    watchdog = threading.Timer(240, proc.kill)   # a server that never prints the hint ends the read (EOF)
    watchdog.start()
    hint = say("cli.first_admin", lang or "en").splitlines()
    lines: list[str] = []
    try:
        for line in proc.stderr:
            lines.append(line.rstrip("\n"))
            if lines[-len(hint):] == hint:
                break
    finally:
        watchdog.cancel()
        proc.terminate()
        proc.wait(timeout=60)
        proc.stderr.close()
    assert lines[0] == say("cli.serve_started", lang or "en", host="127.0.0.1", port=port, data_dir=tmp_path)
    assert lines[-len(hint):] == hint, lines
    if lang in ("es", "pt"):
        assert not set(hint) & set(ENGLISH_HINT.splitlines()[1:])   # the example names are in lang too
        assert "CHAKAMO_DATA_DIR" in hint[-1]


@pytest.fixture
def clean_env(monkeypatch, tmp_path):
    for key in [k for k in os.environ if k.startswith("CHAKAMO_")]:
        monkeypatch.delenv(key)
    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(tmp_path))
    get_settings.cache_clear()
    yield monkeypatch
    get_settings.cache_clear()


@pytest.mark.parametrize("lang", LANGS)
@pytest.mark.parametrize("command,env,code,params", [
    (["serve"], {"CHAKAMO_ENV": "production"}, "settings.no_secret_key", {}),
    (["serve"], {"CHAKAMO_ENV": "production", "CHAKAMO_SECRET_KEY": "short"}, "settings.weak_secret_key",
     {"min": 32}),
    (["migrate"], {"CHAKAMO_ENV": "development", "CHAKAMO_PUBLIC_URL": "chakamo.hospital.example"},
     "settings.public_url", {"value": "chakamo.hospital.example"}),
    (["clinics", "create", "X"], {"CHAKAMO_ENV": "development", "CHAKAMO_ACCESSION_SYSTEM": "accessions"},
     "settings.not_a_uri", {"var": "CHAKAMO_ACCESSION_SYSTEM", "value": "accessions"}),
    (["worker"], {"CHAKAMO_ENV": "development", "CHAKAMO_JOB_BACKEND": "celery", "CHAKAMO_BROKER_URL": "amqp://q"},
     "settings.broker_url", {"value": "amqp://q"}),
    (["serve"], {"CHAKAMO_ENV": "development", "CHAKAMO_WORKERS": "0"}, "settings.at_least",
     {"var": "CHAKAMO_WORKERS", "value": "0", "limit": 1}),
])
def test_settings_refusals_in_lang(command, env, code, params, lang, clean_env, capsys):
    for key, value in env.items():
        clean_env.setenv(key, value)
    assert main([*command, "--lang", lang]) == 2
    err = capsys.readouterr().err.strip()
    assert err == _error(f"chakamo {command[0]}", MESSAGES[code][lang].format(**params), lang)


def test_without_lang_the_refusal_is_english(clean_env, capsys):
    clean_env.setenv("CHAKAMO_ENV", "production")
    assert main(["serve"]) == 2
    assert capsys.readouterr().err.strip() == "chakamo serve: error: " + MESSAGES["settings.no_secret_key"]["en"]


@pytest.mark.parametrize("lang", ["es", "pt"])
def test_a_settings_refusal_from_a_fresh_process(lang, tmp_path):
    proc = subprocess.run([*CHAKAMO, "serve", "--lang", lang], capture_output=True, text=True, timeout=300,
                          env=_env(CHAKAMO_DATA_DIR=str(tmp_path), CHAKAMO_ENV="development",
                                   CHAKAMO_FHIR_PUSH_URL="fhir.hospital.example"))
    assert proc.returncode == 2
    assert proc.stderr.strip() == _error("chakamo serve", MESSAGES["settings.push_url"][lang].format(
        value="fhir.hospital.example"), lang)
    assert "CHAKAMO_FHIR_PUSH_URL" in proc.stderr
