"""``/docs`` in a real Chromium: Swagger UI reads the app's OpenAPI 3.1 document and lists its operations.

Issue 17: the bundled Swagger UI 4.15.5 answered HTTP 200 but drew "Unable to render this definition" (it reads
only ``openapi: 3.0.n``), and the old test checked the status code only.  Here the page itself must show the
operations of the document ``/openapi.json`` serves (every path and method, as Swagger UI lays them out), and
it loads nothing from another origin (clinics are often offline).
"""

from __future__ import annotations

from urllib.parse import urlparse

from screens import look_at
from test_browser_e2e import WAIT_MS, server, slow_expect  # noqa: F401 — fixtures


def test_docs_page_lists_the_operations_of_the_openapi_document(browser, server, slow_expect):  # noqa: F811
    expect = slow_expect
    context = browser.new_context(locale="en-US", viewport={"width": 1280, "height": 900})
    context.set_default_timeout(WAIT_MS)
    page = context.new_page()
    requested: list[str] = []
    page.on("request", lambda req: requested.append(req.url))
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        doc = context.request.get(f"{server}/openapi.json").json()
        assert doc["openapi"].startswith("3.1")
        wanted = {(method.upper(), path) for path, item in doc["paths"].items() for method in item
                  if method in ("get", "post", "put", "patch", "delete")}
        assert len(wanted) > 20

        page.goto(f"{server}/docs")
        expect(page.locator(".swagger-ui .info .title")).to_contain_text("ChakaMo")
        expect(page.locator(".opblock").first).to_be_visible()
        assert page.get_by_text("Unable to render this definition").count() == 0
        look_at(page, page.locator(".swagger-ui .info .title"), page.locator(".opblock").first)
        shown = set()
        for block in page.locator(".opblock-summary").all():
            method = block.locator(".opblock-summary-method").inner_text().strip().upper()
            path = block.locator(".opblock-summary-path").get_attribute("data-path")
            shown.add((method, path))
        assert wanted <= shown, f"operations of /openapi.json missing on /docs: {sorted(wanted - shown)[:10]}"

        # an operation opens and shows its parameters and its answers
        upload = page.locator(".opblock-summary-path[data-path='/api/v1/sessions/{session_id}/recordings']")
        upload.locator("xpath=ancestor::div[contains(@class,'opblock-summary')]").filter(
            has=page.locator(".opblock-summary-method", has_text="POST")).first.click()
        expect(page.locator(".opblock.is-open .responses-table").first).to_be_visible()
        opened = page.locator(".opblock.is-open")
        opened.locator(".responses-table").first.scroll_into_view_if_needed()
        look_at(page, opened.locator(".responses-table").first, opened.locator(".opblock-summary-path"))
        assert not errors, errors
        foreign = [u for u in requested if urlparse(u).netloc and urlparse(u).netloc != urlparse(server).netloc]
        assert not foreign, f"/docs fetched from another origin: {foreign}"
    finally:
        context.close()
