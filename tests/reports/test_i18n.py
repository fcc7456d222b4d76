"""Translation tables and number formatting (reports.i18n)."""

from __future__ import annotations

import json
import math
import re
import string
from pathlib import Path

import pytest

import reports
from estimators.motor_task.tasks import TASKS
from reports import i18n
from reports.i18n import LANGUAGES, MISSING, TranslationError, fmt_mean_sd, fmt_number, load_tables, t

REPORTS_DIR = Path(reports.__file__).parent
#: texts that may legitimately be empty in a language (nothing to say in English)
MAY_BE_EMPTY = {("warnings_language_note", "en")}


def _fields(text: str) -> set[str]:
    return {name for _, name, _, _ in string.Formatter().parse(text) if name}


def test_every_key_has_the_three_languages_and_the_same_fields():
    table = i18n.table()
    assert len(table) > 50
    for key, texts in table.items():
        assert set(texts) == set(LANGUAGES), key
        for lang in LANGUAGES:
            assert texts[lang].strip() or (key, lang) in MAY_BE_EMPTY, (key, lang)
        fields = {lang: _fields(texts[lang]) for lang in LANGUAGES}
        assert fields["es"] == fields["en"] == fields["pt"], (key, fields)


def test_translations_json_is_valid_package_data():
    data = json.loads((REPORTS_DIR / "translations.json").read_text(encoding="utf-8"))
    assert all(k.startswith("_") or set(v) == set(LANGUAGES) for k, v in data.items())
    # every translations*.json next to it is merged (the Excel/HTML helper's table too)
    for f in REPORTS_DIR.glob("translations*.json"):
        for key in json.loads(f.read_text(encoding="utf-8")):
            assert key.startswith("_") or key in i18n.table(), (f.name, key)


def test_every_key_used_by_the_pdf_and_figures_exists():
    used: set[str] = set()
    for name in ("pdf.py", "figures.py"):
        src = (REPORTS_DIR / name).read_text(encoding="utf-8")
        used |= set(re.findall(r"""\b(?:t|tr)\(\s*["']([a-z0-9_]+)["']""", src))
    # keys built from data (f-strings): the values the code can produce
    for prefix, values in {
        "angle_": ("flexion", "adduction", "internal_rotation"),
        "axis_": ("flexion", "adduction", "internal_rotation"),
        "phase_": ("movement", "cycle"),
        "side_": ("right", "left"), "leg_": ("right", "left"), "seg_": ("thigh", "shank"),
        "pose_": ("start", "peak_flexion", "full_extension"),
        "reason_": ("incomplete_start", "incomplete_end", "unmeasurable", "small_excursion", "rmse"),
        "angle_method_": ("grood_suntay", "thesis_zyx"),
    }.items():
        used |= {prefix + v for v in values}
    # phase names come from the session's task (reports.labels.code_label("data.phase", ...))
    used |= {f"data.phase.{p.name}" for task in TASKS.values() for p in task.phases}
    assert len(used) > 60
    missing = sorted(k for k in used if not i18n.has(k))
    assert not missing


def test_decimal_comma_for_spanish_and_portuguese():
    assert fmt_number(66.6784, 1, "es") == "66,7"
    assert fmt_number(66.6784, 1, "pt") == "66,7"
    assert fmt_number(66.6784, 1, "en") == "66.7"
    assert fmt_number(0.44206, 2, "es") == "0,44"
    assert fmt_number(-0.346, 1, "pt") == "-0,3"
    assert fmt_number(45.0, 0, "es") == "45"
    assert fmt_number(12, 1, "en") == "12.0"


def test_no_negative_zero_and_missing_values():
    assert fmt_number(-0.04, 1, "en") == "0.0"
    assert fmt_number(-0.0, 2, "es") == "0,00"
    for missing in (None, math.nan, math.inf, "abc"):
        assert fmt_number(missing, 1, "es") == MISSING


def test_mean_sd():
    assert fmt_mean_sd(66.678, 2.373, 1, "es") == "66,7 ± 2,4"
    assert fmt_mean_sd(66.678, 2.373, 1, "en") == "66.7 ± 2.4"
    assert fmt_mean_sd(66.678, None, 1, "pt") == "66,7"  # one cycle: no SD
    assert fmt_mean_sd(None, 2.0, 1, "en") == MISSING


def test_t_fills_fields_and_never_reinterprets_user_values():
    assert t("stats_note", "en", n=10) == "Mean ± SD; accepted cycles: 10."
    assert t("cycles_summary", "es", detected=4, accepted=3, rejected=1) == "4 detectados, 3 aceptados, 1 rechazados."
    # a value with braces or markup is inserted as it is
    assert t("footer_patient", "es", patient="{nb} <b>x</b> {0}") == "Paciente: {nb} <b>x</b> {0}"


def test_t_errors_name_the_problem():
    with pytest.raises(TranslationError, match="no_such_key"):
        t("no_such_key", "es")
    with pytest.raises(TranslationError, match="n"):
        t("stats_note", "es")  # the field {n} is missing
    with pytest.raises(ValueError, match="language"):
        t("product", "fr")
    with pytest.raises(ValueError, match="language"):
        fmt_number(1.0, 1, "de")


def _write(tmp_path: Path, name: str, data) -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(data, ensure_ascii=False), encoding="utf-8")
    return p


def test_loader_merges_files_and_rejects_conflicts(tmp_path):
    a = _write(tmp_path, "translations.json", {"_comment": "doc", "x": {"es": "x", "en": "x", "pt": "x"}})
    b = _write(tmp_path, "translations_data.json", {"y": {"es": "ñ", "en": "n", "pt": "ç"}})
    assert load_tables([a, b]) == {"x": {"es": "x", "en": "x", "pt": "x"}, "y": {"es": "ñ", "en": "n", "pt": "ç"}}
    c = _write(tmp_path, "translations_c.json", {"x": {"es": "1", "en": "1", "pt": "1"}})
    with pytest.raises(TranslationError, match="'x' is defined in both"):
        load_tables([a, c])
    d = _write(tmp_path, "translations_d.json", {"z": {"es": "1", "en": "1"}})
    with pytest.raises(TranslationError, match="exactly the languages"):
        load_tables([d])
    e = tmp_path / "translations_e.json"
    e.write_text("{not json", encoding="utf-8")
    with pytest.raises(TranslationError, match="not valid JSON"):
        load_tables([e])
