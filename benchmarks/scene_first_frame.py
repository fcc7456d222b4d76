"""How long the results page's 3D view stays blank, in Chromium (issue 17 §4: "blank for about 5 s"; goal: the first
frame within 1 s of opening it).

Runs the real app (uvicorn on loopback, a temporary data folder), processes the demo session through the API, then
opens the session's results page in headless Chromium (Debian's ``chromium``, software WebGL) as a clinician would:
the page opens, the clinician reads for ``--read-s`` seconds (0 and 3 by default), then scrolls to the 3D view.
An init script in every frame notes, on the wall clock, the client's own paints (not a screenshot's: a screenshot of
software WebGL takes seconds on a loaded machine):

* ``still``: the paint of the still first frame that ChakaMo draws from the recording (``#scene-still``,
  ``reports/scene_still.py``: the same meshes, poses and camera as viser's first frame, flat-shaded, no label), by
  the browser's Element Timing (``renderTime`` of the image marked ``elementtiming="scene-still"``: reported when it
  is painted in the viewport);
* ``viser``: viser's first WebGL draw of the bone meshes (``drawElements`` of ≥ 1000 indices: femur and tibia are
  ~14 500 each; the grid and the background draw fewer);
* ``charts``: the first plotly chart drawn (``.js-plotly-plot``), which the still now goes before.

Printed per variant and reading time (median and worst of ``--repeats`` fresh browser contexts, cold caches), from
the results page's navigation (``page →``) and from the scroll to the 3D view (``scroll →``, 0 when drawn before):
the first frame the clinician sees (the still where there is one, else viser's) and viser's own.

Variants (alternated run by run, so a changing load falls on each alike): ``now`` (this tree's page), ``main``
(the results page and 3D view of commit c3da1c0, before the still: viser's frame started with the page) and
``before`` (the results page of commit 95bd85e, an iframe with ``loading=lazy``, started only when scrolled to),
replayed through Playwright's routing on today's server; ``packed`` (today's page with viser's shipped single-file
client served in place of the unpacked one).  The load average and the benchmark's CPU time are printed beside the
table: timings on a shared machine are noisy.  ``--trace DIR`` adds one run per variant with Chromium's performance
trace (written there) and prints the page's main-thread tasks of 50 ms or more, with their longest parts: where the
time to the first frame goes.
Usage: ``python -m benchmarks.scene_first_frame [--repeats 3] [--read-s 0 3] [--variants main now] [--trace DIR]``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
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
#: the front-end files of these commits, for the variants that replay them: variant -> (commit, paths)
VARIANT_COMMITS = {"before": ("95bd85e", ("static/views/results.js",)),
                   "main": ("c3da1c0", ("static/views/results.js", "static/views/scene.js"))}
EMAIL, PASSWORD = "viewer@clinic.test", "correct horse battery staple"
ARGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--hide-scrollbars",
        "--enable-unsafe-swiftshader")
#: the first WebGL draw of many indices (the bone meshes), on the wall clock, in whichever frame draws it; the still's
#: paint (Element Timing) and the first plotly chart in the page
INIT = """
(() => {
  try {
    new PerformanceObserver((list) => {
      for (const e of list.getEntries()) {
        if (e.identifier === "scene-still" && e.renderTime && !window.__still) window.__still = performance.timeOrigin + e.renderTime;
      }
    }).observe({ type: "element", buffered: true });
  } catch (_) { /* no Element Timing */ }
  if (window === window.top) {
    new MutationObserver(() => {
      if (!window.__charts && document.querySelector(".js-plotly-plot")) window.__charts = performance.timeOrigin + performance.now();
    }).observe(document, { childList: true, subtree: true });
  }
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


@contextlib.contextmanager
def served_app(prefix: str = "chakamo-bench-"):
    """:func:`_serve` on a temporary data folder (named ``prefix``…): yields ``(base_url, token)``; on leaving, the
    server stops and the folder is deleted."""
    tmp = Path(tempfile.mkdtemp(prefix=prefix))
    try:
        base, token, stop = _serve(tmp / "data")
        try:
            yield base, token
        finally:
            stop()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def chromium_path() -> str | None:
    """Debian's ``chromium`` (the browser both benchmarks drive), or None when it is not installed."""
    return shutil.which("chromium")


def file_at(commit: str, path: str) -> bytes:
    """The file ``path`` (from the repository's root) as it was at ``commit``: ``git show commit:path``; a
    FileNotFoundError with git's reason when git does not know the commit or the file there."""
    done = subprocess.run(["git", "-C", str(ROOT), "show", f"{commit}:{path}"], capture_output=True)
    if done.returncode != 0:
        raise FileNotFoundError(f"git has no {path} at {commit} ({done.stderr.decode(errors='replace').strip()})")
    return done.stdout


def _demo_session(base: str, token: str) -> int:
    """The demo session (10 step-up cycles) uploaded and processed through the API; its id."""
    import httpx

    from app.pipeline.demo import simulate_session, write_session

    h = {"Authorization": f"Bearer {token}"}
    with tempfile.TemporaryDirectory(prefix="chakamo-demo-") as folder, \
            httpx.Client(base_url=f"{base}/api/v1", headers=h, timeout=120) as c:
        paths = write_session(Path(folder), simulate_session(seed=7, side="right", n_cycles=10))
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


def _fulfil_with(body: bytes):
    """A route handler answering with ``body`` as JavaScript."""
    return lambda route: route.fulfill(body=body, content_type="text/javascript; charset=utf-8")


def _one(browser, base: str, sid: int, variant: str, read_s: float, old_js: dict[str, dict[str, bytes]],
         trace: Path | None = None) -> dict[str, float]:
    """One cold run: ``{"still", "viser", "charts"}`` (ms from the results page's opening; ``still`` NaN when the page
    has none) and ``"still_scroll"``, ``"viser_scroll"`` (ms from the scroll to the 3D view, 0 when drawn before);
    with ``trace``, Chromium's performance trace of it (from the results page's opening to viser's first bone frame)
    is written there."""
    context = browser.new_context(viewport={"width": 1280, "height": 900}, locale="en-GB")
    context.set_default_timeout(180_000)
    context.add_init_script(INIT)
    for path, body in old_js.get(variant, {}).items():
        context.route(f"**/{path}", _fulfil_with(body))
    if variant == "packed":
        from app.web.headers import VISER_CSP
        from reports.scene import static_client_path

        shipped = static_client_path().read_bytes()
        context.route(lambda url: "/viser/index.html" in url, lambda route: route.fulfill(
            body=shipped, content_type="text/html", headers={"Content-Security-Policy": VISER_CSP}))
    page = context.new_page()
    try:
        page.goto(f"{base}/#/patients")
        page.locator("input[name=email]").fill(EMAIL)
        page.locator("input[name=password]").fill(PASSWORD)
        page.locator("form.login button[type=submit]").click()
        page.locator("h1").wait_for()
        if trace is not None:
            browser.start_tracing(page=page, path=str(trace), categories=list(TRACE_CATEGORIES))
            page.evaluate("performance.mark('results-page')")
        page.goto(f"{base}/#/sessions/{sid}")
        opened = page.evaluate("performance.timeOrigin + performance.now()")  # a hash change: no new navigation
        page.locator("#rom-table").wait_for()
        page.wait_for_timeout(read_s * 1000)
        page.locator(".scene-box").scroll_into_view_if_needed()
        scrolled = page.evaluate("performance.timeOrigin + performance.now()")
        has_still = page.locator("#scene-still").count() > 0 or page.evaluate("!!window.__still")
        for _ in range(2400):
            frame = next((f for f in page.frames if "/viser/" in f.url), None)
            bone = frame.evaluate("window.__firstBone || 0") if frame is not None else 0
            still, charts = page.evaluate("[window.__still || 0, window.__charts || 0]")
            if bone and charts and (still or not has_still):
                if trace is not None:
                    frame.evaluate("performance.mark('first-bone')")
                    browser.stop_tracing()
                nan = float("nan")
                return {"still": still - opened if still else nan, "viser": bone - opened, "charts": charts - opened,
                        "still_scroll": max(0.0, still - scrolled) if still else nan,
                        "viser_scroll": max(0.0, bone - scrolled)}
            page.wait_for_timeout(50)
        raise RuntimeError("the 3D view never drew the bones (or the still, or the charts never came)")
    finally:
        context.close()


#: light enough not to slow the page much: tasks, script compile and run, loading, user timing marks
TRACE_CATEGORIES = ("devtools.timeline", "v8.execute", "blink.user_timing", "loading", "toplevel")


def trace_summary(path: Path, min_ms: float = 50.0) -> list[str]:
    """The renderer main thread's tasks of at least ``min_ms`` in a trace written by :func:`_one`, each with its
    start (ms from the results page's opening) and its longest inner events (script URLs where the trace names them):
    where the time to the first frame went."""
    import json

    events = json.loads(path.read_text())
    events = events["traceEvents"] if isinstance(events, dict) else events
    names = {(e["pid"], e["tid"]): e["args"]["name"] for e in events if e.get("ph") == "M" and e.get("name") == "thread_name"}
    marks = {e["name"]: e["ts"] for e in events if "blink.user_timing" in e.get("cat", "") and e.get("name") in
             ("results-page", "first-bone")}
    t0 = marks.get("results-page", min(e["ts"] for e in events if e.get("ts")))
    lines = [f"first bone frame at {(marks['first-bone'] - t0) / 1000:.0f} ms" if "first-bone" in marks else ""]
    for key in (k for k, v in names.items() if v == "CrRendererMain"):
        spans = [e for e in events if (e["pid"], e["tid"]) == key and e.get("ph") == "X"]
        for task in sorted((e for e in spans if e.get("name") in ("RunTask", "ThreadControllerImpl::RunTask")
                            and e.get("dur", 0) >= min_ms * 1000),
                           key=lambda e: e["ts"]):
            inner = sorted((e for e in spans if e is not task and task["ts"] <= e["ts"] and
                            e["ts"] + e.get("dur", 0) <= task["ts"] + task["dur"] and e.get("dur", 0) >= 10_000),
                           key=lambda e: -e["dur"])[:3]
            what = "; ".join(f"{e['name']} {e['dur'] / 1000:.0f} ms"
                             + (f" {((e.get('args') or {}).get('data') or {}).get('url', '')[-40:]}"
                                if ((e.get("args") or {}).get("data") or {}).get("url") else "") for e in inner)
            lines.append(f"  {(task['ts'] - t0) / 1000:7.0f} ms  {task['dur'] / 1000:6.0f} ms  {what}")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--read-s", type=float, nargs="+", default=[0.0, 3.0])
    parser.add_argument("--trace", type=Path, default=None,
                        help="a folder: one more run per variant with Chromium's performance trace, summarised")
    parser.add_argument("--variants", nargs="+", choices=("before", "main", "packed", "now"), default=["main", "now"])
    args = parser.parse_args(argv)
    chromium = chromium_path()
    if chromium is None:
        print("chromium not installed: nothing measured")
        return 1
    from playwright.sync_api import sync_playwright

    old_js = {v: {p: file_at(c, p) for p in paths} for v, (c, paths) in VARIANT_COMMITS.items() if v in args.variants}
    with served_app("chakamo-scene-bench-") as (base, token):
        sid = _demo_session(base, token)
        rows = []
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=chromium, headless=True, args=list(ARGS))
            for read_s in args.read_s:
                runs = {v: [] for v in args.variants}
                for _ in range(args.repeats):
                    for variant in args.variants:   # alternated: main, now, main, now...
                        runs[variant].append((_one(browser, base, sid, variant, read_s, old_js), os.getloadavg()[0]))
                for variant, rs in runs.items():
                    rows.append((variant, read_s, [r for r, _ in rs], [load for _, load in rs]))
            traces = []
            if args.trace is not None:
                args.trace.mkdir(parents=True, exist_ok=True)
                for variant in args.variants:
                    path = args.trace / f"scene-{variant}.json"
                    _one(browser, base, sid, variant, args.read_s[0], old_js, trace=path)
                    traces.append((variant, path))
            browser.close()
    load = os.getloadavg()
    cpu = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = sum(r.ru_utime + r.ru_stime for r in cpu)
    print(f"3D view first frame, Chromium (software WebGL), {args.repeats} cold runs each; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} on {os.cpu_count()} CPUs at the end; "
          f"CPU time {cpu_s:.0f} s (this process and its browser)")
    print("first frame = ChakaMo's still of the recording's first state where the page has one, else viser's own; "
          "median (worst) ms")
    print(f"{'variant':8} {'read s':>6} {'load 1 min':>10} {'page→first frame':>18} {'scroll→first':>14} "
          f"{'page→viser frame':>18} {'scroll→viser':>14} {'page→charts':>14}")

    def cell(values: list[float]) -> str:
        values = [v for v in values if v == v]
        return f"{statistics.median(values):.0f} ({max(values):.0f})" if values else "—"

    for variant, read_s, rs, loads in rows:
        first = [r["still"] if r["still"] == r["still"] else r["viser"] for r in rs]
        first_scroll = [r["still_scroll"] if r["still_scroll"] == r["still_scroll"] else r["viser_scroll"] for r in rs]
        print(f"{variant:8} {read_s:6.1f} {statistics.median(loads):10.1f} {cell(first):>18} {cell(first_scroll):>14} "
              f"{cell([r['viser'] for r in rs]):>18} {cell([r['viser_scroll'] for r in rs]):>14} "
              f"{cell([r['charts'] for r in rs]):>14}")
    for variant, path in traces:
        print(f"\n{variant}: main-thread tasks ≥ 50 ms in {path} (ms from the results page's opening, length, longest parts)")
        print("\n".join(trace_summary(path)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
