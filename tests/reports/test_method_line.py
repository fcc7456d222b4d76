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


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_a_results_file_without_the_angle_convention_names_the_default(lang):
    """An older results.json (no ``angle_method``) was computed in Grood–Suntay, the only convention then and the
    default since (app.choices.ANGLE_CONVENTIONS): the PDF and the HTML say so, as the PDF did before the method lines."""
    from app.choices import ANGLE_CONVENTIONS, DEFAULT_ANGLE_CONVENTION

    assert DEFAULT_ANGLE_CONVENTION == "grood_suntay" in {c.name for c in ANGLE_CONVENTIONS}
    ri = _synthetic_ri(lang)
    ri.results.pop("angle_method", None)
    for text in (" ".join(pdf_pages(render_pdf(ri))), _html_text(render_html(ri))):
        assert t("protocol_angles_label", lang) in text and _words(t("angle_method_grood_suntay", lang)) in text


@pytest.mark.parametrize("side", ["right", "left"])
def test_both_conventions_state_the_signs_their_angles_have(side):
    """Both texts name the same positive directions, and both conventions give a knee flexed, in varus and rotated
    internally (estimators.knee K1, clinical signs) positive angles, on either leg."""
    import numpy as np

    from estimators.knee import knee_angles, knee_quaternion

    q = knee_quaternion(np.radians([40.0, 5.0, 8.0]), side)
    for method in ("grood_suntay", "thesis_zyx"):
        assert (knee_angles(q, side, method=method) > 0).all()
    for lang in LANGUAGES:
        signs = [t(f"angle_method_{m}", lang).split(";")[1] for m in ("grood_suntay", "thesis_zyx")]
        assert signs[0] == signs[1] and len(signs[0]) > 10


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_two_knees_calibrated_differently_have_a_line_each(lang):
    """A session of both knees (results.json ``knees``): one calibration line while the knees share their
    calibration, one per knee, named, when the recordings allowed each a different one."""
    from reports.labels import method_items

    ri = _synthetic_ri(lang)
    ri.results["calibration_method"] = "static"
    protocol = {"segment": "static", "magnetometer": ["ellipsoid"], "recordings": ["task"]}
    ri.results["calibration"]["protocol"] = protocol
    knee = {side: {"calibration": {"protocol": dict(protocol)}} for side in ("left", "right")}
    same = method_items({**ri.results, "knees": knee}, lang)
    assert [label for label, _ in same].count(t("protocol_segment_label", lang)) == 1
    knee["left"]["calibration"]["protocol"]["segment"] = "standing_functional"
    ri.results["knees"] = knee
    items = dict(method_items(ri.results, lang))
    for side, used in (("left", "standing_functional"), ("right", "static")):
        label = f"{t('protocol_segment_label', lang)} ({t(f'knees.{side}', lang)})"
        assert _words(t(f"method.segment.{used}", lang)) in items[label]
    html_text = _html_text(render_html(ri))
    for label, text in items.items():
        assert _words(label) in html_text and _words(text) in html_text
