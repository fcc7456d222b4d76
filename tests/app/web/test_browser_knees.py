"""Both knees and comparisons in the browser (static/views/results.js, wizard.js, patients.js), in real Chromium, in
Portuguese: a four-sensor walk (left flexion 80 % of the right's, simulated) is processed from the wizard with the
left knee chosen as involved; the results page overlays the two knees' curves (plotly's SVG) and shows the LSI table
with the number results.json holds; a second session compared from the results page shows the change; the patient's
trend names its series.  Texts are read from static/i18n/pt.json."""

from __future__ import annotations

import pytest
from screens import look_at
from test_browser_e2e import csrf_header, PROCESS_WAIT_MS, _tables, log_in, open_page, server, slow_expect  # noqa: F401

from app.pipeline.demo import simulate_walk_knees, write_knees_session


@pytest.fixture(scope="module")
def walk_files(tmp_path_factory):
    out = []
    for gain in (0.8, 0.9):
        folder = tmp_path_factory.mktemp(f"bwalk{gain}") / "s"
        write_knees_session(folder, simulate_walk_knees(seed=5, knee_gain={"left": gain}))
        out.append([{"name": p.name, "mimeType": "text/csv", "buffer": p.read_bytes()}
                    for p in sorted(folder.glob("*.csv"))])
    return out


def _fmt(x: float) -> str:
    return f"{x:.1f}".replace(".", ",")


def test_two_knees_lsi_and_comparison_in_the_browser(browser, server, slow_expect, walk_files):  # noqa: F811
    pt = _tables()["pt"]
    context, page, errors = open_page(browser, "pt-BR", height=1000)
    try:
        log_in(page, server)
        page.locator("select#lang").select_option("pt")
        slow_expect(page.locator("h1")).to_have_text(pt["patients.title"])
        api = f"{server}/api/v1"
        csrf = csrf_header(context, api)
        pid = context.request.post(f"{api}/patients", data={"external_id": "BR-KNEES", "side": "right"},
                                   headers=csrf).json()["id"]
        sids = []
        for files, day in zip(walk_files, ("2026-11-01", "2026-11-20")):
            sid = context.request.post(f"{api}/patients/{pid}/sessions", data={"task": "gait", "date": day},
                                       headers=csrf).json()["id"]
            for f in files:
                r = context.request.post(f"{api}/sessions/{sid}/recordings", headers=csrf, multipart={"files": f})
                assert r.status == 201, r.text()
            sids.append(sid)
        before, after = sids
        # the second session through the API; the first from the wizard, the left knee chosen as involved
        job = context.request.post(f"{api}/sessions/{after}/process", data={"involved": "left"}, headers=csrf).json()
        page.goto(f"{server}/#/sessions/{before}/wizard")
        # the zones are one knee's: the four sensors' files stay under "other files", each tagged with the knee,
        # sensor and recording the check recognised, and a note says why
        other = page.locator(".zone[data-segment='']")
        slow_expect(other.locator(".knee-files-note")).to_contain_text(
            pt["wizard.knee_files_here"].split("{n}", 1)[1].split(":")[0].strip())
        tags = other.locator(".tag.knee")
        slow_expect(tags.first).to_be_visible()
        assert tags.count() == len(walk_files[0]), (tags.count(), len(walk_files[0]))
        look_at(page, other.locator(".knee-files-note"), tags.first, page.locator("button.next"))
        page.locator("button.next").click()  # the wizard opens at step 2 (the files are there): on to step 3
        involved = page.locator("select[name=involved]")
        slow_expect(involved.locator("option")).to_have_count(3)  # the patient's, right, left
        involved.select_option("left")
        process = page.get_by_role("button", name=pt["wizard.process"], exact=True)
        look_at(page, involved, process)
        process.click()
        slow_expect(page.locator("#job")).to_have_attribute("data-status", "done", timeout=PROCESS_WAIT_MS)
        page.locator("#see-results").click()
        slow_expect(page.locator("#knees")).to_be_visible()
        for angle in ("flexion", "adduction", "internal_rotation"):
            slow_expect(page.locator(f"#knees-{angle} .main-svg").first).to_be_attached()
        r = context.request.get(f"{api}/sessions/{before}/results").json()
        assert r["involved_side"] == "left"
        swing = next(p for p in r["symmetry"]["parameters"] if p["name"] == "swing_peak_flexion")
        row = page.locator("#lsi-table tr", has_text=pt["knees.param.swing_peak_flexion"]).first
        slow_expect(row).to_contain_text(_fmt(swing["lsi_pct"]))
        assert 75.0 < swing["lsi_pct"] < 85.0
        # the page's top: the summary, which names the calibration used (results.js calibrationUsed)
        summary = page.locator(".card.summary")
        page.evaluate("() => scrollTo(0, 0)")
        look_at(page, summary, summary.locator("dd", has_text=pt["calibration.static"]).first)
        page.locator("#knees-flexion").scroll_into_view_if_needed()
        look_at(page, page.locator("#knees-flexion .main-svg").first)
        row.scroll_into_view_if_needed()
        look_at(page, row)

        while context.request.get(f"{api}/jobs/{job['job_id']}").json()["status"] not in ("done", "failed"):
            page.wait_for_timeout(500)
        page.reload()
        page.locator("#compare-with").select_option(str(after))
        table = page.locator("#compare-table")
        slow_expect(table).to_be_visible()
        slow_expect(table.locator("tr", has_text=pt["knees.param.swing_peak_flexion"]).first).to_contain_text("+")
        assert page.locator("#compare-mismatch").count() == 0
        # the comparison table fits the window: its session headings wrap (it was 2145 px wide in 1280 px, the second
        # session's and the change's columns off the screen)
        table.scroll_into_view_if_needed()
        look_at(page, table, page.locator("#compare-with"))

        page.goto(f"{server}/#/patients/{pid}")
        version = context.request.get(f"{api}/patients/{pid}/trend").json()["pipeline_version"]
        slow_expect(page.locator("#trend-series")).to_contain_text(
            pt["patient.trend_series"].format(filter=pt["filter.chakamo"], version=version,
                                              angles=pt["angle_convention.grood_suntay"],
                                              calibration=pt["calibration.static"]))
        page.locator("#trend-series").scroll_into_view_if_needed()
        look_at(page, page.locator("#trend-series"))
        assert not errors, errors
    finally:
        context.close()
