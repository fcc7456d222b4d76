"""How long the results page's 3D view stays blank, in Chromium (issue 17 §4: "blank for about 5 s"; goal: the first
frame within 1 s of opening it).

Runs the real app (uvicorn on loopback, a temporary data folder), processes the demo session through the API, then
opens the session's results page in headless Chromium (Debian's ``chromium``, software WebGL) as a clinician would:
the page opens, the clinician reads for ``--read-s`` seconds (0 and 3 by default), then scrolls to the 3D view.  An
init script in every frame notes the first WebGL draw of the bone meshes (``drawElements`` of ≥ 1000 indices: femur
and tibia are ~14 500 each; the grid and the background draw fewer) on the wall clock, so the numbers are the
client's own, not a screenshot's (a screenshot of software WebGL takes seconds on a loaded machine).

Printed per variant and reading time (median and worst of ``--repeats`` fresh browser contexts, cold caches):

* ``page → frame``: from the results page's navigation to the first bone frame;
* ``scroll → frame``: from the scroll to the 3D view to the first bone frame (0 when it was drawn before): what the
  clinician sees blank.

Variants: ``now`` (static/views/scene.js: the frame's source given once the page has drawn) and ``before`` (the
results page of commit 95bd85e, served in place of today's through Playwright's routing: an iframe with
``loading=lazy``, started only when scrolled to).  The load average is printed beside the table: timings on a
shared machine are noisy.  Usage: ``python -m benchmarks.scene_first_frame [--repeats 3] [--read-s 0 3]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BEFORE_COMMIT = "95bd85e"
EMAIL, PASSWORD = "viewer@clinic.test", "correct horse battery staple"
ARGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--hide-scrollbars",
        "--enable-unsafe-swiftshader")
#: the first WebGL draw of many indices (the bone meshes), on the wall clock, in whichever frame draws it
INIT = """
(() => {
  const mark = (count) => { if (count >= 1000 && !window.__firstBone) window.__firstBone = performance.timeOrigin + performance.now(); };
  for (const C of [window.WebGLRenderingContext, window.WebGL2RenderingContext]) {
    if (!C) continue;
    const de = C.prototype.drawElements;
    C.prototype.drawElements = function (mode, count) { mark(count); return de.apply(this, arguments); };
  }
})();
"""


def _serve(data_dir: Path):
    """The app on a loopback port (thread) with a clinic, its admin, and the demo session processed; returns
    ``(base_url, session_id, stop)``."""
    import uvicorn

    from app.cli import admin as admin_cli
    from app.settings import Settings
    from app.web.main import create_app

    settings = Settings(CHAKAMO_ENV="development", CHAKAMO_DATA_DIR=data_dir, CHAKAMO_WORKERS=1)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(create_app(settings), log_level="warning", access_log=False))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.05)
    admin_cli.create_clinic(settings, "Bench")
    admin_cli.create_user(settings, clinic="Bench", email=EMAIL, role="admin", name="Dra. Vista", password=PASSWORD)
    token = admin_cli.create_token(settings, clinic="Bench", role="clinician", label="bench")

    def stop() -> None:
        server.should_exit = True
        thread.join(timeout=30)
        sock.close()

    return f"http://127.0.0.1:{port}", token, stop


def _demo_session(base: str, token: str, folder: Path) -> int:
    """The demo session (10 step-up cycles) uploaded and processed through the API; its id."""
    import httpx

    from app.pipeline.demo import simulate_session, write_session

    paths = write_session(folder, simulate_session(seed=7, side="right", n_cycles=10))
    h = {"Authorization": f"Bearer {token}"}
    with httpx.Client(base_url=f"{base}/api/v1", headers=h, timeout=120) as c:
        pid = c.post("/patients", json={"external_id": "BENCH-3D", "side": "right"}).json()["id"]
        sid = c.post(f"/patients/{pid}/sessions", json={"step_height_m": 0.17}).json()["id"]
        files = [("files", (p.name, p.read_bytes(), "text/csv")) for p in sorted(paths) if p.suffix == ".csv"]
        c.post(f"/sessions/{sid}/recordings", files=files).raise_for_status()
        job = c.post(f"/sessions/{sid}/process", json={"lang": "en"}).json()["job_id"]
        while (j := c.get(f"/jobs/{job}").json())["status"] not in ("done", "failed"):
            time.sleep(0.3)
        if j["status"] != "done":
            raise SystemExit(f"processing failed: {j}")
    return sid


def _old_results_js() -> bytes:
    return subprocess.run(["git", "-C", str(ROOT), "show", f"{BEFORE_COMMIT}:static/views/results.js"],
                          capture_output=True, check=True).stdout


def _one(browser, base: str, sid: int, variant: str, read_s: float, old_js: bytes) -> tuple[float, float]:
    """One cold run: ``(page → frame, scroll → frame)`` in ms."""
    context = browser.new_context(viewport={"width": 1280, "height": 900}, locale="en-GB")
    context.set_default_timeout(180_000)
    context.add_init_script(INIT)
    if variant == "before":
        context.route("**/static/views/results.js", lambda route: route.fulfill(
            body=old_js, content_type="text/javascript; charset=utf-8"))
    page = context.new_page()
    try:
        page.goto(f"{base}/#/patients")
        page.locator("input[name=email]").fill(EMAIL)
        page.locator("input[name=password]").fill(PASSWORD)
        page.locator("form.login button[type=submit]").click()
        page.locator("h1").wait_for()
        page.goto(f"{base}/#/sessions/{sid}")
        opened = page.evaluate("performance.timeOrigin + performance.now()")  # a hash change: no new navigation
        page.locator("#rom-table").wait_for()
        page.wait_for_timeout(read_s * 1000)
        page.locator("#scene-frame").scroll_into_view_if_needed()
        scrolled = page.evaluate("performance.timeOrigin + performance.now()")
        frame = None
        for _ in range(1200):
            frame = next((f for f in page.frames if "/viser/" in f.url), None)
            bone = frame.evaluate("window.__firstBone || 0") if frame is not None else 0
            if bone:
                return bone - opened, max(0.0, bone - scrolled)
            page.wait_for_timeout(50)
        raise RuntimeError("the 3D view never drew the bones")
    finally:
        context.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--read-s", type=float, nargs="+", default=[0.0, 3.0])
    args = parser.parse_args(argv)
    chromium = shutil.which("chromium")
    if chromium is None:
        print("chromium not installed: nothing measured")
        return 1
    from playwright.sync_api import sync_playwright

    tmp = Path(tempfile.mkdtemp(prefix="chakamo-scene-bench-"))
    base, token, stop = _serve(tmp / "data")
    try:
        sid = _demo_session(base, token, tmp / "demo")
        old_js = _old_results_js()
        rows = []
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=chromium, headless=True, args=list(ARGS))
            for read_s in args.read_s:
                for variant in ("before", "now"):
                    runs = [_one(browser, base, sid, variant, read_s, old_js) for _ in range(args.repeats)]
                    page, scroll = [r[0] for r in runs], [r[1] for r in runs]
                    rows.append((variant, read_s, statistics.median(page), max(page), statistics.median(scroll),
                                 max(scroll)))
            browser.close()
    finally:
        stop()
        shutil.rmtree(tmp, ignore_errors=True)
    load = os.getloadavg()
    print(f"3D view first frame, Chromium (software WebGL), {args.repeats} cold runs each; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} on {os.cpu_count()} CPUs")
    print(f"{'variant':8} {'read s':>6} {'page→frame median':>18} {'worst':>8} {'scroll→frame median':>20} {'worst':>8}")
    for variant, read_s, pm, pw_, sm, sw in rows:
        print(f"{variant:8} {read_s:6.1f} {pm:15.0f} ms {pw_:5.0f} ms {sm:17.0f} ms {sw:5.0f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
