"""Pairing two one-knee sessions from the results page (static/views/pairing.js), in real Chromium, in Portuguese.

The simulated four-sensor walk (left flexion 80 % of the right's) split into a right-knee and a left-knee session of
one patient, uploaded through the API.  On the left session's page the clinician picks the right session and this
session's knee, pairs, then processes both knees from the card: the page follows the job and opens the analysis,
which overlays both knees (plotly's SVG) and shows the LSI results.json holds (80 % within the pipeline's error:
the patient's side, left, is involved).  Undoing the pairing from the card leaves one knee again."""

from __future__ import annotations

import pytest
from screens import look_at
from test_browser_e2e import csrf_header, PROCESS_WAIT_MS, _tables, log_in, open_page, server, slow_expect  # noqa: F401

from app.pipeline.demo import simulate_walk_knees, write_knees_session


@pytest.fixture(scope="module")
def knee_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bpair") / "s"
    write_knees_session(folder, simulate_walk_knees(seed=5, knee_gain={"left": 0.8}))
    return {side: [{"name": p.name, "mimeType": "text/csv", "buffer": p.read_bytes()}
                   for p in sorted(folder.glob(f"{word}-*.csv"))]
            for side, word in (("left", "izquierda"), ("right", "derecha"))}


def test_pair_two_sessions_and_see_both_knees(browser, server, slow_expect, knee_files):  # noqa: F811
    pt = _tables()["pt"]
    context, page, errors = open_page(browser, "pt-PT", height=1000)
    try:
        log_in(page, server)
        page.locator("select#lang").select_option("pt")
        slow_expect(page.locator("h1")).to_have_text(pt["patients.title"])
        api = f"{server}/api/v1"
        csrf = csrf_header(context, api)
        pid = context.request.post(f"{api}/patients", data={"external_id": "PT-PAIR", "side": "left"},
                                   headers=csrf).json()["id"]
        sids = {}
        for side in ("right", "left"):
            sid = context.request.post(f"{api}/patients/{pid}/sessions", data={"task": "gait", "date": "2026-11-09"},
                                       headers=csrf).json()["id"]
            for f in knee_files[side]:
                assert context.request.post(f"{api}/sessions/{sid}/recordings", headers=csrf,
                                            multipart={"files": f}).status == 201
            sids[side] = sid
        page.goto(f"{server}/#/sessions/{sids['left']}")
        card = page.locator("#pairing")
        slow_expect(card.locator("h2")).to_have_text(pt["pair.title"])
        assert page.locator("#pair-button").is_disabled()
        page.locator("#pair-with").select_option(str(sids["right"]))
        page.locator("#pair-knee").select_option("left")
        card.scroll_into_view_if_needed()
        look_at(page, card.locator("h2"), page.locator("#pair-with"), page.locator("#pair-knee"),
                page.locator("#pair-button"))
        page.locator("#pair-button").click()
        slow_expect(page.locator("#pair-state")).to_contain_text(pt["pair.knee.left"])
        look_at(page, page.locator("#pair-state"), page.locator("#pair-process"), page.locator("#pair-undo"))
        page.locator("#pair-process").click()
        for _ in range(PROCESS_WAIT_MS // 250):
            if "analysis_id=" in page.url:
                break
            page.wait_for_timeout(250)
        slow_expect(page.locator("#knees")).to_be_visible()
        slow_expect(page.locator("#knees-flexion .main-svg").first).to_be_attached()
        r = context.request.get(f"{api}/sessions/{sids['left']}/results").json()
        assert sorted(r["knees"]) == ["left", "right"] and r["involved_side"] == "left"
        swing = next(p for p in r["symmetry"]["parameters"] if p["name"] == "swing_peak_flexion")
        assert swing["lsi_pct"] == pytest.approx(80.0, abs=4.0)
        row = page.locator("#lsi-table tr", has_text=pt["knees.param.swing_peak_flexion"]).first
        slow_expect(row).to_contain_text(f"{swing['lsi_pct']:.1f}".replace(".", ","))
        page.locator("#knees-flexion").scroll_into_view_if_needed()
        look_at(page, page.locator("#knees-flexion .main-svg").first)
        row.scroll_into_view_if_needed()
        look_at(page, row)
        assert context.request.get(f"{api}/sessions/{sids['right']}").json()["paired_session_id"] == sids["left"]

        page.locator("#pair-undo").click()
        slow_expect(page.locator("#pair-with")).to_be_visible()
        page.locator("#pair-with").scroll_into_view_if_needed()
        look_at(page, page.locator("#pair-with"), page.locator("#pair-knee"))
        assert context.request.get(f"{api}/sessions/{sids['left']}").json()["paired_session_id"] is None
        assert not errors, errors
    finally:
        context.close()
