"""Quality warnings in the report's language, translated by their ``code`` from their ``params``.

The estimators and the pipeline write each warning as ``{"code", "message", "params"}``
(``results.json`` ``quality.warnings``, :class:`estimators.quality.QualityWarning`): an English message and
the values it states, by name and unrounded.  Reports print them in Spanish, English or Portuguese from
``reports/translations_warnings.json``:

* ``warning.<code>`` (or ``warning.<code>.<variant>``, picked by ``params["variant"]``) holds one text per
  language with ``{name:spec}`` fields for numbers (``{seconds:.2f}``) and ``{name}`` fields for words
  (``{posture}``); ``warning.term.<word>`` translates such words (``standing``, ``thigh``, ``gyr``).  Numbers
  are printed with the field's format and the language's decimal mark.  The ``en`` text is the estimators'
  wording, kept so a test can check that the params say what the message says.
* ``params["segment"]`` that the text does not use becomes a translated prefix (``"Muslo: "``), with
  ``params["role"]`` the ingestion notes' ``"Muslo, tarea: "``.
* ``cycles_rejected`` lists the rejected cycles with their translated reasons from
  ``results["cycles"]["rejected"]`` (the reason codes), not the estimators' English sentences.
* ``params["knee"]`` (``left``/``right``: a session of both knees, :func:`app.pipeline.results.knees_warnings`)
  puts the knee first, ``warning.knee.<side>`` (``"Rodilla izquierda: "``), in every language, English and the
  English fallback included; its rejected cycles are then that knee's (``results["knees"][side]``).

Clinical warnings and technical notes (:func:`is_technical`, the one classification every layer uses): a note on
how the files were read — a stream's tail cut to the common span, clock drift, a CSV dialect, a file ignored, one
recording split into the protocol's parts (:data:`TECHNICAL_VARIANTS`, listed one by one) — describes the
recording's handling, not the patient, so
``results.json`` keeps it in ``quality.technical_notes`` apart from ``quality.warnings``; the UI shows it folded
away, the PDF and HTML in a small section of their own, and FHIR's ``conclusion`` never.  The ingestion notes
that change how the knee was measured (no figure-eight, no supine or no standing recording: another calibration),
file names that disagree, rows missing and streams without epoch time stamps stay clinical warnings
(:data:`CLINICAL_VARIANTS`), and so does any variant not listed.

Anything that cannot be translated completely — a code (or variant) without an entry, params missing a
field or holding ``null`` where a number belongs (``results.json`` has no infinity) — is printed in English
as it was written, never half-translated; the reports then add their "some warnings are in English" note.
English reports print every message verbatim.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from reports import i18n

__all__ = ["CLINICAL_VARIANTS", "TECHNICAL_CODES", "TECHNICAL_VARIANTS", "is_technical", "warning_text"]

#: warning codes whose variants may be technical notes (module docstring)
TECHNICAL_CODES = frozenset({"ingestion_note"})
#: the ingestion notes on how the files were read (``params["variant"]`` of an ``ingestion_note``): listed one by
#: one, so that a note nobody classified stays a clinical warning, shown to the clinician (tests/reports check
#: that every variant the ingestion can write is in exactly one of the two sets)
TECHNICAL_VARIANTS = frozenset({
    "stream_cut_after", "stream_cut_before", "clock_drift",  # align: streams cut to their common span, drift
    "csv_decimal_comma", "csv_semicolon", "csv_ignored",  # a CSV dialect, a file left out
    "sheet_chosen", "sheet_chosen_of", "file_sheet_chosen", "file_sheet_chosen_of",  # which sheet was read
    "excel_epoch_local", "excel_epoch_offset", "excel_epoch_rebuilt",  # spreadsheet time stamps
    "duplicate_rows", "truncated_last_row", "file_unrecognised",  # rows and files repaired or ignored
    "mag_normalised", "phone_ios_frames",  # units and frames of a phone's or a sensor's export
    "recording_split",  # one continuous recording split into the protocol's parts
})
#: the ingestion notes that are clinical warnings: the knee was measured otherwise (another calibration), the files
#: disagree about whom or what they record, or the streams' timing is uncertain (rows missing, no epoch)
CLINICAL_VARIANTS = frozenset({"no_mag_calibration", "no_lying", "no_standing", "recording_split_no_fig8",
                               "names_disagree", "rows_missing", "no_epoch", None})


def is_technical(warning: Mapping[str, Any] | Any) -> bool:
    """Whether ``warning`` (a results.json ``{"code", "params"}`` or a ``QualityWarning``) is a technical note."""
    code = warning.get("code") if isinstance(warning, Mapping) else getattr(warning, "code", None)
    params = warning.get("params") if isinstance(warning, Mapping) else getattr(warning, "params", None)
    variant = params.get("variant") if isinstance(params, Mapping) else None
    return code in TECHNICAL_CODES and variant in TECHNICAL_VARIANTS

_FIELD = re.compile(r"\{(\w+)(?::([^}]*))?\}")


_ISO_DAY = re.compile(r"\d{4}-\d{2}-\d{2}")


def _text(key: str, lang: str) -> str | None:
    entry = i18n.table().get(key)
    return None if entry is None else entry[lang]


def _format(template: str, params: Mapping[str, Any], lang: str) -> str:
    """``template`` filled from ``params``: numbers with the field's spec and decimal mark, words via
    ``warning.term.*``.  Raises KeyError/ValueError/TypeError when a field is missing or not a number."""
    mark = "." if lang == "en" else ","

    def fill(m: re.Match[str]) -> str:
        name, spec = m.group(1), m.group(2)
        value = params[name]
        if spec:
            if isinstance(value, (bool, str)) or value is None:
                raise TypeError(f"field {name!r} needs a number, got {value!r}")
            x = float(value)
            s = format(int(round(x)), spec) if spec.endswith("d") else format(x, spec)
            return s.replace(".", mark)
        word = str(value)
        if _ISO_DAY.fullmatch(word) and (name == "date" or name.endswith("_date")):
            return i18n.fmt_date(word, lang)  # one date format per language on a page (issue 17 §3)
        term = _text(f"warning.term.{word.lower()}", lang)
        return word if term is None else term

    return _FIELD.sub(fill, template)


def _cycle_details(results: Mapping[str, Any] | None, lang: str) -> tuple[str, int] | None:
    """``cycle 3: <reason>; cycle 7: <reason>`` from ``results["cycles"]["rejected"]``, translated, and how many
    (the pipeline's rejections only)."""
    rejected = [r for r in ((results or {}).get("cycles") or {}).get("rejected") or ()
                if r.get("reason") != "excluded_by_clinician"]  # the clinician's are no warning (cycles.excluded)
    if not rejected:
        return None
    items = []
    for r in rejected:
        code, idx = str(r.get("reason") or ""), r.get("index")
        reason = i18n.t(f"reason_{code}", lang) if code and i18n.has(f"reason_{code}") else (
            code or i18n.t("reason_unknown", lang))
        items.append(_format(_text("warning.cycle_item", lang) or "{n}: {reason}",
                             {"n": "?" if idx is None else int(idx) + 1, "reason": reason}, lang))
    return "; ".join(items), len(items)


def warning_text(warning: Mapping[str, Any] | str, lang: str, results: Mapping[str, Any] | None = None
                 ) -> tuple[str, bool]:
    """The warning as printed in ``lang``, and whether it is in that language (False: English fallback).

    warning : ``{"code", "message", "params"}`` from ``results["quality"]["warnings"]`` (a bare string is
        printed as it is).  ``params``: the values of the message by field name; ``"variant"`` picks
        ``warning.<code>.<variant>``; ``"segment"`` (and ``"role"``) add the prefix when the text does not
        name the segment.  A warning without ``params`` is translated only if its text has no fields.
    results : the ``results.json`` dictionary, for ``cycles_rejected``'s per-cycle reasons.
    English, and anything that cannot be translated completely, returns the message as written.
    """
    if not isinstance(warning, Mapping):
        return str(warning), lang == "en"
    params = warning.get("params")
    knee = params.get("knee") if isinstance(params, Mapping) else None
    entry = i18n.table().get(f"warning.knee.{knee}")
    if entry is None:
        return _warning_text(warning, lang, results)
    text, translated = _warning_text(warning, lang, ((results or {}).get("knees") or {}).get(knee, results))
    return entry[lang if translated else "en"] + text, translated


def _warning_text(warning: Mapping[str, Any], lang: str, results: Mapping[str, Any] | None) -> tuple[str, bool]:
    """:func:`warning_text` but the knee's prefix."""
    code = str(warning.get("code") or "")
    message = str(warning.get("message") or code)
    if lang == "en" or not code:
        return message, lang == "en"
    params = warning.get("params")
    if params is None:
        params = {}
    if not isinstance(params, Mapping):
        return message, False
    variant = params.get("variant")
    key = f"warning.{code}" + (f".{variant}" if variant else "")
    template = _text(key, lang)
    if template is None:
        return message, False
    values: dict[str, Any] = dict(params)
    prefix = None
    if "segment" in params and "{segment" not in template:
        prefix = "warning.ingestion_prefix" if "role" in params else "warning.prefix"
    try:
        if code == "cycles_rejected":
            details = _cycle_details(results, lang)
            if details is None or int(values["rejected"]) != details[1]:
                return message, False
            values["details"] = details[0]
        text = _format(template, values, lang)
        if prefix is not None:
            text = _format(i18n.table()[prefix][lang], values, lang) + text
    except (KeyError, ValueError, TypeError):
        return message, False
    return text[:1].upper() + text[1:], True
