"""Fixtures shared across the test tree.

``pg_url``: a new empty database on the PostgreSQL server named by ``CHAKAMO_TEST_POSTGRES_URL`` (which
``.ci/run`` starts and sets), dropped after the test; skipped when the variable is unset.

``browser``: a real headless Chromium (Debian's ``/usr/bin/chromium``, installed by ``.ci/run``) driven by
Playwright.  Playwright's own browser download cannot work on our machines (no network but the package
registries), so it launches the system binary.  Tests that use it skip when either is missing.
"""

from __future__ import annotations

import shutil

import pytest

#: Chromium flags for a closed network: without the background-networking ones Chromium keeps trying to
#: reach Google's hosts; SwiftShader gives WebGL in software (no GPU here).
CHROMIUM_ARGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-extensions", "--hide-scrollbars", "--enable-unsafe-swiftshader")


@pytest.fixture(scope="session")
def browser():
    """A Playwright ``Browser`` on the system Chromium, shared by the whole run."""
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("chromium not installed (apt-get install chromium)")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium, headless=True, args=list(CHROMIUM_ARGS))
        try:
            yield browser
        finally:
            browser.close()


@pytest.fixture
def pg_url():
    """URL of a new empty PostgreSQL database (``CHAKAMO_TEST_POSTGRES_URL``'s server; dropped after the test)."""
    import os

    from live_fixtures import fresh_database

    server = os.environ.get("CHAKAMO_TEST_POSTGRES_URL")
    if not server:
        pytest.skip("CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")
    with fresh_database(server) as url:
        yield url
