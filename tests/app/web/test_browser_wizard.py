"""The wizard's sensor check in a real browser: a MAC typed in step 1 makes step 2 warn when a zone gets the
files of another sensor (MetaBase file names carry the MAC).

Same set-up as ``test_browser_e2e.py`` (its ``server``, ``demo_files`` and ``slow_expect`` fixtures: the real
app under uvicorn on loopback, the demo session's real MetaBase files, Debian's Chromium): the thigh sensor's
MAC is typed, the shank's task recording is dropped (a real ``drop`` event) on the thigh's task zone → the
zone warns, naming the files' MAC; the shank's own zone stays quiet; once the shank's MAC is typed too, the
stored files are flagged as swapped sensors.  Without any typed MAC, the serials the server stored with the
uploads flag one sensor recorded on both segments.
"""

from __future__ import annotations

from pathlib import Path

from screens import look_at_widths as _look
from test_browser_e2e import (  # noqa: F401 - the fixtures are used by name
    EMAIL, PASSWORD, _api_session, _no_raw_values, demo_files, open_page, server, slow_expect)

THIGH_MAC, SHANK_MAC = "D4:F1:A2:B3:C4:E5", "E8:C2:B1:A0:F9:D7"   # app.pipeline.ingestion.writers.DEFAULT_MACS


def _drop(page, zone, paths: list[str]) -> None:
    """Drop ``paths`` on ``zone`` as a user drags them from the file manager (a DataTransfer of Files)."""
    files = [{"name": Path(p).name, "text": Path(p).read_text(encoding="utf-8")} for p in paths]
    dropped = page.evaluate_handle("(files) => { const d = new DataTransfer();"
                                   " for (const f of files) d.items.add(new File([f.text], f.name, {type: 'text/csv'}));"
                                   " return d; }", files)
    zone.dispatch_event("dragover", {"dataTransfer": dropped})
    zone.dispatch_event("drop", {"dataTransfer": dropped})


def test_files_of_the_other_sensor_are_flagged(browser, server, demo_files, slow_expect):  # noqa: F811
    expect = slow_expect
    for files in demo_files.values():   # the fixture's files carry the MACs this test types
        assert all(THIGH_MAC.replace(":", "") in Path(f).name or SHANK_MAC.replace(":", "") in Path(f).name
                   for f in files)
    context, page, errors = open_page(browser, "en-US")
    try:
        page.goto(f"{server}/#/patients")
        page.get_by_label("Email").fill(EMAIL)
        page.get_by_label("Password").fill(PASSWORD)
        page.get_by_role("button", name="Log in").click()
        expect(page.get_by_role("heading", level=1)).to_have_text("Patients")
        sid = _api_session(context, server, "E2E-MAC", "right")

        # step 1: sensor 1 (on the thigh by default) gets the thigh's MAC, in lower case without colons
        page.goto(f"{server}/#/sessions/{sid}/wizard")
        expect(page.get_by_role("heading", name="1. Which sensor is on which segment?")).to_be_visible()
        page.get_by_label("Name or MAC (optional)").first.fill("MetaWear " + THIGH_MAC.replace(":", "").lower())
        # looked at: the two sensors' cards (name or MAC, the segment chosen) and the way on
        sensors = page.locator(".card.sensor")
        _look(page, sensors.nth(0), sensors.nth(1), sensors.nth(0).locator("input[name=sensor-1]"),
              page.get_by_role("button", name="Next"))
        page.get_by_role("button", name="Next").click()
        expect(page.get_by_role("heading", name="2. The four recordings of each sensor")).to_be_visible()
        # looked at: the step's heading and the thigh's group of four zones, named with the sensor typed
        thigh = page.locator("fieldset[data-segment=thigh]")
        _look(page, page.get_by_role("heading", name="2. The four recordings of each sensor"), thigh.locator("legend"),
              *[thigh.locator(f".zone[data-role={role}] h3") for role in ("mag_calibration", "standing", "lying", "task")])

        # the shank's task recording dropped on the THIGH's task zone: a warning naming the files' MAC
        thigh_task = page.locator(".zone[data-segment=thigh][data-role=task]")
        _drop(page, thigh_task, demo_files[("shank", "task")])
        expect(thigh_task.locator("ul.files li")).to_have_count(3)       # stored anyway: only a warning
        warning = thigh_task.locator(".zone-mac [role=alert]")
        expect(warning).to_contain_text("Not the thigh sensor?")
        expect(warning).to_contain_text(SHANK_MAC)
        expect(warning).to_contain_text(THIGH_MAC)
        # looked at: the zone's warning (both MACs spelled out) whole on the screen, and its three files listed: a
        # file name too long for the zone ends in an ellipsis on purpose, its title holding it whole (look_at's
        # cut_text lets exactly that pass)
        _look(page, thigh_task, warning, thigh_task.locator("ul.files"))

        # the shank's own files in the shank zone: nothing to say (only the thigh's MAC is known)
        shank_task = page.locator(".zone[data-segment=shank][data-role=task]")
        _drop(page, shank_task, demo_files[("shank", "standing")])
        expect(shank_task.locator("ul.files li")).to_have_count(3)
        assert shank_task.locator(".zone-mac [role=alert]").count() == 0
        # the thigh's own files in the thigh zone: nothing either
        thigh_standing = page.locator(".zone[data-segment=thigh][data-role=standing]")
        _drop(page, thigh_standing, demo_files[("thigh", "standing")])
        expect(thigh_standing.locator("ul.files li")).to_have_count(3)
        assert thigh_standing.locator(".zone-mac [role=alert]").count() == 0
        _no_raw_values(page)

        # the shank's MAC typed too: the stored files of the thigh's task zone are now "swapped sensors"
        page.get_by_role("button", name="Back").click()
        page.get_by_label("Name or MAC (optional)").nth(1).fill(SHANK_MAC)
        page.get_by_role("button", name="Next").click()
        warning = page.locator(".zone[data-segment=thigh][data-role=task] .zone-mac [role=alert]")
        expect(warning).to_contain_text("Sensors swapped?")
        expect(warning).to_contain_text(SHANK_MAC)
        assert page.locator(".zone-mac [role=alert]").count() == 1    # the other zones hold the right files
        _look(page, page.locator(".zone[data-segment=thigh][data-role=task]"), warning)

        # the same warning in Spanish once the language is switched (the page is drawn again)
        page.get_by_label("Language").select_option("es")
        zone = page.locator(".zone[data-segment=thigh][data-role=task]")
        expect(zone.locator(".zone-mac [role=alert]")).to_contain_text("¿Sensores intercambiados?")
        _look(page, zone, zone.locator(".zone-mac [role=alert]"), zone.get_by_role("button", name="Elegir archivos"))
    finally:
        context.close()
    assert not errors, f"JavaScript errors: {errors}"


def test_one_sensor_on_both_segments_is_flagged_from_the_server(browser, server, demo_files, slow_expect):  # noqa: F811
    """No MAC typed: the serials the server stored with the uploads (``sensor_warnings``) still catch the shank's
    sensor recorded on both segments, in the UI's language."""
    expect = slow_expect
    context, page, errors = open_page(browser, "en-US")
    try:
        page.goto(f"{server}/#/patients")
        page.get_by_label("Email").fill(EMAIL)
        page.get_by_label("Password").fill(PASSWORD)
        page.get_by_role("button", name="Log in").click()
        expect(page.get_by_role("heading", level=1)).to_have_text("Patients")
        sid = _api_session(context, server, "E2E-MAC2", "right")
        page.goto(f"{server}/#/sessions/{sid}/wizard")
        page.get_by_role("button", name="Next").click()
        expect(page.get_by_role("heading", name="2. The four recordings of each sensor")).to_be_visible()
        thigh_task = page.locator(".zone[data-segment=thigh][data-role=task]")
        _drop(page, thigh_task, demo_files[("shank", "task")])
        expect(thigh_task.locator("ul.files li")).to_have_count(3)
        assert thigh_task.locator(".zone-mac [role=alert]").count() == 0     # one segment only so far
        shank_standing = page.locator(".zone[data-segment=shank][data-role=standing]")
        _drop(page, shank_standing, demo_files[("shank", "standing")])
        expect(shank_standing.locator("ul.files li")).to_have_count(3)
        for zone in (thigh_task, shank_standing):
            expect(zone.locator(".zone-mac [role=alert]")).to_contain_text(SHANK_MAC.replace(":", ""))
            _look(page, zone, zone.locator(".zone-mac [role=alert]"))
        page.get_by_label("Language").select_option("pt")
        zone = page.locator(".zone[data-segment=thigh][data-role=task]")
        expect(zone.locator(".zone-mac [role=alert]")).to_contain_text("coxa")
        _look(page, zone, zone.locator(".zone-mac [role=alert]"), zone.locator("ul.files"))
    finally:
        context.close()
    assert not errors, f"JavaScript errors: {errors}"
