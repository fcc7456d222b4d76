"""The patient's identity on every page and the recordings' date (issue 17 §3), read back from the rendered files.

The session is the demo's simulated one (real MetaBase files through the real pipeline): its phone clock starts at
:data:`app.pipeline.demo.EPOCH0_S` (2026-11-22 UTC), the truth for "the recordings' date", while its ``session.json``
says another day (the day the session was created) that must not be printed as the recordings'.  Every PDF page's
text (poppler's ``pdftotext``, one page at a time) must carry the record number with its identifier system, the
birth date with the age at the recordings' date (a birthday one day after them: not yet reached), the sex and the
clinic.  A session.json that says none of these (the CLI with no patient store) prints none of them: nothing is
invented.
"""

from __future__ import annotations

import datetime as dt
import io
import json
import shutil
import subprocess
import tempfile
from dataclasses import replace
from pathlib import Path

import pytest

from reports.i18n import LANGUAGES, t
from reports.model import Amendment, Interpretation, ReportInput
from pdf_pages import pdf_pages

pytestmark = pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext not installed")

IDENTITY = {"patient_id": "HC-0042", "identifier_system": "urn:oid:2.16.724.4.9.20.90",
            "name": "Ana Sánchez", "birth_date": "1960-11-23", "sex": "female", "clinic": "Hospital Universitario Norte",
            "date": "2026-12-01"}
REPORT_DATE = dt.date(2026, 12, 2)


def _ri(session_extra: dict) -> ReportInput:
    from app.pipeline.demo import simulate_session, write_session
    from app.pipeline.process import process_folder
    from app.pipeline.results import build_results, report_input

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "session"
        write_session(folder, simulate_session(seed=7, side="right", n_cycles=4))
        manifest = json.loads((folder / "session.json").read_text(encoding="utf-8"))
        (folder / "session.json").write_text(json.dumps(manifest | session_extra), encoding="utf-8")
        outcome, _ = process_folder(folder, Path(tmp) / "out", reports=False)
        return report_input(outcome, build_results(outcome))


@pytest.fixture(scope="module")
def identified() -> ReportInput:
    return _ri(IDENTITY)


@pytest.fixture(scope="module")
def anonymous() -> ReportInput:
    return _ri({})




def _expected(lang: str) -> list[str]:
    born = dt.date(1960, 11, 23).strftime(t("date_format", lang))
    recorded = dt.date(2026, 11, 22).strftime(t("date_format", lang))  # the demo's phone clock (EPOCH0_S)
    return [f"{t('id.record', lang)}: HC-0042 (urn:oid:2.16.724.4.9.20.90)",
            f"{t('id.born', lang)}: {t('id.born_age', lang, date=born, age=65)}",  # 66 only on 2026-11-23
            f"{t('id.sex', lang)}: {t('id.sex.female', lang)}",
            f"{t('id.clinic', lang)}: Hospital Universitario Norte",
            f"{t('id.recorded', lang)}: {recorded}"]


def test_the_recordings_date_is_their_time_stamps_day(identified):
    from app.pipeline.demo import EPOCH0_S

    day = dt.datetime.fromtimestamp(EPOCH0_S, tz=dt.timezone.utc).date().isoformat()
    assert identified.patient.recorded == day == "2026-11-22" and identified.patient.recorded_last == ""
    assert identified.patient.date == "2026-12-01"  # the session's own date is kept apart


@pytest.mark.parametrize("lang", LANGUAGES)
def test_every_pdf_page_carries_the_identity(identified, lang):
    from reports.pdf import render_pdf

    pages = pdf_pages(render_pdf(replace(identified, language=lang), report_date=REPORT_DATE))
    assert len(pages) >= 3
    for i, text in enumerate(pages):
        for part in _expected(lang):
            assert part in text, (lang, i + 1, part)
        assert "Ana Sánchez" in text
    # the session's creation day is printed as the session's, never as the recordings'
    created = dt.date(2026, 12, 1).strftime(t("date_format", lang))
    assert f"{t('id.recorded', lang)}: {created}" not in " ".join(pages)
    # one date format on the page: no ISO date where the language writes dd/mm/yyyy (file names aside)
    if lang != "en":
        words = [w for w in " ".join(pages).split() if "MetaWear" not in w]
        assert not [w for w in words if "2026-11-22" in w or "2026-12-01" in w or "1960-11-23" in w]


@pytest.mark.parametrize("lang", LANGUAGES)
def test_html_and_excel_headers_carry_the_identity(identified, lang):
    import html as htmllib
    import re

    from openpyxl import load_workbook

    from reports.excel import write_angles_xlsx, write_quaternions_xlsx
    from reports.html import render_html

    ri = replace(identified, language=lang)
    page = render_html(ri)
    header = htmllib.unescape(re.sub(r"<[^>]+>", "", page[page.index("<header>"):page.index("</header>")]))
    header = " ".join(header.split())
    for part in _expected(lang):
        assert part in header, (lang, part)
    assert f"<th>{htmllib.escape(t('data.patient.step_height_cm', lang))}</th><td>17</td>" in page  # cm, as the PDF
    with tempfile.TemporaryDirectory() as tmp:
        for writer in (write_angles_xlsx, write_quaternions_xlsx):
            path = Path(tmp) / "w.xlsx"
            writer(ri, path)
            wb = load_workbook(io.BytesIO(path.read_bytes()))
            for ws in wb.worksheets:
                text = ws.oddHeader.left.text.replace("&&", "&")
                for part in _expected(lang):
                    assert part in text, (writer.__name__, ws.title, part)


def test_nothing_unknown_is_printed(anonymous):
    """The CLI's session.json with a record number only: no birth date, age, sex or clinic appears."""
    from reports.pdf import render_pdf

    p = anonymous.patient
    assert (p.birth_date, p.sex, p.clinic, p.record_system) == ("", "", "", "")
    text = " ".join(pdf_pages(render_pdf(replace(anonymous, language="en"), report_date=REPORT_DATE)))
    for key in ("id.born", "id.sex", "id.clinic"):
        assert f"{t(key, 'en')}:" not in text
    assert f"{t('id.record', 'en')}: DEMO-001 ·" in text  # no "()" for an unknown system


@pytest.mark.parametrize("lang", LANGUAGES)
def test_signed_and_amended_interpretation_is_printed(identified, lang):
    from reports.html import render_html
    import html as htmllib

    from reports.labels import signature_line, signed_line
    from reports.pdf import render_pdf

    it = Interpretation(text="Flexión limitada respecto a la referencia; revisar en 6 semanas.",
                        signed_by="Dra. Laura Pérez", signed_role="clinician", signed_at="2026-12-02T09:15:00+00:00",
                        amendments=(Amendment(previous_text="Flexión normal.", by="Dra. Laura Pérez",
                                              role="clinician", at="2026-12-02T10:05:00+00:00",
                                              reason="error de transcripción"),))
    ri = replace(identified, language=lang, interpretation=it)
    text = " ".join(pdf_pages(render_pdf(ri, report_date=REPORT_DATE)))
    # the amended text is not printed under "Signed by A" alone: first signed by A; last amended by B (reason)
    first = signed_line(lang, "interp.first_signed", "Dra. Laura Pérez", "clinician", "2026-12-02T09:15:00+00:00")
    last = signed_line(lang, "interp.last_amended", "Dra. Laura Pérez", "clinician", "2026-12-02T10:05:00+00:00",
                       reason="error de transcripción")
    assert signature_line(lang, it) == f"{first}; {last}"
    for part in (t("interp.section", lang), it.text, f"{first}; {last}", t("interp.amended", lang),
                 "Flexión normal.", "error de transcripción", "09:15", "10:05"):
        assert part in text, (lang, part)
    alone = signed_line(lang, "interp.signed", "Dra. Laura Pérez", "clinician", "2026-12-02T09:15:00+00:00")
    assert alone not in text
    assert t("signature", lang) not in text  # the hand-signature lines give way to the electronic sign-off
    page = render_html(ri)
    for part in (it.text, "Flexión normal.", "error de transcripción", first, last):
        assert htmllib.escape(part, quote=False) in page or part in page, part
    # never amended: "Signed by A" as before
    assert signature_line(lang, replace(it, amendments=())) == alone


@pytest.mark.parametrize("lang", ["en", "pt"])
def test_a_long_clinic_name_is_cut_in_the_header_never_over_the_content(identified, lang):
    """The identity under the header's rule takes at most two lines at the smallest size (6 pt): a clinic's name
    that would need more is cut with "…" (read back with poppler: no word of the header below the content's top,
    :data:`reports.pdf_page.HEADER_BOTTOM_MM`)."""
    import re

    from reports.pdf import render_pdf
    from reports.pdf_page import HEADER_BOTTOM_MM

    clinic = "Hospital Universitario " + " ".join(f"Zzclinic{i}" for i in range(60))
    ri = replace(identified, language=lang, patient=replace(identified.patient, clinic=clinic))
    pdf = render_pdf(ri, report_date=REPORT_DATE)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.pdf"
        path.write_bytes(pdf)
        xml = subprocess.run(["pdftotext", "-f", "1", "-l", "1", "-bbox", str(path), "-"], check=True,
                             capture_output=True, text=True).stdout
    words = re.findall(r'<word xMin="[\d.]+" yMin="([\d.]+)" xMax="[\d.]+" yMax="([\d.]+)">([^<]*)</word>', xml)
    # the header's words: the top of the page (the patient table further down prints the whole name)
    clinic_words = [(float(y1), w) for _, y1, w in words if w.startswith("Zzclinic") and float(y1) < 150.0]
    assert clinic_words and max(y for y, _ in clinic_words) <= HEADER_BOTTOM_MM * 72 / 25.4, clinic_words[-3:]
    assert any("…" in w for y, _, w in words if float(y) < 150.0)
    assert len(clinic_words) < 60  # cut


def test_an_excel_header_cut_leaves_no_lone_ampersand():
    """A cut within Excel's 250 characters never leaves a single ``&`` before "…" (it would start a code)."""
    from reports.excel import _header_text

    for text in ("&" * 300, "a" + "&" * 300, "x" * 248 + "&&&"):
        out = _header_text(text)
        assert len(out) <= 250 and out.endswith("…"), out[-5:]
        assert "&" not in out.replace("&&", ""), out[-5:]
        assert out[:-1].replace("&&", "&") == text[:len(out[:-1].replace("&&", "&"))]


@pytest.mark.parametrize("lang", LANGUAGES)
def test_no_raw_ids_and_the_ui_angle_order_in_the_pdf(identified, lang):
    from reports.model import ANGLES
    from reports.pdf import render_pdf

    text = " ".join(pdf_pages(render_pdf(replace(identified, language=lang), report_date=REPORT_DATE)))
    for raw in ("chakamo", "grood_suntay", "thesis_zyx", "step_up", "internal_rotation"):
        assert raw not in text, (lang, raw)
    assert t("data.filter.chakamo", lang) in text
    rom = text[text.index(t("section_rom", lang)):]
    positions = [rom.index(t(f"angle_{a}", lang)) for a in ANGLES]
    assert positions == sorted(positions), (lang, positions)
    assert "0,17 m" not in text and "0.17 m" not in text and "17 cm" in text
