"""The refusals of the environment (issue 14 §5): every ``SettingsError`` is a code of :data:`app.settings.MESSAGES`
whose sentence exists in es/en/pt with the parameters its raise gives, names the variable and reads in English
through ``str()`` (logs, programs); pydantic's own refusals name their variable too."""

from __future__ import annotations

import ast
import inspect
import os

import pytest

import app.settings as settings_module
from app.settings import MESSAGES, SettingsError
from app.web.messages import CATALOGUE, LANGUAGES, placeholders

SOURCE = inspect.getsource(settings_module)


def _raises() -> list[ast.Call]:
    return [node for node in ast.walk(ast.parse(SOURCE)) if isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name) and node.func.id == "SettingsError"]


def test_every_raise_names_a_code_of_three_languages_with_its_parameters():
    calls = _raises()
    assert len(calls) >= 8, len(calls)   # public URL, URI, identifier base, push URL, broker, https, key x2
    for call in calls:
        assert call.args and isinstance(call.args[0], ast.Constant), ast.unparse(call)
        code = call.args[0].value
        assert code in MESSAGES, code
        given = {kw.arg for kw in call.keywords}
        for lang in LANGUAGES:
            assert placeholders(MESSAGES[code][lang]) == given, (code, lang)


@pytest.mark.parametrize("code", sorted(MESSAGES))
def test_each_sentence_in_three_languages_with_the_same_placeholders(code):
    texts = MESSAGES[code]
    assert set(texts) == set(LANGUAGES)
    assert placeholders(texts["es"]) == placeholders(texts["en"]) == placeholders(texts["pt"])
    assert len(set(texts.values())) == 3   # really translated
    assert CATALOGUE[code] is texts   # one table: the CLI catalogue holds it (and the consistency tests read it)


def test_pydantic_kinds_map_to_sentences_of_the_table():
    for code, _bound in settings_module._PYDANTIC.values():
        assert code in MESSAGES


def _refusal(monkeypatch, tmp_path, env: dict[str, str], clean: bool = False) -> SettingsError:
    """The SettingsError ``get_settings()`` raises in development on ``tmp_path`` with ``env`` set (``clean``: every
    other CHAKAMO_ variable of this process' environment removed first)."""
    from app.settings import get_settings

    if clean:
        for key in [k for k in os.environ if k.startswith("CHAKAMO_")]:
            monkeypatch.delenv(key)
    monkeypatch.setenv("CHAKAMO_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CHAKAMO_ENV", "development")
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    get_settings.cache_clear()
    try:
        with pytest.raises(SettingsError) as caught:
            get_settings()
    finally:
        get_settings.cache_clear()
    return caught.value


@pytest.mark.parametrize("env,code,variable", [
    ({"CHAKAMO_PUBLIC_URL": "ftp://x"}, "settings.public_url", "CHAKAMO_PUBLIC_URL"),
    ({"CHAKAMO_ACCESSION_SYSTEM": "hospital numbers"}, "settings.not_a_uri", "CHAKAMO_ACCESSION_SYSTEM"),
    ({"CHAKAMO_PATIENT_IDENTIFIER_SYSTEM": "mrn"}, "settings.not_a_uri", "CHAKAMO_PATIENT_IDENTIFIER_SYSTEM"),
    ({"CHAKAMO_FHIR_IDENTIFIER_BASE": "urn:oid:1.2.3"}, "settings.identifier_base", "CHAKAMO_FHIR_IDENTIFIER_BASE"),
    ({"CHAKAMO_FHIR_PUSH_URL": "fhir.example"}, "settings.push_url", "CHAKAMO_FHIR_PUSH_URL"),
    ({"CHAKAMO_JOB_BACKEND": "celery", "CHAKAMO_BROKER_URL": "amqp://x"}, "settings.broker_url", "CHAKAMO_BROKER_URL"),
    ({"CHAKAMO_WORKERS": "0"}, "settings.at_least", "CHAKAMO_WORKERS"),
    ({"CHAKAMO_WORKERS": "99"}, "settings.at_most", "CHAKAMO_WORKERS"),
    ({"CHAKAMO_SESSION_HOURS": "0"}, "settings.more_than", "CHAKAMO_SESSION_HOURS"),
    ({"CHAKAMO_MAX_FILES": "many"}, "settings.not_an_integer", "CHAKAMO_MAX_FILES"),
    ({"CHAKAMO_MAX_FILE_MB": "1,5"}, "settings.not_a_number", "CHAKAMO_MAX_FILE_MB"),
    ({"CHAKAMO_FHIR_PATIENT": "inline"}, "settings.not_a_choice", "CHAKAMO_FHIR_PATIENT"),
    ({"CHAKAMO_ENV": "staging"}, "settings.not_a_choice", "CHAKAMO_ENV"),
])
def test_each_refusal_names_its_variable_in_every_language(env, code, variable, monkeypatch, tmp_path):
    error = _refusal(monkeypatch, tmp_path, env, clean=True)
    assert [c for c, _ in error.parts] == [code]
    assert str(error) == error.message("en")
    for lang in LANGUAGES:
        assert variable in error.message(lang), (lang, error.message(lang))
    assert len({error.message(lang) for lang in LANGUAGES}) == 3


def test_the_choices_offered_are_the_fields_own(monkeypatch, tmp_path):
    assert _refusal(monkeypatch, tmp_path, {"CHAKAMO_FHIR_PATIENT": "inline"}).parts == (("settings.not_a_choice", {"var": "CHAKAMO_FHIR_PATIENT", "value": "inline",
                                                              "choices": "contained, identifier, reference"}),)


def test_several_refusals_are_joined_one_sentence_each(monkeypatch, tmp_path):
    error = _refusal(monkeypatch, tmp_path, {"CHAKAMO_WORKERS": "0", "CHAKAMO_PUBLIC_URL": "chakamo.example"})
    assert sorted(c for c, _ in error.parts) == ["settings.at_least", "settings.public_url"]
    for lang in LANGUAGES:
        text = error.message(lang)
        assert text.count("; CHAKAMO_") == 1 and "CHAKAMO_WORKERS='0'" in text, text


def test_a_secret_is_never_echoed(monkeypatch, tmp_path):
    """A refusal shows the value it refuses, but never the secret key's."""
    parts = settings_module._parts({"type": "string_too_short", "loc": ("CHAKAMO_SECRET_KEY",),
                                    "input": "hunter2", "msg": "too short"})
    assert parts[0][1]["value"] == "***"
