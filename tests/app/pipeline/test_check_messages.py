"""Every sentence the session check stores comes in es/en/pt (issue 14 §5), read from the source: the codes the
store and the web layer pass to :func:`app.pipeline.service_messages.item` / ``render`` / ``_failed``, the notes'
variants (an ingestion catalogue ``note.*`` entry, or the reports' ``warning.ingestion_note.*``), the ``how_*``
words of :func:`~app.pipeline.service_messages.recognised_item`; and a stored check renders in each language."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from app.pipeline.ingestion.messages import CATALOGUE as INGESTION, LANGUAGES
from app.pipeline.ingestion.model import ROLES, Recognition
from app.pipeline.messages import PIPELINE_CATALOGUE
from app.pipeline.service_messages import CATALOGUE as SERVICE, _how, item, item_texts, recognised_item
from app.web.messages import CATALOGUE as WEB
from reports import i18n

APP = Path(__file__).resolve().parents[3] / "app"


def _complete(entry) -> bool:
    return set(LANGUAGES) <= set(entry) and all(str(entry[x]).strip() for x in LANGUAGES)


def test_every_code_the_check_stores_has_three_languages():
    used = set()
    for p in [*(APP / "store").glob("*.py"), *(APP / "web").rglob("*.py"), APP / "pipeline" / "service_messages.py"]:
        text = p.read_text(encoding="utf-8")
        used |= set(re.findall(r"(?:item|render|_failed|Refusal\(\d+,)\s*\(?\s*[\"']([a-z_]+\.[a-z_]+)[\"']", text))
    tables = {**INGESTION, **PIPELINE_CATALOGUE, **SERVICE, **WEB}  # the web layer's own refusals (app.web.messages)
    assert "session.recognised" in used and "session.no_files_yet" in used
    missing = sorted(c for c in used if c not in tables or not _complete(tables[c]))
    assert not missing, missing


_DOMAIN = {"DomainError", "NotFound", "Conflict", "Invalid", "LimitExceeded", "PreconditionFailed"}


def _domain_calls():
    """Every ``NotFound(...)``/``Conflict(...)``/… call in app/ and every ``super().__init__(...)`` of a class
    derived from one (transitively, by name: ``Busy(Conflict)``, ``NotReady(Conflict)``), as ``(where, call)``."""
    import ast

    trees = {p: ast.parse(p.read_text(encoding="utf-8")) for p in APP.rglob("*.py")}
    domain = set(_DOMAIN)
    for _ in range(3):   # subclasses of subclasses (Busy(Conflict), …)
        for tree in trees.values():
            for node in ast.walk(tree):
                if isinstance(node, ast.ClassDef) and any(getattr(b, "id", None) in domain for b in node.bases):
                    domain.add(node.name)
    for p, tree in trees.items():
        if p.name == "errors.py" and p.parent.name == "store":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) in _DOMAIN - {"DomainError"}:
                yield f"{p.relative_to(APP)}:{node.lineno}", node   # (a subclass's own __init__ is checked below)
            if isinstance(node, ast.ClassDef) and node.name in domain:
                for call in ast.walk(node):
                    if isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute) \
                            and call.func.attr == "__init__" and isinstance(call.func.value, ast.Call):
                        yield f"{p.relative_to(APP)}:{call.lineno}", call


def test_every_refusal_of_the_data_layer_has_a_code_in_three_languages():
    """A store/jobs refusal (:mod:`app.store.errors`) reaches the user as a 4xx answer whose ``message`` is
    es/en/pt only when it is raised with ``code=`` (issue 14 §5): one raised with an English sentence, or with
    a code whose entry lacks a language, fails here."""
    tables = {**INGESTION, **SERVICE}
    seen, english, incomplete = 0, [], []
    for where, call in _domain_calls():
        seen += 1
        code = next((k.value for k in call.keywords if k.arg == "code"), None)
        if code is None or any(isinstance(a, (ast_str := __import__("ast")).Constant) and isinstance(a.value, str)
                               or isinstance(a, ast_str.JoinedStr) for a in call.args):
            english.append(where)
        elif isinstance(code, __import__("ast").Constant) and not (code.value in tables
                                                                  and _complete(tables[code.value])):
            incomplete.append((where, code.value))
    assert seen > 30
    assert not english, f"raised with an English sentence, give it a code= in service_messages: {english}"
    assert not incomplete, incomplete


def test_no_code_is_defined_twice():
    """A stored code is looked up in the service table first: one also in the ingestion's would show the wrong text."""
    assert not set(SERVICE) & set(INGESTION) and not set(SERVICE) & set(PIPELINE_CATALOGUE)
    assert not set(PIPELINE_CATALOGUE) & set(INGESTION)


def test_every_note_variant_has_three_languages():
    variants = set()
    for p in (APP / "pipeline" / "ingestion").glob("*.py"):
        text = p.read_text(encoding="utf-8")
        variants |= set(re.findall(r"[\"']variant[\"']:\s*[\"']([a-z_0-9]+)[\"']", text))
        variants |= set(re.findall(r"Note\.of\(\s*f?[\"']([a-z_0-9]+)[\"']", text))
        for line in re.findall(r"^\s*variant = (.+)$", text, re.M):   # variant = "a" if ... else "b"
            variants |= set(re.findall(r"(?:^|else )[\"']([a-z_0-9]+)[\"']", line))
    variants |= {f"no_{role}" for role in ROLES if role != "task"}   # Note.of(f"no_{r}"): a role not recorded
    warnings = i18n.table()
    assert {"stream_cut_after", "recording_split"} <= variants
    missing = sorted(v for v in variants if not (f"note.{v}" in INGESTION and _complete(INGESTION[f"note.{v}"]))
                     and not _complete(warnings.get(f"warning.ingestion_note.{v}", {})))
    assert not missing, missing


def test_every_way_a_segment_is_recognised_has_words():
    for method in ("file name", "MetaBase label", "session.json", "split"):
        word = _how(method)
        assert isinstance(word, dict) and _complete(INGESTION[word["code"]]), method


def test_a_stored_check_line_renders_in_each_language():
    line = recognised_item("thigh", "task", {"files": ["a/step-muslo.csv"], "found_by": {
        "segment": [Recognition("thigh", "file name", "muslo").method, "muslo"], "role": ["file name", "step"]}})
    texts = item_texts(line)
    assert texts["en"] == line["text"] == ("thigh task: step-muslo.csv — segment from the file name ('muslo'), role "
                                           "from the file name ('step')")
    assert texts["es"].startswith("muslo tarea: step-muslo.csv — segmento según el nombre del archivo")
    assert texts["pt"].startswith("coxa tarefa: step-muslo.csv — segmento segundo o nome do ficheiro")
    # a note only the reports translate, and a plain sentence stored before codes were
    cut = item(None, {"variant": "stream_cut_after", "stream": "gyr", "seconds": 1.5, "segment": "thigh",
                      "role": "task"}, "thigh task: gyr ran on 1.50 s after the common span (cut)", note=True)
    assert item_texts(cut)["es"] != item_texts(cut)["en"] and "1,50" in item_texts(cut)["es"]
    assert set(item_texts("an old English line").values()) == {"an old English line"}


@pytest.mark.parametrize("uploaded, words", [([1, 2], "debe ser un objeto JSON"),
                                             ({"recordings": 3}, "debe ser una lista"),
                                             ({"recordings": [{"files": ["../x.csv"]}]}, "no es uno de los archivos")])
def test_a_stored_manifest_refusal_comes_in_each_language(uploaded, words):
    import datetime as dt

    from app.pipeline.ingestion import IngestionError
    from app.store.models import KneeSession, Patient, Recording
    from app.store.workspace import build_manifest

    rows = (KneeSession(id=1, clinic_id=1, patient_id=1, date=dt.date(2026, 12, 1), task="step_up"),
            Patient(id=1, clinic_id=1, external_id="W-1", side="left"),
            [Recording(id=1, session_id=1, file_name="a.csv", size_bytes=1, sha256="0" * 64)])
    with pytest.raises(IngestionError) as exc:
        build_manifest(*rows, uploaded=uploaded)
    assert exc.value.code.startswith("manifest.") and words in exc.value.message("es")
    assert "borre esa grabación" in exc.value.message("es") and "apague essa gravação" in exc.value.message("pt")
