"""The wizard's zones, badge, options and progress labels (static/views/wizard.js) in real Chromium, in Spanish and
Portuguese, with the demo session's real MetaBase files:

* all 24 files dropped at once on "other files" land in the eight zones the server's check recognised them for
  (3 each), none stays in "other files", and the session badge says "ready to process" (it stayed "no files");
* a file the check rejects turns its zone red with the refusal, never green "stored" (screenshot pixels: the zone's
  border is the error red, not the "filled" green);
* step 3 offers the calibration and the angle convention of GET /options and sends them: the job that ran says so;
* every stage the job really went through (its log, written by the server) reads as a sentence, never a file name
  such as "report.pdf es" or "scene.viser".
"""

from __future__ import annotations

import re
import time

import numpy as np

from screens import colour_share, look_at_widths, rgb
from test_browser_e2e import (  # noqa: F401 - the fixtures are used by name
    PROCESS_WAIT_MS, _api_session, _tables, demo_files, log_in, open_page, server, slow_expect)

FILE_NAME = re.compile(r"\.(pdf|html|viser|xlsx|json|npz|csv)\b", re.I)
RED, GREEN = (0xB3, 0x26, 0x1E), (0x9F, 0xC5, 0xA1)     # style.css: --bad, .zone.filled's border


def _lines(locator) -> int:
    """How many lines the text of ``locator`` is drawn on."""
    return locator.evaluate("(e) => { const r = document.createRange(); r.selectNodeContents(e);"
                            " return new Set([...r.getClientRects()].map((q) => Math.round(q.top))).size; }")


def test_bulk_drop_fills_the_zones_and_options_reach_the_job(browser, server, demo_files, slow_expect):  # noqa: F811
    expect = slow_expect
    es = _tables()["es"]
    context, page, errors = open_page(browser, "es-ES")
    try:
        log_in(page, server)
        expect(page.locator("h1")).to_have_text(es["patients.title"])
        sid = _api_session(context, server, "ZONES-1", "right")
        page.goto(f"{server}/#/sessions/{sid}/wizard")
        expect(page.locator(".title-row .badge")).to_have_text(es["status.empty"])
        page.locator("button.next").click()
        every = sorted(f for files in demo_files.values() for f in files)
        assert len(every) == 24
        page.locator(".zone[data-segment=''] input[type=file]").set_input_files(every)
        expect(page.locator(".ingestion-box.ok")).to_be_visible()
        for (seg, role), files in demo_files.items():
            zone = page.locator(f".zone[data-segment={seg}][data-role={role}]")
            expect(zone.locator("ul.files li")).to_have_count(3)
            shown = sorted(zone.locator(".file-name").all_inner_texts())
            assert shown == sorted(f.rsplit("/", 1)[-1] for f in files), (seg, role)
            expect(zone).to_have_attribute("data-state", "filled")
        expect(page.locator(".zone[data-segment=''] ul.files li")).to_have_count(0)
        expect(page.locator(".title-row .badge")).to_have_text(es["status.ready"])
        # looked at: the badge beside the title; each segment's four zones filled, their files listed; the check's box
        look_at_widths(page, page.locator(".title-row"), page.locator(".title-row .badge"), page.locator("h1"))
        for seg in ("thigh", "shank"):
            for role in ("mag_calibration", "standing", "lying", "task"):
                zone = page.locator(f".zone[data-segment={seg}][data-role={role}]")
                look_at_widths(page, zone, zone.locator("h3"), zone.locator("ul.files"))
        look_at_widths(page, page.locator(".ingestion-box.ok"), page.locator(".ingestion-box.ok .ok-line"))

        # step 3: the two choices of GET /options, in Spanish, sent with the request
        page.locator("button.next").click()
        calibration = page.get_by_label(es["wizard.calibration"])
        expect(calibration.locator("option")).to_have_text([es["calibration.static"], es["calibration.functional"]])
        expect(page.get_by_label(es["wizard.angle_convention"]).locator("option")).to_have_text(
            [es["angle_convention.grood_suntay"], es["angle_convention.thesis_zyx"]])
        calibration.select_option("functional")
        page.get_by_label(es["wizard.angle_convention"]).select_option("thesis_zyx")
        # looked at: the form with both choices and Process; every menu's every choice reads whole once chosen, at
        # both widths (look_at's cut_options: they were cut, "De pie + eje de flexión de l", "Ángulos de Euler ZYX
        # de la" at 1280 px)
        process = page.get_by_role("button", name=es["wizard.process"], exact=True)
        form = page.locator("form.process-form")
        look_at_widths(page, form, calibration, page.get_by_label(es["wizard.angle_convention"]), process)
        process.click()
        seen = set()
        job = page.locator("#job")
        expect(job).to_be_visible()
        # looked at: the job's box with its bar and stage, whatever stage it is at
        look_at_widths(page, job, job.locator("#job-progress"), job.locator("h3"))
        deadline = time.monotonic() + PROCESS_WAIT_MS / 1000   # a job that never ends fails the test, not hangs it
        while job.get_attribute("data-status") not in ("done", "failed"):
            assert time.monotonic() < deadline, f"the job did not end in {PROCESS_WAIT_MS / 1000:.0f} s: {seen}"
            seen.add(page.locator("#job .stage").inner_text())
            page.wait_for_timeout(50)
        expect(job).to_have_attribute("data-status", "done", timeout=PROCESS_WAIT_MS)
        # looked at: the finished job, its bar full, the way to the results; "100 %" on one line (it wrapped at 768 px)
        def one_line(width):
            assert _lines(job.locator(".pct")) == 1, (width, job.locator(".pct").inner_text())

        look_at_widths(page, job, job.locator("#job-progress"), page.locator("#see-results"), each=one_line)
        ran = context.request.get(f"{server}/api/v1/sessions/{sid}").json()["jobs"][0]
        assert (ran["calibration"], ran["angle_convention"]) == ("functional", "thesis_zyx")
        assert not [s for s in seen if FILE_NAME.search(s)], seen

        # every stage the server wrote in the job's log, as the page words it
        stages = [line.split(" ", 1)[1] for line in ran["log"] if " " in line and not line.split(" ", 1)[1].startswith("started")]
        assert any(s.startswith("report.pdf") for s in stages) and "scene.viser" in stages, stages
        words = page.evaluate("async (stages) => { const w = await import('/static/views/wizard.js');"
                              " return stages.map((s) => w.stageText(s)); }", stages)
        bad = [(s, w) for s, w in zip(stages, words) if FILE_NAME.search(w) or not w]
        assert not bad, bad
        pdf = dict(zip(stages, words))[next(s for s in stages if s.startswith("report.pdf "))]
        assert pdf.startswith(es["stage.report_pdf"]), pdf
        # the report's language named in the UI's (Spanish) words, not in its own ("English", "Português")
        named = page.evaluate("async () => { const w = await import('/static/views/wizard.js');"
                              " return ['report.pdf en', 'report.pdf pt'].map((s) => w.stageText(s)); }")
        assert named == [f"{es['stage.report_pdf']} (inglés)", f"{es['stage.report_pdf']} (portugués)"], named
        assert errors == []
    finally:
        context.close()


def test_a_rejected_file_turns_its_zone_red_not_saved(browser, server, slow_expect, tmp_path):  # noqa: F811

    expect = slow_expect
    pt = _tables()["pt"]
    context, page, errors = open_page(browser, "pt-PT")
    try:
        log_in(page, server)
        expect(page.locator("h1")).to_have_text(pt["patients.title"])
        sid = _api_session(context, server, "ZONES-2", "left")
        page.goto(f"{server}/#/sessions/{sid}/wizard")
        page.locator("button.next").click()
        bad = tmp_path / "step-muslo-ZONES2-01012026-1.csv"
        bad.write_text("this,is\nnot,a recording\n", encoding="utf-8")
        zone = page.locator(".zone[data-segment=thigh][data-role=task]")
        zone.locator("input[type=file]").set_input_files(str(bad))
        expect(zone.locator("ul.files li")).to_have_count(1)
        expect(zone).to_have_attribute("data-state", "rejected")
        expect(zone.locator(".rejected-note")).to_contain_text(bad.name)
        expect(zone.locator(".zone-status .ok")).to_have_count(0)        # never "stored" in green
        expect(page.locator(".title-row .badge")).to_have_text(pt["status.incomplete"])
        # looked at: the red zone, the refusal naming the file, the file listed
        look_at_widths(page, zone, zone.locator(".rejected-note"), zone.locator("ul.files"))
        img = rgb(zone.screenshot())
        edge = np.concatenate([img[:3].reshape(-1, 3), img[-3:].reshape(-1, 3)])[None]
        red, green = colour_share(edge, RED, tolerance=40), colour_share(edge, GREEN, tolerance=40)
        assert red > 0.3 and green < 0.05, (red, green)

        # removing it: the zone is empty again, neither red nor green
        zone.get_by_role("button", name=pt["wizard.remove_file"].replace("{name}", bad.name)).click()
        expect(zone).to_have_attribute("data-state", "empty")
        expect(zone.locator(".rejected-note")).to_have_count(0)
        assert errors == []
    finally:
        context.close()


def test_a_zone_is_rejected_only_for_its_whole_file_name(browser, server):  # noqa: F811
    """static/views/wizard.js namesWhole in real Chromium: the check's refusal names a file whole ("a.csv" was
    marked rejected by a sentence naming "data.csv"), or the MetaBase recording label its files share."""
    context, page, errors = open_page(browser, "es-ES")
    try:
        page.goto(f"{server}/")
        said = "data.csv: no es un registro; step-muslo-ABC123_2026 y notas.csv.bak, (b.csv)."
        got = page.evaluate("""async ([said, cases]) => { const w = await import('/static/views/wizard.js');
            return cases.map(([word, label]) => w.namesWhole(said, word, label)); }""",
                            [said, [["a.csv", False], ["data.csv", False], ["ata.csv", False], ["notas.csv", False],
                                    ["b.csv", False], ["step-muslo-ABC123", True], ["muslo-ABC123", True],
                                    ["step-muslo-ABC12", True]]])
        assert got == [False, True, False, False, True, True, False, False]
        assert errors == []
    finally:
        context.close()
