"""The PDF report's figures, drawn as vectors with fpdf2's own drawing operations.

Why vectors: a matplotlib raster cost ~100 ms per figure (layout, Agg rendering, then fpdf2 deflating
1.3 million pixels), a third of the whole report; lines, filled polygons and text drawn straight into
the page cost a few milliseconds, print sharply at any zoom, and their labels are real text (searchable,
extracted by ``pdftotext``).  The price is that axes are laid out here by hand: a fixed grid of three
stacked panels sharing the x axis, "nice" ticks (1, 2, 2.5, 5 × 10ⁿ), the language's decimal mark.

Public entry points draw into an :class:`fpdf.FPDF` page inside a box ``(x, y, w, h)`` in mm:

* :func:`draw_curves` — mean ± SD over the normalised cycle of flexion-extension, adduction-abduction and
  internal-external rotation (the one order of every report and the UI), the mean phase boundaries dashed, the
  phase names on top;
* :func:`draw_task` — the three angles over the whole task, accepted cycles shaded and numbered,
  rejected ones hatched and numbered in red;
* :func:`draw_key_poses` — the bones at the key poses (:func:`reports.bones.key_poses`), ~7,000 shaded
  triangles, with the pose names and the knee flexion at each.

Long curves and the triangles go through :mod:`reports.vector` (one content-stream string per array).

Everything plotted comes from ``results`` (curves, phases, cycles) or the task's series; nothing
clinical is computed here.  Texts come from the translation tables (:mod:`reports.i18n`); the font is
whatever the document set up (the report's DejaVu Sans).  Drawing changes colours, line widths and dash
patterns inside :meth:`fpdf.FPDF.local_context`, so the page's state is left as it was found.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from reports.i18n import fmt_number, t
from reports.labels import code_label, phase_names, phase_spans_pct
from reports.model import ANGLES, ReportInput
from reports.vector import fill_triangles, stroke_polyline

#: the order angles are shown in: the one order of every report and of the UI (results.json ``angles``,
#: :data:`reports.model.ANGLES`; static/charts.js ``ANGLES``), issue 17 §3
ANGLE_ORDER: tuple[str, ...] = ANGLES

#: figure heights in mm for the full text width (180 mm on A4 with 15 mm margins)
CURVES_HEIGHT_MM = 132.0
TASK_HEIGHT_MM = 126.0

_PT = 25.4 / 72.0            # mm per point
_LINE = (31, 78, 121)
_BAND = (187, 216, 239)      # the mean line's colour, light (opaque: no transparency group needed)
_ACCEPTED_FILL = (228, 242, 233)
_ACCEPTED = (46, 139, 87)
_REJECTED = (192, 57, 43)
_PHASE_LINE = (85, 85, 85)
_REFERENCE = (214, 120, 0)     # the reference's key ranges (results["reference"]["keypoints"])
_GRID = (221, 221, 221)
_AXIS = (60, 60, 60)
_TEXT = (30, 30, 30)

_LEFT_MM = 17.0              # y tick labels and the rotated y label
_RIGHT_MM = 2.0
_TOP_FIRST_MM = 11.0         # title, legend and phase names / cycle numbers above the first panel
_TOP_MM = 5.5                # title above the other panels
_BOTTOM_MM = 10.0            # x tick labels and the x label
_GAP_MM = 4.5
_TICK_PT = 6.5
_LABEL_PT = 7.0
_TITLE_PT = 8.5


# ------------------------------------------------------------------------------------------- helpers
def phase_boundaries_pct(results: dict[str, Any]) -> list[float]:
    """Mean phase boundaries in % of the cycle: the ends of every phase of the session's task but the last
    (step-up: impulse, then impulse + extension; :func:`reports.labels.phase_spans_pct`).  A missing
    percentage ends the list early."""
    return [end for _, _, end in phase_spans_pct(results)[:len(phase_names(results)) - 1]]


def reference_keypoints(results: dict[str, Any]) -> list[dict[str, Any]]:
    """The reference's key ranges of the mean flexion curve (``results["reference"]["keypoints"]``: ``pct`` and
    ``deg`` pairs), or [] without a reference; the PDF and the HTML figure both draw them."""
    keys = (results.get("reference") or {}).get("keypoints") or []
    return [k for k in keys if len(k.get("pct") or ()) == 2 and len(k.get("deg") or ()) == 2]


def nice_ticks(lo: float, hi: float, target: int = 5, *, expand: bool = True) -> tuple[float, float, list[float]]:
    """Axis limits and ticks at 1, 2, 2.5 or 5 × 10ⁿ steps: the smallest step that makes at most about
    ``target`` intervals.

    ``expand=True`` widens ``[lo, hi]`` to the enclosing ticks (value axes); ``False`` keeps the limits
    and returns the ticks inside them (time axes).  Non-finite or empty ranges become ``[lo − 1, lo + 1]``
    (``[0, 1]`` if ``lo`` is not finite).  Returns ``(lo, hi, ticks)``.
    """
    if not (math.isfinite(lo) and math.isfinite(hi)):
        lo, hi = 0.0, 1.0
    if hi <= lo:
        lo, hi = lo - 1.0, hi + 1.0
    raw = (hi - lo) / max(target, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw * 0.999)
    first, last = math.floor(lo / step + 1e-9), math.ceil(hi / step - 1e-9)
    if expand:
        lo, hi = first * step, last * step
    else:
        first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    ticks = [k * step for k in range(first, last + 1)]
    return lo, hi, ticks


def _tick_decimals(ticks: Sequence[float]) -> int:
    """Fewest decimals that print every tick exactly (0 for integers, 1 for 2.5 steps...)."""
    for d in range(4):
        if all(abs(v * 10**d - round(v * 10**d)) < 1e-6 for v in ticks):
            return d
    return 4


def _finite_runs(*arrays: np.ndarray) -> list[slice]:
    """Slices of consecutive samples where every array is finite (a line is broken at NaN)."""
    ok = np.logical_and.reduce([np.isfinite(a) for a in arrays])
    if not ok.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate(([0], ok.view(np.int8), [0]))))
    return [slice(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2]) if b - a >= 2]


class _Panel:
    """One plot area: data → page coordinates, the frame, the grid and the tick labels."""

    def __init__(self, pdf: Any, x: float, y: float, w: float, h: float,
                 xlim: tuple[float, float], ylim: tuple[float, float]) -> None:
        self.pdf, self.x, self.y, self.w, self.h = pdf, x, y, w, h
        self.x0, self.x1 = xlim
        self.y0, self.y1 = ylim

    def px(self, v: Any) -> Any:
        return self.x + (np.asarray(v, dtype=np.float64) - self.x0) * (self.w / (self.x1 - self.x0))

    def py(self, v: Any) -> Any:
        return self.y + self.h - (np.asarray(v, dtype=np.float64) - self.y0) * (self.h / (self.y1 - self.y0))

    def grid(self, xticks: Sequence[float], yticks: Sequence[float]) -> None:
        pdf = self.pdf
        pdf.set_draw_color(*_GRID)
        pdf.set_line_width(0.1)
        for v in xticks:
            xx = float(self.px(v))
            pdf.line(xx, self.y, xx, self.y + self.h)
        for v in yticks:
            yy = float(self.py(v))
            pdf.line(self.x, yy, self.x + self.w, yy)

    def frame(self) -> None:
        """Left and bottom spines (top and right left open, as in the clinical figures of the thesis)."""
        pdf = self.pdf
        pdf.set_draw_color(*_AXIS)
        pdf.set_line_width(0.2)
        pdf.line(self.x, self.y, self.x, self.y + self.h)
        pdf.line(self.x, self.y + self.h, self.x + self.w, self.y + self.h)

    def y_labels(self, ticks: Sequence[float], lang: str, label: str) -> None:
        pdf = self.pdf
        d = _tick_decimals(ticks)
        pdf.set_font(size=_TICK_PT)
        pdf.set_text_color(*_TEXT)
        for v in ticks:
            s = fmt_number(v, d, lang)
            yy = float(self.py(v))
            pdf.line(self.x - 0.8, yy, self.x, yy)
            pdf.text(self.x - 1.3 - pdf.get_string_width(s), yy + 0.35 * _TICK_PT * _PT, s)
        pdf.set_font(size=_LABEL_PT)
        xc, yc = self.x - _LEFT_MM + 2.6, self.y + self.h / 2
        with pdf.rotation(90, xc, yc):
            pdf.text(xc - pdf.get_string_width(label) / 2, yc, label)

    def x_labels(self, ticks: Sequence[float], lang: str, label: str | None) -> None:
        pdf = self.pdf
        d = _tick_decimals(ticks)
        pdf.set_font(size=_TICK_PT)
        pdf.set_text_color(*_TEXT)
        yb = self.y + self.h
        for v in ticks:
            s = fmt_number(v, d, lang)
            xx = float(self.px(v))
            pdf.line(xx, yb, xx, yb + 0.8)
            pdf.text(xx - pdf.get_string_width(s) / 2, yb + 1.2 + _TICK_PT * _PT, s)
        if label:
            pdf.set_font(size=_LABEL_PT)
            pdf.text(self.x + self.w / 2 - pdf.get_string_width(label) / 2, yb + 8.5, label)

    def title(self, text: str, baseline_y: float | None = None) -> None:
        """The panel's title at its top left (``baseline_y`` raises it above what the first panel shows)."""
        pdf = self.pdf
        pdf.set_font(style="B", size=_TITLE_PT)
        pdf.set_text_color(*_TEXT)
        pdf.text(self.x, self.y - 1.6 if baseline_y is None else baseline_y, text)
        pdf.set_font(style="", size=_TICK_PT)

    def angle_axes(self, angle: str, k: int, xticks: Sequence[float], yticks: Sequence[float], lang: str,
                   top_y: float) -> None:
        """Frame, tick labels and title of the ``k``-th of the three angle panels over the cycle (the last one
        names the x axis; the first's title is raised above the legend, to ``top_y + 3.4`` mm)."""
        self.frame()
        self.y_labels(yticks, lang, t(f"axis_{angle}", lang))
        self.x_labels(xticks, lang, t("fig_cycle_pct", lang) if k == 2 else None)
        self.title(t(f"angle_{angle}", lang), top_y + 3.4 if k == 0 else None)

    def line(self, xs: np.ndarray, ys: np.ndarray, rgb: tuple[int, int, int], width_mm: float) -> None:
        """A polyline, broken where a value is missing."""
        pdf = self.pdf
        pdf.set_draw_color(*rgb)
        pdf.set_line_width(width_mm)
        px, py = self.px(xs), self.py(ys)
        for run in _finite_runs(px, py):
            stroke_polyline(pdf, px[run], py[run])

    def band(self, xs: np.ndarray, lo: np.ndarray, hi: np.ndarray, rgb: tuple[int, int, int]) -> None:
        """The filled area between ``lo`` and ``hi`` (one polygon per run of finite values)."""
        pdf = self.pdf
        pdf.set_fill_color(*rgb)
        px, plo, phi = self.px(xs), self.py(lo), self.py(hi)
        for run in _finite_runs(plo, phi):
            pts = list(zip(px[run].tolist(), phi[run].tolist())) + list(zip(px[run][::-1].tolist(),
                                                                            plo[run][::-1].tolist()))
            pdf.polygon(pts, style="F")


def _legend(pdf: Any, right_x: float, y: float, items: Sequence[tuple[str, Any]]) -> None:
    """A one-line legend ending at ``right_x``; items are ``(label, draw_swatch(x, y, w, h))``."""
    pdf.set_font(size=_TICK_PT)
    pdf.set_text_color(*_TEXT)
    sw, gap = 4.0, 1.2
    widths = [sw + gap + pdf.get_string_width(label) + 3.0 for label, _ in items]
    x = right_x - sum(widths) + 3.0
    for (label, swatch), w in zip(items, widths):
        swatch(x, y - 1.6, sw, 1.8)
        pdf.text(x + sw + gap, y, label)
        x += w


def _layout(x: float, y: float, w: float, h: float, n: int = 3) -> list[tuple[float, float, float, float]]:
    """Boxes of ``n`` stacked panels inside the figure box (titles above each, x labels below the last)."""
    inner = h - _TOP_FIRST_MM - _BOTTOM_MM - (n - 1) * (_TOP_MM + _GAP_MM)
    ph = inner / n
    boxes, yy = [], y + _TOP_FIRST_MM
    for _ in range(n):
        boxes.append((x + _LEFT_MM, yy, w - _LEFT_MM - _RIGHT_MM, ph))
        yy += ph + _TOP_MM + _GAP_MM
    return boxes


def _curve(curves: dict[str, Any], angle: str, key: str) -> np.ndarray:
    values = (curves.get(angle) or {}).get(key) or []
    return np.asarray([np.nan if v is None else v for v in values], dtype=np.float64)


# ------------------------------------------------------------------------------------------- figures
def draw_curves(pdf: Any, ri: ReportInput, x: float, y: float, w: float, h: float = CURVES_HEIGHT_MM) -> None:
    """Mean ± SD over the normalised cycle (0–100 %) of the three angles in the box ``(x, y, w, h)`` mm,
    the mean phase boundaries (:func:`phase_boundaries_pct`) dashed and the phase names above."""
    lang = ri.language
    curves = ri.results.get("curves") or {}
    bounds = phase_boundaries_pct(ri.results)
    _, _, xticks = nice_ticks(0.0, 100.0, 10, expand=False)
    with pdf.local_context():
        for k, (box, angle) in enumerate(zip(_layout(x, y, w, h), ANGLE_ORDER)):
            mean, sd = _curve(curves, angle, "mean"), _curve(curves, angle, "sd")
            has_sd = sd.size == mean.size
            lo_hi = np.concatenate([mean - sd, mean + sd]) if has_sd else mean
            finite = lo_hi[np.isfinite(lo_hi)] if lo_hi.size else lo_hi
            if finite.size == 0 and mean.size:
                finite = mean[np.isfinite(mean)]
            lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (math.nan, math.nan)
            keys = reference_keypoints(ri.results) if angle == "flexion" else []
            if keys and finite.size:
                lo, hi = min([lo] + [kp["deg"][0] for kp in keys]), max([hi] + [kp["deg"][1] for kp in keys])
            y0, y1, yticks = nice_ticks(lo, hi, 4)
            panel = _Panel(pdf, *box, (0.0, 100.0), (y0, y1))
            panel.grid(xticks, yticks)
            if mean.size:
                xs = np.linspace(0.0, 100.0, mean.size)
                if has_sd:
                    panel.band(xs, mean - sd, mean + sd, _BAND)
                panel.line(xs, mean, _LINE, 0.45)
            pdf.set_draw_color(*_REFERENCE)
            pdf.set_line_width(0.35)
            for kp in keys:  # the reference's range of the mean at its place in the cycle: an open box
                (a, b), (c, d) = kp["pct"], kp["deg"]
                pdf.rect(float(panel.px(a)), float(panel.py(d)), float(panel.px(b) - panel.px(a)),
                         float(panel.py(c) - panel.py(d)), style="D")
            pdf.set_draw_color(*_PHASE_LINE)
            pdf.set_line_width(0.25)
            pdf.set_dash_pattern(1.2, 0.8)
            for b in bounds:
                bx = float(panel.px(b))
                pdf.line(bx, panel.y, bx, panel.y + panel.h)
            pdf.set_dash_pattern()
            panel.angle_axes(angle, k, xticks, yticks, lang, y)
            if k == 0:
                pdf.set_font(size=_TICK_PT)
                pdf.set_text_color(*_PHASE_LINE)
                names = phase_names(ri.results)
                if len(bounds) == len(names) - 1:
                    edges = [0.0, *bounds, 100.0]
                    for name, a, b in zip(names, edges[:-1], edges[1:]):
                        text = code_label("data.phase", name, lang)
                        pdf.text(float(panel.px((a + b) / 2)) - pdf.get_string_width(text) / 2, panel.y - 0.8, text)

                def band_swatch(sx: float, sy: float, sw: float, sh: float) -> None:
                    pdf.set_fill_color(*_BAND)
                    pdf.rect(sx, sy, sw, sh, style="F")

                def line_swatch(sx: float, sy: float, sw: float, sh: float) -> None:
                    pdf.set_draw_color(*_LINE)
                    pdf.set_line_width(0.45)
                    pdf.line(sx, sy + sh / 2, sx + sw, sy + sh / 2)

                def reference_swatch(sx: float, sy: float, sw: float, sh: float) -> None:
                    pdf.set_draw_color(*_REFERENCE)
                    pdf.set_line_width(0.35)
                    pdf.rect(sx, sy, sw, sh, style="D")

                items = [(t("fig_sd", lang), band_swatch), (t("fig_mean", lang), line_swatch)]
                if keys:
                    items.append((t("fig_reference", lang), reference_swatch))
                _legend(pdf, panel.x + panel.w, y + 3.2, items)


def _cycle_spans(ri: ReportInput) -> list[tuple[int, float, float, bool]]:
    """``(index, start_s, end_s, accepted)`` per detected cycle; unknown ends at the recording's ends."""
    if len(ri.t_s) == 0:
        return []
    t0, t1 = float(ri.t_s[0]), float(ri.t_s[-1])
    return [(i, t0 if a is None else float(a), t1 if b is None else float(b), ok)
            for i, (a, b, ok) in enumerate(ri.cycle_bounds_s())]


def _hatch(pdf: Any, x: float, y: float, w: float, h: float, spacing_mm: float = 1.6) -> None:
    """Diagonal hatching of the rectangle (lines clipped to it; colour and width as currently set)."""
    if w <= 0 or h <= 0:
        return
    with pdf.rect_clip(x, y, w, h):
        c = -h
        while c < w:
            pdf.line(x + c, y + h, x + c + h, y)
            c += spacing_mm


def draw_task(pdf: Any, ri: ReportInput, x: float, y: float, w: float, h: float = TASK_HEIGHT_MM) -> None:
    """The three angles over the whole task in the box ``(x, y, w, h)`` mm; accepted cycles shaded green
    and numbered, rejected ones hatched and numbered in bold red, cycle starts as thin grey lines."""
    lang = ri.language
    t_s = np.asarray(ri.t_s, dtype=np.float64)
    spans = _cycle_spans(ri)
    if len(t_s):
        xlim = (float(t_s[0]), float(t_s[-1]) if t_s[-1] > t_s[0] else float(t_s[0]) + 1.0)
    else:
        xlim = (0.0, 1.0)
    _, _, xticks = nice_ticks(*xlim, 10, expand=False)
    with pdf.local_context():
        for k, (box, angle) in enumerate(zip(_layout(x, y, w, h), ANGLE_ORDER)):
            values = ri.angles_deg[:, ANGLES.index(angle)] if len(t_s) else np.zeros(0)
            finite = values[np.isfinite(values)]
            lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (math.nan, math.nan)
            keys = reference_keypoints(ri.results) if angle == "flexion" else []
            if keys and finite.size:
                lo, hi = min([lo] + [kp["deg"][0] for kp in keys]), max([hi] + [kp["deg"][1] for kp in keys])
            y0, y1, yticks = nice_ticks(lo, hi, 4)
            panel = _Panel(pdf, *box, xlim, (y0, y1))
            for _, a, b, ok in spans:
                xa, xb = float(panel.px(max(a, xlim[0]))), float(panel.px(min(b, xlim[1])))
                if ok:
                    pdf.set_fill_color(*_ACCEPTED_FILL)
                    pdf.rect(xa, panel.y, xb - xa, panel.h, style="F")
            pdf.set_draw_color(*_REJECTED)
            pdf.set_line_width(0.15)
            for _, a, b, ok in spans:
                if not ok:
                    xa, xb = float(panel.px(max(a, xlim[0]))), float(panel.px(min(b, xlim[1])))
                    _hatch(pdf, xa, panel.y, xb - xa, panel.h)
            panel.grid(xticks, yticks)
            pdf.set_draw_color(153, 153, 153)
            pdf.set_line_width(0.12)
            for _, a, _, _ in spans:
                xa = float(panel.px(a))
                pdf.line(xa, panel.y, xa, panel.y + panel.h)
            if len(t_s):
                panel.line(t_s, values, _LINE, 0.25)
            panel.frame()
            panel.y_labels(yticks, lang, t(f"axis_{angle}", lang))
            panel.x_labels(xticks, lang, t("fig_time_s", lang) if k == 2 else None)
            panel.title(t(f"angle_{angle}", lang), y + 3.4 if k == 0 else None)
            if k == 0:
                for i, a, b, ok in spans:
                    label = str(i + 1)
                    pdf.set_font(style="" if ok else "B", size=_TICK_PT)
                    pdf.set_text_color(*(_ACCEPTED if ok else _REJECTED))
                    xc = float(panel.px((max(a, xlim[0]) + min(b, xlim[1])) / 2))
                    pdf.text(xc - pdf.get_string_width(label) / 2, panel.y - 0.8, label)
                pdf.set_font(style="", size=_TICK_PT)

                def accepted_swatch(sx: float, sy: float, sw: float, sh: float) -> None:
                    pdf.set_fill_color(*_ACCEPTED_FILL)
                    pdf.set_draw_color(*_ACCEPTED)
                    pdf.set_line_width(0.1)
                    pdf.rect(sx, sy, sw, sh, style="DF")

                def rejected_swatch(sx: float, sy: float, sw: float, sh: float) -> None:
                    pdf.set_draw_color(*_REJECTED)
                    pdf.set_line_width(0.15)
                    _hatch(pdf, sx, sy, sw, sh, spacing_mm=0.9)
                    pdf.rect(sx, sy, sw, sh, style="D")

                _legend(pdf, panel.x + panel.w, y + 3.2, [(t("fig_accepted", lang), accepted_swatch),
                                                          (t("fig_rejected", lang), rejected_swatch)])


def draw_key_poses(pdf: Any, kp: Any, titles: Sequence[str], lang: str, x: float, y: float, w: float,
                   h: float) -> None:
    """The key-pose still (:class:`reports.bones.KeyPoses`) centred in the box ``(x, y, w, h)`` mm at equal
    scale: shaded bones, the floor line, ``titles`` above each pose and its knee flexion (°) below."""
    vx0, vx1, vy0, vy1 = kp.view
    scale = min(w / (vx1 - vx0), h / (vy1 - vy0))
    x0 = x + (w - scale * (vx1 - vx0)) / 2
    px = lambda v: x0 + (np.asarray(v) - vx0) * scale  # noqa: E731
    py = lambda v: y + (vy1 - np.asarray(v)) * scale   # noqa: E731
    with pdf.local_context():
        fill_triangles(pdf, np.stack([px(kp.triangles[..., 0]), py(kp.triangles[..., 1])], axis=-1), kp.rgb)
        gx0, gx1, gy = kp.ground
        pdf.set_draw_color(153, 153, 153)
        pdf.set_line_width(0.3)
        pdf.line(float(px(gx0)), float(py(gy)), float(px(gx1)), float(py(gy)))
        pdf.set_font(size=9)
        pdf.set_text_color(0, 0, 0)
        for xc, title, flexion in zip(kp.centres_x, titles, kp.flexion_deg):
            angle = f"{fmt_number(flexion, 0, lang)}°"
            xm = float(px(xc))
            pdf.text(xm - pdf.get_string_width(title) / 2, float(py(1.04 * kp.height_m)) - 1.0, title)
            pdf.text(xm - pdf.get_string_width(angle) / 2, float(py(-0.07 * kp.height_m)) + 2.5, angle)
