"""Every refusal the web layer raises carries a code of the catalogues, hence ``code``, ``params`` and the
es/en/pt ``message`` (house rule: every message a user can cause exists in three languages).

A static check of the source (``ast``): an ``HTTPException`` raised with a sentence of its own is English only;
a ``Refusal``, an authentication refusal (``_refuse``) or a domain error's ``code`` must name an entry of
:data:`app.pipeline.service_messages.CATALOGUE`, :data:`app.web.messages.CATALOGUE` or the ingestion's, in all
three languages.  The English-only ones written before this check are listed (to be translated), so a new one
fails.
"""

from __future__ import annotations

import ast
from pathlib import Path

from app.pipeline.ingestion.messages import CATALOGUE as INGESTION
from app.pipeline.service_messages import CATALOGUE as SERVICE
from app.web.messages import CATALOGUE as ACCOUNTS

ROOT = Path(__file__).resolve().parents[3] / "app"
CODES = {**INGESTION, **SERVICE, **ACCOUNTS}
#: English-only HTTPExceptions older than this check (file: how many): none left, the last three (If-Match, FHIR's 409)
#: answer catalogue entries now
OLD_ENGLISH_ONLY: dict[str, int] = {}


def _calls():
    for path in sorted(ROOT.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                name = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
                yield path.relative_to(ROOT).as_posix(), name, node


def test_no_new_english_only_http_exception():
    found: dict[str, int] = {}
    for where, name, node in _calls():
        if name == "HTTPException" and len(node.args) >= 2 and isinstance(node.args[1], (ast.Constant, ast.JoinedStr)):
            found[where] = found.get(where, 0) + 1
    assert found == OLD_ENGLISH_ONLY, "raise Refusal(status, code, **params) with a catalogue entry instead"


def test_every_refusal_code_is_in_a_catalogue_in_three_languages():
    import inspect

    from app.web.api.deps import _refuse

    # the code's place is read from _refuse's own signature (a hard-coded place went stale when db was added, and
    # its calls' codes silently dropped out); every call must name its code as a constant there
    at = list(inspect.signature(_refuse).parameters).index("code")
    codes = set()
    for where, name, node in _calls():
        if name == "Refusal" and len(node.args) >= 2 and isinstance(getattr(node.args[1], "value", None), str):
            codes.add((where, node.args[1].value))
        if name == "_refuse" and isinstance(node.func, ast.Name) and where == "web/api/deps.py":
            code = node.args[at] if len(node.args) > at else None
            assert isinstance(getattr(code, "value", None), str), (where, node.lineno, "_refuse without a code")
            codes.add((where, code.value))
        if name == "FhirExportError" and node.args:   # the FHIR export's reasons, quoted by its 409
            assert isinstance(getattr(node.args[0], "value", None), str), (where, node.lineno)
            codes.add((where, node.args[0].value))
    # the data layer's refusals (DomainError(code=...)) are checked by tests/app/pipeline/test_check_messages.py
    assert {c for _, c in codes} >= {"auth.scope_missing", "auth.token_expired", "webhook.url_refused",
                                     "fhir.no_patient_identifier"}
    missing = [(w, c) for w, c in codes if c not in CODES or set(CODES[c]) != {"es", "en", "pt"}]
    assert not missing, missing


def test_the_password_hashing_busy_error_speaks_every_language():
    """:class:`app.web.security.Busy` was an English sentence of its own; it is now the catalogue's
    ``password.busy`` (the routes answer it as that refusal), in es/en/pt."""
    from app.web.security import Busy

    busy = Busy()
    assert busy.code == "password.busy" and str(busy) == ACCOUNTS["password.busy"]["en"]
    assert busy.message("es") == ACCOUNTS["password.busy"]["es"] and busy.message("es").startswith("El servidor")
    assert busy.message("pt") == ACCOUNTS["password.busy"]["pt"] and busy.message("pt").startswith("O servidor")


def _literal_what(where: str, node: ast.Call, position: int) -> str | None:
    """The ``what`` argument of a call (a string, or a name the enclosing function assigns one string to)."""
    arg = node.args[position] if len(node.args) > position else next(
        (k.value for k in node.keywords if k.arg == "what"), None)
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value
    if isinstance(arg, ast.Name):
        tree = ast.parse((ROOT / where).read_text(encoding="utf-8"))
        fn = max((f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)
                  and f.lineno <= node.lineno <= f.end_lineno), key=lambda f: f.lineno)   # the innermost holding it
        if arg.id in {a.arg for a in fn.args.args + fn.args.kwonlyargs}:
            return None   # passed on: its callers' literals are checked
        values = {a.value.value for a in ast.walk(fn) if isinstance(a, ast.Assign) and isinstance(a.value, ast.Constant)
                  and any(getattr(t, "id", None) == arg.id for t in a.targets)}
        assert len(values) == 1, (where, node.lineno, arg.id)
        return values.pop()
    raise AssertionError(f"{where}:{node.lineno}: give 'what' as a string literal (a store.then.* key)")


def test_every_busy_what_is_a_catalogue_fragment():
    """Review finding: ``Busy``'s ``what`` names a ``store.then.*`` fragment; a key the catalogue lacks turned the
    409 into a 500 when it was rendered.  Every caller's literal key exists in es/en/pt (statically), and
    :class:`app.store.sessions.Busy` refuses an unknown one when built (a programming error, at once)."""
    import pytest

    from app.store.sessions import Busy

    positions = {"Busy": 2, "refuse_while_processing": 2, "_refuse_while_any_processing": 2}
    found = set()
    for where, name, node in _calls():
        if name in positions and not where.startswith("web/security"):
            what = _literal_what(where, node, positions[name])
            if what is not None:
                found.add((where, what))
    assert {w for _, w in found} >= {"process", "upload", "delete_patient"}
    missing = [(w, k) for w, k in found if set(SERVICE.get(f"store.then.{k}", {})) != {"es", "en", "pt"}]
    assert not missing, missing
    for code in ("store.busy", "store.superseded", "store.superseded_tail"):   # SupersededResults' and Busy's own
        assert set(SERVICE[code]) == {"es", "en", "pt"}
    with pytest.raises(ValueError, match="store.then.uplaod"):
        Busy(1, 2, "uplaod")
    assert Busy(1, 2, "upload").params["what"] == {"code": "store.then.upload"}
