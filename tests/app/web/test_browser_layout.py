"""Every page at a tablet's 768 px and a desktop's 1280 px, in Spanish and Portuguese, in real Chromium (issue 17 §4:
at 768 px the header and the ROM table were cut and the page scrolled sideways; the sessions table's buttons
overflowed at 1280 px).

For each page — login, patients, a patient with sessions, the wizard's three steps, the results of a processed
session, the account, the three admin pages, the Bluetooth recording page and the not-found page — the checks are
facts of the drawn page:

* ``document.documentElement.scrollWidth <= innerWidth`` (no sideways scroll);
* the full-page screenshot is exactly the viewport's width (Chromium widens it to the scroll width) and is not
  blank: the header's navy band fills its top rows, and the page below it has more than one colour;
* nothing of the header (brand, menu, user, language), no button of the sessions table, no cell or button of the
  ROM, users and tokens tables lies outside the viewport or outside its card (bounding boxes); the tokens table
  is drawn with a token in it (the fixture creates one).

The HTML report (``report.html`` in the page's language) and the API's ``/docs`` (Swagger UI) are checked for the first
only: no sideways scroll.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from screens import NAVY, WIDTHS, colour_share, look_at, rgb
from test_browser_e2e import (  # noqa: F401 - the fixtures are used by name
    csrf_header,
    demo_files, log_in, open_page, server, slow_expect)


@pytest.fixture(scope="module")
def processed(browser, server, demo_files):  # noqa: F811
    """(patient id, session id) of a session of the demo files processed through the API (the results page needs
    one), with a second, empty session beside it (the sessions table then has rows of both kinds)."""
    context, page, _ = open_page(browser, "es-ES")
    try:
        log_in(page, server)
        page.wait_for_selector("#nav a")
        api = f"{server}/api/v1"
        csrf = csrf_header(context, api)
        pid = context.request.post(f"{api}/patients", headers=csrf, data={
            "external_id": "LAYOUT-0001-ABCDEFGH", "side": "right",
            "name": "María de los Ángeles Fernández-Castellanos de la Torre"}).json()["id"]
        sid = context.request.post(f"{api}/patients/{pid}/sessions", data={}, headers=csrf).json()["id"]
        # the 24 files in one drop on the wizard's "other files" (one request, as a user does it)
        page.goto(f"{server}/#/sessions/{sid}/wizard")
        page.locator("ol.steps li:nth-child(2) button").click()
        page.locator(".zone[data-segment=''] input[type=file]").set_input_files(
            sorted(f for fs in demo_files.values() for f in fs))
        page.wait_for_selector(".ingestion-box.ok", timeout=400_000)
        job = context.request.post(f"{api}/sessions/{sid}/process", headers=csrf, data={"lang": "es"}).json()["job_id"]
        deadline = time.monotonic() + 400
        while (state := context.request.get(f"{api}/jobs/{job}").json())["status"] not in ("done", "failed"):
            assert time.monotonic() < deadline, state
            time.sleep(0.5)
        assert state["status"] == "done", state
        context.request.post(f"{api}/patients/{pid}/sessions", data={}, headers=csrf)
        # a token with a long label, every scope and an end, so the tokens table is drawn (and widest)
        r = context.request.post(f"{api}/tokens", headers=csrf, data={
            "label": "Sistema de información hospitalaria (RIS/PACS)", "role": "read_only", "expires_days": 365,
            "scopes": ["patients:read", "sessions:read", "results:read", "fhir:read", "audit:read"]})
        assert r.status == 201, r.text()
        return pid, sid
    finally:
        context.close()


def _pages(pid: int, sid: int):
    """(name, hash, what to click after loading, the selector that says the page is drawn)."""
    return [
        ("patients", "#/patients", None, "#patients-table"),
        ("patient", f"#/patients/{pid}", None, "#sessions-table"),
        ("wizard-1", f"#/sessions/{sid}/wizard", "ol.steps li:nth-child(1) button", ".sensor"),
        ("wizard-2", f"#/sessions/{sid}/wizard", "ol.steps li:nth-child(2) button", ".ingestion-box"),
        ("wizard-3", f"#/sessions/{sid}/wizard", "ol.steps li:nth-child(3) button", "form.process-form"),
        ("results", f"#/sessions/{sid}", None, "#curve-flexion .main-svg"),   # the charts drawn
        ("account", "#/account", None, "#session-list li"),
        ("admin-users", "#/admin/users", None, "#users-table"),
        ("admin-tokens", "#/admin/tokens", None, "#tokens-table td"),
        ("admin-audit", "#/admin/audit", None, "#audit-table"),
        ("record", f"#/sessions/{sid}/record", None, "section.record h1"),
        ("not-found", "#/no-such-page", None, "section.view h1"),
    ]


def _check_drawn(page, width: int, what: str) -> None:
    scroll = page.evaluate("() => [document.documentElement.scrollWidth, innerWidth]")
    assert scroll[0] <= scroll[1], f"{what}: scrolls sideways ({scroll[0]} > {scroll[1]} px)"
    img = rgb(page.screenshot(full_page=True))
    assert img.shape[1] == width, f"{what}: the page is {img.shape[1]} px wide"
    header = page.locator("header.topbar").bounding_box()
    band = img[2:int(header["height"]) - 2]
    navy = colour_share(band, NAVY)
    assert navy > 0.5, f"{what}: the header is not drawn ({navy:.0%} navy)"
    body = img[int(header["height"]):]
    assert len(np.unique(body.reshape(-1, 3)[::97], axis=0)) > 8, f"{what}: a blank page"
    outside = page.evaluate("""(w) => [...document.querySelectorAll(
        'header.topbar *, #sessions-table button, #sessions-table a, #rom-table td, #rom-table th, ' +
        '#tokens-table td, #tokens-table button, #users-table td, #users-table button')]
      .filter((e) => e.getClientRects().length)
      .filter((e) => { const r = e.getBoundingClientRect(); const card = e.closest('.card');
        const c = card ? card.getBoundingClientRect() : { left: 0, right: w };
        return r.right > Math.min(w, c.right) + 1 || r.left < Math.max(0, c.left) - 1; })
      .map((e) => `${e.tagName}.${e.className} ${(e.textContent || '').trim().slice(0, 30)}`)""", width)
    assert not outside, f"{what}: outside the page or its card: {outside}"


@pytest.mark.parametrize("locale", ["es-ES", "pt-PT"])
def test_every_page_fits_768_and_1280(browser, server, processed, slow_expect, locale):  # noqa: F811
    expect = slow_expect
    pid, sid = processed
    context, page, errors = open_page(browser, locale)
    try:
        for width in WIDTHS:
            page.set_viewport_size({"width": width, "height": 900})
            page.context.clear_cookies()
            page.goto(f"{server}/#/patients")
            expect(page.locator("form.login")).to_be_visible()
            _check_drawn(page, width, f"login @ {width}")
            log_in(page, server)
            expect(page.locator("#nav-admin")).to_be_visible()
            for name, where, click, ready in _pages(pid, sid):
                page.goto(f"{server}/#/patients" if where != "#/patients" else f"{server}/#/account")
                page.goto(f"{server}/{where}")
                if click:
                    page.locator(click).click()
                expect(page.locator(ready).first).to_be_visible()
                page.wait_for_timeout(300)   # charts and late cards settle
                _check_drawn(page, width, f"{name} @ {width} ({locale})")
                if name == "wizard-3":   # step 3's menus: every choice reads whole once chosen (look_at's cut_options)
                    look_at(page, page.locator("form.process-form"))
            # the pages outside the app's frame: the HTML report (in the page's language) and the API's /docs
            lang = locale[:2]
            for name, url, ready in (("report.html", f"/api/v1/sessions/{sid}/report.html?lang={lang}", "#quality"),
                                     ("docs", "/docs", ".opblock")):
                page.goto(f"{server}{url}")
                expect(page.locator(ready).first).to_be_visible()
                page.wait_for_timeout(300)
                scroll = page.evaluate("() => [document.documentElement.scrollWidth, innerWidth]")
                assert scroll[0] <= scroll[1], f"{name} @ {width} ({locale}): scrolls sideways ({scroll[0]} > {scroll[1]} px)"
        assert errors == []
    finally:
        context.close()
