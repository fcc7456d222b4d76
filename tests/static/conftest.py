"""A page of the repository's ``static/`` modules in the real (headless) Chromium, no server: Playwright's request
routing answers ``http://localhost/<path>`` from ``static/`` (``localhost`` is a secure context, as the app's
own origin must be for Web Bluetooth, IndexedDB quotas and ``crypto.subtle``)."""

from __future__ import annotations

import mimetypes
from pathlib import Path

import pytest

STATIC = Path(__file__).resolve().parents[2] / "static"
ORIGIN = "http://localhost"


def _serve(route):
    path = route.request.url[len(ORIGIN):].split("?")[0]
    if path == "/page.html":
        return route.fulfill(body='<!doctype html><meta charset="utf-8"><title>t</title>', content_type="text/html")
    file = STATIC / path.lstrip("/")
    if not file.is_file():
        return route.fulfill(status=404, body="")
    return route.fulfill(body=file.read_bytes(), content_type=mimetypes.guess_type(file.name)[0] or "text/javascript")


def _page(browser, **context_options):
    context = browser.new_context(**context_options)
    context.route(f"{ORIGIN}/**", _serve)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(f"{ORIGIN}/page.html")
    yield page
    context.close()
    assert not errors, f"JavaScript errors: {errors}"


@pytest.fixture
def static_page(browser):
    """A blank page of the ``localhost`` origin whose scripts ``import('/metawear/…')``; uncaught errors fail."""
    yield from _page(browser)


@pytest.fixture
def zoned_page(browser, request):
    """:func:`static_page` in the time zone ``request.param`` (an IANA name: the browser's local time)."""
    yield from _page(browser, timezone_id=request.param)
