"""Every quality-warning code the estimators or the pipeline can emit has its es/en/pt text in
``reports/translations_warnings.json`` (the reports translate warnings by code; a missing entry prints English
in a Spanish or Portuguese report).  Read from the source, so a new code fails here before any data provokes it."""

from __future__ import annotations

import re
from pathlib import Path

from reports import i18n

REPO = Path(__file__).resolve().parents[2]
#: QualityWarning("code", ...), QualityWarning(\n "code", ...), the functional calibration's _warn("code", ...)
_CODE = re.compile(r"""(?:QualityWarning|_warn)\(\s*["']([a-z][a-z0-9_]*)["']""")


def _codes() -> dict[str, str]:
    found = {}
    for folder in ("estimators", "app"):
        for path in (REPO / folder).rglob("*.py"):
            for code in _CODE.findall(path.read_text(encoding="utf-8")):
                found.setdefault(code, str(path.relative_to(REPO)))
    return found


def test_every_warning_code_in_the_source_has_its_three_languages():
    codes = _codes()
    assert len(codes) > 20, sorted(codes)  # the scan found the warnings (a broken pattern finds none)
    table = i18n.table()
    missing = {code: where for code, where in codes.items()
               if f"warning.{code}" not in table or any(not table[f"warning.{code}"].get(lang)
                                                        for lang in i18n.LANGUAGES)}
    # ingestion_note is translated per variant (warning.ingestion_note.<variant>), checked with the catalogue
    missing.pop("ingestion_note", None)
    assert not missing, f"codes without es/en/pt text in reports/translations_warnings.json: {missing}"
