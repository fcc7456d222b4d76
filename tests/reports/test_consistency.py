"""One vocabulary across the UI and the reports (issue 17 §3): the same angle names and order in the browser
(static/i18n, static/charts.js) and in the PDF, HTML and Excel (reports/translations*.json, reports.model.ANGLES),
one Portuguese (European, pt-PT: the README says so) in both, and the date format of each language."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from reports import figures
from reports.i18n import LANGUAGES, fmt_date, t
from reports.model import ANGLES

ROOT = Path(__file__).resolve().parents[2]
UI = {lang: json.loads((ROOT / "static" / "i18n" / f"{lang}.json").read_text(encoding="utf-8")) for lang in LANGUAGES}
#: Brazilian forms whose European spelling or word the tables use instead (registo, ficheiro, aceites, palavra-passe,
#: guardar, registe, registado, liberte, livro, utilizador, ecrã, aplicação...)
BRAZILIAN = ("registro", "registros", "arquivo", "arquivos", "planilha", "aceitos", "acelerômetro", "magnetômetro",
             "magnetômetros", "detectados", "conexão", "eletrônicos", "fêmur", "você", "usuário", "usuários", "tela",
             "senha", "senhas", "salvar", "salve", "salvo", "salvos", "salva", "registre", "registrado", "registrada",
             "libere", "aplicativo", "requisição", "requisições")
#: Brazilian phrases (several words)
BRAZILIAN_PHRASES = ("pasta de trabalho", "está sendo", "estão sendo")


def _pt_texts(source: str) -> list[str]:
    """The Portuguese texts of one table: the reports', the UI's (static/i18n/pt.json) or the server's messages."""
    from app.pipeline.ingestion.messages import CATALOGUE as INGESTION
    from app.pipeline.messages import PIPELINE_CATALOGUE
    from app.pipeline.service_messages import CATALOGUE as SERVICE
    from app.web.messages import CATALOGUE as WEB
    from reports.i18n import table

    def flat(value) -> list[str]:
        return [x for v in value.values() for x in flat(v)] if isinstance(value, dict) else [str(value)]

    if source == "reports":
        return [v["pt"] for v in table().values()]
    if source == "static/i18n/pt.json":
        return flat(UI["pt"])
    catalogue = {"app/pipeline/ingestion/messages.py": INGESTION, "app/pipeline/messages.py": PIPELINE_CATALOGUE,
                 "app/pipeline/service_messages.py": SERVICE, "app/web/messages.py": WEB}[source]
    return [v["pt"] for v in catalogue.values()]


@pytest.mark.parametrize("lang", LANGUAGES)
def test_angle_names_are_the_same_in_the_ui_and_the_reports(lang):
    for a in ANGLES:
        assert UI[lang][f"angle.{a}"] == t(f"angle_{a}", lang) == t(f"data.angle.{a}", lang), (lang, a)


def test_angle_order_is_the_same_in_the_ui_and_the_reports():
    js = (ROOT / "static" / "charts.js").read_text(encoding="utf-8")
    ui_order = tuple(re.findall(r'"(\w+)"', re.search(r"export const ANGLES = \[([^\]]*)\]", js).group(1)))
    assert ui_order == ANGLES == figures.ANGLE_ORDER


@pytest.mark.parametrize("source", ["reports", "static/i18n/pt.json", "app/pipeline/ingestion/messages.py",
                                    "app/pipeline/messages.py", "app/pipeline/service_messages.py",
                                    "app/web/messages.py"])
def test_one_portuguese_in_the_ui_and_the_reports(source):
    """The reports' and the UI's tables, and the messages the server answers (ingestion, pipeline, store, web)."""
    texts = [x.lower() for x in _pt_texts(source)]
    found = sorted({w for text in texts for w in re.findall(r"[\wÀ-ÿ]+(?:-[oa]s?)?", text) if w in BRAZILIAN
                    or w.split("-")[0] in BRAZILIAN})
    found += sorted({p for p in BRAZILIAN_PHRASES for text in texts if p in text})
    assert not found, f"Brazilian forms in the pt table of {source}: {found}"


@pytest.mark.parametrize("lang,expected", [("es", "22/11/2026"), ("en", "2026-11-22"), ("pt", "22/11/2026")])
def test_one_date_format_per_language(lang, expected):
    assert fmt_date("2026-11-22", lang) == fmt_date("2026-11-22T10:00:00+00:00", lang) == expected
    assert fmt_date("", lang) == "" and fmt_date("not a date", lang) == "not a date"
