"""``chakamo``'s own words in ``--lang`` (issue 14 §5): argparse's usage errors and ``--help`` frame, and the
start-up lines of ``serve``, ``migrate`` and ``worker``, as a user meets them (fresh processes, or ``main()``).

The expected sentences are the catalogue's (app/web/messages.py), filled as argparse fills its msgids; the
msgids themselves are checked against the argparse this Python ships, so a renamed msgid fails here rather
than falling back to English unnoticed.
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
import socket
import subprocess
import sys

import pytest

from app.cli.language import ARGPARSE, HELP, requested, say
from app.cli.main import main
from app.web.messages import CATALOGUE

LANGS = ("es", "en", "pt")


#: the ``chakamo`` console script, in this interpreter (``-m app.cli.main`` prints runpy's warning first)
CHAKAMO = [sys.executable, "-c", "from app.cli.main import console; console()"]


def _chakamo(*args: str, data_dir=None, **env_extra: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("CHAKAMO_")} | env_extra
    if data_dir is not None:
        env |= {"CHAKAMO_DATA_DIR": str(data_dir), "CHAKAMO_ENV": "development"}
    return subprocess.run([*CHAKAMO, *args], env=env, capture_output=True, text=True,
                          timeout=300)


def _error(prog: str, message: str, lang: str) -> str:
    return (say("cli.argparse_error", lang) % {"prog": prog, "message": message}).rstrip("\n")


def test_every_argparse_msgid_we_translate_is_one_argparse_uses():
    """The keys of ARGPARSE are argparse's own msgids (its source passes them to ``_`` / ``ngettext``)."""
    source = inspect.getsource(argparse)
    for msgid in ARGPARSE:
        assert repr(msgid) in source or repr(msgid).replace("'", '"') in source, msgid


@pytest.mark.parametrize("code", sorted(set(ARGPARSE.values()) | set(HELP.values())))
def test_each_sentence_exists_in_three_languages_with_argparse_placeholders(code):
    texts = CATALOGUE[code]
    assert set(texts) == set(LANGS)
    fields = {lang: sorted(re.findall(r"%\(\w+\)[sr]|%[sr]", t)) for lang, t in texts.items()}
    assert fields["es"] == fields["en"] == fields["pt"], fields
    msgids = [m for m, c in {**ARGPARSE, **HELP}.items() if c == code]
    assert texts["en"] in msgids   # English reads exactly as argparse (or our parser) writes it


@pytest.mark.parametrize("lang", LANGS)
def test_an_unknown_option_is_refused_in_the_language_asked_for(lang, tmp_path):
    out = _chakamo("process", str(tmp_path), "--out", str(tmp_path / "o"), "--bogus", "--lang", lang)
    assert out.returncode == 2
    last = out.stderr.strip().splitlines()[-1]
    assert last == _error("chakamo", say("cli.argparse_unrecognized", lang) % "--bogus", lang)
    words = {"es": "chakamo: error: argumentos no reconocidos: --bogus",
             "en": "chakamo: error: unrecognized arguments: --bogus",
             "pt": "chakamo: erro: argumentos não reconhecidos: --bogus"}[lang]
    assert last == words
    usage = {"es": "uso: chakamo", "en": "usage: chakamo", "pt": "utilização: chakamo"}[lang]
    assert out.stderr.startswith(usage), out.stderr


def test_without_lang_the_errors_are_argparses_own(tmp_path):
    """No ``--lang``: English, word for word what a plain argparse parser says."""
    out = _chakamo("process", str(tmp_path), "--out", str(tmp_path / "o"), "--bogus")
    assert out.returncode == 2 and out.stderr.strip().splitlines()[-1] == \
        "chakamo: error: unrecognized arguments: --bogus"


@pytest.mark.parametrize("lang", LANGS)
def test_missing_arguments_and_invalid_choices_in_lang(lang, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["process", "--lang", lang])
    assert exit_.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last == _error("chakamo process", say("cli.argparse_required", lang) % "SESSION_DIR, --out", lang)

    with pytest.raises(SystemExit):
        main(["process", "S", "--out", "O", "--filter", "nope", "--lang", lang])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    choice = say("cli.argparse_invalid_choice", lang) % {
        "value": "nope", "choices": "'chakamo', 'guo', 'madgwick', 'valenti_cf', 'valenti_kf'"}
    assert last == _error("chakamo process", say("cli.argparse_argument", lang) % {
        "argument_name": "--filter", "message": choice}, lang)
    if lang == "pt":
        assert "opção inválida: 'nope' (escolha entre" in last

    with pytest.raises(SystemExit):   # a value our own converter refuses
        main(["reprocess", "--filter", "guo", "--since", "2020-13-01", "--lang", lang])
    assert say("cli.not_a_date", lang, value="2020-13-01") in capsys.readouterr().err


@pytest.mark.parametrize("lang", LANGS)
def test_help_frame_in_lang(lang, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["migrate", "--help", "--lang", lang])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(say("cli.argparse_usage", lang) + "chakamo migrate")
    assert f"\n{say('cli.argparse_options', lang)}:\n" in out
    assert say("cli.argparse_help", lang) in out
    with pytest.raises(SystemExit):
        main(["process", "--help", "--lang", lang])
    assert f"\n{say('cli.argparse_positionals', lang)}:\n" in capsys.readouterr().out


def test_the_language_is_read_from_the_whole_command_line():
    assert requested(["process", "x", "--lang", "pt"]) == "pt"
    assert requested(["--lang=es", "process"]) == "es"
    assert requested(["process", "--lang", "fr"]) is None   # argparse refuses it, in English
    assert requested(["process", "--", "--lang", "es"]) is None


def test_the_language_is_the_one_argparse_reads(capsys):
    """Review finding: the last ``--lang`` wins and argparse's abbreviations count (``--lan es`` was parsed as
    Spanish by argparse but its errors came out in English; ``--lang pt --lang es`` erred in Portuguese)."""
    assert requested(["process", "--lang", "pt", "--lang", "es"]) == "es"
    assert requested(["process", "--lan", "es"]) == "es" and requested(["process", "--la=pt"]) == "pt"
    assert requested(["process", "--l", "es"]) is None and requested(["process", "--langx", "es"]) is None
    with pytest.raises(SystemExit):
        main(["process", "--bogus", "--lan", "es"])
    assert say("cli.argparse_required", "es").split("%")[0] in capsys.readouterr().err


def test_serve_s_lang_option_is_explained_in_lang(capsys):
    """Review finding: ``serve --help --lang pt`` printed its ``--lang`` line in English."""
    with pytest.raises(SystemExit):
        main(["serve", "--help", "--lang", "pt"])
    assert say("cli.help_lang_messages", "pt") in capsys.readouterr().out


@pytest.mark.parametrize("lang", LANGS)
def test_migrate_says_it_in_lang(lang, tmp_path):
    out = _chakamo("migrate", "--lang", lang, data_dir=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == say("cli.migrated", lang, url=f"sqlite:///{tmp_path / 'chakamo.db'}")


@pytest.mark.parametrize("lang", LANGS)
def test_worker_refusals_in_lang(lang, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CHAKAMO_ENV", "development")
    monkeypatch.setenv("CHAKAMO_JOB_BACKEND", "inprocess")
    from app.settings import get_settings

    get_settings.cache_clear()
    try:
        assert main(["worker", "--lang", lang]) == 2
        assert capsys.readouterr().err.strip() == _error("chakamo worker", say("cli.worker_needs_celery", lang), lang)
    finally:
        get_settings.cache_clear()


@pytest.mark.parametrize("lang", ["es", "pt"])
def test_serve_start_up_line_in_lang(lang, tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if not k.startswith("CHAKAMO_")} | {
        "CHAKAMO_DATA_DIR": str(tmp_path), "CHAKAMO_ENV": "development"}
    proc = subprocess.Popen([*CHAKAMO, "serve", "--port", str(port), "--lang", lang],
                            env=env, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        first = proc.stderr.readline().strip()
    finally:
        proc.terminate()
        proc.wait(timeout=60)
    assert first == say("cli.serve_started", lang, host="127.0.0.1", port=port, data_dir=tmp_path)


def _help_texts(parser) -> set[str]:
    texts = {parser.description}
    for action in parser._actions:
        texts.add(action.help)
        for sub in getattr(action, "_get_subactions", lambda: [])():
            texts.add(sub.help)
        for child in (action.choices or {}).values() if isinstance(action.choices, dict) else ():
            texts |= _help_texts(child)
    return texts


def test_every_translated_help_text_is_one_the_parser_shows():
    """HELP is keyed by the English text: an English help changed in add_parsers would lose its translation
    silently, so every key must still be a help text of the parser."""
    from app.cli.main import _build_parser

    shown = _help_texts(_build_parser())
    assert set(HELP) <= shown, set(HELP) - shown


@pytest.mark.parametrize("lang", ["es", "pt"])
def test_the_commands_are_listed_in_lang(lang, capsys):
    with pytest.raises(SystemExit):
        main(["--help", "--lang", lang])
    out = capsys.readouterr().out
    assert say("cli.help_process", lang) in out and say("cli.description", lang) in out
