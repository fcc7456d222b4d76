"""The PDF report: real renders of the demo session in es/en/pt, read back with poppler.

Golden test: the numbers printed equal results.json rounded as printed (reports.pdf.DECIMALS), with the
decimal comma in Spanish and Portuguese.  The expected strings are formatted here with Python's own
``format`` (not with reports.i18n) so a formatting bug cannot hide itself.
"""

from __future__ import annotations

import datetime as dt
import re
import shutil
import subprocess
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from reports import figures
from reports.i18n import LANGUAGES, t
from reports.model import Patient, ReportInput
from reports.pdf import DECIMALS, render_pdf
from reports.warning_text import warning_text

HAS_POPPLER = shutil.which("pdftoppm") is not None and shutil.which("pdftotext") is not None
needs_poppler = pytest.mark.skipif(not HAS_POPPLER, reason="poppler-utils (pdftoppm, pdftotext) not installed")
REPORT_DATE = dt.date(2026, 3, 14)

PATIENT = Patient(
    name_or_id="José Muñoz-Conceição", date="13/03/2023", professional="Dra. Begoña Araújo",
    side="right", step_height_m=0.17, weight_kg=72.5, height_m=1.78,
    observations="Rodilla derecha: dolor 3/10 a 90° de flexión; aquí está el niño; ação, canção, lições.",
)
LITERAL_TEXTS = ["=SUM(A1:A3)", "+cmd|' /C calc'!A0", "<b>negrita</b>", "<script>alert('x')</script>",
                 "{nb}", "{page}", "**not bold**", "$x^2$", "%s"]


def _expected(x: float, decimals: int, lang: str) -> str:
    s = f"{x:.{decimals}f}"
    if float(s) == 0.0:
        s = s.lstrip("-")
    return s.replace(".", ",") if lang in ("es", "pt") else s


def _mean_sd(d: dict, decimals: int, lang: str, mean="mean", sd="sd") -> str:
    return f"{_expected(d[mean], decimals, lang)} ± {_expected(d[sd], decimals, lang)}"


def _text(pdf: bytes) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.pdf"
        path.write_bytes(pdf)
        out = subprocess.run(["pdftotext", "-layout", "-enc", "UTF-8", str(path), "-"], check=True,
                             capture_output=True).stdout.decode("utf-8")
    return out


def _flat(text: str) -> str:
    """Whitespace collapsed (table cells and wrapped lines)."""
    return re.sub(r"\s+", " ", text)


def _page_count(pdf: bytes) -> int:
    return len(re.findall(rb"/Type /Page\b", pdf))


# ---------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def demo_ri() -> ReportInput:
    """The demo session (10 step-up cycles, right leg) through the real pipeline."""
    from app.pipeline.demo import simulate_session, write_session
    from app.pipeline.process import process_folder
    from app.pipeline.results import build_results, report_input

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "session"
        write_session(folder, simulate_session(seed=7, side="right", n_cycles=10))
        outcome, _ = process_folder(folder, Path(tmp) / "out")
        results = build_results(outcome)
        return report_input(outcome, results, patient=PATIENT)


@pytest.fixture(scope="module")
def demo_pdfs(demo_ri) -> dict[str, bytes]:
    return {lang: render_pdf(replace(demo_ri, language=lang), report_date=REPORT_DATE) for lang in LANGUAGES}


def _synthetic_ri(language: str = "en", patient: Patient | None = None) -> ReportInput:
    """A small session with rejected cycles, an incomplete first cycle (unknown start), one cycle's
    statistics (no SD) and several warnings; left leg, no step height."""
    fs = 50.0
    t_s = np.arange(0.0, 24.0, 1.0 / fs)
    flex = 30.0 - 30.0 * np.cos(2 * np.pi * t_s / 6.0)
    angles = np.column_stack([flex, 0.05 * flex, 0.1 * flex])
    n = len(t_s)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    curve = {"mean": list(np.linspace(0, 60, 101)), "sd": [None] * 101}
    results = {
        "side": "left", "task": "step_up", "filter": {"name": "madgwick", "params": {}},
        "angles": ["flexion", "adduction", "internal_rotation"], "angle_method": "grood_suntay",
        "cycles": {"detected": 4, "accepted": 1, "accepted_indices": [2],
                   "rejected": [{"index": 0, "reason": "incomplete_start", "message": "starts during"},
                                {"index": 1, "reason": "rmse", "message": "rmse"},
                                {"index": 3, "reason": "something_new", "message": "?"}],
                   "boundaries_s": [[None, 6.0], [6.0, 12.0], [12.0, 18.0], [18.0, None]]},
        "rom_deg": {a: {s: {"mean": v, "sd": None} for s, v in (("max", 60.04), ("min", -0.04), ("range", 60.08))}
                    for a in ("flexion", "adduction", "internal_rotation")},
        "phases": {"impulse": {"mean_s": 1.234, "sd_s": None, "mean_pct": 20.55, "sd_pct": None},
                   "extension": {"mean_s": 2.0, "sd_s": None, "mean_pct": 33.3, "sd_pct": None},
                   "fall": {"mean_s": 2.766, "sd_s": None, "mean_pct": 46.15, "sd_pct": None}},
        "curves": {a: curve for a in ("flexion", "adduction", "internal_rotation")},
        "calibration": {"magnetometer": {"thigh": {"field_ut": 80.0, "quality": {"field_ut": 80.0,
                                                   "coverage_fraction": 0.35, "residual_pct": 7.5, "reliable": False}}},
                        "segment": {}},
        "quality": {"warnings": [{"code": "mag_field", "message": "Thigh sensor: field 80.0 µT is far from the "
                                  "expected 25–65 µT"},
                                 {"code": "cycles_rejected", "message": "3 of 4 cycles were left out of the "
                                  "statistics: cycle 1: starts during; cycle 2: rmse; cycle 4: ?",
                                  "params": {"rejected": 3, "detected": 4}},
                                 {"code": "MAG_FIELD_IMPLAUSIBLE", "message": "x", "params": {
                                     "segment": "thigh", "field_ut": 80.04, "lo_ut": 25, "hi_ut": 65}}]},
        "software": {"version": "9.8.7"},
    }
    return ReportInput(results, t_s, angles, {"thigh": q, "shank": q}, {"femur": q, "tibia": q},
                       {"thigh": q[0], "shank": q[0]}, patient or Patient(), language)


# ---------------------------------------------------------------- structure


@pytest.mark.parametrize("lang", LANGUAGES)
def test_pdf_is_a4_with_a_sane_page_count(demo_pdfs, lang):
    pdf = demo_pdfs[lang]
    assert pdf.startswith(b"%PDF-") and pdf.rstrip().endswith(b"%%EOF")
    assert b"/MediaBox [0 0 595.28 841.89]" in pdf  # A4 in points
    assert 3 <= _page_count(pdf) <= 6


def test_render_is_deterministic(demo_ri):
    assert render_pdf(demo_ri, report_date=REPORT_DATE) == render_pdf(demo_ri, report_date=REPORT_DATE)


def test_figure_axes_use_nice_ticks_and_the_mean_phase_boundaries(demo_ri):
    lo, hi, ticks = figures.nice_ticks(-3.2, 67.9, 4)
    assert lo <= -3.2 and hi >= 67.9 and ticks[0] == lo and ticks[-1] == hi
    steps = np.diff(ticks)
    assert np.allclose(steps, steps[0]) and steps[0] == 20.0
    lo, hi, ticks = figures.nice_ticks(0.0, 51.7, 10, expand=False)   # time axis: limits kept, ticks inside
    assert (lo, hi) == (0.0, 51.7) and ticks == [10.0 * k for k in range(6)]
    assert figures.nice_ticks(4.0, 4.0)[:2] == (3.0, 5.0)               # flat data still gets an axis
    assert figures.nice_ticks(float("nan"), float("nan"))[:2] == (0.0, 1.0)
    assert figures.phase_boundaries_pct(demo_ri.results) == pytest.approx(
        [demo_ri.results["phases"]["impulse"]["mean_pct"],
         demo_ri.results["phases"]["impulse"]["mean_pct"] + demo_ri.results["phases"]["extension"]["mean_pct"]])


def test_figures_and_key_poses_are_vectors_not_images(demo_pdfs):
    for pdf in demo_pdfs.values():
        assert b"/Subtype /Image" not in pdf


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_figure_labels_are_translated_text(demo_ri, demo_pdfs, lang):
    text = _flat(_text(demo_pdfs[lang]))
    for key in ("axis_flexion", "axis_internal_rotation", "axis_adduction", "fig_cycle_pct", "fig_time_s",
                "fig_mean", "fig_sd", "fig_accepted", "fig_rejected", "pose_start", "pose_peak_flexion",
                "pose_full_extension"):
        assert _flat(t(key, lang)) in text, (lang, key)
    assert text.count(t("angle_flexion", lang)) >= 3  # ROM table, curves panel, task panel
    # the cycle numbers over the task figure, in order
    n = demo_ri.results["cycles"]["detected"]
    assert " ".join(str(i) for i in range(1, n + 1)) in text


@needs_poppler
def test_curves_are_drawn_in_the_line_colour(demo_pdfs, tmp_path):
    pdf = tmp_path / "r.pdf"
    pdf.write_bytes(demo_pdfs["en"])
    subprocess.run(["pdftoppm", "-r", "60", "-png", str(pdf), str(tmp_path / "p")], check=True)
    blue = 0
    for page in sorted(tmp_path.glob("p-*.png")):
        rgb = np.asarray(Image.open(page).convert("RGB"), dtype=np.int32)
        blue += int(np.sum(np.abs(rgb - np.array([31, 78, 121])).sum(axis=2) < 60))
    assert blue > 1500  # two figures × three panels of curves (a blank figure area gives ~0)


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_no_page_is_blank(demo_pdfs, lang, tmp_path):
    pdf = tmp_path / "r.pdf"
    pdf.write_bytes(demo_pdfs[lang])
    subprocess.run(["pdftoppm", "-r", "50", "-png", str(pdf), str(tmp_path / "p")], check=True)
    pages = sorted(tmp_path.glob("p-*.png"))
    assert len(pages) == _page_count(demo_pdfs[lang])
    for page in pages:
        gray = np.asarray(Image.open(page).convert("L"), dtype=np.float64)
        assert gray.shape[0] > gray.shape[1]  # portrait
        ink = np.mean(gray < 200)
        assert gray.std() > 5.0 and ink > 0.005, f"{page.name} looks blank (std {gray.std():.1f}, ink {ink:.4f})"


# ---------------------------------------------------------------- text content


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_translated_headings_and_labels_are_printed(demo_pdfs, lang):
    text = _flat(_text(demo_pdfs[lang]))
    keys = ["report_title", "section_patient", "section_task", "section_protocol", "section_phases", "section_rom",
            "section_curves", "section_task_time", "section_quality", "quality_mag", "quality_cycles",
            "quality_posture", "quality_warnings", "signature", "task_step_up", "col_phase", "col_time_s",
            "col_pct_cycle", "col_range", "col_max", "col_min", "data.phase.impulse", "data.phase.extension",
            "data.phase.fall",
            "angle_flexion", "angle_internal_rotation", "angle_adduction", "seg_thigh", "seg_shank",
            "patient_name", "professional", "step_height", "observations", "side_right"]
    for key in keys:
        assert _flat(t(key, lang)) in text, (lang, key)
    assert t("product", lang) in text
    assert t("header_date", lang, date=REPORT_DATE.strftime(t("date_format", lang))) in text
    n = _page_count(demo_pdfs[lang])
    assert t("page_number", lang, page=1, pages=n) in text and t("page_number", lang, page=n, pages=n) in text
    other = {"es": "Rango de movimiento", "en": "Range of motion", "pt": "Amplitude de movimento"}
    for other_lang, heading in other.items():
        assert (heading in text) == (other_lang == lang)


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_golden_numbers_printed_equal_results_json(demo_ri, demo_pdfs, lang):
    r = demo_ri.results
    text = _flat(_text(demo_pdfs[lang]))
    expected = []
    for angle in ("flexion", "adduction", "internal_rotation"):
        for stat in ("range", "max", "min"):
            expected.append(_mean_sd(r["rom_deg"][angle][stat], DECIMALS["deg"], lang))
    for phase in ("impulse", "extension", "fall"):
        ph = r["phases"][phase]
        expected.append(_mean_sd(ph, DECIMALS["time_s"], lang, "mean_s", "sd_s"))
        expected.append(_mean_sd(ph, DECIMALS["pct"], lang, "mean_pct", "sd_pct"))
    for seg in ("thigh", "shank"):
        expected.append(_expected(r["calibration"]["magnetometer"][seg]["quality"]["field_ut"], 1, lang))
        expected.append(_expected(r["calibration"]["segment"][seg]["angle_between_postures_deg"], 1, lang))
    for s in expected:
        assert s in text, (lang, s)
    # the headline number, spelled out: ROM flexion range mean with one decimal and the language's mark
    flex = _expected(r["rom_deg"]["flexion"]["range"]["mean"], 1, lang)
    assert ("," in flex) == (lang != "en") and f"{flex} ±" in text
    c = r["cycles"]
    assert t("cycles_summary", lang, detected=c["detected"], accepted=c["accepted"],
             rejected=len(c["rejected"])) in text
    assert t("stats_note", lang, n=c["accepted"]) in text
    assert t("header_version", lang, version=r["software"]["version"]) in text
    # the filter by its human name, never the raw id (issue 17 §3)
    assert f"{t('protocol_filter_label', lang)}: {t('data.filter.' + r['filter']['name'], lang)}" in text
    assert r["quality"]["technical_notes"]      # the demo has technical notes (a stream cut at alignment)
    for w in r["quality"]["warnings"] + r["quality"]["technical_notes"]:   # translated by code; English verbatim
        printed, translated = warning_text(w, lang, r)
        assert translated and _flat(printed) in text
        assert (_flat(w["message"]) in text) == (lang == "en")


@needs_poppler
@pytest.mark.parametrize("lang", ["es", "pt"])
def test_demo_warnings_print_without_english(demo_ri, demo_pdfs, lang):
    text = _flat(_text(demo_pdfs[lang]))
    warnings = demo_ri.results["quality"]["warnings"] + demo_ri.results["quality"]["technical_notes"]
    assert warnings
    for w in warnings:
        assert _flat(w["message"]) not in text
        for words in ("ran on", "common span", "sensor:", "cut)", "thigh", "shank", "gyr "):
            assert words not in w["message"] or words not in text, (lang, words)
    assert _flat(t("warnings_language_note", lang)) not in text   # nothing left in English


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_patient_text_with_accents_prints(demo_pdfs, lang):
    text = _flat(_text(demo_pdfs[lang]))
    for s in (PATIENT.name_or_id, PATIENT.professional, PATIENT.date, PATIENT.observations):
        assert _flat(s) in text, s
    assert _expected(72.5, 1, lang) + " kg" in text and _expected(1.78, 2, lang) + " m" in text
    assert "17 cm" in text
    for ch in "áéíóúñçãõ°±µ":  # µ from the field column, ± from the tables
        assert ch in text, ch


@needs_poppler
def test_formula_and_html_like_patient_text_prints_literally():
    obs = " ".join(LITERAL_TEXTS)
    patient = Patient(name_or_id="<i>ID-7</i>", professional="=HYPERLINK(\"x\")", observations=obs)
    text = _flat(_text(render_pdf(_synthetic_ri("es", patient), report_date=REPORT_DATE)))
    for s in LITERAL_TEXTS + ["<i>ID-7</i>", "=HYPERLINK(\"x\")"]:
        assert s in text, s


@needs_poppler
def test_names_outside_the_font_cut_print_with_the_full_font():
    patient = Patient(name_or_id="Иван Петров", professional="Αθηνά Παπαδοπούλου")
    text = _flat(_text(render_pdf(_synthetic_ri("es", patient), report_date=REPORT_DATE)))
    assert "Иван Петров" in text and "Αθηνά Παπαδοπούλου" in text


def test_characters_missing_from_the_font_do_not_break_the_report():
    patient = Patient(name_or_id="患者 7 🦵", observations="tab\there\r\nnew line \x07bell")
    pdf = render_pdf(_synthetic_ri("pt", patient), report_date=REPORT_DATE)
    assert pdf.startswith(b"%PDF-")


@needs_poppler
@pytest.mark.parametrize("lang", LANGUAGES)
def test_rejected_cycles_missing_sd_and_warnings(lang):
    ri = _synthetic_ri(lang)
    text = _flat(_text(render_pdf(ri, report_date=REPORT_DATE)))
    assert t("cycle_rejected", lang, n=1, reason=t("reason_incomplete_start", lang)) in text
    assert t("cycle_rejected", lang, n=2, reason=t("reason_rmse", lang)) in text
    assert t("cycle_rejected", lang, n=4, reason="something_new") in text  # unknown code shown as it is
    assert t("cycles_summary", lang, detected=4, accepted=1, rejected=3) in text
    unknown, rejected, with_params = ri.results["quality"]["warnings"]
    assert unknown["message"] in text                          # unknown code: English as written, in any language
    assert lang == "en" or _flat(t("warnings_language_note", lang)) in text   # ... and a note says so
    assert (rejected["message"] in text) == (lang == "en")
    reasons = [t("reason_incomplete_start", lang), t("reason_rmse", lang), "something_new"]
    if lang != "en":                                          # translated reasons from the rejection codes
        assert all(_flat(reason) in text for reason in reasons)
        assert "3 de 4" in text
    printed = {"es": "Muslo: La intensidad de campo ajustada es 80,0 µT; el campo terrestre es de 25–65 µT.",
               "pt": "Coxa: A intensidade de campo ajustada é 80,0 µT; o campo terrestre é de 25–65 µT.",
               "en": "x"}[lang]                               # params: numbers formatted here; en prints the message
    assert _flat(printed) in text
    assert t("side_left", lang) in text and t("data.filter.madgwick", lang) in text and "9.8.7" in text
    assert _flat(t("task_description_no_height", lang, leg=t("leg_left", lang))) in text  # no step height
    # one accepted cycle: no SD, the mean alone, rounded as printed (no negative zero)
    assert f" {_expected(60.08, 1, lang)} {_expected(60.04, 1, lang)} {_expected(-0.04, 1, lang)} " in text
    assert _expected(1.234, 2, lang) in text and _expected(20.55, 1, lang) in text
    assert t("no_warnings", lang) not in text
    # magnetometer row of the thigh: field, coverage 35 %, residual, unknown disturbance, not reliable
    row = f"{t('seg_thigh', lang)} {_expected(80.0, 1, lang)} 35 % {_expected(7.5, 1, lang)} — {t('no', lang)}"
    assert row in text


@needs_poppler
def test_key_poses_figure_is_printed(demo_pdfs):
    text = _flat(_text(demo_pdfs["en"]))
    assert t("section_key_poses", "en") in text
    assert all(_flat(t(f"pose_{k}", "en")) in text for k in ("start", "peak_flexion", "full_extension"))


@needs_poppler
def test_key_poses_can_be_left_out(demo_ri):
    text = _flat(_text(render_pdf(replace(demo_ri, language="en"), report_date=REPORT_DATE, key_poses=False)))
    assert t("section_key_poses", "en") not in text and t("section_curves", "en") in text


@needs_poppler
def test_long_patient_name_wraps_in_the_block_and_is_cut_in_the_footer():
    name = "María de los Ángeles " * 12
    text = _flat(_text(render_pdf(_synthetic_ri("es", Patient(name_or_id=name)), report_date=REPORT_DATE)))
    assert text.count("Ángeles") >= 12 + 1  # the patient block wraps it whole (+ part of it in the footer)
    assert "…" in text                 # the footer line is cut with an ellipsis


@needs_poppler
def test_phase_table_and_curves_follow_the_session_task():
    """A squat session shows the squat's phases (descent, hold, ascent), not the step-up's."""
    ri = _synthetic_ri("en")
    ri.results["task"] = "squat"
    ri.results["phases"] = {"descent": {"mean_s": 1.11, "sd_s": 0.12, "mean_pct": 30.0, "sd_pct": 1.5},
                            "hold": {"mean_s": 0.55, "sd_s": 0.05, "mean_pct": 15.0, "sd_pct": 0.5},
                            "ascent": {"mean_s": 2.22, "sd_s": 0.21, "mean_pct": 55.0, "sd_pct": 2.0}}
    assert figures.phase_boundaries_pct(ri.results) == pytest.approx([30.0, 45.0])
    text = _flat(_text(render_pdf(ri, report_date=REPORT_DATE)))
    for name, mean_s, mean_pct in (("descent", "1.11 ± 0.12", "30.0 ± 1.5"), ("hold", "0.55 ± 0.05", "15.0 ± 0.5"),
                                   ("ascent", "2.22 ± 0.21", "55.0 ± 2.0")):
        assert f"{t('data.phase.' + name, 'en')} {mean_s} {mean_pct}" in text
    assert t("data.phase.impulse", "en") not in text


@needs_poppler
@pytest.mark.parametrize("lang", ["es", "en", "pt"])
@pytest.mark.parametrize("used", ["magnetometer", "constraint"])
def test_the_quality_section_says_which_heading_the_angles_use(lang, used):
    """results.json's ``quality.heading`` (``--heading``) is printed in the quality section, in the report's
    language, with the disagreement and the bound it was chosen by."""
    from reports.labels import heading_sentence
    from reports.html import render_html

    ri = _synthetic_ri(lang)
    ri.results["quality"]["heading"] = {"mode": "auto", "used": used, "run": "6d" if used == "constraint" else "9d",
                                        "disagreement_deg": 26.2, "bound_deg": 6.0}
    sentence = heading_sentence(ri.results, lang)
    assert sentence and "26" in sentence and "6" in sentence
    assert sentence != heading_sentence(ri.results, "en" if lang != "en" else "es")  # translated
    other = "constraint" if used == "magnetometer" else "magnetometer"
    assert sentence != heading_sentence({"quality": {"heading": {**ri.results["quality"]["heading"], "used": other}}},
                                        lang)
    assert _flat(sentence) in _flat(_text(render_pdf(ri)))
    import html as _html

    assert sentence in _html.unescape(render_html(ri))


@needs_poppler
@pytest.mark.parametrize("lang", ["es", "en", "pt"])
@pytest.mark.parametrize("segment, mag, acc", [("static", "ellipsoid", "bias"), ("standing_functional", "factory", "none"),
                                               ("task_functional", "factory", "none"), ("static", "ellipsoid", "bias_scale")])
def test_the_report_says_which_calibration_was_used(lang, segment, mag, acc):
    """results.json's ``calibration.protocol`` magnetometer and accelerometer models are printed in the PDF and the
    HTML, translated; the sensor-to-segment calibration is said once, on the method line (test_method_line.py)."""
    import html as _html

    from reports.html import render_html
    from reports.labels import calibration_sentence

    ri = _synthetic_ri(lang)
    ri.results["calibration"]["protocol"] = {"segment": segment, "magnetometer": [mag], "accelerometer": [acc],
                                             "recordings": ["task"]}
    sentence = calibration_sentence(ri.results, lang)
    assert sentence and "calibration." not in sentence  # every code has its translation
    other = calibration_sentence({"calibration": {"protocol": {"segment": segment, "magnetometer": [
        "sphere" if mag != "sphere" else "factory"], "accelerometer": [acc]}}}, lang)
    assert sentence != other
    without = calibration_sentence({"calibration": {"protocol": {"segment": segment, "magnetometer": [mag]}}}, lang)
    assert sentence != without  # the accelerometer's model is said
    pdf_text, html_text = _flat(_text(render_pdf(ri))), _html.unescape(render_html(ri))
    assert _flat(sentence) in pdf_text
    segment_name = _flat(t(f"method.segment.{segment}", lang))
    assert pdf_text.count(segment_name) == 1 and " ".join(html_text.split()).count(segment_name) == 1
    assert sentence in _html.unescape(render_html(ri))
