"""The clinical PDF report's page: A4 with 15 mm margins, the embedded DejaVu Sans, header and footer on
every page, and the text blocks the report is made of (section headings, paragraphs, ``label: text``
lines, tables) — :mod:`reports.pdf` fills it with the session's content.

Every text is literal: what people typed goes through :func:`user_text` (control characters removed, never
interpreted as markup), tables and cells print their text as is.  Page totals are written after the
content (:meth:`ReportPDF.draw_page_chrome`, no ``{nb}`` alias), so no user text is ever substituted.
Numbers are printed with :data:`DECIMALS` places of their kind and the language's decimal mark.
"""

from __future__ import annotations

import re
from typing import Any

from fpdf import FPDF, FontFace
from fpdf.enums import TableBordersLayout, XPos, YPos

from reports import fonts
from reports.i18n import fmt_number, t

__all__ = ["ReportPDF", "user_text", "DECIMALS", "FONT", "ACCENT", "GREY"]

FONT = "dejavu"

MARGIN_MM = 15.0
HEADER_BOTTOM_MM = 29.5     # content starts below the header rule and the patient's identity (up to two lines)
FOOTER_TOP_MM = 282.0       # the footer line sits here (A4 is 297 mm high)
ACCENT = (31, 78, 121)     # headings and rules
GREY = (90, 90, 90)

#: decimals printed for each kind of number (the golden tests read these too)
DECIMALS = {"time_s": 2, "pct": 1, "deg": 1, "field_ut": 1, "coverage_pct": 0, "residual_pct": 1,
            "disturbance_pct": 1, "weight_kg": 1, "height_m": 2}
_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


def user_text(value: Any) -> str:
    """What a person typed, as printable text: str() of it, CR/LF normalised, tabs to spaces, other
    control characters removed.  Never interpreted (no markdown, no HTML, no templates)."""
    if value is None:
        return ""
    s = str(value).replace("\r\n", "\n").replace("\r", "\n").replace("\t", " ")
    return _CONTROL.sub("", s).strip()


class ReportPDF(FPDF):
    """FPDF with the report's font and helpers; header/footer are drawn at the end on every page."""

    def __init__(self, lang: str, *, full_font: bool = False) -> None:
        super().__init__(orientation="P", unit="mm", format="A4")
        self.lang = lang
        self.alias_nb_pages(None)  # page totals are written after the content: user text is never substituted
        for style, path in fonts.font_files(full=full_font).items():
            self.add_font(FONT, style, str(path))
        self.set_margins(MARGIN_MM, HEADER_BOTTOM_MM, MARGIN_MM)
        self.set_auto_page_break(True, margin=297.0 - FOOTER_TOP_MM + 3.0)
        self.set_font(FONT, "", 9.5)

    def tr(self, key: str, **fields: Any) -> str:
        return t(key, self.lang, **fields)

    def num(self, x: Any, kind: str) -> str:
        return fmt_number(x, DECIMALS[kind], self.lang)

    def ensure_space(self, height_mm: float) -> None:
        """A new page unless ``height_mm`` fits above the footer."""
        if self.get_y() + height_mm > self.page_break_trigger:
            self.add_page()

    def section(self, key: str, space_after_mm: float = 14.0) -> None:
        """A section heading (kept with at least ``space_after_mm`` of what follows)."""
        self.ensure_space(10.0 + space_after_mm)
        self.ln(3.0)
        self.set_font(FONT, "B", 11.5)
        self.set_text_color(*ACCENT)
        self.cell(0, 6.5, self.tr(key), new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.set_draw_color(*ACCENT)
        self.set_line_width(0.3)
        self.line(self.l_margin, self.get_y(), self.w - self.r_margin, self.get_y())
        self.ln(1.8)
        self.set_text_color(0, 0, 0)
        self.set_font(FONT, "", 9.5)

    def paragraph(self, text: str, size: float = 9.5, style: str = "", color=(0, 0, 0)) -> None:
        self.set_font(FONT, style, size)
        self.set_text_color(*color)
        self.multi_cell(0, size * 0.48, text, align="L", new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.set_text_color(0, 0, 0)
        self.set_font(FONT, "", 9.5)

    def labelled(self, label: str, text: str) -> None:
        """``label: text`` with the label in bold, wrapped to the page width."""
        self.set_font(FONT, "B", 9.5)
        self.write(4.6, label + ": ")
        self.set_font(FONT, "", 9.5)
        self.write(4.6, text)
        self.ln(5.2)

    def grid(self, rows: list[list[str]], col_widths: tuple[float, ...], *, headings: bool = True,
             align: tuple[str, ...] | None = None, bold_cols: tuple[int, ...] = ()) -> None:
        """A table; every cell is literal text (fpdf2 tables do not interpret markup by default)."""
        self.set_font(FONT, "", 9)
        head = FontFace(emphasis="BOLD", color=(255, 255, 255), fill_color=ACCENT)
        with self.table(col_widths=col_widths, text_align=align or "LEFT", line_height=5.2,
                        first_row_as_headings=headings, headings_style=head, padding=(0.8, 1.5),
                        borders_layout=TableBordersLayout.HORIZONTAL_LINES, align="LEFT",
                        width=self.epw) as table:
            for r, row in enumerate(rows):
                tr = table.row()
                for c, text in enumerate(row):
                    style = FontFace(emphasis="BOLD") if c in bold_cols and (r or not headings) else None
                    tr.cell(text, style=style)
        self.ln(1.5)

    def fit(self, text: str, width_mm: float) -> str:
        """``text`` cut with an ellipsis so that it fits ``width_mm`` on one line in the current font."""
        if self.get_string_width(text) <= width_mm:
            return text
        while text and self.get_string_width(text + "…") > width_mm:
            text = text[:-1]
        return text + "…"

    def two_lines(self, text: str) -> str:
        """``text`` as :meth:`multi_cell` wraps it over the page's width, cut with an ellipsis at the end of the
        second line when it needs more (the header's identity above :data:`HEADER_BOTTOM_MM`, however long the
        clinic's name: never over the page's content)."""
        lines = self.multi_cell(self.epw, 3.4, text, dry_run=True, output="LINES")
        if len(lines) <= 2:
            return text
        rest = " ".join(line.strip() for line in lines[1:])
        return lines[0].rstrip() + " " + self.fit(rest, self.epw - 2.0)

    def draw_page_chrome(self, version: str, date_text: str, patient: str, identity: str = "") -> None:
        """Header and footer on every page (after the content, so the page total is known).  ``identity`` (the
        patient's record number with its system, birth date and age, sex, clinic, the recordings' date:
        :func:`reports.labels.identity_line`) is printed under the header's rule of every page, in a smaller
        size when it is long, so each printed page says whose it is."""
        total = self.pages_count
        self.set_auto_page_break(False)
        for p in range(1, total + 1):
            self.page = p
            # header
            self.set_xy(self.l_margin, 10.0)
            self.set_font(FONT, "B", 13)
            self.set_text_color(*ACCENT)
            product = self.tr("product")
            self.cell(self.get_string_width(product) + 2.0, 7, product)
            self.set_font(FONT, "", 10)
            self.set_text_color(*GREY)
            self.cell(0, 7, self.tr("report_title"))
            self.set_xy(self.l_margin, 10.0)
            self.set_font(FONT, "", 8)
            self.cell(0, 3.5, self.tr("header_version", version=version), align="R")
            self.set_xy(self.l_margin, 13.8)
            self.cell(0, 3.5, self.tr("header_date", date=date_text), align="R")
            self.set_draw_color(*ACCENT)
            self.set_line_width(0.5)
            self.line(self.l_margin, 19.0, self.w - self.r_margin, 19.0)
            if identity:
                self.set_text_color(0, 0, 0)
                size = 7.5
                self.set_font(FONT, "", size)
                while size > 6.0 and len(self.multi_cell(self.epw, 3.4, identity, dry_run=True,
                                                          output="LINES")) > 2:
                    size -= 0.5
                    self.set_font(FONT, "", size)
                identity = self.two_lines(identity)
                self.set_xy(self.l_margin, 19.8)
                self.multi_cell(self.epw, 3.4, identity, align="L", max_line_height=3.4)
                self.set_text_color(*GREY)
            # footer
            self.set_line_width(0.2)
            self.set_draw_color(*GREY)
            self.line(self.l_margin, FOOTER_TOP_MM, self.w - self.r_margin, FOOTER_TOP_MM)
            self.set_xy(self.l_margin, FOOTER_TOP_MM + 1.5)
            self.set_font(FONT, "", 8)
            if patient:
                self.cell(self.epw * 0.7, 4, self.fit(self.tr("footer_patient", patient=patient), self.epw * 0.7))
            self.set_xy(self.l_margin, FOOTER_TOP_MM + 1.5)
            self.cell(0, 4, self.tr("page_number", page=p, pages=total), align="R")
        self.set_text_color(0, 0, 0)
