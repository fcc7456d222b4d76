"""Fast vector drawing into an fpdf2 page: long polylines and thousands of shaded triangles.

fpdf2's shape methods (:meth:`fpdf.FPDF.polyline`, :meth:`fpdf.FPDF.polygon`) append one content-stream
line per point through ``FPDF._out``; for the task figure's 5,000-sample curves and the key-pose still's
~7,000 triangles that costs tens of milliseconds.  These functions format the same PDF operators (``m``,
``l``, ``S``, ``rg``, ``RG``, ``b``) for a whole array in one string and append it with one ``_out`` call,
the call fpdf2's own shapes use (the one private fpdf2 name the reports rely on; checked by the PDF tests,
which render and read every page).  Coordinates are page millimetres, top-left origin, as everywhere in
fpdf2; numbers are rounded to 0.01 pt.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["stroke_polyline", "fill_triangles"]


def _page_xy(pdf: Any, x_mm: Any, y_mm: Any) -> np.ndarray:
    """PDF user-space points (origin bottom left) of page millimetres (origin top left)."""
    x = np.asarray(x_mm, dtype=np.float64)
    y = np.asarray(y_mm, dtype=np.float64)
    return np.stack([x * pdf.k, (pdf.h - y) * pdf.k], axis=-1)


def stroke_polyline(pdf: Any, x_mm: Any, y_mm: Any) -> None:
    """Stroke the polyline through the points ``(x_mm[i], y_mm[i])`` in the current colour and line width
    (what :meth:`fpdf.FPDF.polyline` draws).  Fewer than two points draw nothing."""
    n = len(x_mm)
    if n < 2:
        return
    vals = np.round(_page_xy(pdf, x_mm, y_mm), 2).ravel().tolist()
    pdf._out("%.2f %.2f m\n" % (vals[0], vals[1]) + ("%.2f %.2f l\n" * (n - 1)) % tuple(vals[2:]) + "S")


def fill_triangles(pdf: Any, tri_mm: Any, rgb: Any, *, seam_pt: float = 0.2) -> None:
    """Fill triangles ``tri_mm`` (T, 3, 2) in page mm, each in its colour ``rgb`` (T, 3) in 0..1, in order
    (painter's algorithm: pass them far to near).

    Each triangle is also stroked in its own colour with a ``seam_pt`` line (round joins) so that
    anti-aliasing leaves no light seams between neighbours.  The block is wrapped in ``q``/``Q``, so fpdf2's
    current colours and line width stay what it believes they are.
    """
    tri = np.asarray(tri_mm, dtype=np.float64)
    n = len(tri)
    if n == 0:
        return
    xy = np.round(_page_xy(pdf, tri[..., 0], tri[..., 1]).reshape(n, 6), 2)
    c = np.round(np.clip(np.asarray(rgb, dtype=np.float64), 0.0, 1.0), 3)
    values = np.column_stack([c, c, xy])
    body = ("%g %g %g rg %g %g %g RG %g %g m %g %g l %g %g l b\n" * n) % tuple(values.ravel().tolist())
    pdf._out(f"q {seam_pt:g} w 1 j\n" + body + "Q")
