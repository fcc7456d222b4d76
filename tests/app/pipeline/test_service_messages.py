"""The server's own messages (``app/pipeline/service_messages.py``): three languages with the same placeholders,
and every code the web layer and the checks raise is in the table."""

from __future__ import annotations

import re
from pathlib import Path

from app.pipeline.ingestion.messages import LANGUAGES, placeholders
from app.pipeline.service_messages import CATALOGUE, message_dict

APP = Path(__file__).resolve().parents[3] / "app"


def test_every_code_has_three_languages_with_the_same_placeholders():
    for code, entry in CATALOGUE.items():
        assert set(entry) == set(LANGUAGES), code
        assert all(entry[lang].strip() for lang in LANGUAGES), code
        assert placeholders(entry["es"]) == placeholders(entry["en"]) == placeholders(entry["pt"]), code


def test_every_code_used_is_in_the_table():
    used = set()
    for p in list((APP / "web").rglob("*.py")) + [APP / "store" / "checks.py"]:
        used |= set(re.findall(r"[\"']((?:request|session)\.[a-z_]+)[\"']", p.read_text(encoding="utf-8")))
    assert used and not used - set(CATALOGUE), sorted(used - set(CATALOGUE))


def test_message_dict_renders_each_language():
    d = message_dict("request.body_too_large", {"limit_kb": 1024})
    assert d["code"] == "request.body_too_large" and all("1024" in d["message"][x] for x in LANGUAGES)
