"""Excel workbooks of one knee session: ``angles.xlsx`` and ``quaternions.xlsx``.

Reports present; they compute nothing clinical.  Every number comes from :class:`~reports.model.ReportInput`
(``results.json`` plus the task's series); which cycle and phase each sample falls in comes from
:mod:`reports.labels` (shared with the HTML and PDF reports).

``angles.xlsx`` sheets: angles over time (time s, flexion, adduction, internal rotation in degrees, cycle
1-based — empty outside a cycle —, phase); per cycle (accepted / rejected and why, start/end s, ROM
max/min/range per angle, phase durations s and %, from ``results["cycles"]["per_cycle"]``); normalised
curves (0..100 % of the cycle, mean and SD per angle); patient and session.
``quaternions.xlsx`` sheets: sensor orientations ``q_earth_sensor`` of thigh and shank, segment
orientations ``q_earth_segment`` of femur and tibia (w, x, y, z) with time, and the sensor-to-segment
calibrations.

Safety: every text cell is written as a string cell (never a formula), characters XML cannot carry are
dropped, and a text that a spreadsheet could take for a formula (starting with ``=``, ``+``, ``-``, ``@``,
tab or a line end — OWASP "CSV injection") also gets Excel's *quote prefix* style, so that editing the
cell in Excel keeps it text.  The stored text is the exact literal the user typed (line ends as LF: XML
readers turn a stored CR into LF anyway).

Reproducible: the same input gives byte-identical files (a retried processing job stores the same
artefacts): the zip entries carry a fixed time stamp and the document's created/modified properties are the
fixed :data:`DOC_TIME`, never the wall clock.

Speed: openpyxl writes ~6 µs per cell (no lxml), ~0.8 s for 5000 rows × 4 sheets.  So openpyxl writes the
workbook (styles, headers, small sheets, all user text); the long numeric tables are then generated as
SpreadsheetML rows directly and spliced into their (header-only) sheets.  Floats are written with
``repr`` (shortest round-trip form): reading back gives the same float64 values; NaN/inf cells are empty.
"""

from __future__ import annotations

import io
import itertools
import math
import os
import re
import zipfile
from pathlib import Path
from typing import Any, Sequence
from xml.sax.saxutils import escape as _xml_escape

import numpy as np
from openpyxl import Workbook
from openpyxl.cell import WriteOnlyCell
from openpyxl.styles import Font
from openpyxl.utils import get_column_letter

from reports import knees
from reports.labels import (EXCLUDED, all_excluded_lines, code_label, cycle_and_phase_per_sample, excluded_lines, get_path, identity_line,
                            phase_names,
                            session_rows, tr)
from reports.model import ANGLES, ReportInput

__all__ = ["write_angles_xlsx", "write_quaternions_xlsx", "neutralise_text"]

#: first characters that make a spreadsheet read a text as a formula (OWASP CSV injection; CR is stored as LF)
FORMULA_TRIGGERS = ("=", "+", "-", "@", "\t", "\r", "\n")
_ILLEGAL_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")
_BOLD = Font(bold=True)
#: the zip entries' time stamp (the zip format's epoch) and the workbook's created/modified properties
ZIP_TIME = (1980, 1, 1, 0, 0, 0)
DOC_TIME = "1980-01-01T00:00:00Z"
_CORE_TIMES = re.compile(r"(<dcterms:(created|modified)[^>]*>)[^<]*(</dcterms:\2>)")


# ---------------------------------------------------------------------------------------------- texts
def neutralise_text(value: Any) -> str:
    """The text as it will be stored: ``str(value)`` without the control characters XML cannot hold.

    Line ends become ``\n`` (XML parsers, Excel's included, turn a stored CR into LF anyway, so this
    makes the stored text what every reader sees).  The text is not altered otherwise; formula-looking
    texts are made harmless by the cell type and the quote-prefix style (see :func:`_text_cell`), so what
    the user typed reads back unchanged.
    """
    text = "" if value is None else str(value)
    return _ILLEGAL_XML.sub("", text.replace("\r\n", "\n").replace("\r", "\n"))


def _text_cell(ws: Any, value: Any, *, bold: bool = False) -> WriteOnlyCell:
    """A string cell that no spreadsheet evaluates, whatever the text starts with."""
    text = neutralise_text(value)
    cell = WriteOnlyCell(ws, value=text)
    cell.data_type = "s"                       # openpyxl would make "=..." a formula
    if text.startswith(FORMULA_TRIGGERS):
        cell.quotePrefix = True                # Excel keeps it text even when the cell is edited
    if bold:
        cell.font = _BOLD
    return cell


def _cell(ws: Any, value: Any) -> Any:
    """Numbers stay numbers (NaN/inf → empty), booleans and None as they are, everything else is text."""
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(float(value)) else None
    return _text_cell(ws, value)


def _append(ws: Any, values: Sequence[Any]) -> None:
    ws.append([_cell(ws, v) for v in values])


def _header(ws: Any, titles: Sequence[str], widths: Sequence[float] | None = None) -> None:
    for j, w in enumerate(widths or [max(10.0, 1.1 * len(t) + 2) for t in titles]):
        ws.column_dimensions[get_column_letter(j + 1)].width = w
    ws.freeze_panes = "A2"
    ws.append([_text_cell(ws, t, bold=True) for t in titles])


def _sheet_title(text: str) -> str:
    """Excel sheet names: ≤ 31 characters, none of ``[]:*?/\\``."""
    return re.sub(r"[\[\]:*?/\\]", " ", text)[:31] or "Sheet"


# ------------------------------------------------------------------------------- fast numeric tables
class _Bulk:
    """Columns to splice into a header-only sheet: ``("num", float array)``, ``("int", ints/None)``,
    ``("str", texts)``; all of length n, written from spreadsheet row 2."""

    def __init__(self, columns: Sequence[tuple[str, Any]]):
        self.columns = columns

    def rows_xml(self, first_row: int = 2) -> str:
        """The SpreadsheetML ``<row>`` elements of the columns, from spreadsheet row ``first_row``.

        A column of finite numbers is formatted by one ``%``-operation over the whole table (``%r`` is the
        float's shortest round-trip ``repr``, looped in C); other columns are cell strings made per value
        (empty where a number is NaN/inf or a value is missing).  ~3× quicker than a Python-level loop per
        cell, same text."""
        if not self.columns:
            return ""
        n = len(self.columns[0][1])
        rows = range(first_row, first_row + n)
        template = ['<row r="%d">']
        per_column: list[list[Any]] = []  # per column: the values for its placeholders, per row
        for j, (kind, values) in enumerate(self.columns):
            col = get_column_letter(j + 1)
            if kind == "num":
                arr = np.asarray(values, dtype=np.float64)
                vals = arr.tolist()
                if np.isfinite(arr).all():
                    template.append(f'<c r="{col}%d"><v>%r</v></c>')
                    per_column.append([rows, vals])
                    continue
                cells = [f'<c r="{col}{r}"><v>{v!r}</v></c>' if math.isfinite(v) else ""
                         for r, v in zip(rows, vals)]
            elif kind == "int":
                cells = [f'<c r="{col}{r}"><v>{int(v)}</v></c>' if v is not None else ""
                         for r, v in zip(rows, values)]
            else:  # str: our own labels, escaped anyway
                esc = {v: _xml_escape(neutralise_text(v)) for v in set(values) if v}
                cells = [f'<c r="{col}{r}" t="inlineStr"><is><t>{esc[v]}</t></is></c>' if v else ""
                         for r, v in zip(rows, values)]
            template.append("%s")
            per_column.append([cells])
        template.append("</row>")
        streams = [rows] + [stream for column in per_column for stream in column]
        args = tuple(itertools.chain.from_iterable(zip(*streams)))
        return ("".join(template) * n) % args


def _header_text(text: str) -> str:
    """A text for an Excel page header or footer: ``&`` doubled (a single one starts a code: ``&P`` the page),
    control characters removed, within Excel's 255 characters a section: cut (with "…") before the doubling, so a
    cut never leaves a lone ``&`` (which would swallow the "…" as a code)."""
    text = neutralise_text(text).replace("\n", " ")
    if len(text.replace("&", "&&")) > 250:
        while len(text.replace("&", "&&")) > 249:
            text = text[:-1]
        text += "…"
    return text.replace("&", "&&")


def _stamp_identity(wb: Workbook, ri: ReportInput) -> None:
    """Every sheet's printed pages carry the patient's identity (issue 17 §3): the header
    :func:`reports.labels.identity_line` (name or ID, record number with its system, birth date and age, sex,
    clinic, the recordings' date), the footer "page n of N" (Excel's ``&P``/``&N``)."""
    identity = _header_text(identity_line(ri.patient, ri.language))
    for ws in wb.worksheets:
        if identity:
            ws.oddHeader.left.text = identity
            ws.oddHeader.left.size = 8
        ws.oddFooter.right.text = tr("page_number", ri.language, page="&P", pages="&N")
        ws.oddFooter.right.size = 8


def _save(wb: Workbook, bulk: dict[int, _Bulk], path: str | os.PathLike) -> None:
    """Save ``wb``, splicing the numeric rows of ``bulk`` ({sheet number (1-based): rows}) into their sheets."""
    buf = io.BytesIO()
    wb.save(buf)
    buf.seek(0)
    out = Path(path)
    tmp = out.with_name(f".{out.name}.tmp")
    try:
        with zipfile.ZipFile(buf) as src, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as dst:
            for info in src.infolist():
                data = src.read(info.filename)
                m = re.fullmatch(r"xl/worksheets/sheet(\d+)\.xml", info.filename)
                if m and int(m.group(1)) in bulk:
                    xml = data.decode("utf-8")
                    if xml.count("<row ") != 1:   # header only, else the sheet numbering assumption broke
                        raise RuntimeError(f"{info.filename}: expected a header-only sheet to fill")
                    k = xml.rindex("</sheetData>")
                    data = (xml[:k] + bulk[int(m.group(1))].rows_xml() + xml[k:]).encode("utf-8")
                elif info.filename == "docProps/core.xml":
                    data = _CORE_TIMES.sub(lambda t: t.group(1) + DOC_TIME + t.group(3), data.decode("utf-8")).encode()
                dst.writestr(zipfile.ZipInfo(info.filename, date_time=ZIP_TIME), data,
                             compress_type=zipfile.ZIP_DEFLATED, compresslevel=1)
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()


# ------------------------------------------------------------------------------------------ angles.xlsx
def _angle_titles(lang: str) -> list[str]:
    return [f"{tr('data.angle.' + a, lang)} (°)" for a in ANGLES]


def _angles_sheet(wb: Workbook, ri: ReportInput, lang: str) -> _Bulk:
    ws = wb.create_sheet(_sheet_title(tr("data.sheet.angles", lang)))
    _header(ws, [tr("data.col.time_s", lang), *_angle_titles(lang), tr("data.col.cycle", lang),
                 tr("data.col.phase", lang)], [11, 22, 22, 26, 8, 14])
    cycle, phase = cycle_and_phase_per_sample(ri)
    labels = {p: code_label("data.phase", p, lang) for p in set(phase) if p}
    a = np.asarray(ri.angles_deg, dtype=np.float64)
    return _Bulk([("num", ri.t_s), ("num", a[:, 0]), ("num", a[:, 1]), ("num", a[:, 2]),
                  ("int", cycle), ("str", [labels.get(p, "") for p in phase])])


def _cycles_sheet(wb: Workbook, ri: ReportInput, lang: str) -> None:
    ws = wb.create_sheet(_sheet_title(tr("data.sheet.cycles", lang)))
    names = phase_names(ri.results)
    stats = ("max", "min", "range")
    titles = [tr("data.col.cycle", lang), tr("data.col.status", lang), tr("data.col.reason", lang),
              tr("data.col.start_s", lang), tr("data.col.end_s", lang)]
    titles += [f"{tr('data.angle.' + a, lang)} {tr('data.stat.' + s, lang)} (°)" for a in ANGLES for s in stats]
    titles += [f"{code_label('data.phase', p, lang)} ({u})" for p in names for u in ("s", "%")]
    titles.append(tr("data.col.message", lang))
    _header(ws, titles, [8, 12, 24, 10, 10] + [14] * (len(titles) - 6) + [50])
    cycles = ri.results.get("cycles", {})
    per_cycle = cycles.get("per_cycle")
    if not per_cycle:
        _append(ws, ["", tr("data.not_available", lang)])
        return
    messages = {r.get("index"): r.get("message", "") for r in cycles.get("rejected", []) if isinstance(r, dict)}
    # the clinician's exclusions: their own words, who and when (cycles.excluded, numbered from 1)
    messages |= {e["cycle"] - 1: line for e, line in zip(cycles.get("excluded") or [], excluded_lines(cycles, lang))}
    for c in per_cycle:
        reason = c.get("reason")
        status = "data.status.accepted" if c.get("accepted") else "data.status.rejected"
        row = [int(c["index"]) + 1 if c.get("index") is not None else None,
               tr("data.status.excluded" if reason == EXCLUDED else status, lang),
               code_label("data.reason", reason, lang) if reason else "",
               c.get("start_s"), c.get("end_s")]
        row += [get_path(c, "rom_deg", a, s) for a in ANGLES for s in stats]
        row += [get_path(c, "phases", p, u) for p in names for u in ("s", "pct")]
        row.append(messages.get(c.get("index"), "") or "")
        _append(ws, row)


def _curves_sheet(wb: Workbook, ri: ReportInput, lang: str) -> None:
    ws = wb.create_sheet(_sheet_title(tr("data.sheet.curves", lang)))
    mean, sd = tr("data.stat.mean", lang), tr("data.stat.sd", lang)
    titles = [tr("data.col.cycle_pct", lang)]
    titles += [f"{tr('data.angle.' + a, lang)} {s} (°)" for a in ANGLES for s in (mean, sd)]
    _header(ws, titles, [10] + [26] * 6)
    curves = ri.results.get("curves") or {}
    cols = [(curves.get(a) or {}).get(k) for a in ANGLES for k in ("mean", "sd")]
    n = max((len(c) for c in cols if c), default=0)
    if n == 0:
        _append(ws, ["", tr("data.not_available", lang)])
        return
    pct = np.linspace(0.0, 100.0, n) if n > 1 else np.zeros(1)
    for i in range(n):
        _append(ws, [float(pct[i])] + [(c[i] if c and i < len(c) else None) for c in cols])


def _session_sheet(wb: Workbook, ri: ReportInput, lang: str) -> None:
    ws = wb.create_sheet(_sheet_title(tr("data.sheet.session", lang)))
    _header(ws, [tr("data.col.field", lang), tr("data.col.value", lang)], [32, 60])
    for name, value in session_rows(ri, lang):
        _append(ws, [name, value])


def _knees_sheets(wb: Workbook, ri: ReportInput, lang: str) -> None:
    """A two-knee session (:mod:`reports.knees`): each knee's mean curves side by side, and the LSI table."""
    ws = wb.create_sheet(_sheet_title(tr("knees.sheet", lang)))
    sides = sorted(ri.results["knees"])
    mean = tr("data.stat.mean", lang)
    _header(ws, [tr("data.col.cycle_pct", lang)] + [f"{tr('knees.' + side, lang)}: {tr('data.angle.' + a, lang)} "
                                                    f"{mean} (°)" for side in sides for a in ANGLES],
            [10] + [30] * (3 * len(sides)))
    cols = [get_path(ri.results, "knees", side, "curves", a, "mean") or [] for side in sides for a in ANGLES]
    n = max((len(c) for c in cols), default=0)
    pct = np.linspace(0.0, 100.0, n) if n > 1 else np.zeros(n)
    for i in range(n):
        _append(ws, [float(pct[i])] + [c[i] if i < len(c) else None for c in cols])
    excluded = all_excluded_lines(ri.results, lang)  # both knees' (the cycles sheet is the primary knee's)
    if excluded:
        _append(ws, [])
        for line in excluded:
            _append(ws, [line])
    ws = wb.create_sheet(_sheet_title(tr("lsi.sheet", lang)))
    rows = knees.lsi_rows(ri.results, lang)
    if rows is None:
        _header(ws, [tr("section.lsi", lang)], [80])
        _append(ws, [tr("lsi.no_involved", lang)])
        return
    sym = ri.results["symmetry"]
    _header(ws, [rows[0][0], tr("lsi.col.unit", lang), *rows[0][1:]], [44, 14, 22, 22, 12])
    for p, row in zip(sym["parameters"], rows[1:]):  # numbers stay numbers in the workbook
        _append(ws, [row[0], tr(f"lsi.unit.{p['unit']}", lang), p.get("involved"), p.get("uninvolved"),
                     p.get("lsi_pct")])


def _comparison_sheet(wb: Workbook, ri: ReportInput, lang: str) -> None:
    """The earlier session's numbers beside this one's (``results["comparison"]``), numbers as numbers."""
    note, warning, rows = knees.comparison_table(ri.results, lang)
    ws = wb.create_sheet(_sheet_title(tr("compare.sheet", lang)))
    _header(ws, [*rows[0], tr("lsi.col.unit", lang)], [44, 22, 16, 14, 12])
    for label, r in zip((row[0] for row in rows[1:]), ri.results["comparison"]["rows"]):
        _append(ws, [label, r.get("a"), r.get("b"), r.get("change"), r["unit"]])
    _append(ws, [note])
    if warning:
        _append(ws, [warning])


def write_angles_xlsx(ri: ReportInput, path: str | os.PathLike) -> None:
    """Write ``angles.xlsx``: angles over time with cycle and phase, per-cycle table, normalised curves,
    patient and session (a two-knee session also both knees' curves and the symmetry index).  Labels in
    ``ri.language``; the file appears complete or not at all."""
    lang = ri.language
    wb = Workbook(write_only=True)
    bulk = {1: _angles_sheet(wb, ri, lang)}
    _cycles_sheet(wb, ri, lang)
    _curves_sheet(wb, ri, lang)
    if knees.has_knees(ri.results):
        _knees_sheets(wb, ri, lang)
    if knees.has_comparison(ri.results):
        _comparison_sheet(wb, ri, lang)
    _session_sheet(wb, ri, lang)
    _stamp_identity(wb, ri)
    _save(wb, bulk, path)


# ------------------------------------------------------------------------------------- quaternions.xlsx
def _quat_sheet(wb: Workbook, ri: ReportInput, lang: str, title_key: str, qs: dict[str, Any],
                names: Sequence[str]) -> _Bulk:
    ws = wb.create_sheet(_sheet_title(tr(title_key, lang)))
    present = [s for s in names if s in qs] + [s for s in qs if s not in names]
    titles = [tr("data.col.time_s", lang)]
    titles += [f"{code_label('data.seg', s, lang)} {c}" for s in present for c in "wxyz"]
    _header(ws, titles, [11] + [12] * (len(titles) - 1))
    cols: list[tuple[str, Any]] = [("num", ri.t_s)]
    for s in present:
        q = np.asarray(qs[s], dtype=np.float64)
        cols += [("num", q[:, j]) for j in range(4)]
    return _Bulk(cols)


def write_quaternions_xlsx(ri: ReportInput, path: str | os.PathLike) -> None:
    """Write ``quaternions.xlsx``: ``q_earth_sensor`` (thigh, shank) and ``q_earth_segment`` (femur, tibia)
    as w, x, y, z with time, and the ``q_sensor_segment`` calibrations."""
    lang = ri.language
    wb = Workbook(write_only=True)
    bulk = {1: _quat_sheet(wb, ri, lang, "data.sheet.sensors", ri.q_earth_sensor, ("thigh", "shank")),
            2: _quat_sheet(wb, ri, lang, "data.sheet.segments", ri.q_earth_segment, ("femur", "tibia"))}
    ws = wb.create_sheet(_sheet_title(tr("data.sheet.calibration", lang)))
    _header(ws, [tr("data.col.segment", lang), "w", "x", "y", "z"], [40, 14, 14, 14, 14])
    for seg, q in ri.q_sensor_segment.items():
        _append(ws, [f"{code_label('data.seg', seg, lang)}: {tr('data.quat.sensor_segment', lang)}",
                     *np.asarray(q, dtype=np.float64).tolist()])
    _append(ws, [])
    _append(ws, [tr("data.quat.note", lang)])
    _stamp_identity(wb, ri)
    _save(wb, bulk, path)
