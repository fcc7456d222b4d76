"""The demo's report.html and scene.viser, looked at in a real (headless) browser.

A loopback HTTP server (127.0.0.1, free port) serves a temp folder holding the outputs of
:func:`app.pipeline.process.process_folder` on a simulated 3-cycle session, plus viser's static client
(:func:`reports.scene.static_client_path`) as ``index.html``.  Headless Chromium takes screenshots of

(a) ``report.html``: the plotly charts must be drawn — pixels of each angle's line colour exist;
(b) ``index.html?playbackPath=scene.viser``: the femur and tibia must be drawn — warm bone-coloured
    pixels exist (the rest of the client is white, neutral grey grid, a blue time bar and an orange
    "software WebGL" notice, none of them bone coloured);
(c) the single-file page of :func:`reports.scene.scene_html`, opened as ``file://``: the same.

Checked by hand that the checks bite: with ``Plotly.newPlot`` broken the report has 0 line-coloured
pixels; the client without a recording, or with a missing one, has 0 bone-coloured pixels.

The ``browser`` fixture (tests/conftest.py: Playwright on Debian's ``chromium``) skips when either is
missing.  Each check polls screenshots until it holds (or 90 s pass), so a slow, loaded machine only waits
longer: WebGL runs in software (SwiftShader) here.
"""

from __future__ import annotations

import functools
import http.server
import io
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    """Static files with Content-Length and no compression (what viser's playback needs), no log."""

    def log_message(self, format, *args):  # noqa: A002 - signature of the base class
        pass


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """Base URL of a loopback server over the demo outputs and viser's client."""
    from app.pipeline.demo import simulate_session, write_session
    from app.pipeline.process import process_folder
    from app.pipeline.results import build_results, report_input
    from reports.scene import scene_html, static_client_path

    root = tmp_path_factory.mktemp("browser")
    session_dir, out_dir = root / "session", root / "out"
    write_session(session_dir, simulate_session(seed=7, side="right", n_cycles=3))
    outcome, _ = process_folder(session_dir, out_dir)
    shutil.copyfile(static_client_path(), out_dir / "index.html")
    single = root / "scene_single.html"               # outside the served folder: opened as file://
    single.write_text(scene_html(report_input(outcome, build_results(outcome))), encoding="utf-8")
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             functools.partial(_QuietHandler, directory=str(out_dir)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", out_dir, single
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)


def _look(browser, url: str, png: Path, *, width: int, height: int, until: Callable[[np.ndarray], bool],
          timeout_s: float = 90.0) -> np.ndarray:
    """Open ``url`` in a fresh page and take screenshots until ``until(image)`` holds or ``timeout_s`` passes;
    the last (H, W, 3) uint8 image is returned (and saved to ``png`` for a human to look at)."""
    from PIL import Image

    page = browser.new_page(viewport={"width": width, "height": height})
    try:
        page.goto(url, wait_until="load", timeout=timeout_s * 1000)
        deadline = time.monotonic() + timeout_s
        while True:
            shot = page.screenshot(timeout=timeout_s * 1000)
            img = np.asarray(Image.open(io.BytesIO(shot)).convert("RGB"))
            if until(img) or time.monotonic() > deadline:
                png.write_bytes(shot)
                return img
            page.wait_for_timeout(500)
    finally:
        page.close()


def _near(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 30) -> int:
    """Number of pixels within ``tol`` (per channel) of ``rgb``."""
    return int(np.all(np.abs(img.astype(np.int16) - np.asarray(rgb, np.int16)) <= tol, axis=-1).sum())


_LINE_COLOURS = {"flexion": (0x1f, 0x77, 0xb4), "adduction": (0xff, 0x7f, 0x0e),   # html._ANGLE_COLOURS
                 "internal_rotation": (0x2c, 0xa0, 0x2c)}


def _lines_drawn(img: np.ndarray) -> bool:
    return all(_near(img, rgb) > 500 for rgb in _LINE_COLOURS.values())


def test_report_html_charts_drawn(browser, site, tmp_path):
    base, _, _ = site
    img = _look(browser, f"{base}/report.html", tmp_path / "report.png", width=1280, height=2000,
                until=_lines_drawn)
    assert img.std() > 10.0, "blank page"
    # the angle lines: only plotly draws them; the page's own CSS has no such colours
    for name, rgb in _LINE_COLOURS.items():
        assert _near(img, rgb) > 500, f"no {name} line drawn"


def _bone_pixels(img: np.ndarray) -> int:
    """Shaded bone (reports.bones.BONE_RGB, a warm off-white, lit to ~(140..230, ...)): red above blue by a
    little, not saturated (excludes the orange notice bar), not white."""
    rgb = img.astype(np.int16)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return int(((r - b >= 8) & (r - b <= 60) & (r >= g) & (r >= 60) & (r <= 245)).sum())


def _bones_drawn(img: np.ndarray) -> bool:
    return _bone_pixels(img) > 300


def test_scene_viser_plays_in_static_client(browser, site, tmp_path):
    base, out_dir, _ = site
    assert (out_dir / "scene.viser").stat().st_size > 1000
    img = _look(browser, f"{base}/index.html?playbackPath={base}/scene.viser", tmp_path / "scene.png",
                width=640, height=480, until=_bones_drawn)
    assert img.std() > 5.0, "blank page"
    n = _bone_pixels(img)
    assert n > 300, f"femur and tibia not drawn ({n} bone-coloured pixels)"


def test_scene_html_single_file_offline(browser, site, tmp_path):
    _, _, single = site
    img = _look(browser, single.as_uri(), tmp_path / "scene_single.png", width=640, height=480,
                until=_bones_drawn)
    n = _bone_pixels(img)
    assert n > 300, f"femur and tibia not drawn ({n} bone-coloured pixels)"
