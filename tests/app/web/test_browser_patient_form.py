"""The patient form (static/views/records.js patientForm) in real Chromium, in English, Portuguese and Spanish
browsers: "165,5" and "165.5" are both 165.5 cm whatever the UI language (an ``<input type=number>`` followed the
browser's locale and turned "165,5" into 1655 with an English message); a malformed or out-of-range number is
refused in the UI's language before anything is sent; the sex field (the API's) is stored and shown; the
registration date is not called "Alta" (discharge, in a Spanish hospital); a new session's professional is the
logged-in user; the correction form shows the stored decimals in the UI's language and saves a change.

What was stored is read back through the API; the texts expected come from static/i18n/*.json.
"""

from __future__ import annotations

import pytest

from screens import look_at
from test_browser_e2e import _tables, log_in, open_page, server, slow_expect  # noqa: F401 - fixtures


@pytest.mark.parametrize("locale, code, typed", [("en-US", "en", "165,5"), ("pt-PT", "pt", "165.5"),
                                                 ("es-ES", "es", "165,5")])
def test_decimals_sex_and_professional_in_every_language(browser, server, slow_expect, locale, code, typed):  # noqa: F811
    expect = slow_expect
    tr = _tables()[code]
    context, page, errors = open_page(browser, locale)
    try:
        log_in(page, server)
        expect(page.locator("h1")).to_have_text(tr["patients.title"])
        page.get_by_role("button", name=tr["patients.new"]).click()
        form = page.locator("#new-patient")
        form.get_by_label(tr["patient.external_id"]).fill(f"FORM-{code}")
        form.get_by_label(tr["patient.sex"]).select_option("female")
        height = form.get_by_label(tr["patient.height_cm"])

        # refused in the UI's language, nothing sent
        height.fill("16,5,5")
        form.get_by_role("button", name=tr["patients.create"]).click()
        said = tr["patient.number_invalid"].split("{field}")[1].split("{example}")[0]
        expect(form.locator("[role=alert]")).to_contain_text(said.strip())
        expect(height).to_have_attribute("aria-invalid", "true")
        look_at(page, form.locator("[role=alert]"), height)   # the refusal is on screen beside the field
        height.fill("300")
        form.get_by_role("button", name=tr["patients.create"]).click()
        expect(form.locator("[role=alert]")).to_contain_text(tr["patient.number_range"].split("{min}")[0]
                                                             .replace("{field}", tr["patient.height_cm"]).strip())
        assert context.request.get(f"{server}/api/v1/patients", params={"q": f"FORM-{code}"}).json() == []

        height.fill(typed)
        form.get_by_label(tr["patient.mass_kg"]).fill("62,25" if code != "en" else "62.25")
        form.get_by_role("button", name=tr["patients.create"]).click()
        expect(page.locator("h1")).to_have_text(f"FORM-{code}")
        pid = int(page.url.rsplit("/", 1)[1])
        stored = context.request.get(f"{server}/api/v1/patients/{pid}").json()
        assert stored["height_cm"] == 165.5 and stored["mass_kg"] == 62.25 and stored["sex"] == "female"
        details = page.locator("dl.details")
        expect(details).to_contain_text(tr["sex.female"])
        expect(details).to_contain_text(tr["patient.created_at"])
        look_at(page, page.locator("h1"), details)
        assert tr["patient.created_at"] != "Alta"

        # the correction form shows the stored value as this language writes it, and saves a change
        page.get_by_role("button", name=tr["patient.edit"]).click()
        edit = page.locator("#edit-patient")
        shown = "165.5" if code == "en" else "165,5"
        expect(edit.get_by_label(tr["patient.height_cm"])).to_have_value(shown)
        edit.get_by_label(tr["patient.height_cm"]).fill("170,2")
        edit.get_by_role("button", name=tr["common.save"]).click()
        expect(page.locator("#edit-patient")).to_have_count(0)
        assert context.request.get(f"{server}/api/v1/patients/{pid}").json()["height_cm"] == 170.2

        # a new session: the professional is the logged-in user
        page.get_by_role("button", name=tr["sessions.new"]).click()
        me = context.request.get(f"{server}/api/v1/auth/me").json()["user"]
        expect(page.get_by_label(tr["session.professional"])).to_have_value(me["name"])
        assert errors == []
    finally:
        context.close()


def test_parse_decimal_refuses_what_cannot_be_read_for_sure(browser, server):  # noqa: F811
    """static/dom.js parseDecimal in real Chromium: one comma or point is the decimal mark; inner spaces ("7 5" was
    read as 75) and a mark before exactly three digits after a non-zero whole part ("1,655": 1655 to an English
    reader, 1.655 or 1655 to a Spanish one) are refused (NaN), the caller saying so in the UI's language."""
    context, page, errors = open_page(browser, "es-ES")
    try:
        page.goto(f"{server}/")
        got = page.evaluate("""async (cases) => { const { parseDecimal } = await import('/static/dom.js');
            return cases.map((c) => { const v = parseDecimal(c); return Number.isNaN(v) ? 'NaN' : v; }); }""",
                            ["165,5", "165.5", " 62.25 ", "", "7 5", "1 655", "1,655", "1.655", "-2,500", "0,175",
                             ".5", "12,5", "1,6555", "16,5,5", "abc"])
        assert got == [165.5, 165.5, 62.25, None, "NaN", "NaN", "NaN", "NaN", "NaN", 0.175,
                       0.5, 12.5, 1.6555, "NaN", "NaN"]
        assert errors == []
    finally:
        context.close()
