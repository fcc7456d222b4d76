"""Logging in when one email has accounts in two clinics (issue 16 finding 10b: accounts are per clinic), in real
Chromium, in Portuguese: without the clinic the form refuses with the sentence that says to name it; with the
clinic's name typed in the form's clinic field the user lands in that clinic's patient list (read back through
``/auth/me``).  Texts from static/i18n/pt.json.  Both screens are looked at (``screens.look_at``: not blank, the refusal and the
clinic field shown, no sideways scroll)."""

from __future__ import annotations

from screens import look_at
from test_browser_e2e import SETTINGS, _tables, log_in, open_page, server, slow_expect  # noqa: F401 — fixtures

TWO = "two.clinics@clinic.test"
PASSWORD_A, PASSWORD_B = "amber falcon river stone", "quiet harbour violet maple"


def test_an_email_with_accounts_in_two_clinics_logs_in_by_naming_the_clinic(browser, server, slow_expect):  # noqa: F811
    from app.cli import admin as admin_cli

    settings = SETTINGS[server]
    for clinic, password in (("Clínica Norte", PASSWORD_A), ("Clínica Sul", PASSWORD_B)):
        admin_cli.create_clinic(settings, clinic)
        admin_cli.create_user(settings, clinic=clinic, email=TWO, role="clinician", name=clinic, password=password)
    pt = _tables()["pt"]
    context, page, errors = open_page(browser, "pt-PT")
    try:
        log_in(page, server, TWO, PASSWORD_B)  # no clinic named: which account is unknown
        slow_expect(page.locator("form.login .form-message")).to_contain_text(pt["login.failed"])
        look_at(page, page.locator("form.login .form-message"), page.locator("input[name=clinic]"))
        page.locator("input[name=clinic]").fill("Clínica Sul")
        page.locator("form.login button[type=submit]").click()
        slow_expect(page.locator("h1")).to_have_text(pt["patients.title"])
        look_at(page, page.locator("h1"))
        me = context.request.get(f"{server}/api/v1/auth/me").json()
        assert me["user"]["email"] == TWO and me["user"]["name"] == "Clínica Sul", me
        assert not errors, errors
    finally:
        context.close()


LONG_CLINIC = "Clínica de Fisioterapia e Reabilitação do Hospital Universitário de Santa Maria"


def test_a_long_clinic_name_in_the_header_can_be_read_whole(browser, server, slow_expect):  # noqa: F811
    """Below 1100 px the header ellipsises the clinic's name; its title carries it whole (look_at's cut-text check
    fails an ellipsis without one: the header's names had none)."""
    from app.cli import admin as admin_cli

    settings = SETTINGS[server]
    admin_cli.create_clinic(settings, LONG_CLINIC)
    admin_cli.create_user(settings, clinic=LONG_CLINIC, email="long.clinic@clinic.test", role="clinician",
                          name="Long Clinic", password=PASSWORD_A)
    pt = _tables()["pt"]
    context, page, errors = open_page(browser, "pt-PT")
    try:
        page.set_viewport_size({"width": 1000, "height": 900})
        log_in(page, server, "long.clinic@clinic.test", PASSWORD_A)
        slow_expect(page.locator("h1")).to_have_text(pt["patients.title"])
        clinic = page.locator("#who .clinic")
        assert clinic.evaluate("e => e.scrollWidth > e.clientWidth")  # cut at this width
        assert clinic.get_attribute("title") == LONG_CLINIC
        look_at(page, page.locator("#who"))
        assert not errors, errors
    finally:
        context.close()
