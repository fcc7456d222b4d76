"""The report's method lines (issue 17 §3): the sensor-to-segment calibration asked for (results.json
``calibration_method``: static or functional) and the one used (``calibration.protocol.segment``: a session without a
supine recording is calibrated on the task even when static was asked for), and the knee-angle convention
(``angle_method``) with its signs, printed in the PDF's protocol section and the HTML's quality section in es/en/pt.

Read back as a reader sees them: the PDF's pages through poppler (tests/pdf_pages.py), the HTML's text unescaped.
The demo session's real results.json (processed by the pipeline) is checked too, and its quality section names the
thigh–shank heading the angles used (``quality.heading``)."""

from __future__ import annotations

import html as _html
import re
import shutil
from dataclasses import replace

import pytest
from pdf_pages import pdf_pages
from test_pdf import _synthetic_ri, demo_ri  # noqa: F401

from reports.html import render_html
from reports.i18n import LANGUAGES, t
from reports.labels import heading_sentence
from reports.pdf import render_pdf

needs_poppler = pytest.mark.skipif(shutil.which("pdftotext") is None or shutil.which("pdfinfo") is None,
                                   reason="poppler-utils (pdfinfo, pdftotext) not installed")


def _words(text: str) -> str:
    return " ".join(text.split())


def _html_text(doc: str) -> str:
    return _words(_html.unescape(re.sub(r"<[^>]+>", " ", doc)))


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
@pytest.mark.parametrize("asked, used", [("static", "static"), ("static", "standing_functional"),
                                         ("functional", "functional"), ("functional", "task_functional")])
@pytest.mark.parametrize("convention", ["grood_suntay", "thesis_zyx"])
def test_the_report_names_the_calibration_asked_for_and_used_and_the_angle_convention(lang, asked, used, convention):
    ri = _synthetic_ri(lang)
    ri.results.update(calibration_method=asked, angle_method=convention)
    ri.results["calibration"]["protocol"] = {"segment": used, "magnetometer": ["ellipsoid"], "recordings": ["task"]}
    pages = pdf_pages(render_pdf(ri))
    page = next(p for p in pages if t("section_protocol", lang) in p)   # the method is said where the method is
    html_text = _html_text(render_html(ri))
    for text in (page, html_text):
        assert t("protocol_segment_label", lang) in text
        assert _words(t(f"method.segment.{used}", lang)) in text
        if asked == used:  # said once, as asked
            assert _words(t("method.calibration_as_asked", lang, used=t(f"method.segment.{used}", lang))) in text
        else:  # both named: the one asked for, then the one the recordings allowed
            said = _words(t("method.calibration_asked_used", lang, asked=t(f"method.segment.{asked}", lang),
                            used=t(f"method.segment.{used}", lang)))
            assert said in text
        assert t("protocol_angles_label", lang) in text
        assert _words(t(f"angle_method_{convention}", lang)) in text
        other = "thesis_zyx" if convention == "grood_suntay" else "grood_suntay"
        assert _words(t(f"angle_method_{other}", lang)) not in text
        # no raw id reaches the reader
        assert not re.search(r"\b(standing_functional|task_functional|grood_suntay|thesis_zyx)\b", text)
    # the old fixed text ("from the static standing and supine postures") is gone from a functional calibration
    if used != "static" and asked != "static":
        assert _words(t("method.segment.static", lang)) not in page


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_a_results_file_without_the_calibration_names_no_calibration(lang):
    """An older results.json (no ``calibration_method``, no ``protocol``) prints no calibration line: nothing invented."""
    ri = _synthetic_ri(lang)
    ri.results.pop("calibration_method", None)
    ri.results["calibration"].pop("protocol", None)
    words = " ".join(pdf_pages(render_pdf(ri)))
    assert t("protocol_segment_label", lang) not in words
    assert _words(t("angle_method_grood_suntay", lang)) in words


@needs_poppler
def test_the_demo_session_names_its_calibration_convention_and_heading(demo_ri):  # noqa: F811
    """The pipeline's own results.json (the demo: figure-eight, standing and supine, static asked) in every language:
    the calibration asked for and used, the convention, and the heading the angles used."""
    r = demo_ri.results
    assert r["calibration_method"] == "static" and r["calibration"]["protocol"]["segment"] == "static"
    assert r["angle_method"] == "grood_suntay" and r["quality"]["heading"]["used"] in ("magnetometer", "constraint")
    for lang in LANGUAGES:
        ri = replace(demo_ri, language=lang)
        words = " ".join(pdf_pages(render_pdf(ri)))
        assert _words(t("method.calibration_as_asked", lang, used=t("method.segment.static", lang))) in words
        assert _words(t("angle_method_grood_suntay", lang)) in words
        assert t("quality_heading", lang) in words and _words(heading_sentence(r, lang)) in words
        html_text = _html_text(render_html(ri))
        assert _words(heading_sentence(r, lang)) in html_text
