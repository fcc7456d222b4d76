"""The admin pages (static/views/admin.js) in real Chromium, in Portuguese and Spanish: users (create — a weak
password refused in the UI's language —, change role, disable, unlock), API tokens (create with a scope, shown once,
used by a hospital system; rotate; revoke after confirming) and the audit log (filter by action, page back).

What the pages did is read back through the API (the server's truth), and the token shown is used as a real
``Authorization: Bearer`` header.  Texts expected come from static/i18n/*.json.  A clinician sees neither the menu
entry nor the pages.  Same server as test_browser_e2e.py (its ``server`` fixture: the real app under uvicorn).
"""

from __future__ import annotations

import json
import urllib.request

from screens import NAVY, colour_share, rgb
from test_browser_e2e import (  # noqa: F401 - the fixtures are used by name
    EMAIL, PASSWORD, SETTINGS, _tables, log_in, open_page, server, slow_expect)

NEW_EMAIL, NEW_PASSWORD = "fisio.admin@clinic.test", "sete corujas pardas ao amanhecer"


def _bearer_get(url: str, token: str) -> int:
    """The status of GET ``url`` sent as a hospital system sends it: a bearer token, no cookie."""
    req = urllib.request.Request(url, headers={"Authorization": f"Bearer {token}", "Accept": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=60) as answer:
            return answer.status
    except urllib.error.HTTPError as err:
        return err.code


def test_admin_manages_users_tokens_and_reads_the_audit_log(browser, server, slow_expect):  # noqa: F811
    expect = slow_expect
    pt = _tables()["pt"]
    context, page, errors = open_page(browser, "pt-PT")
    try:
        log_in(page, server)
        expect(page.locator("#nav-admin")).to_have_text(pt["nav.admin"])
        page.locator("#nav-admin").click()
        expect(page.locator("h1")).to_have_text(pt["admin.title_users"])
        api = f"{server}/api/v1"

        # --- a user: a weak password is refused in Portuguese, a good one creates the account
        page.get_by_role("button", name=pt["admin.user_new"]).click()
        form = page.locator("#new-user-form")
        form.get_by_label(pt["login.email"]).fill(NEW_EMAIL)
        form.get_by_label(pt["admin.user_name"]).fill("Fisio Nova")
        form.get_by_label(pt["admin.user_password"]).fill("password1234")
        form.get_by_role("button", name=pt["admin.user_create"]).click()
        refusal = form.locator("[role=alert]")
        expect(refusal).to_be_visible()
        said = refusal.inner_text()
        assert "senha" in said.lower() or "palavra-passe" in said.lower() or "comum" in said.lower(), said
        form.get_by_label(pt["admin.user_password"]).fill(NEW_PASSWORD)
        form.get_by_role("button", name=pt["admin.user_create"]).click()
        expect(page.locator(".notice.info")).to_contain_text(NEW_EMAIL)
        users = {u["email"]: u for u in context.request.get(f"{api}/users").json()}
        row = page.locator(f"#users-table tr[data-user-id='{users[NEW_EMAIL]['id']}']")
        assert users[NEW_EMAIL]["role"] == "clinician" and users[NEW_EMAIL]["active"]

        # role change and disabling, each read back from the API; one's own row offers neither
        row.locator("select").select_option("read_only")
        expect(page.locator(".notice.info")).to_contain_text(pt["admin.user_changed"].split(":")[-1].strip())
        row = page.locator(f"#users-table tr[data-user-id='{users[NEW_EMAIL]['id']}']")
        row.locator("[data-action=disable]").click()
        expect(page.locator(f"#users-table tr[data-user-id='{users[NEW_EMAIL]['id']}']")).to_have_attribute(
            "data-active", "false")
        changed = {u["email"]: u for u in context.request.get(f"{api}/users").json()}[NEW_EMAIL]
        assert changed["role"] == "read_only" and changed["active"] is False
        me = page.locator(f"#users-table tr[data-user-id='{users[EMAIL]['id']}']")
        expect(me.locator("select")).to_be_disabled()
        expect(me.locator("[data-action=disable]")).to_have_count(0)
        me.locator("[data-action=unlock]").click()
        expect(page.locator(".notice.info")).to_be_visible()

        # --- a token limited to reading patients: shown once, honoured as a bearer token, rotated, revoked
        page.get_by_role("link", name=pt["admin.tab_tokens"]).click()
        expect(page.locator("h1")).to_have_text(pt["admin.title_tokens"])
        page.get_by_role("button", name=pt["admin.token_new"]).click()
        form = page.locator("#new-token-form")
        form.get_by_label(pt["admin.token_label"]).fill("PACS do hospital")
        form.get_by_label(pt["admin.token_days"]).fill("4000")            # beyond ten years: said before sending
        form.get_by_role("button", name=pt["admin.token_create"]).click()
        expect(form.locator("[role=alert]")).to_have_text(pt["admin.token_days_too_long"].replace("{max}", "3650"))
        form.get_by_label(pt["admin.token_days"]).fill("12,5")            # a decimal comma in Portuguese
        form.locator("input[type=checkbox][value='patients:read']").check()
        form.get_by_role("button", name=pt["admin.token_create"]).click()
        secret = page.locator("#token-secret")
        expect(secret).to_be_visible()
        token = secret.input_value()
        assert token and _bearer_get(f"{api}/patients", token) == 200
        assert _bearer_get(f"{api}/jobs/1", token) == 403              # outside its scope
        (listed,) = [t for t in context.request.get(f"{api}/tokens").json() if t["label"] == "PACS do hospital"]
        assert listed["scopes"] == ["patients:read"] and listed["expires_at"]
        page.reload()                                                    # shown once: gone when the page is drawn again
        expect(page.locator(f"#tokens-table tr[data-token-id='{listed['id']}']")).to_be_visible()
        # its scope in words, not the raw id
        expect(page.locator(f"#tokens-table tr[data-token-id='{listed['id']}']")).to_contain_text(
            f"{pt['scope_resource.patients']} — {pt['scope_action.read']}")
        expect(page.locator("#token-secret")).to_have_count(0)

        page.locator(f"#tokens-table tr[data-token-id='{listed['id']}'] [data-action=rotate]").click()
        expect(page.locator("#token-secret")).to_be_visible()
        successor = page.locator("#token-secret").input_value()
        assert successor != token and _bearer_get(f"{api}/patients", successor) == 200
        new_id = max(t["id"] for t in context.request.get(f"{api}/tokens").json())
        page.locator(f"#tokens-table tr[data-token-id='{new_id}'] [data-action=revoke]").click()
        dialog = page.locator("dialog.confirm")
        expect(dialog).to_contain_text(pt["admin.token_revoke_text"])
        dialog.get_by_role("button", name=pt["admin.token_revoke"]).click()
        expect(page.locator(f"#tokens-table tr[data-token-id='{new_id}']")).to_have_attribute("data-state", "revoked")
        assert _bearer_get(f"{api}/patients", successor) == 401

        # --- the audit log: enough events for two pages, a filter, paging back
        for _ in range(55):
            assert context.request.get(f"{api}/patients").status == 200
        page.get_by_role("link", name=pt["admin.tab_audit"]).click()
        expect(page.locator("h1")).to_have_text(pt["admin.title_audit"])
        rows = page.locator("#audit-table tbody tr")
        expect(rows).to_have_count(50)
        first_page = [int(x) for x in rows.evaluate_all("rs => rs.map(r => r.dataset.eventId)")]
        assert first_page == sorted(first_page, reverse=True)             # newest first
        page.locator("#audit-older").click()
        expect(page.locator("#audit-newest")).to_be_visible()
        expect(rows.first).not_to_have_attribute("data-event-id", str(first_page[0]))
        second_page = [int(x) for x in rows.evaluate_all("rs => rs.map(r => r.dataset.eventId)")]
        assert second_page and max(second_page) < min(first_page)
        page.locator("select[name=action]").select_option("token_revoke")
        page.get_by_role("button", name=pt["admin.audit_apply"]).click()
        expect(rows).to_have_count(1)
        expect(rows.first).to_have_attribute("data-action", "token_revoke")
        expect(rows.first).to_contain_text(pt["audit_action.token_revoke"])

        # the audit page at a tablet's width: nothing sideways, and a real page drawn (the header's navy band)
        page.set_viewport_size({"width": 768, "height": 900})
        page.locator("select[name=action]").select_option("")
        page.get_by_role("button", name=pt["admin.audit_apply"]).click()
        expect(rows).to_have_count(50)
        img = rgb(page.screenshot(full_page=True))
        assert img.shape[1] == 768, f"the page is {img.shape[1]} px wide at 768: it scrolls sideways"
        navy = colour_share(img[:40], NAVY)
        assert navy > 0.5, f"the header is not drawn ({navy:.0%} navy)"
        table = page.locator("#audit-table").bounding_box()
        assert table and table["x"] >= 0 and table["x"] + table["width"] <= 768
        assert errors == []
    finally:
        context.close()


def test_a_clinician_sees_no_admin_pages(browser, server, slow_expect):  # noqa: F811
    from app.cli import admin as admin_cli

    expect = slow_expect
    es = _tables()["es"]
    email = "clinico.sin.admin@clinic.test"
    admin_cli.create_user(SETTINGS[server], clinic="Clínica E2E", email=email, role="clinician", name="Clínico",
                          password=PASSWORD)
    context, page, errors = open_page(browser, "es-ES")
    try:
        log_in(page, server, email, PASSWORD)
        expect(page.locator("h1")).to_have_text(es["patients.title"])
        expect(page.locator("#nav-admin")).to_have_count(0)
        page.goto(f"{server}/#/admin/tokens")
        expect(page.locator("main [role=alert]")).to_have_text(es["admin.only_admins"])
        expect(page.locator("#tokens-table")).to_have_count(0)
        assert context.request.get(f"{server}/api/v1/tokens").status == 403
        assert json.dumps(errors) == "[]"
    finally:
        context.close()


def test_a_refused_role_change_is_undone_and_the_audit_day_is_local(browser, server, slow_expect):  # noqa: F811
    """A role change the server refuses (the acting admin was demoted meanwhile by another admin: 403) leaves the
    select showing the stored role, not the refused one; the audit log's "since" day is the admin's local day
    (Europe/Madrid: 2026-12-01 starts at 2026-11-30T23:00Z), not UTC midnight."""
    from app.cli import admin as admin_cli

    expect = slow_expect
    acting, other, target = "admin.degradado@clinic.test", "otra.admin@clinic.test", "objetivo@clinic.test"
    for email, role in ((acting, "admin"), (other, "admin"), (target, "clinician")):
        admin_cli.create_user(SETTINGS[server], clinic="Clínica E2E", email=email, role=role, name=email.split("@")[0],
                              password=PASSWORD)
    context, page, errors = open_page(browser, "es-ES", timezone_id="Europe/Madrid")
    second = browser.new_context()
    try:
        log_in(page, server, acting, PASSWORD)
        expect(page.locator("#nav-admin")).to_be_visible()
        page.goto(f"{server}/#/admin/users")
        expect(page.locator("#users-table")).to_be_visible()
        users = {u["email"]: u for u in context.request.get(f"{server}/api/v1/users").json()}
        row = page.locator(f"#users-table tr[data-user-id='{users[target]['id']}']")
        expect(row.locator("select")).to_have_value("clinician")
        # the other admin demotes the acting one (a real refusal follows: 403, the admin role is needed)
        other_page = second.new_page()
        log_in(other_page, server, other, PASSWORD)
        expect(other_page.locator("#nav-admin")).to_be_visible()
        csrf = {"X-CSRF-Token": second.request.get(f"{server}/api/v1/auth/me").json()["csrf_token"]}
        r = second.request.patch(f"{server}/api/v1/users/{users[acting]['id']}", data={"role": "clinician"},
                                 headers=csrf)
        assert r.status == 200, r.text()
        row.locator("select").select_option("admin")
        expect(page.locator("[role=alert]").first).to_be_visible()
        expect(row.locator("select")).to_have_value("clinician")      # the stored role, not the refused one
        assert {u["email"]: u for u in second.request.get(f"{server}/api/v1/users").json()}[target]["role"] == \
            "clinician"
        got = page.evaluate("""async () => (await import('/static/views/admin.js')).sinceInstant('2026-12-01')""")
        assert got == "2026-11-30T23:00:00.000Z"
        assert page.evaluate("""async () => (await import('/static/views/admin.js')).sinceInstant('2026-07-01')""") \
            == "2026-06-30T22:00:00.000Z"                                # summer time
        assert json.dumps(errors) == "[]"
    finally:
        second.close()
        context.close()
