"""Translations and number formatting for every report (PDF, Excel, HTML, 3D scene).

All user-visible texts live in translation tables shipped beside this module as package data:
``reports/translations.json`` (PDF and shared texts) and any other ``reports/translations*.json``
(e.g. ``translations_data.json`` for the Excel/HTML sheet and column names).  Each file maps a key to
``{"es": ..., "en": ..., "pt": ...}``; a key may appear in only one file.  Code never holds the texts,
only keys.

Texts may contain ``str.format`` fields (``"{n} ciclos"``); :func:`t` fills them with the keyword
arguments.  Values typed by people are passed *as arguments*, never as the template, so braces or
markup in them print literally.

Numbers: :func:`fmt_number` uses a decimal point for ``en`` and a decimal comma for ``es`` and ``pt``
(no thousands separator: clinical values are small and a separator would be confused with the
decimal mark).  Missing values (None, NaN, inf) print as an em dash.

Dates: :func:`fmt_date` prints every date of a report in the one format of its language (``date_format``:
31/12/2026 in es and pt, 2026-12-31 in en), so a page never mixes two formats.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from functools import lru_cache
from importlib import resources
from collections.abc import Iterable
from typing import Any

LANGUAGES: tuple[str, ...] = ("es", "en", "pt")
DEFAULT_LANGUAGE = "es"
#: what a missing number prints as (the same in every language)
MISSING = "—"

_DECIMAL_MARK = {"es": ",", "en": ".", "pt": ","}


class TranslationError(ValueError):
    """A translation table is malformed, or a key is unknown."""


def _check_language(lang: str) -> None:
    if lang not in LANGUAGES:
        raise ValueError(f"language must be one of {', '.join(LANGUAGES)}, got {lang!r}")


@lru_cache(maxsize=1)
def table() -> dict[str, dict[str, str]]:
    """Every ``reports/translations*.json`` merged into one ``{key: {lang: text}}`` (loaded once)."""
    files = sorted((f for f in resources.files("reports").iterdir()
                    if f.name.startswith("translations") and f.name.endswith(".json")), key=lambda f: f.name)
    return load_tables(files)


def load_tables(files: Iterable[Any]) -> dict[str, dict[str, str]]:
    """Merge translation files (paths or ``importlib.resources`` traversables) into ``{key: {lang: text}}``.

    Keys starting with ``_`` document a file and are skipped.  Raises :class:`TranslationError` if a file
    is not a JSON object of keys to exactly the three languages, a text is not a string, or a key is
    defined in two files.
    """
    merged: dict[str, dict[str, str]] = {}
    origin: dict[str, str] = {}
    for f in files:
        try:
            data = json.loads(f.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise TranslationError(f"{f.name} is not valid JSON: {exc}") from exc
        if not isinstance(data, dict):
            raise TranslationError(f"{f.name} must be a JSON object of key -> {{es, en, pt}}")
        for key, texts in data.items():
            if key.startswith("_"):
                continue
            if key in merged:
                raise TranslationError(f"translation key {key!r} is defined in both {origin[key]} and {f.name}")
            if not isinstance(texts, dict) or set(texts) != set(LANGUAGES):
                raise TranslationError(f"{f.name}: key {key!r} must have exactly the languages "
                                       f"{', '.join(LANGUAGES)}, got {texts!r}")
            if not all(isinstance(v, str) for v in texts.values()):
                raise TranslationError(f"{f.name}: key {key!r} has a text that is not a string")
            merged[key] = dict(texts)
            origin[key] = f.name
    return merged


def has(key: str) -> bool:
    """Whether ``key`` is in the tables (for optional texts chosen from data, e.g. reason codes)."""
    return key in table()


def t(key: str, lang: str, /, **fields: Any) -> str:
    """The text of ``key`` in ``lang``, with ``{fields}`` filled from the keyword arguments.

    Raises :class:`TranslationError` for an unknown key or a field the text needs and was not given.
    """
    _check_language(lang)
    try:
        text = table()[key][lang]
    except KeyError:
        raise TranslationError(f"no translation for key {key!r}; add it to reports/translations*.json") from None
    try:
        return text.format(**fields)
    except (KeyError, IndexError) as exc:
        raise TranslationError(f"translation {key!r} ({lang}) needs the field {exc}") from None


def _finite(x: Any) -> float | None:
    if x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def fmt_number(x: Any, decimals: int, lang: str) -> str:
    """``x`` rounded to ``decimals`` places with the language's decimal mark; :data:`MISSING` if absent.

    ``fmt_number(66.678, 1, "es") == "66,7"``; ``fmt_number(-0.04, 1, "en") == "0.0"`` (no negative zero).
    """
    _check_language(lang)
    v = _finite(x)
    if v is None:
        return MISSING
    s = f"{v:.{decimals}f}"
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s.replace(".", _DECIMAL_MARK[lang])


def fmt_mean_sd(mean: Any, sd: Any, decimals: int, lang: str) -> str:
    """``"mean ± sd"`` (``"66,7 ± 2,4"``); only the mean when the SD is missing (a single cycle)."""
    m = fmt_number(mean, decimals, lang)
    if m == MISSING:
        return MISSING
    s = fmt_number(sd, decimals, lang)
    return m if s == MISSING else f"{m} ± {s}"


def fmt_date(value: Any, lang: str) -> str:
    """A date (``datetime.date``/``datetime`` or an ISO ``YYYY-MM-DD...`` text) in the language's ``date_format``;
    "" when absent; a text that is not an ISO date is returned as typed (never guessed at)."""
    _check_language(lang)
    if value is None or value == "":
        return ""
    if isinstance(value, _dt.datetime):
        value = value.date()
    if not isinstance(value, _dt.date):
        try:
            value = _dt.date.fromisoformat(str(value).strip()[:10])
        except ValueError:
            return str(value)
    return value.strftime(t("date_format", lang))
