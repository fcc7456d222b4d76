"""Quality warnings in the report's language, translated by their ``code``.

The estimators and the pipeline write each warning as ``{"code": ..., "message": ...}`` with an English
message (``results.json`` ``quality.warnings``).  Reports print them in Spanish, English or Portuguese
from ``reports/translations_warnings.json``:

* ``warning.<code>`` (or ``warning.<code>.<variant>``) holds one text per language.  Its ``en`` text is the
  estimators' exact wording with ``{name:spec}`` fields for the numbers (``{seconds:.2f}``) and ``{name}``
  fields for words (``{posture}``); ``warning.term.<word>`` translates such words (``standing``,
  ``thigh``, ``gyr``).  Numbers are printed with the field's format and the language's decimal mark.
* The numbers come from the warning's ``params`` mapping when it has one.  Warnings without ``params``
  (the estimators do not emit them yet) are read back from the English message with the ``en`` text as the
  pattern: a message that matches gives the same numbers, printed with the same decimals; one that does
  not (wording changed, an unknown code) is printed in English as it was written — never half-translated.
* Messages the pipeline prefixed with the segment (``"Thigh sensor: "``, ``"thigh: "``) or with the
  segment and recording (``"thigh task: "``, ingestion notes) keep that prefix, translated.
* ``cycles_rejected`` lists the rejected cycles with their translated reasons from
  ``results["cycles"]["rejected"]`` (the reason codes), not the estimators' English sentences.

English reports print every message verbatim (the ``en`` texts are the same words).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from functools import lru_cache
from typing import Any

from reports import i18n

__all__ = ["warning_text"]

_FIELD = re.compile(r"\{(\w+)(?::([^}]*))?\}")
_NUMBER = r"[-+]?\d+(?:\.\d+)?"
#: prefixes the pipeline puts before an estimator's message, most specific first
_PREFIXES = (
    ("sensor", re.compile(r"(?P<segment>Thigh|Shank) sensor: ")),
    ("recording", re.compile(r"(?P<segment>thigh|shank) (?P<role>[a-z_]+): ")),
    ("segment", re.compile(r"(?P<segment>thigh|shank|sensor): ")),
)
_PREFIX_KEY = {"sensor": "warning.prefix", "segment": "warning.prefix", "recording": "warning.ingestion_prefix"}


def _text(key: str, lang: str) -> str | None:
    entry = i18n.table().get(key)
    return None if entry is None else entry[lang]


@lru_cache(maxsize=None)
def _pattern(template: str) -> re.Pattern[str]:
    """A regex that matches what ``template`` formats to: numeric fields as numbers, word fields as the
    shortest run without ``:``/``;`` (``details``: anything)."""
    parts, pos = [], 0
    for m in _FIELD.finditer(template):
        parts.append(re.escape(template[pos:m.start()]))
        name, spec = m.group(1), m.group(2)
        word = ".+" if name == "details" else r"[^:;]+?"  # a word field never spans a prefix's colon
        parts.append(f"(?P<{name}>{_NUMBER})" if spec else f"(?P<{name}>{word})")
        pos = m.end()
    parts.append(re.escape(template[pos:]))
    return re.compile("".join(parts) + r"\Z", re.S)


def _variants(code: str) -> list[str]:
    """Translation keys of ``code``: ``warning.<code>`` and every ``warning.<code>.<variant>``."""
    base = f"warning.{code}"
    return [k for k in i18n.table() if k == base or k.startswith(base + ".")]


def _format(template: str, params: Mapping[str, Any], lang: str) -> str:
    """``template`` filled from ``params``: numbers with the field's spec and decimal mark, words via
    ``warning.term.*``.  Raises KeyError/ValueError/TypeError when a field is missing or not a number."""
    mark = "." if lang == "en" else ","

    def fill(m: re.Match[str]) -> str:
        name, spec = m.group(1), m.group(2)
        value = params[name]
        if spec:
            x = float(value)
            s = format(int(round(x)), spec) if spec.endswith("d") else format(x, spec)
            return s.replace(".", mark)
        word = str(value)
        term = _text(f"warning.term.{word.lower()}", lang)
        return word if term is None else term

    return _FIELD.sub(fill, template)


def _cycle_details(results: Mapping[str, Any] | None, lang: str) -> str | None:
    """``cycle 3: <reason>; cycle 7: <reason>`` from ``results["cycles"]["rejected"]``, translated."""
    rejected = ((results or {}).get("cycles") or {}).get("rejected")
    if not rejected:
        return None
    items = []
    for r in rejected:
        code, idx = str(r.get("reason") or ""), r.get("index")
        reason = i18n.t(f"reason_{code}", lang) if code and i18n.has(f"reason_{code}") else (
            code or i18n.t("reason_unknown", lang))
        items.append(_format(_text("warning.cycle_item", lang) or "{n}: {reason}",
                             {"n": "?" if idx is None else int(idx) + 1, "reason": reason}, lang))
    return "; ".join(items)


def _parse(code: str, message: str) -> tuple[str, str | None, dict[str, str]] | None:
    """``(translation key, prefix kind, params)`` read from an English ``message``; None if it matches no
    ``en`` text of ``code``."""
    keys = _variants(code)
    candidates = []
    for kind, rx in _PREFIXES:
        m = rx.match(message)
        if m:
            candidates.append((kind, message[m.end():], m.groupdict()))
    candidates.append((None, message, {}))
    for key in keys:
        pattern = _pattern(i18n.table()[key]["en"])
        for kind, rest, prefix_params in candidates:
            m = pattern.match(rest)
            if m:
                return key, kind, {**prefix_params, **m.groupdict()}
    return None


def warning_text(warning: Mapping[str, Any] | str, lang: str, results: Mapping[str, Any] | None = None
                 ) -> tuple[str, bool]:
    """The warning as printed in ``lang``, and whether it is in that language (False: English fallback).

    warning : ``{"code", "message"[, "params"]}`` from ``results["quality"]["warnings"]`` (a bare string is
        printed as it is).  ``params`` (optional): the numbers and words of the message by field name;
        ``"variant"`` picks ``warning.<code>.<variant>``; ``"segment"`` (and ``"role"``) add the prefix.
    results : the ``results.json`` dictionary, for ``cycles_rejected``'s per-cycle reasons.
    English, and anything that cannot be translated completely, returns the message as written.
    """
    if not isinstance(warning, Mapping):
        return str(warning), lang == "en"
    code = str(warning.get("code") or "")
    message = str(warning.get("message") or code)
    if lang == "en" or not code:
        return message, lang == "en"
    params = warning.get("params")
    try:
        if isinstance(params, Mapping) and params:
            variant = params.get("variant")
            key = f"warning.{code}" + (f".{variant}" if variant else "")
            if key not in i18n.table():
                return message, False
            kind = None
            if "segment" in params and "{segment" not in i18n.table()[key]["en"]:
                kind = "recording" if "role" in params else "segment"
            values: dict[str, Any] = dict(params)
        else:
            parsed = _parse(code, message)
            if parsed is None:
                return message, False
            key, kind, values = parsed
        if code == "cycles_rejected":
            details = _cycle_details(results, lang)
            if details is None or int(float(values["rejected"])) != len((results or {})["cycles"]["rejected"]):
                return message, False
            values["details"] = details
        text = _format(i18n.table()[key][lang], values, lang)
        if kind is not None:
            text = _format(i18n.table()[_PREFIX_KEY[kind]][lang], values, lang) + text
    except (KeyError, ValueError, TypeError):
        return message, False
    return text[:1].upper() + text[1:], True
