"""The report's figures as PNG bytes (matplotlib, Agg canvas, in memory, deterministic).

Figures are drawn on :class:`matplotlib.figure.Figure` objects attached to an explicit
:class:`~matplotlib.backends.backend_agg.FigureCanvasAgg`: no ``pyplot``, no global backend switch and
no global state, so rendering works the same whether or not an application already chose a matplotlib
backend, from any thread.  Fonts are matplotlib's own DejaVu Sans (no download); PNG metadata carries
no timestamp, so the same input gives the same bytes.

Everything plotted comes from ``results`` (curves, phases, cycles) or the task's series; nothing
clinical is computed here.  Tick labels use the language's decimal mark (:mod:`reports.i18n`).
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import ScalarFormatter
from PIL import Image

from reports.i18n import t
from reports.model import ANGLES, ReportInput

#: the order angles are shown in (clinical reading order), with their column in ``angles_deg``
ANGLE_ORDER: tuple[str, ...] = ("flexion", "internal_rotation", "adduction")
PHASES: tuple[str, ...] = ("impulse", "extension", "fall")
DPI = 150

_LINE = "#1f4e79"
_BAND = "#9dc3e6"
_ACCEPTED = "#2e8b57"
_REJECTED = "#c0392b"
_PHASE_LINE = "#555555"


class _DecimalFormatter(ScalarFormatter):
    """Matplotlib's tick labels with the language's decimal mark."""

    def __init__(self, mark: str) -> None:
        super().__init__(useOffset=False)
        self._mark = mark

    def __call__(self, x: float, pos: int | None = None) -> str:
        s = super().__call__(x, pos)
        return s.replace(".", self._mark) if self._mark != "." else s


def _decimal_mark(lang: str) -> str:
    return "." if lang == "en" else ","


def _new_figure(width_in: float, height_in: float, top: float) -> Figure:
    """A figure on its own Agg canvas; fixed margins (a layout engine would double the drawing time)."""
    fig = Figure(figsize=(width_in, height_in), dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.095, right=0.985, bottom=0.075, top=top, hspace=0.42)
    return fig


def to_png(fig: Figure) -> bytes:
    """PNG bytes of ``fig`` (no timestamp or software metadata: deterministic)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    return buf.getvalue()


def to_image(fig: Figure) -> Image.Image:
    """``fig`` drawn by Agg as an RGB :class:`PIL.Image.Image` (the same pixels as :func:`to_png`).

    The PDF embeds this directly: fpdf2 re-compresses every raster image itself, so going through PNG
    would only add an encode and a decode (~30 ms per figure).
    """
    fig.canvas.draw()
    return Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy(), mode="RGB")


def _style_axes(ax: Any, lang: str) -> None:
    mark = _decimal_mark(lang)
    ax.xaxis.set_major_formatter(_DecimalFormatter(mark))
    ax.yaxis.set_major_formatter(_DecimalFormatter(mark))
    ax.grid(True, color="#dddddd", linewidth=0.5)
    ax.tick_params(labelsize=7)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)


def _title(ax: Any, text: str, raised: bool) -> None:
    """A panel title at the top left (a plain text: ``set_title`` would re-measure the tick labels
    on every draw to avoid them, a third of the drawing time here)."""
    ax.text(0.0, 1.13 if raised else 1.03, text, transform=ax.transAxes, ha="left", va="bottom", fontsize=9)


def phase_boundaries_pct(results: dict[str, Any]) -> list[float]:
    """Mean phase boundaries in % of the cycle: cumulative mean % of impulse, then of extension.

    Read from ``results["phases"][phase]["mean_pct"]``; a missing percentage ends the list early.
    """
    phases = results.get("phases") or {}
    out: list[float] = []
    acc = 0.0
    for name in PHASES[:-1]:
        pct = (phases.get(name) or {}).get("mean_pct")
        if pct is None or not np.isfinite(pct):
            break
        acc += float(pct)
        out.append(acc)
    return out


def curves_png(ri: ReportInput) -> bytes:
    """:func:`curves_figure` as PNG bytes."""
    return to_png(curves_figure(ri))


def task_png(ri: ReportInput) -> bytes:
    """:func:`task_figure` as PNG bytes."""
    return to_png(task_figure(ri))


def curves_figure(ri: ReportInput) -> Figure:
    """Mean ± SD over the normalised cycle of flexion-extension, internal-external rotation and
    abduction-adduction, with the mean phase boundaries as vertical lines and the phase names on top."""
    lang = ri.language
    curves = ri.results.get("curves") or {}
    bounds = phase_boundaries_pct(ri.results)
    fig = _new_figure(7.0, 5.6, top=0.93)
    axes = fig.subplots(3, 1, sharex=True)
    for k, (ax, angle) in enumerate(zip(axes, ANGLE_ORDER)):
        c = curves.get(angle) or {}
        mean = np.asarray([np.nan if v is None else v for v in c.get("mean", [])], dtype=np.float64)
        sd = np.asarray([np.nan if v is None else v for v in c.get("sd", [])], dtype=np.float64)
        _style_axes(ax, lang)
        if mean.size:
            x = np.linspace(0.0, 100.0, mean.size)
            if sd.size == mean.size:
                ax.fill_between(x, mean - sd, mean + sd, color=_BAND, alpha=0.7, linewidth=0,
                                label=t("fig_sd", lang))
            ax.plot(x, mean, color=_LINE, linewidth=1.4, label=t("fig_mean", lang))
        for b in bounds:
            ax.axvline(b, color=_PHASE_LINE, linestyle="--", linewidth=0.8)
        _title(ax, t(f"angle_{angle}", lang), raised=k == 0)
        ax.set_ylabel(t(f"axis_{angle}", lang), fontsize=8)
        ax.set_xlim(0.0, 100.0)
        if k == 0:
            edges = [0.0, *bounds, 100.0] if len(bounds) == 2 else []
            for name, lo, hi in zip(PHASES, edges[:-1], edges[1:]):
                ax.text((lo + hi) / 2, 1.01, t(f"phase_{name}", lang), transform=ax.get_xaxis_transform(),
                        ha="center", va="bottom", fontsize=7, color=_PHASE_LINE)
            ax.legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.1), ncol=2, frameon=False,
                      borderaxespad=0.0)
    axes[-1].set_xlabel(t("fig_cycle_pct", lang), fontsize=8)
    return fig


def _cycle_spans(ri: ReportInput) -> list[tuple[int, float, float, bool]]:
    """``(index, start_s, end_s, accepted)`` per detected cycle; unknown ends at the recording's ends."""
    if len(ri.t_s) == 0:
        return []
    t0, t1 = float(ri.t_s[0]), float(ri.t_s[-1])
    return [(i, t0 if a is None else float(a), t1 if b is None else float(b), ok)
            for i, (a, b, ok) in enumerate(ri.cycle_bounds_s())]


def task_figure(ri: ReportInput) -> Figure:
    """The three angles over the whole task; accepted cycles shaded and numbered, rejected ones hatched."""
    lang = ri.language
    fig = _new_figure(7.0, 5.4, top=0.92)
    axes = fig.subplots(3, 1, sharex=True)
    spans = _cycle_spans(ri)
    accepted = [(a, b - a) for _, a, b, ok in spans if ok]
    rejected = [(a, b - a) for _, a, b, ok in spans if not ok]
    for k, (ax, angle) in enumerate(zip(axes, ANGLE_ORDER)):
        _style_axes(ax, lang)
        band = ax.get_xaxis_transform()  # x in seconds, y from the bottom (0) to the top (1) of the panel
        # one collection per kind (not one artist per cycle: drawing time grows with the artist count)
        if accepted:
            ax.broken_barh(accepted, (0.0, 1.0), transform=band, facecolor=_ACCEPTED, alpha=0.12, linewidth=0)
        if rejected:
            ax.broken_barh(rejected, (0.0, 1.0), transform=band, facecolor="none", edgecolor=_REJECTED,
                           hatch="///", alpha=0.6, linewidth=0)
        if spans:
            ax.vlines([a for _, a, _, _ in spans], 0.0, 1.0, transform=band, color="#999999", linewidth=0.5)
        if k == 0:
            for i, a, b, ok in spans:
                ax.text((a + b) / 2, 1.02, str(i + 1), transform=band, ha="center", va="bottom", fontsize=7,
                        color=_ACCEPTED if ok else _REJECTED, fontweight="normal" if ok else "bold")
        ax.plot(ri.t_s, ri.angles_deg[:, ANGLES.index(angle)], color=_LINE, linewidth=0.7)
        _title(ax, t(f"angle_{angle}", lang), raised=k == 0)
        ax.set_ylabel(t(f"axis_{angle}", lang), fontsize=8)
        if len(ri.t_s):
            ax.set_xlim(float(ri.t_s[0]), float(ri.t_s[-1]))
    handles = [Patch(facecolor=_ACCEPTED, alpha=0.25, label=t("fig_accepted", lang)),
               Patch(facecolor="none", edgecolor=_REJECTED, hatch="///", label=t("fig_rejected", lang))]
    axes[0].legend(handles=handles, fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.1), ncol=2,
                   frameon=False, borderaxespad=0.0)
    axes[-1].set_xlabel(t("fig_time_s", lang), fontsize=8)
    return fig
