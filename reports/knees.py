"""The two-knee and comparison parts of every report: left and right curves overlaid, the limb symmetry index
table, and an earlier session's numbers side by side (``results["comparison"]``, ``chakamo process --compare-with``).

Everything comes from ``results.json`` (:func:`app.pipeline.results.build_knees_results`): ``knees`` (each knee's
one-knee results: its ``curves``), ``involved_side`` and ``symmetry`` (the LSI per parameter, computed by the
pipeline; nothing is computed here).  A one-knee session has no ``knees``: :func:`has_knees` is False and no
format shows these parts.

* :func:`lsi_rows` — the LSI table (heading row first) as texts in a language, for the PDF, HTML and Excel;
* :func:`draw_knees_curves` — the PDF figure (three stacked panels: each knee's mean curve, left and right in
  two colours), drawn with :mod:`reports.figures`' panels;
* :func:`knees_figure` — the same as a plotly spec for the HTML report;
* :func:`comparison_table` — the comparison rows (earlier, this session, change) as texts, with the note and the
  warning when the two analyses differ in method (:mod:`app.pipeline.comparison`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from reports.figures import ANGLE_ORDER, _curve, _layout, _legend, _Panel, nice_ticks
from reports.i18n import fmt_number, t
from reports.labels import code_label

#: each side's line colour (both reports): left blue, right orange (told apart in grey print by the dash)
SIDE_COLOURS = {"left": (31, 78, 121), "right": (214, 110, 22)}
#: decimals of the LSI table's values per unit
DECIMALS = {"deg": 1, "pct": 1, "s": 2, "steps_min": 1}


def has_knees(results: dict[str, Any]) -> bool:
    """True for a session of both knees (``results["knees"]`` holds two)."""
    return isinstance(results.get("knees"), dict) and len(results["knees"]) == 2


def involved_text(results: dict[str, Any], lang: str) -> str:
    """The involved knee's name in ``lang``, or "not chosen"."""
    side = results.get("involved_side")
    return t(f"knees.{side}", lang) if side in ("left", "right") else t("knees.none_involved", lang)


def lsi_rows(results: dict[str, Any], lang: str) -> list[list[str]] | None:
    """The LSI table: a heading row (parameter, involved, uninvolved, LSI), then one row per parameter (values with
    their unit, the LSI in %, "—" where missing); None without a symmetry (no involved knee)."""
    sym = results.get("symmetry")
    if not isinstance(sym, dict):
        return None
    rows = [[t("lsi.col.parameter", lang),
             t("lsi.col.involved", lang, side=t(f"lsi.side.{sym['involved']}", lang)),
             t("lsi.col.uninvolved", lang, side=t(f"lsi.side.{sym['uninvolved']}", lang)),
             t("lsi.col.lsi", lang)]]
    for p in sym.get("parameters", []):
        rows.append([t(f"lsi.param.{p['name']}", lang), _value(p.get("involved"), p["unit"], lang),
                     _value(p.get("uninvolved"), p["unit"], lang),
                     "—" if p.get("lsi_pct") is None else fmt_number(p["lsi_pct"], 1, lang)])
    return rows


def _value(x: float | None, unit: str, lang: str) -> str:
    """A parameter's value with its unit ("—" when missing)."""
    if x is None:
        return "—"
    return f"{fmt_number(x, DECIMALS.get(unit, 1), lang)} {t(f'lsi.unit.{unit}', lang)}".replace(" °", "°")


def _knee_curves(results: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {side: knee.get("curves") or {} for side, knee in sorted((results.get("knees") or {}).items())}


def draw_knees_curves(pdf: Any, results: dict[str, Any], lang: str, x: float, y: float, w: float, h: float) -> None:
    """Each knee's mean curve over the normalised cycle, left and right overlaid, one panel per angle, in the box
    ``(x, y, w, h)`` mm of the PDF page."""
    curves = _knee_curves(results)
    _, _, xticks = nice_ticks(0.0, 100.0, 10, expand=False)
    with pdf.local_context():
        for k, (box, angle) in enumerate(zip(_layout(x, y, w, h), ANGLE_ORDER)):
            means = {side: _curve(c, angle, "mean") for side, c in curves.items()}
            finite = np.concatenate([m[np.isfinite(m)] for m in means.values()]) if means else np.zeros(0)
            lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (math.nan, math.nan)
            y0, y1, yticks = nice_ticks(lo, hi, 4)
            panel = _Panel(pdf, *box, (0.0, 100.0), (y0, y1))
            panel.grid(xticks, yticks)
            for side, m in means.items():
                if m.size:
                    if side == "right":
                        pdf.set_dash_pattern(1.6, 0.8)
                    panel.line(np.linspace(0.0, 100.0, m.size), m, SIDE_COLOURS.get(side, (0, 0, 0)), 0.45)
                    pdf.set_dash_pattern()
            panel.angle_axes(angle, k, xticks, yticks, lang, y)
            if k == 0:
                def swatch(side: str):
                    def draw(sx: float, sy: float, sw: float, sh: float) -> None:
                        pdf.set_draw_color(*SIDE_COLOURS[side])
                        pdf.set_line_width(0.45)
                        if side == "right":
                            pdf.set_dash_pattern(1.6, 0.8)
                        pdf.line(sx, sy + sh / 2, sx + sw, sy + sh / 2)
                        pdf.set_dash_pattern()
                    return draw

                _legend(pdf, panel.x + panel.w, y + 3.2, [(t(f"knees.{side}", lang), swatch(side))
                                                          for side in means if side in SIDE_COLOURS])


def knees_figure(results: dict[str, Any], lang: str) -> dict[str, Any]:
    """:func:`draw_knees_curves` as a plotly spec ``{"data", "layout"}`` (one panel per angle)."""
    curves = _knee_curves(results)
    n = len(ANGLE_ORDER)
    gap = 0.06
    height = (1.0 - gap * (n - 1)) / n
    data: list[dict[str, Any]] = []
    layout: dict[str, Any] = {"height": 600, "margin": {"l": 60, "r": 20, "t": 30, "b": 50},
                              "hovermode": "x unified", "legend": {"orientation": "h", "y": 1.06}}
    for i, angle in enumerate(ANGLE_ORDER):
        ax = "" if i == 0 else str(i + 1)
        top = 1.0 - i * (height + gap)
        layout[f"yaxis{ax}"] = {"domain": [top - height, top], "title": {"text": t(f"axis_{angle}", lang)}}
        layout[f"xaxis{ax}"] = {"anchor": f"y{ax}", "range": [0, 100], "showticklabels": i == n - 1,
                                **({"matches": "x"} if i else {}),
                                **({"title": {"text": t("fig_cycle_pct", lang)}} if i == n - 1 else {})}
        for side, c in curves.items():
            m = _curve(c, angle, "mean")
            if not m.size:
                continue
            rgb = SIDE_COLOURS.get(side, (0, 0, 0))
            data.append({"type": "scatter", "mode": "lines", "xaxis": f"x{ax}", "yaxis": f"y{ax}",
                         "x": np.linspace(0.0, 100.0, m.size).tolist(),
                         "y": [None if not np.isfinite(v) else float(v) for v in m],
                         "name": t(f"knees.{side}", lang), "legendgroup": side, "showlegend": i == 0,
                         "line": {"color": "rgb({},{},{})".format(*rgb), "width": 2,
                                  "dash": "dash" if side == "right" else "solid"}})
    return {"data": data, "layout": layout}


def has_comparison(results: dict[str, Any]) -> bool:
    """True when ``results`` carries a comparison with an earlier analysis."""
    return isinstance(results.get("comparison"), dict) and bool(results["comparison"].get("rows"))


def _row_label(key: str, lang: str) -> str:
    group, name, stat = (key.split(".") + ["", ""])[:3]
    if group == "rom_deg":
        return f"{t(f'angle_{name}', lang)} · {t(f'col_{stat}', lang)}"
    if group == "phases":
        return f"{code_label('data.phase', name, lang)} (%)"
    if group == "gait":
        return t(f"compare.gait.{stat}", lang)
    if group == "symmetry":
        return f"LSI · {t(f'lsi.param.{name}', lang)} (%)"
    return key


def comparison_table(results: dict[str, Any], lang: str) -> tuple[str, str | None, list[list[str]]]:
    """``(note, mismatch warning or None, rows)`` of ``results["comparison"]``: rows start with the heading row
    (parameter, earlier, this session, change); numbers with their unit, the change signed."""
    c = results["comparison"]
    w = c.get("with") or {}
    note = t("compare.note", lang, date=w.get("date") or "—", filter=w.get("filter") or "—",
             version=w.get("pipeline_version") or "—")
    warning = None if c.get("comparable", True) else t(
        "compare.mismatch", lang, what=", ".join(t(f"compare.what.{m}", lang) for m in c.get("mismatch", [])))
    rows = [[t("compare.col.parameter", lang), f"{t('compare.col.earlier', lang)} ({w.get('date') or '—'})",
             t("compare.col.this", lang), t("compare.col.change", lang)]]
    for r in c["rows"]:
        unit = r["unit"] if r["unit"] in ("deg", "s", "steps_min") else "pct_plain"
        rows.append([_row_label(r["key"], lang), _plain(r.get("a"), unit, lang), _plain(r.get("b"), unit, lang),
                     _plain(r.get("change"), unit, lang, signed=True)])
    return note, warning, rows


def _plain(x: float | None, unit: str, lang: str, signed: bool = False) -> str:
    if x is None:
        return "—"
    text = fmt_number(x, DECIMALS.get(unit, 1), lang)
    text = f"+{text}" if signed and x > 0 else text
    return {"deg": f"{text}°", "s": f"{text} s", "steps_min": f"{text} {t('lsi.unit.steps_min', lang)}"}.get(unit, text)


__all__ = ["DECIMALS", "comparison_table", "has_comparison", "SIDE_COLOURS", "draw_knees_curves", "has_knees", "involved_text", "knees_figure", "lsi_rows"]
