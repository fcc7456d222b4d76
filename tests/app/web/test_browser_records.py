"""Correcting and erasing in the browser (static/views/records.js), in real Chromium, in Spanish and Portuguese: an admin edits a
patient, cancels and then confirms a session's deletion in the modal dialog, and erases the patient only after
typing its identifier.  The texts expected are read from static/i18n/<lang>.json; what the API holds afterwards is
read back through the API, and the stored recording's file is checked gone from disk."""

from __future__ import annotations

import hashlib

import pytest

from screens import look_at
from test_browser_e2e import csrf_header, _tables, log_in, open_page, server, slow_expect  # noqa: F401 — fixtures

DATA = b"acc_x (g),acc_y (g),acc_z (g)\n0.0,0.0,1.0\n# browser erasure\n"


@pytest.mark.parametrize("locale, code", [("es-ES", "es"), ("pt-PT", "pt")])
def test_edit_patient_and_delete_session_and_patient_with_confirmation(browser, server, slow_expect,  # noqa: F811
                                                                        tmp_path_factory, locale, code):
    tr = _tables()[code]   # the UI's texts in the language tested
    context, page, errors = open_page(browser, locale)
    try:
        log_in(page, server)
        slow_expect(page.locator("h1")).to_have_text(tr["patients.title"])
        api = f"{server}/api/v1"
        csrf = csrf_header(context, api)
        pid = context.request.post(f"{api}/patients", data={"external_id": "BR-ERASE", "side": "left"},
                                   headers=csrf).json()["id"]
        sid = context.request.post(f"{api}/patients/{pid}/sessions", data={}, headers=csrf).json()["id"]
        r = context.request.post(f"{api}/sessions/{sid}/recordings", headers=csrf,
                                 multipart={"files": {"name": "thigh_task.csv", "mimeType": "text/csv", "buffer": DATA}})
        assert r.status == 201, r.text()
        sha = hashlib.sha256(DATA).hexdigest()  # the server's data dir: the `server` fixture's temporary folder
        blobs = list(tmp_path_factory.getbasetemp().glob("chakamo-data*/blobs"))
        assert any((b / sha[:2] / sha[2:]).is_file() for b in blobs)

        page.goto(f"{server}/#/patients/{pid}")
        page.get_by_role("button", name=tr["patient.edit"]).click()
        form = page.locator("#edit-patient")
        look_at(page, form.locator("input[name=name]"), form.get_by_role("button", name=tr["common.save"]))
        form.locator("input[name=name]").fill("Ana <b>Edit</b>")
        form.get_by_role("button", name=tr["common.save"]).click()
        slow_expect(page.locator("h1")).to_have_text("Ana <b>Edit</b> (BR-ERASE)")  # text, never markup
        assert context.request.get(f"{api}/patients/{pid}").json()["version"] == 2
        look_at(page, page.locator("h1"), page.locator("[data-action=delete-session]"))

        # the session: the dialog says what is lost; Cancel keeps it
        page.locator("[data-action=delete-session]").click()
        dialog = page.locator("dialog.confirm")
        slow_expect(dialog).to_be_visible()
        slow_expect(dialog).to_contain_text(tr["sessions.delete_text"])
        box = dialog.bounding_box()
        assert box and box["width"] > 200 and box["height"] > 80  # shown, not a zero-size element
        look_at(page, dialog, dialog.get_by_role("button", name=tr["common.cancel"]),
                dialog.get_by_role("button", name=tr["common.delete_for_good"]))
        dialog.get_by_role("button", name=tr["common.cancel"]).click()
        slow_expect(dialog).to_have_count(0)
        assert context.request.get(f"{api}/sessions/{sid}").status == 200
        page.locator("[data-action=delete-session]").click()
        page.locator("dialog.confirm").get_by_role("button", name=tr["common.delete_for_good"]).click()
        slow_expect(page.locator("#sessions-table")).to_have_count(0)
        assert context.request.get(f"{api}/sessions/{sid}").status == 404
        assert not any((b / sha[:2] / sha[2:]).exists() for b in blobs)

        # the patient: a wrong identifier is refused in the dialog, the right one erases it
        page.locator("#delete-patient").click()
        dialog = page.locator("dialog.confirm")
        slow_expect(dialog).to_contain_text(tr["patient.delete_text"].replace("{id}", "BR-ERASE"))
        dialog.locator("input[name=confirm]").fill("BR-ERAS")
        dialog.get_by_role("button", name=tr["common.delete_for_good"]).click()
        slow_expect(dialog).to_contain_text(tr["patient.delete_mismatch"])
        look_at(page, dialog, dialog.get_by_text(tr["patient.delete_mismatch"]), dialog.locator("input[name=confirm]"))
        assert context.request.get(f"{api}/patients/{pid}").status == 200
        dialog.locator("input[name=confirm]").fill("BR-ERASE")
        dialog.get_by_role("button", name=tr["common.delete_for_good"]).click()
        slow_expect(page.locator("h1")).to_have_text(tr["patients.title"])
        look_at(page, page.locator("h1"))
        assert context.request.get(f"{api}/patients/{pid}").status == 404
        assert errors == []
    finally:
        context.close()
