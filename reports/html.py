"""Interactive HTML report of one knee session: one self-contained file, plotly.js embedded.

Reports present; they compute nothing clinical.  Every number shown comes from ``results.json``
(``rom_deg``, ``phases``, ``cycles``, ``curves``, ``calibration``, ``quality``) or the task's series of
:class:`~reports.model.ReportInput`.  Phase boundaries on the normalised curves are the cumulative mean
phase percentages of ``results["phases"]`` (the curves and the percentages share the same normalisation
span, see :mod:`estimators.motor_task`).

Self-contained: plotly.js comes from the installed ``plotly`` package and is inlined once; the CSS is
inline and uses the system fonts; nothing refers to a URL, so the file works offline (clinics often are).
The figures are plain plotly JSON specs in ``<script type="application/json" id="fig-...">`` blocks drawn by
``Plotly.newPlot`` (faster than building ``plotly.graph_objects`` figures, and the data can be read back
by tests and other tools).  Every text a user typed is escaped with :func:`html.escape`; JSON inside
``<script>`` has ``<``, ``>`` and ``&`` escaped as ``\\u003c``... so no text can close the script element.

Language: ``ri.language`` (es, en, pt), labels from ``reports/translations_data.json``; numbers use a
decimal comma in es and pt.
"""

from __future__ import annotations

import html
import json
import math
from functools import lru_cache
from typing import Any

import numpy as np

from reports import i18n, knees
from reports.figures import reference_keypoints
from reports.labels import (EXCLUDED, all_excluded_lines, calibration_sentence, code_label, cycle_and_phase_per_sample,
                            get_path, heading_sentence, identity_items, method_items, phase_names, phase_spans_pct,
                            reference_sentence, session_rows, signature_line, signed_line, split_rejected, tr)
from reports.warning_text import warning_text
from reports.model import ANGLES, ReportInput

__all__ = ["render_html", "figure_specs"]

_ACCEPTED_FILL = "rgba(46, 160, 67, 0.13)"
_REJECTED_FILL = "rgba(214, 39, 40, 0.20)"
_ACCEPTED_MARK, _REJECTED_MARK = "rgba(46, 160, 67, 0.5)", "rgba(214, 39, 40, 0.6)"
_ANGLE_COLOURS = {"flexion": "#1f77b4", "adduction": "#ff7f0e", "internal_rotation": "#2ca02c"}
_RGBA = {"flexion": "rgba(31,119,180,0.2)", "adduction": "rgba(255,127,14,0.2)",
         "internal_rotation": "rgba(44,160,44,0.2)"}
_REFERENCE_COLOUR = "#d67800"  # the reference's key ranges (reports.figures draws them in the same colour)

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"Helvetica Neue",Arial,sans-serif;margin:0;
color:#1d2433;background:#f5f7fa}
main{max-width:1100px;margin:0 auto;padding:24px}
header{background:#1d3557;color:#fff;padding:18px 24px}
header h1{margin:0;font-size:1.5em} header p{margin:4px 0 0;opacity:.85}
section{background:#fff;border-radius:8px;box-shadow:0 1px 3px rgba(0,0,0,.08);padding:16px 20px;margin:0 0 18px}
h2{font-size:1.15em;margin:0 0 10px;color:#1d3557}
table{border-collapse:collapse;width:100%;font-size:.92em}
th,td{border-bottom:1px solid #e3e7ee;padding:5px 8px;text-align:left}
th{background:#eef2f7} td.num{text-align:right;font-variant-numeric:tabular-nums}
details.technical{font-size:.8em;color:#555}
tr.rejected td{background:#fdecec} tr.outside td{background:#fff4e0;font-weight:600}
ul.warnings li{margin:3px 0} .muted{color:#5c677d}
header p.identity{font-size:.92em} header .muted-h{opacity:.75} p.interp{white-space:pre-wrap}
footer{font-size:.85em;color:#5c677d;text-align:center;padding:12px}
section{overflow-x:auto}
@media (max-width:820px){main{padding:12px} section{padding:12px} th,td{padding:4px 5px}}
"""


# ------------------------------------------------------------------------------------------- helpers
def _num(x: Any, lang: str, digits: int = 1) -> str:
    """A number as printed: fixed ``digits``, decimal comma in es/pt, a dash when missing."""
    return i18n.fmt_number(x, digits, lang)


def _pm(stat: Any, lang: str, mean_key: str = "mean", sd_key: str = "sd", digits: int = 1) -> str:
    """``mean ± sd`` of a results.json statistic (only the mean when the SD is missing)."""
    if not isinstance(stat, dict):
        return i18n.MISSING
    return i18n.fmt_mean_sd(stat.get(mean_key), stat.get(sd_key), digits, lang)


def _e(text: Any) -> str:
    return html.escape("" if text is None else str(text), quote=True)


def _json_for_script(obj: Any) -> str:
    """JSON that cannot end a ``<script>`` element or open a comment (``<``, ``>``, ``&`` as escapes)."""
    s = json.dumps(obj, ensure_ascii=False, allow_nan=False, separators=(",", ":"))
    return s.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026") \
        .replace("\u2028", "\\u2028").replace("\u2029", "\\u2029")


def _finite_list(a: Any) -> list[float | None]:
    """A float list for JSON: NaN/inf → None (plotly draws a gap)."""
    arr = np.asarray(a, dtype=np.float64)
    out = arr.tolist()
    if not np.isfinite(arr).all():
        out = [v if math.isfinite(v) else None for v in out]
    return out


def _drop_none(obj: Any) -> Any:
    """Remove None-valued keys from nested dicts (plotly specs: "not set" rather than null)."""
    if isinstance(obj, dict):
        return {k: _drop_none(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, list) and obj and isinstance(obj[0], dict):
        return [_drop_none(v) for v in obj]
    return obj


@lru_cache(maxsize=1)
def plotly_js() -> str:
    """plotly.js from the installed plotly package (no CDN); read once per process (4.6 MB)."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


# ------------------------------------------------------------------------------------------- figures
def _stacked_axes(n: int, gap: float = 0.06) -> list[list[float]]:
    h = (1.0 - gap * (n - 1)) / n
    return [[1.0 - (i + 1) * h - i * gap, 1.0 - i * h - i * gap] for i in range(n)]


def _task_figure(ri: ReportInput, lang: str) -> dict[str, Any]:
    """Whole task over time: one panel per angle, detected cycles shaded (accepted green, rejected red)."""
    t = _finite_list(ri.t_s)
    cycle, phase = cycle_and_phase_per_sample(ri)
    phase_names = {p: code_label("data.phase", p, lang) for p in set(phase) if p}
    custom = [[c if c is not None else "", phase_names.get(p, "")] for c, p in zip(cycle, phase)]
    cyc_lbl = tr("data.col.cycle", lang)
    data: list[dict[str, Any]] = []
    # top margin: plotly's mode bar (top right), then the legend, then the cycle numbers just above the
    # plot — stacked so that none overlaps another (seen in a browser screenshot: with t=30 they did)
    layout: dict[str, Any] = {"height": 680, "margin": {"l": 60, "r": 20, "t": 80, "b": 50},
                              "hovermode": "x unified",
                              "legend": {"orientation": "h", "y": 1.04, "yanchor": "bottom", "x": 0},
                              "shapes": [], "annotations": []}
    domains = _stacked_axes(len(ANGLES))
    for i, angle in enumerate(ANGLES):
        ax = "" if i == 0 else str(i + 1)
        data.append({"type": "scattergl" if len(t) > 20000 else "scatter", "mode": "lines",
                     "name": tr(f"data.angle.{angle}", lang), "x": t, "y": _finite_list(ri.angles_deg[:, i]),
                     "xaxis": f"x{ax}", "yaxis": f"y{ax}", "line": {"color": _ANGLE_COLOURS[angle], "width": 1.5},
                     "customdata": custom if i == 0 else None,
                     "hovertemplate": (f"%{{y:.1f}}°<br>{_e(cyc_lbl)} %{{customdata[0]}} · %{{customdata[1]}}"
                                       "<extra></extra>") if i == 0 else "%{y:.1f}°<extra></extra>"})
        layout[f"yaxis{ax}"] = {"domain": domains[i], "title": {"text": f"{tr(f'data.angle.{angle}', lang)} (°)"},
                                "zeroline": True}
        layout[f"xaxis{ax}"] = {"anchor": f"y{ax}", "matches": "x" if i else None,
                                "showticklabels": i == len(ANGLES) - 1,
                                "title": {"text": tr("data.col.time_s", lang)} if i == len(ANGLES) - 1 else None}
    for b0, b1, accepted in ri.cycle_bounds_s():
        if b0 is None or b1 is None:
            continue
        layout["shapes"].append({"type": "rect", "xref": "x", "yref": "paper", "x0": b0, "x1": b1, "y0": 0, "y1": 1,
                                 "fillcolor": _ACCEPTED_FILL if accepted else _REJECTED_FILL, "line": {"width": 0},
                                 "layer": "below", "name": "accepted" if accepted else "rejected"})
    for k, (b0, b1, _) in enumerate(ri.cycle_bounds_s()):
        if b0 is not None and b1 is not None:
            layout["annotations"].append({"x": (b0 + b1) / 2, "y": 1.0, "xref": "x", "yref": "paper",
                                          "text": str(k + 1), "showarrow": False, "yanchor": "bottom",
                                          "font": {"size": 11, "color": "#5c677d"}})
    for key, colour in (("accepted", _ACCEPTED_MARK), ("rejected", _REJECTED_MARK)):   # legend entries
        data.append({"type": "scatter", "mode": "markers", "x": [None], "y": [None], "showlegend": True,
                     "name": tr(f"html.legend.{key}", lang), "hoverinfo": "skip",
                     "marker": {"symbol": "square", "size": 14, "color": colour}})
    return _drop_none({"data": data, "layout": layout})


def _curves_figure(ri: ReportInput, lang: str) -> dict[str, Any]:
    """Mean ± SD over the normalised cycle, one panel per angle, phase boundaries as dashed lines."""
    curves = ri.results.get("curves") or {}
    mean_sd = tr("html.mean_sd", lang)
    data: list[dict[str, Any]] = []
    # t=60: the phase names above the plot stay clear of plotly's mode bar (top right)
    layout: dict[str, Any] = {"height": 660, "margin": {"l": 60, "r": 20, "t": 60, "b": 50},
                              "hovermode": "x unified", "showlegend": False, "shapes": [], "annotations": []}
    domains = _stacked_axes(len(ANGLES))
    for i, angle in enumerate(ANGLES):
        ax = "" if i == 0 else str(i + 1)
        c = curves.get(angle) or {}
        mean, sd = c.get("mean"), c.get("sd")
        name = tr(f"data.angle.{angle}", lang)
        layout[f"yaxis{ax}"] = {"domain": domains[i], "title": {"text": f"{name} (°)"}}
        layout[f"xaxis{ax}"] = {"anchor": f"y{ax}", "matches": "x" if i else None, "range": [0, 100],
                                "showticklabels": i == len(ANGLES) - 1,
                                "title": {"text": tr("data.col.cycle_pct", lang)} if i == len(ANGLES) - 1 else None}
        if not mean:
            continue
        m = np.asarray([np.nan if v is None else v for v in mean], dtype=np.float64)
        s = np.asarray([np.nan if v is None else v for v in (sd or [None] * len(m))], dtype=np.float64)
        pct = np.linspace(0.0, 100.0, len(m)).tolist()
        common = {"xaxis": f"x{ax}", "yaxis": f"y{ax}", "x": pct, "mode": "lines"}
        data.append({**common, "type": "scatter", "y": _finite_list(m + s), "line": {"width": 0},
                     "hoverinfo": "skip", "name": f"{name} +SD"})
        data.append({**common, "type": "scatter", "y": _finite_list(m - s), "line": {"width": 0},
                     "fill": "tonexty", "fillcolor": _RGBA[angle], "hoverinfo": "skip", "name": f"{name} -SD"})
        data.append({**common, "type": "scatter", "y": _finite_list(m), "name": f"{name} ({mean_sd})",
                     "line": {"color": _ANGLE_COLOURS[angle], "width": 2},
                     "customdata": _finite_list(s), "hovertemplate": "%{y:.1f} ± %{customdata:.1f}°<extra></extra>"})
    for kp in reference_keypoints(ri.results):  # the reference's ranges of the mean flexion (flexion is panel 1)
        (a, b), (c, d) = kp["pct"], kp["deg"]
        layout["shapes"].append({"type": "rect", "xref": "x", "yref": "y", "x0": a, "x1": b, "y0": c, "y1": d,
                                 "line": {"color": _REFERENCE_COLOUR, "width": 2}})
    bounds = phase_spans_pct(ri.results)
    for k, (name, p0, p1) in enumerate(bounds):
        if k > 0:
            layout["shapes"].append({"type": "line", "xref": "x", "yref": "paper", "x0": p0, "x1": p0, "y0": 0,
                                     "y1": 1, "line": {"color": "#444", "width": 1, "dash": "dash"}})
        layout["annotations"].append({"x": (p0 + p1) / 2, "y": 1.0, "xref": "x", "yref": "paper",
                                      "yanchor": "bottom", "showarrow": False,
                                      "text": _e(code_label("data.phase", name, lang)), "font": {"size": 12}})
    return _drop_none({"data": data, "layout": layout})


def figure_specs(ri: ReportInput) -> dict[str, dict[str, Any]]:
    """The plotly specs (``{"data": [...], "layout": {...}}``) of the report's figures, by element id."""
    lang = ri.language
    specs = {"fig-task": _task_figure(ri, lang), "fig-curves": _curves_figure(ri, lang)}
    if knees.has_knees(ri.results):
        specs["fig-knees"] = knees.knees_figure(ri.results, lang)
    return specs


# -------------------------------------------------------------------------------------------- tables
def _table(head: list[str], rows: list[tuple[list[str], str]], numeric_from: int = 1) -> str:
    """``rows`` = (escaped cell texts, row css class)."""
    th = "".join(f"<th>{h}</th>" for h in head)
    body = []
    for cells, cls in rows:
        tds = "".join(f'<td class="num">{c}</td>' if j >= numeric_from else f"<td>{c}</td>"
                      for j, c in enumerate(cells))
        body.append(f'<tr class="{cls}">{tds}</tr>' if cls else f"<tr>{tds}</tr>")
    return f"<table><thead><tr>{th}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _rom_table(r: dict[str, Any], lang: str) -> str:
    rom = r.get("rom_deg") or {}
    head = [_e(tr("data.col.angle", lang))] + [
        f"{_e(tr('data.stat.' + s, lang))} (°), {_e(tr('html.mean_sd', lang))}" for s in ("range", "max", "min")]
    rows = [([_e(tr(f"data.angle.{a}", lang))] + [_pm(get_path(rom, a, s), lang) for s in ("range", "max", "min")], "")
            for a in ANGLES]
    return _table(head, rows)


def _phase_table(r: dict[str, Any], lang: str) -> str:
    ms = tr("html.mean_sd", lang)
    head = [_e(tr("data.col.phase", lang)), f"{_e(tr('data.col.duration_s', lang))}, {_e(ms)}",
            f"{_e(tr('data.col.cycle_pct', lang))}, {_e(ms)}"]
    rows = []
    for name in phase_names(r):
        ph = get_path(r, "phases", name)
        rows.append(([_e(code_label("data.phase", name, lang)), _pm(ph, lang, "mean_s", "sd_s", 2),
                      _pm(ph, lang, "mean_pct", "sd_pct", 1)], ""))
    return _table(head, rows)


def _reference_block(r: dict[str, Any], lang: str) -> str:
    """The task's reference (``results["reference"]``): its source and population, then per parameter the
    session's value, the band (or the reference's mean when it only shows one) and the flag (L / N / H)."""
    ref = r.get("reference")
    if not ref:
        return f'<p class="muted">{_e(tr("data.not_available", lang))}</p>'
    head = [_e(tr("ref.parameter", lang)), _e(tr("ref.value", lang)), _e(tr("ref.band", lang)),
            _e(tr("ref.flag", lang))]
    rows = []
    for name, p in (ref.get("parameters") or {}).items():
        unit = {"deg": "°", "pct": " %", "s": " s"}.get(p.get("unit"), "")
        digits = 2 if p.get("unit") == "s" else 1
        band = (f"{_num(p['low'], lang, digits)}–{_num(p['high'], lang, digits)}{unit}"
                if p.get("low") is not None and p.get("high") is not None else f"{_num(p.get('mean'), lang, digits)}{unit}")
        flag = p.get("interpretation")
        rows.append(([_e(code_label("data.ref_param", name, lang)), f"{_num(p.get('value'), lang, digits)}{unit}",
                      _e(band), _e(tr(f"ref.flag_{flag}", lang)) if flag else "–"],
                     "outside" if p.get("within_band") is False else ""))
    return f"<p>{_e(reference_sentence(ref, lang))}</p>" + _table(head, rows)


def _cycles_table(r: dict[str, Any], lang: str) -> str:
    per_cycle = get_path(r, "cycles", "per_cycle")
    if not per_cycle:
        return f'<p class="muted">{_e(tr("data.not_available", lang))}</p>'
    names = phase_names(r)
    head = [_e(tr("data.col.cycle", lang)), _e(tr("data.col.status", lang)), _e(tr("data.col.start_s", lang)),
            _e(tr("data.col.end_s", lang))]
    head += [f"{_e(tr('data.angle.' + a, lang))} {_e(tr('data.stat.range', lang))} (°)" for a in ANGLES]
    head += [f"{_e(code_label('data.phase', p, lang))} (%)" for p in names]
    rows = []
    for c in per_cycle:
        ok = bool(c.get("accepted"))
        status = tr("data.status.accepted" if ok else "data.status.rejected", lang)
        if c.get("reason") == EXCLUDED:
            status = tr("data.status.excluded", lang)
        elif not ok and c.get("reason"):
            status += f": {code_label('data.reason', c['reason'], lang)}"
        idx = c.get("index")
        cells = [_e(idx + 1 if isinstance(idx, int) else i18n.MISSING), _e(status), _num(c.get("start_s"), lang, 2),
                 _num(c.get("end_s"), lang, 2)]
        cells += [_num(get_path(c, "rom_deg", a, "range"), lang) for a in ANGLES]
        cells += [_num(get_path(c, "phases", p, "pct"), lang) for p in names]
        rows.append((cells, "" if ok else "rejected"))
    return _table(head, rows, numeric_from=2)


def _quality_block(r: dict[str, Any], lang: str) -> str:
    cycles = r.get("cycles") or {}
    rejected, _ = split_rejected(cycles)
    summary = tr("html.cycles_summary", lang, detected=cycles.get("detected", i18n.MISSING),
                 accepted=cycles.get("accepted", i18n.MISSING), rejected=len(rejected))
    # how the numbers were computed: the calibration asked for and used, the angle convention (reports.labels)
    parts = [f'<p class="method"><strong>{_e(label)}:</strong> {_e(text)}</p>' for label, text in method_items(r, lang)]
    parts.append(f"<p>{_e(summary)}</p>")
    # the clinician's exclusions (every knee's), then the pipeline's
    items = [_e(line) for line in all_excluded_lines(r, lang)]
    for rej in rejected:
        if not isinstance(rej, dict):
            continue
        idx = rej.get("index")
        label = code_label("data.reason", rej.get("reason"), lang) if rej.get("reason") else ""
        items.append(f"{_e(tr('data.col.cycle', lang))} {_e(idx + 1 if isinstance(idx, int) else i18n.MISSING)}: "
                     f"{_e(label)} — {_e(rej.get('message', ''))}")
    for seg, cal in (get_path(r, "calibration", "magnetometer") or {}).items():
        q = cal.get("quality", {}) if isinstance(cal, dict) else {}
        field_ut = q.get("field_ut", cal.get("field_ut") if isinstance(cal, dict) else None)
        cov = q.get("coverage_fraction")
        items.append(_e(tr("html.mag_field", lang,
            segment=code_label("data.seg", seg, lang), field=_num(field_ut, lang, 1),
            coverage=_num(None if cov is None else 100.0 * cov, lang, 0))))
    for seg, cal in (get_path(r, "calibration", "segment") or {}).items():
        angle = cal.get("angle_between_postures_deg") if isinstance(cal, dict) else None
        if angle is not None:
            items.append(_e(tr("html.posture_angle", lang, segment=code_label("data.seg", seg, lang),
                                                                 angle=_num(angle, lang, 1))))
    calibration = calibration_sentence(r, lang)
    if calibration:
        items.append(_e(calibration))
    heading = heading_sentence(r, lang)
    if heading:
        items.append(_e(heading))
    for seg, frac in (get_path(r, "quality", "magnetic_disturbance_fraction") or {}).items():
        items.append(_e(tr("html.mag_disturbance", lang,
            segment=code_label("data.seg", seg, lang), pct=_num(None if frac is None else 100.0 * frac, lang, 1))))
    warnings = get_path(r, "quality", "warnings") or []
    for w in warnings:
        items.append(_e(warning_text(w, lang, r)[0]))
    if not warnings:
        items.append(_e(tr("html.no_warnings", lang)))
    parts.append('<ul class="warnings">' + "".join(f"<li>{i}</li>" for i in items) + "</ul>")
    notes = get_path(r, "quality", "technical_notes") or []
    if notes:  # how the files were read: small, folded, apart from the clinical warnings
        parts.append(f'<details class="technical"><summary>{_e(tr("technical_notes", lang))}</summary><ul>'
                     + "".join(f"<li>{_e(warning_text(w, lang, r)[0])}</li>" for w in notes) + "</ul></details>")
    return "".join(parts)


def _patient_block(ri: ReportInput, lang: str) -> str:
    rows = []
    for name, value in session_rows(ri, lang):
        if isinstance(value, float):
            value = _num(value, lang, 2)
        rows.append(f"<tr><th>{_e(name)}</th><td>{_e('' if value is None else value)}</td></tr>")
    return f"<table>{''.join(rows)}</table>"


def _identity(ri: ReportInput, lang: str) -> str:
    """The header's identity line: who the report is about (:func:`reports.labels.identity_items`)."""
    items = identity_items(ri.patient, lang)
    return " · ".join(f'<span class="id"><span class="muted-h">{_e(k)}:</span> {_e(v)}</span>' for k, v in items)


def _interpretation_block(ri: ReportInput, lang: str) -> str:
    """The clinician's signed interpretation: text, signer, date; "amended" with each amendment and its text."""
    it = ri.interpretation
    parts = [f'<p class="warning"><strong>{_e(tr("interp.amended", lang))}</strong></p>'] if it.amendments else []
    parts.append(f'<p class="interp">{_e(it.text)}</p>')
    parts.append(f'<p class="muted">{_e(signature_line(lang, it))}</p>')
    if it.amendments:
        items = "".join(
            f'<li>{_e(signed_line(lang, "interp.amendment", a.by, a.role, a.at, reason=a.reason))}'
            f'<br><span class="muted">{_e(tr("interp.previous", lang))}: {_e(a.previous_text)}</span></li>'
            for a in it.amendments)
        parts.append(f'<h3>{_e(tr("interp.history", lang))}</h3><ul class="amendments">{items}</ul>')
    return "".join(parts)


def _knees_sections(r: dict[str, Any], lang: str, section) -> str:
    """Both knees' curves overlaid and the LSI table (:mod:`reports.knees`)."""
    note = f'<p class="note">{_e(tr("knees.curves_note", lang, involved=knees.involved_text(r, lang)))}</p>'
    rows = knees.lsi_rows(r, lang)
    lsi = f"<p>{_e(tr('lsi.no_involved', lang))}</p>" if rows is None else \
        _table([_e(c) for c in rows[0]], [([_e(c) for c in row], "") for row in rows[1:]]) + \
        f'<p class="note">{_e(tr("lsi.note", lang))}</p>'
    return section("section.knees", note + '<div class="plot" id="fig-knees"></div>') + section("section.lsi", lsi)


def _comparison_section(r: dict[str, Any], lang: str, section) -> str:
    """An earlier session's numbers beside this one's (:func:`reports.knees.comparison_table`)."""
    note, warning, rows = knees.comparison_table(r, lang)
    warn = f'<p class="warning"><strong>{_e(warning)}</strong></p>' if warning else ""
    table = _table([_e(c) for c in rows[0]], [([_e(c) for c in row], "") for row in rows[1:]])
    return section("section.compare", f'<p class="note">{_e(note)}</p>{warn}{table}')


# ---------------------------------------------------------------------------------------------- page
def render_html(ri: ReportInput) -> str:
    """The interactive report as one self-contained HTML document (UTF-8 text)."""
    lang = ri.language
    r = ri.results
    title = tr("html.title", lang)
    who = ri.patient.name_or_id
    figs = figure_specs(ri)
    fig_blocks = "".join(
        f'<script type="application/json" id="{fid}-data">{_json_for_script(spec)}</script>'
        for fid, spec in figs.items())
    draw = ("(function(){var cfg={displaylogo:false,responsive:true};"
            "document.querySelectorAll('div.plot').forEach(function(el){"
            "var s=JSON.parse(document.getElementById(el.id+'-data').textContent);"
            "Plotly.newPlot(el,s.data,s.layout,cfg);});})();")

    def section(key: str, body: str) -> str:
        return f'<section id="{key.split(".")[-1]}"><h2>{_e(tr(key, lang))}</h2>{body}</section>'

    body = "".join([
        section("html.section.patient", _patient_block(ri, lang)),
        section("html.section.task", '<div class="plot" id="fig-task"></div>'),
        section("html.section.curves", '<div class="plot" id="fig-curves"></div>'),
        _knees_sections(r, lang, section) if knees.has_knees(r) else "",
        _comparison_section(r, lang, section) if knees.has_comparison(r) else "",
        section("html.section.rom", _rom_table(r, lang)),
        section("html.section.phases", _phase_table(r, lang)),
        *([section("html.section.reference", _reference_block(r, lang))] if r.get("reference") else []),
        section("html.section.cycles", _cycles_table(r, lang)),
        section("html.section.quality", _quality_block(r, lang)),
        section("interp.section", _interpretation_block(ri, lang)) if ri.interpretation is not None else "",
    ])
    version = get_path(r, "software", "version") or ""
    return (
        f'<!DOCTYPE html>\n<html lang="{_e(lang)}"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{_e(title)}{' — ' + _e(who) if who else ''}</title><style>{_CSS}</style>"
        f"<script>{plotly_js()}</script></head><body>"
        f"<header><h1>{_e(title)}</h1>"
        f'<p class="identity">{_identity(ri, lang)}</p></header>'
        f"<main>{body}</main><footer>{_e(tr('html.footer', lang, version=version))}</footer>"
        f"{fig_blocks}<script>{draw}</script></body></html>\n"
    )
