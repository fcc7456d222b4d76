"""The demo's report.html and scene.viser, looked at in a real (headless) browser.

A loopback HTTP server (127.0.0.1, free port) serves a temp folder holding the outputs of
:func:`app.process.process_folder` on a simulated 3-cycle session, plus viser's static client
(:func:`reports.scene.static_client_path`) as ``index.html``.  Debian's ``chromium`` takes screenshots of

(a) ``report.html``: the plotly charts must be drawn — pixels of each angle's line colour exist;
(b) ``index.html?playbackPath=scene.viser``: the femur and tibia must be drawn — warm bone-coloured
    pixels exist (the rest of the client is white, neutral grey grid, a blue time bar and an orange
    "software WebGL" notice, none of them bone coloured);
(c) the single-file page of :func:`reports.scene.scene_html`, opened as ``file://``: the same.

Checked by hand that the checks bite: with ``Plotly.newPlot`` broken the report has 0 line-coloured
pixels; the client without a recording, or with a missing one, has 0 bone-coloured pixels.

Skipped when ``chromium`` is not on PATH (Debian package ``chromium``).  WebGL runs in software
(SwiftShader) here, so the scene page is small and its virtual time short (~6 s wall).
"""

from __future__ import annotations

import functools
import http.server
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (apt-get install chromium)")

_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
          "--disable-background-networking", "--disable-component-update", "--disable-sync",
          "--disable-extensions", "--hide-scrollbars", "--enable-unsafe-swiftshader")


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    """Static files with Content-Length and no compression (what viser's playback needs), no log."""

    def log_message(self, format, *args):  # noqa: A002 - signature of the base class
        pass


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """Base URL of a loopback server over the demo outputs and viser's client."""
    from app.demo import simulate_session, write_session
    from app.process import process_folder
    from app.results import build_results, report_input
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


def _screenshot(url: str, png: Path, *, width: int, height: int, budget_ms: int) -> np.ndarray:
    """Headless Chromium screenshot of ``url`` after ``budget_ms`` of virtual time; (H, W, 3) uint8."""
    from PIL import Image

    with tempfile.TemporaryDirectory() as profile:
        proc = subprocess.run([CHROMIUM, *_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
                               f"--virtual-time-budget={budget_ms}", f"--screenshot={png}", url],
                              capture_output=True, text=True, timeout=120)
    assert png.is_file(), f"no screenshot (exit {proc.returncode}):\n{proc.stderr[-2000:]}"
    return np.asarray(Image.open(png).convert("RGB"))


def _near(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 30) -> int:
    """Number of pixels within ``tol`` (per channel) of ``rgb``."""
    return int(np.all(np.abs(img.astype(np.int16) - np.asarray(rgb, np.int16)) <= tol, axis=-1).sum())


def test_report_html_charts_drawn(site, tmp_path):
    base, _, _ = site
    img = _screenshot(f"{base}/report.html", tmp_path / "report.png", width=1280, height=2000, budget_ms=5000)
    assert img.std() > 10.0, "blank page"
    # the angle lines (html._ANGLE_COLOURS): only plotly draws them; the page's own CSS has no such colours
    for name, rgb in {"flexion": (0x1f, 0x77, 0xb4), "adduction": (0xff, 0x7f, 0x0e),
                      "internal_rotation": (0x2c, 0xa0, 0x2c)}.items():
        assert _near(img, rgb) > 500, f"no {name} line drawn"


def _bone_pixels(img: np.ndarray) -> int:
    """Shaded bone (reports.bones.BONE_RGB, a warm off-white, lit to ~(140..230, ...)): red above blue by a
    little, not saturated (excludes the orange notice bar), not white."""
    rgb = img.astype(np.int16)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return int(((r - b >= 8) & (r - b <= 60) & (r >= g) & (r >= 60) & (r <= 245)).sum())


def test_scene_viser_plays_in_static_client(site, tmp_path):
    base, out_dir, _ = site
    assert (out_dir / "scene.viser").stat().st_size > 1000
    img = _screenshot(f"{base}/index.html?playbackPath={base}/scene.viser", tmp_path / "scene.png",
                      width=640, height=480, budget_ms=500)
    assert img.std() > 5.0, "blank page"
    n = _bone_pixels(img)
    assert n > 300, f"femur and tibia not drawn ({n} bone-coloured pixels)"


def test_scene_html_single_file_offline(site, tmp_path):
    _, _, single = site
    img = _screenshot(single.as_uri(), tmp_path / "scene_single.png", width=640, height=480, budget_ms=500)
    n = _bone_pixels(img)
    assert n > 300, f"femur and tibia not drawn ({n} bone-coloured pixels)"
