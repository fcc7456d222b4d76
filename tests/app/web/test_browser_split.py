"""The split of a continuous recording in a real browser (issue 14 §3a) and the server's sentences in the UI's
language (§5): Spanish, then Portuguese.

Same set-up as ``test_browser_e2e.py`` (the real app under uvicorn, Debian's Chromium).  Each sensor's continuous
recording (the simulator's protocol joined at known times, ``tests/app/pipeline/test_continuous_session.py``) is
dropped on the wizard's "whole protocol" zone; the page must show each sensor's trace with the parts the server
found, in Spanish.  The clinician drags the thigh's standing start, types its end, confirms: the cuts are stored
on the server (a fresh page and the API show them), the session is processed, and the results page shows the
moved cut and its warnings in Spanish; the same session read in Portuguese shows the Portuguese sentences.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from screens import look_at_widths
from test_browser_e2e import (  # noqa: F401 - the fixtures are used by name
    csrf_header,
    EMAIL, PASSWORD, PROCESS_WAIT_MS, WAIT_MS, _api_session, open_page, server, slow_expect)
from test_browser_wizard import _drop

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "pipeline"))
from test_continuous_session import _continuous, _write  # noqa: E402


@pytest.fixture(scope="module")
def continuous_files(tmp_path_factory):
    streams, _, truth = _continuous(seed=3, n_cycles=4)
    folder = _write(tmp_path_factory.mktemp("continuous"), streams, word="")
    files = {seg: sorted(str(p) for p in folder.glob(f"{'muslo' if seg == 'thigh' else 'pierna'}-*.csv"))
             for seg in ("thigh", "shank")}
    return files, truth


def _login(page, base: str, email_label: str, password_label: str, button: str) -> None:
    page.goto(f"{base}/#/patients")
    page.get_by_label(email_label).fill(EMAIL)
    page.get_by_label(password_label, exact=True).fill(PASSWORD)
    page.get_by_role("button", name=button).click()


def test_the_clinician_moves_a_cut_in_spanish_and_reads_it_in_portuguese(
        browser, server, continuous_files, slow_expect, tmp_path):  # noqa: F811
    expect = slow_expect
    files, truth = continuous_files
    context, page, errors = open_page(browser, "es-ES", height=1000)
    try:
        _login(page, server, "Correo electrónico", "Contraseña", "Entrar")
        expect(page.get_by_role("heading", level=1)).to_have_text("Pacientes")
        sid = _api_session(context, server, "E2E-SPLIT", "right")
        page.goto(f"{server}/#/sessions/{sid}/wizard")
        page.get_by_role("button", name="Siguiente").click()
        for seg in ("thigh", "shank"):
            zone = page.locator(f".zone[data-segment={seg}][data-role=continuous]")
            expect(zone.locator("h3")).to_have_text("Protocolo completo (una grabación)")
            _drop(page, zone, files[seg])
            expect(zone.locator("ul.files li")).to_have_count(3)

        # the check, in Spanish: its lines and the split it found, drawn per sensor
        box = page.locator("#ingestion")
        expect(box).to_have_class("card ingestion-box ok")
        expect(box.locator("ul.messages")).to_contain_text("segmento según")
        expect(box.locator("ul.messages")).to_contain_text("una grabación continua, dividida en")
        assert "segment from" not in box.inner_text() and "one continuous recording" not in box.inner_text()
        editor = page.locator("#split")
        expect(editor.locator(".split-state")).to_have_attribute("data-confirmed", "no")
        expect(editor.locator(".split-state")).to_contain_text("Cortes automáticos")
        for seg in ("thigh", "shank"):
            sensor = editor.locator(f".split-sensor[data-segment={seg}]")
            expect(sensor.locator("svg.split-trace polyline")).to_have_count(1)
            expect(sensor.locator("svg.split-trace .parts rect")).to_have_count(4)   # figure-eight, standing, supine, task
            expect(sensor.locator(".cut")).to_have_count(8)
            # looked at: the sensor's trace with the parts, its heading naming its file above it
            look_at_widths(page, sensor.locator("svg.split-trace"), sensor.locator("h4"))
        # the automatic standing start is where the simulator put it
        thigh = editor.locator(".split-sensor[data-segment=thigh]")
        start = thigh.locator("input[name=split-thigh-standing-from]")
        expect(start).to_have_attribute("aria-label", "Muslo, De pie: inicio (s)")
        auto_start = float(start.input_value())
        assert abs(auto_start - truth["thigh"]["standing"][0]) < 1.0, (auto_start, truth["thigh"]["standing"])

        # drag the standing start 40 px to the right: the typed seconds follow the pointer
        grip = thigh.locator(".cut[data-role=standing][data-edge=from]")
        thigh.locator("svg.split-trace").scroll_into_view_if_needed()
        plot = thigh.locator("svg.split-trace").bounding_box()
        g = grip.bounding_box()
        duration = float(start.get_attribute("max"))
        page.mouse.move(g["x"] + g["width"] / 2, g["y"] + g["height"] / 2)
        page.mouse.down()
        page.mouse.move(g["x"] + g["width"] / 2 + 20, g["y"] + g["height"] / 2, steps=4)
        page.mouse.move(g["x"] + g["width"] / 2 + 40, g["y"] + g["height"] / 2, steps=4)
        page.mouse.up()
        dragged = float(start.input_value())
        expected = auto_start + 40 / plot["width"] * duration
        assert abs(dragged - expected) < 0.6 + duration / plot["width"], (dragged, expected)
        # and a typed end (one second before the automatic one)
        end = thigh.locator("input[name=split-thigh-standing-to]")
        typed_end = round(float(end.input_value()) - 1.0, 1)
        end.fill(str(typed_end))
        # a start after the end is refused in the browser, with the Spanish sentence
        wrong = thigh.locator("input[name=split-thigh-lying-from]")
        saved_lying = wrong.input_value()
        wrong.fill("99999")
        editor.get_by_role("button", name="Confirmar los cortes").click()
        expect(editor.get_by_role("alert")).to_contain_text("el inicio debe ir antes del fin")
        wrong.fill(saved_lying)
        expect(editor.get_by_role("alert")).to_have_count(0)   # corrected: the refusal goes

        editor.get_by_role("button", name="Confirmar los cortes").click()
        expect(page.locator("#split .split-state")).to_have_attribute("data-confirmed", "yes")
        expect(page.locator("#split .split-state")).to_contain_text("Cortes confirmados")

        # stored on the server: a fresh page (nothing kept in the browser) and the API show the same cuts
        stored = context.request.get(f"{server}/api/v1/sessions/{sid}").json()["ingestion"]
        moved = stored["confirmed_split"]["thigh"]["standing"]
        assert moved == [dragged, typed_end], (moved, dragged, typed_end)
        assert stored["splits"]["thigh"]["spans_s"]["standing"] == moved
        page.evaluate("localStorage.clear()")
        page.reload()   # the session has files: the wizard opens on step 2
        thigh = page.locator("#split .split-sensor[data-segment=thigh]")
        expect(thigh.locator("input[name=split-thigh-standing-from]")).to_have_value(str(dragged))
        expect(page.locator("#split .split-state")).to_have_attribute("data-confirmed", "yes")

        # processed with the stored cuts: the results page shows them, and its warnings in Spanish
        page.get_by_role("button", name="Siguiente").click()
        assert page.locator("#split-unconfirmed").count() == 0
        page.get_by_role("button", name="Procesar", exact=True).click()
        expect(page.locator("#job")).to_have_attribute("data-status", "done", timeout=PROCESS_WAIT_MS)
        page.locator("#see-results").click()
        row = page.locator("#split-table tbody tr").first
        expect(row).to_contain_text(f"{dragged:.1f}".replace(".", ","))
        results = context.request.get(f"{server}/api/v1/sessions/{sid}/results").json()
        assert results["session"]["split"]["thigh"]["spans_s"]["standing"] == moved
        served = context.request.get(f"{server}/api/v1/sessions/{sid}/warnings").json()
        assert any(w["technical"] for w in served), "a continuous session has at least its split notes"
        warnings = [w for w in served if not w["technical"]]  # the split notes are technical: folded away apart
        assert [w["code"] for w in warnings] == [w["code"] for w in results["quality"]["warnings"]]
        assert [w["code"] for w in served if w["technical"]] == [w["code"] for w in results["quality"]["technical_notes"]]
        shown = page.locator("#warnings li.warning[data-code]")
        expect(shown).to_have_count(len(warnings))
        texts = shown.all_inner_texts()
        assert texts == [w["message"]["es"] for w in warnings]
        notes = page.locator("#technical-notes li[data-code]")
        assert notes.all_text_contents() == [w["message"]["es"] for w in served if w["technical"]]  # folded: text
        assert any(w["message"]["es"] != w["message"]["en"] for w in served)
        assert not any("one continuous recording" in t for t in texts), texts
        assert errors == []
    except Exception:
        page.screenshot(path=str(tmp_path / "split-es.png"), full_page=True)
        raise
    finally:
        context.close()

    # --- the same session in Portuguese: the check, the cuts' state and the warnings
    context, page, errors = open_page(browser, "pt-BR", height=1000)
    try:
        _login(page, server, "Correio eletrónico", "Palavra-passe", "Entrar")
        page.goto(f"{server}/#/sessions/{sid}/wizard")   # opens on step 2 (the session has files)
        page.locator(".steps button").nth(1).click()
        expect(page.locator("#ingestion ul.messages")).to_contain_text("segmento segundo")
        expect(page.locator("#split .split-state")).to_contain_text("Cortes confirmados e guardados")
        page.goto(f"{server}/#/sessions/{sid}")
        shown = page.locator("#warnings li.warning[data-code]")
        expect(shown).to_have_count(len(warnings))
        assert shown.all_inner_texts() == [w["message"]["pt"] for w in warnings]
        assert errors == []   # the Portuguese page's script errors are checked too
    except Exception:
        page.screenshot(path=str(tmp_path / "split-pt.png"), full_page=True)
        raise
    finally:
        context.close()


def test_a_four_sensor_sessions_cuts_get_one_editor_per_sensor(browser, server, tmp_path, slow_expect):  # noqa: F811
    """Both knees' continuous recordings (file names say the side): step 2 shows an editor for each of the four
    sensors, named by side and segment (none appeared: the wizard looked for "thigh" and "shank" only), and a cut
    moved on the right shank is stored under ``right_shank`` and applied to that sensor only."""
    from app.pipeline.ingestion.metabase import write_recording_metabase

    expect = slow_expect
    streams, _, _ = _continuous(seed=1, n_cycles=3)
    words = {"left": "izquierda", "right": "derecha", "thigh": "muslo", "shank": "pierna"}
    folder = tmp_path / "knees"
    folder.mkdir()
    for i, side in enumerate(("left", "right")):
        for j, seg in enumerate(("thigh", "shank")):
            write_recording_metabase(folder, f"{words[seg]}-{words[side]}-ML1-13032023-1", f"D4F1A2B3C4{i}{j}",
                                     streams[seg])
    context, page, errors = open_page(browser, "en-US", height=1000)
    try:
        _login(page, server, "Email", "Password", "Log in")
        expect(page.get_by_role("heading", level=1)).to_have_text("Patients")
        sid = _api_session(context, server, "E2E-SPLIT-KNEES", "right")
        api = f"{server}/api/v1"
        csrf = csrf_header(context, api)
        for side in ("left", "right"):
            for seg in ("thigh", "shank"):
                files = sorted(folder.glob(f"{words[seg]}-{words[side]}-*.csv"))
                for p in files:
                    r = context.request.post(f"{api}/sessions/{sid}/recordings", headers=csrf, multipart={
                        "files": {"name": p.name, "mimeType": "text/csv", "buffer": p.read_bytes()},
                        "segment": seg, "role": "continuous"})
                    assert r.status == 201, r.text()
        page.goto(f"{server}/#/sessions/{sid}/wizard")   # the session has files: the wizard opens on step 2
        editor = page.locator("#split")
        keys = ("left_thigh", "left_shank", "right_thigh", "right_shank")
        for key in keys:
            expect(editor.locator(f".split-sensor[data-segment={key}] svg.split-trace polyline")).to_have_count(1)
        start = editor.locator("input[name=split-right_shank-standing-from]")
        expect(start).to_have_attribute("aria-label", "Right · Shank, Standing: start (s)")
        moved = round(float(start.input_value()) + 1.0, 1)
        start.fill(str(moved))
        editor.get_by_role("button", name="Confirm the cuts").click()
        expect(page.locator("#split .split-state")).to_have_attribute("data-confirmed", "yes")
        stored = context.request.get(f"{api}/sessions/{sid}").json()["ingestion"]
        assert stored["confirmed_split"]["right_shank"]["standing"][0] == moved
        assert stored["splits"]["right_shank"]["how"] == "session.json"
        assert stored["splits"]["left_shank"]["spans_s"] == stored["confirmed_split"]["left_shank"]  # kept as shown
        assert not errors, errors
    finally:
        context.close()
