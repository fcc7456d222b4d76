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
    codes = set()
    for where, name, node in _calls():
        if name == "Refusal" and len(node.args) >= 2 and isinstance(getattr(node.args[1], "value", None), str):
            codes.add((where, node.args[1].value))
        if name == "_refuse" and len(node.args) >= 3 and isinstance(getattr(node.args[2], "value", None), str):
            codes.add((where, node.args[2].value))
    # the data layer's refusals (DomainError(code=...)) are checked by tests/app/pipeline/test_check_messages.py
    assert {c for _, c in codes} >= {"auth.scope_missing", "auth.token_expired", "webhook.url_refused"}
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
