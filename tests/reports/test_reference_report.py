"""The reference (results.json ``reference``, :mod:`estimators.motor_task.reference`) on the reports: the gait key
ranges as boxes on the flexion curve (PDF and HTML, same colour), the HTML table with each parameter's flag."""

from __future__ import annotations

import dataclasses
import subprocess

import numpy as np
import pytest
from PIL import Image

from estimators.motor_task import reference
from reports import figures
from reports.html import _REFERENCE_COLOUR, figure_specs, render_html
from reports.pdf import render_pdf

try:
    from test_excel import make_report_input
except ImportError:  # pragma: no cover - when tests are a package
    from tests.reports.test_excel import make_report_input


def _with_gait_reference(lang: str):
    ri = make_report_input(lang)
    values = {"loading_response_peak_flexion_deg": 17.0, "stance_min_flexion_deg": 1.0,  # absolute: never flagged
              "swing_peak_flexion_deg": 70.0, "flexion_rom_deg": 50.0, "stance_pct": 65.0}
    results = {**ri.results, "reference": reference.compare(reference.GAIT, values)}
    return dataclasses.replace(ri, results=results)


def test_html_draws_the_key_ranges_on_the_flexion_panel_and_flags_the_values_outside():
    ri = _with_gait_reference("en")
    shapes = [s for s in figure_specs(ri)["fig-curves"]["layout"]["shapes"] if s["type"] == "rect"]
    assert [(s["x0"], s["x1"], s["y0"], s["y1"]) for s in shapes] == [
        (k.pct_low, k.pct_high, k.low_deg, k.high_deg) for k in reference.GAIT.keypoints]
    assert all(s["xref"] == "x" and s["yref"] == "y" for s in shapes)  # the first panel: flexion
    page = render_html(ri)
    assert "Published normative reference" in page and "Perry" in page
    assert page.count('<tr class="outside">') == 2                     # ROM low, stance % high
    assert "below the reference" in page and "above the reference" in page
    assert "Valores de referencia" in render_html(_with_gait_reference("es"))
    assert "Valores de referência" in render_html(_with_gait_reference("pt"))


def test_no_reference_no_boxes_and_no_section():
    ri = make_report_input("en")
    assert not [s for s in figure_specs(ri)["fig-curves"]["layout"]["shapes"] if s["type"] == "rect"]
    assert "Reference values" not in render_html(ri)


@pytest.mark.skipif(subprocess.run(["which", "pdftoppm"], capture_output=True).returncode != 0,
                    reason="poppler's pdftoppm is not installed")
def test_pdf_draws_the_boxes_in_the_reference_colour(tmp_path):
    def orange_pixels(ri) -> int:
        pdf = tmp_path / "r.pdf"
        pdf.write_bytes(render_pdf(ri))
        for old in tmp_path.glob("p-*.png"):
            old.unlink()
        subprocess.run(["pdftoppm", "-r", "80", "-png", str(pdf), str(tmp_path / "p")], check=True)
        colour = np.array(figures._REFERENCE)
        return sum(int(np.sum(np.abs(np.asarray(Image.open(p).convert("RGB"), dtype=np.int32) - colour).sum(axis=2) < 40))
                   for p in tmp_path.glob("p-*.png"))

    assert orange_pixels(make_report_input("en")) == 0
    assert orange_pixels(_with_gait_reference("en")) > 100
    assert _REFERENCE_COLOUR.lower() == "#%02x%02x%02x" % figures._REFERENCE


def test_pdf_lists_the_reference_with_its_flags():
    pdf_text = subprocess.run(["pdftotext", "-layout", "-", "-"], input=render_pdf(_with_gait_reference("pt")),
                              capture_output=True, check=True).stdout.decode("utf-8")
    assert "Valores de referência" in pdf_text and "Referência normativa publicada" in pdf_text
    assert "abaixo da referência" in pdf_text and "acima da referência" in pdf_text
    no_ref = subprocess.run(["pdftotext", "-layout", "-", "-"], input=render_pdf(make_report_input("pt")),
                            capture_output=True, check=True).stdout.decode("utf-8")
    assert "Valores de referência" not in no_ref


def test_the_reference_texts_are_translated_and_the_english_is_the_modules():
    from reports import i18n

    for ref in (reference.GAIT, *reference.STEP_UP.values()):
        for field in ("population", "conditions", "transcription"):
            key = f"ref.{ref.id}.{field}"
            assert i18n.t(key, "en") == getattr(ref, field)
            assert i18n.t(key, "es") != getattr(ref, field) and i18n.t(key, "pt") != getattr(ref, field)
