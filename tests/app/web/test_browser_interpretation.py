"""The clinician's interpretation and sign-off on the results page (static/views/results.js, issue 17 §3), in real
Chromium, in Spanish: a clinician writes the interpretation, signs it (the confirmation dialog accepted), sees it
locked with their name and role, amends it (refused without a reason, then with one), and finds the earlier text in
the history; the PDF downloaded afterwards prints the amended text, the signer and the earlier text (poppler's
pdftotext).  Texts are read from static/i18n/es.json; the demo session (real MetaBase files) is processed through
the API first."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from screens import look_at_widths
from test_browser_e2e import csrf_header, SETTINGS, _tables, demo_files, log_in, open_page, server, slow_expect  # noqa: F401

CLINICIAN, PASSWORD = "clinica@clinic.test", "another long enough password"


def _pdf_text(pdf: bytes) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.pdf"
        path.write_bytes(pdf)
        out = subprocess.run(["pdftotext", "-enc", "UTF-8", str(path), "-"], check=True, capture_output=True, text=True)
        return " ".join(out.stdout.split())


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext not installed")
def test_clinician_signs_and_amends_in_the_browser(browser, server, demo_files, slow_expect, tmp_path):  # noqa: F811
    from PIL import Image

    from app.cli import admin as admin_cli

    es = _tables()["es"]
    admin_cli.create_user(SETTINGS[server], clinic="Clínica E2E", email=CLINICIAN, role="clinician",
                          name="Dra. Clínica", password=PASSWORD)
    context, page, errors = open_page(browser, "es-ES", height=1200)
    dialogs: list[str] = []
    page.on("dialog", lambda d: (dialogs.append(d.message), d.accept()))
    try:
        log_in(page, server, CLINICIAN, PASSWORD)
        page.locator("select#lang").select_option("es")
        slow_expect(page.locator("h1")).to_have_text(es["patients.title"])
        api = f"{server}/api/v1"
        csrf = csrf_header(context, api)
        pid = context.request.post(f"{api}/patients", data={"external_id": "HC-SIGN", "side": "right"},
                                   headers=csrf).json()["id"]
        sid = context.request.post(f"{api}/patients/{pid}/sessions", data={"step_height_m": 0.17},
                                   headers=csrf).json()["id"]
        for paths in demo_files.values():
            for p in paths:
                r = context.request.post(f"{api}/sessions/{sid}/recordings", headers=csrf, multipart={
                    "files": {"name": Path(p).name, "mimeType": "text/csv", "buffer": Path(p).read_bytes()}})
                assert r.status == 201, r.text()
        job_id = context.request.post(f"{api}/sessions/{sid}/process", data={"lang": "es"}, headers=csrf).json()["job_id"]
        deadline = time.monotonic() + 400
        while (job := context.request.get(f"{api}/jobs/{job_id}").json())["status"] not in ("done", "failed"):
            assert time.monotonic() < deadline, job
            time.sleep(0.5)
        assert job["status"] == "done", job

        page.goto(f"{server}/#/sessions/{sid}")
        section = page.locator("#interpretation")
        slow_expect(section.locator("h2")).to_have_text(es["interp.title"])
        slow_expect(page.locator("#interp-status")).to_have_text(es["interp.none"])
        first = "Flexión máxima reducida respecto a la referencia; revisar en 6 semanas."
        page.locator("#interp-text").fill(first)
        page.locator("#interp-sign").click()
        status = page.locator("#interp-status")
        slow_expect(status).to_contain_text("Dra. Clínica")
        slow_expect(status).to_contain_text(es["role.clinician"])
        assert dialogs == [es["interp.sign_confirm"]]
        assert page.locator("#interp-text").evaluate("el => el.readOnly")
        slow_expect(page.locator("#interp-sign")).to_be_hidden()
        slow_expect(page.locator("#interp-save")).to_be_hidden()

        second = "Flexión máxima reducida; revisar en 4 semanas."
        page.locator("#interp-amend").click()
        page.locator("#interp-text").fill(second)
        page.locator("#interp-amend-save").click()
        slow_expect(page.locator("#interp-message")).to_contain_text(es["interp.reason_needed"])
        page.locator("#interp-reason").fill("plazo corregido")
        page.locator("#interp-amend-save").click()
        slow_expect(status).to_contain_text(es["interp.amended"])
        history = page.locator("#interp-history li")
        slow_expect(history).to_have_count(1)
        slow_expect(history.first).to_contain_text(first)
        slow_expect(history.first).to_contain_text("plazo corregido")
        slow_expect(page.locator("#interp-text")).to_have_value(second)
        # looked at: who signed and that it was amended, the text, the earlier version with its reason
        look_at_widths(page, status)

        def as_wide_as_its_card(width):   # it was a 200 px box beside its label, the label at its foot
            ratio = page.locator("#interp-text").evaluate("(e) => e.getBoundingClientRect().width"
                                                          " / e.closest('section').clientWidth")
            assert ratio > 0.8, (width, ratio)

        look_at_widths(page, page.locator("#interp-text"), each=as_wide_as_its_card)
        look_at_widths(page, history.first)

        shot = tmp_path / "interpretation.png"
        section.screenshot(path=str(shot))
        img = np.asarray(Image.open(shot).convert("L"))
        assert img.shape[0] > 150 and (img < 128).mean() > 0.005  # the section drawn, with its text

        pdf = context.request.get(f"{api}/sessions/{sid}/report.pdf", params={"lang": "es"}).body()
        text = _pdf_text(pdf)
        for part in (second, first, "Dra. Clínica", "plazo corregido", "Enmendado", "Interpretación clínica",
                     "N.º de historia: HC-SIGN"):
            assert part in text, part
    finally:
        context.close()
    assert not errors, f"JavaScript errors: {errors}"
