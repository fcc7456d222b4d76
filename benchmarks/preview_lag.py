"""How far the recording page's live knee angle preview lags behind the data (issue 18's goal: ≤ 200 ms).

Runs the real app (uvicorn on loopback, a temporary data folder) and its recording page in headless Chromium with
two emulated MetaMotion sensors: the browser tests' machinery (``tests/app/web/metawear_peripherals.py``: Chromium's
DevTools ``BluetoothEmulation`` for the chooser, connection and commands, and its documented stand-in for the
notifications, which the emulation cannot send).  The clinician's path: connect both sensors, identify the thigh,
record the standing and supine postures (the preview's segment axes), then start the task.

The task's samples have known content: the thigh stands still, vertical; the shank holds a knee flexion of 0° or
``--step-deg`` (40°) for a time drawn in ``--hold-s`` (0.5–0.8 s, so that the switches fall at every phase of
the page's refresh) and switches within one gyroscope notification (three
samples at ±step/0.03 s about the segment's z axis, the accelerometer's posture switching with it), so the preview's
flexion (the first of its three angles) must read ≈ 0° or ≈ 40° and cross 20° in the first frame that includes that
notification.  The notifications of
both sensors (acc and gyro three samples each, magnetometer one, at 100/100/20 Hz) are framed by the protocol's
Python twin (``tests/metawear_frames.py``) and leave the sensor at the BLE connection events after their last
sample (``--interval-ms``, 15 ms): that connection event is the packet's *arrival*.

Delivery and measurement happen inside the page, on one clock (``performance.now()``): a pacer dispatches each
packet through the stand-in when due, stamped with its arrival time (a busy page dispatches late, and the lateness
counts as lag); an init script watches the preview's text (a MutationObserver: the DOM time) and stamps the next
animation frame (``requestAnimationFrame``: the frame that shows it).  The lag of switch j: the first frame after
its arrival whose preview is on the new side of the midpoint, minus the arrival.  The frame stamp is an upper bound
by one frame (~17 ms) when the page writes the text inside an animation frame callback (today's page): the probe's
``requestAnimationFrame``, asked from there, runs in the frame after the one that paints it.

Printed: median, p95 and max over the switches, for the packet's handing to the page (the pacer's lateness: a
loaded machine's, which delays a real notification's event just as well), the DOM update and the frame; the
page's long tasks (over 50 ms, PerformanceObserver "longtask"); the load average and the CPU time of this process; ``--seconds`` of task per run, ``--repeats`` runs (each a fresh browser, page and session).
``--before COMMIT`` serves that commit's recording page — ``static/views/record.js`` and ``static/metawear/*.js``
(Playwright's routing), and the translation keys it has that today's tables lack — for an old-vs-new pair.
Usage: ``python -m benchmarks.preview_lag [--seconds 60] [--repeats 1] [--before COMMIT]``.
"""

from __future__ import annotations

import argparse
import base64
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT / "tests", ROOT / "tests" / "app" / "web"):     # the browser tests' machinery
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

from benchmarks.scene_first_frame import EMAIL, PASSWORD, chromium_path, file_at, served_app  # noqa: E402
from metawear_frames import notifications  # noqa: E402
from metawear_peripherals import STAND_IN, Bench, Peripheral  # noqa: E402

ARGS = ("--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-extensions",
        "--enable-experimental-web-platform-features")
G = 9.80665
MAG_UT = np.array([20.0, 0.0, -40.0])
#: the preview's text watched (its first number: the flexion), each change stamped (DOM) and its next frame stamped
PROBE = """
(() => {
  window.__previews = [];
  let last = null;
  const look = () => {
    const li = document.querySelector('li.preview');
    if (!li) return;
    const m = li.textContent.match(/(-?\\d+)°/);
    if (!m || m[1] === last) return;
    last = m[1];
    const rec = {dom: performance.now(), value: Number(m[1]), frame: null};
    window.__previews.push(rec);
    requestAnimationFrame(() => { rec.frame = performance.now(); });
  };
  new MutationObserver(look).observe(document, {subtree: true, childList: true, characterData: true});
  // the page's main thread blocked (tasks over 50 ms: [start, duration])
  window.__long = [];
  try {
    new PerformanceObserver((list) => { for (const e of list.getEntries()) window.__long.push([e.startTime, e.duration]); })
      .observe({type: 'longtask', buffered: true});
  } catch (_) { /* no long task timing */ }
  // the packets of a paced run: [[sensor name, base64 payload, due ms from the start], ...] sorted by due time
  window.__pace = (schedule) => {
    const t0 = performance.now() + 100;
    window.__paceT0 = t0;
    window.__paceDone = false;
    let i = 0;
    window.__dispatched = new Float64Array(schedule.length);    // when each packet was handed to the page
    const tick = () => {
      const now = performance.now();
      while (i < schedule.length && t0 + schedule[i][2] <= now) {
        const [name, b64, due] = schedule[i];
        window.__dispatched[i++] = performance.now();
        window.__notify(name, [[b64, performance.timeOrigin + t0 + due]]);
      }
      if (i < schedule.length) setTimeout(tick, Math.max(0, t0 + schedule[i][2] - performance.now()));
      else window.__paceDone = true;
    };
    setTimeout(tick, 100);
    return t0;
  };
})();
"""


def _still(seconds: float, acc_g: np.ndarray, t0_s: float = 0.0, gyr_dps: np.ndarray | None = None):
    """{kind: (t_s, SI values)} of a sensor held in one posture (``acc_g``: its specific force in g), optionally
    turning at ``gyr_dps``."""
    t = t0_s + np.arange(int(round(seconds * 100))) / 100.0
    tm = t0_s + np.arange(int(round(seconds * 20))) / 20.0
    gyr = np.zeros(3) if gyr_dps is None else np.deg2rad(gyr_dps)
    return {"acc": (t, np.tile(acc_g * G, (len(t), 1))), "gyr": (t, np.tile(gyr, (len(t), 1))),
            "mag": (tm, np.tile(MAG_UT, (len(tm), 1)))}


def _frames(streams: dict) -> list:
    every = [n for kind in ("acc", "gyr", "mag") for n in notifications(kind, *streams[kind])]
    return sorted(every, key=lambda n: n.arrival_s)


def task_streams(seconds: float, hold_s: tuple[float, float], step_deg: float, seed: int = 0):
    """The task's samples: the thigh vertical and still; the shank switching between 0° and ``step_deg`` of flexion
    within three gyroscope samples, held for a time drawn uniformly in ``hold_s`` (s; random, so that the switches
    fall at every phase of the page's refresh).  Returns ``(thigh, shank, switches)``: streams (t from 0) and
    ``[(index of the switch's last gyro sample, flexion after, deg)]``.

    Segment axes from the postures (standing: specific force along sensor y; supine: along x) are the sensor's, so
    a shank flexed by θ is the sensor turned by β = −θ about z: specific force (−sin θ, cos θ, 0) g, and the turn
    is ω_z = dβ/dt (preview.js (P2)–(P3))."""
    n = int(round(seconds * 100))
    t = np.arange(n) / 100.0
    rng = np.random.default_rng(seed)
    flex = np.zeros(n)
    gyr = np.zeros((n, 3))
    switches = []
    state = 0.0
    start = 0
    while True:
        start += int(round(rng.uniform(*hold_s) * 100))
        start -= start % 3                      # the three samples of one packed notification
        if start + 3 > n:
            break
        new = step_deg - state
        gyr[start:start + 3, 2] = np.deg2rad(-(new - state) / 0.03)
        flex[start + 2:] = new
        state = new
        switches.append((start + 2, new))
    theta = np.deg2rad(flex)
    acc = np.stack([-np.sin(theta), np.cos(theta), np.zeros(n)], axis=1) * G
    tm = np.arange(int(round(seconds * 20))) / 20.0
    mag = np.tile(MAG_UT, (len(tm), 1))
    thigh = _still(seconds, np.array([0.0, 1.0, 0.0]))
    shank = {"acc": (t, acc), "gyr": (t, gyr), "mag": (tm, mag)}
    return thigh, shank, switches


def _b64(payload: bytes) -> str:
    return base64.b64encode(payload).decode()


def _deliver_now(bench, page, sensors: dict, streams: dict) -> None:
    """A posture step's packets, delivered at once (not paced), stamped on the wall clock from now."""
    t_now = page.evaluate("performance.timeOrigin + performance.now()") / 1e3
    for name, p in sensors.items():
        shifted = {k: (t + t_now, v) for k, (t, v) in streams[name].items()}
        frames = _frames(shifted)
        for i in range(0, len(frames), 200):
            bench.notify(p, frames[i:i + 200])
            bench.pump()


def _session(base: str, token: str, external_id: str) -> int:
    import httpx

    h = {"Authorization": f"Bearer {token}"}
    with httpx.Client(base_url=f"{base}/api/v1", headers=h, timeout=60) as c:
        pid = c.post("/patients", json={"external_id": external_id, "side": "right"}).json()["id"]
        return c.post(f"/patients/{pid}/sessions", json={}).json()["id"]


#: the recording page's modules a ``--before`` commit is served with: its own, so that they agree with each other
PAGE_JS = ("static/views/record.js", "static/metawear/checks.js", "static/metawear/csv.js", "static/metawear/device.js",
           "static/metawear/files.js", "static/metawear/preview.js", "static/metawear/protocol.js",
           "static/metawear/recorder.js", "static/metawear/store.js", "static/metawear/timeline.js")


#: the translation tables, served to a ``--before`` page as today's plus the keys only that commit has
I18N = tuple(f"static/i18n/{code}.json" for code in ("en", "es", "pt"))


def old_page_js(commit: str) -> dict[str, bytes]:
    """The recording page's modules (PAGE_JS) as they were at ``commit``, by path, served instead of today's so that
    they agree with each other (an old record.js with today's recorder.js may call what it no longer has).  A commit
    git does not know, or without a recording page, is refused at once (SystemExit with git's reason); a module the
    commit lacks is served as today's.  The translation tables (I18N) are today's with the commit's keys that today's
    lack added: the old page's texts (its flexion preview's "record.preview", which the probe reads, deleted since)
    and today's modules' (login, navigation) both found."""
    out = {}
    for path in PAGE_JS:
        try:
            out[path] = file_at(commit, path)
        except FileNotFoundError as exc:
            if path == "static/views/record.js":
                raise SystemExit(f"--before {commit}: {exc}") from None
    for path in I18N:
        try:
            old = json.loads(file_at(commit, path))
        except FileNotFoundError:
            old = {}
        out[path] = json.dumps({**old, **json.loads((ROOT / path).read_text(encoding="utf-8"))},
                               ensure_ascii=False).encode()
    return out


def _serve(body: bytes, path: str):
    """A route handler answering ``body`` as ``path``'s type, JavaScript or JSON (one argument: Playwright passes the
    request to a second)."""
    kind = "application/json" if path.endswith(".json") else "text/javascript"
    return lambda route: route.fulfill(body=body, content_type=f"{kind}; charset=utf-8")


def one_run(browser, base: str, token: str, run: int, args) -> dict:
    """One fresh page and session through the postures to a paced task: the switches' lags (``dom``, ``frame``, ms),
    how late the pacer handed each switch's packet to the page (``late``, ms: the machine's, not the page's), the
    switches whose display was never seen (``unseen``), per switch |last value shown − flexion held| (``error``,
    deg), and the page's long tasks during the task (``long``, ms)."""
    context = browser.new_context(locale="en-US", viewport={"width": 1280, "height": 1000})
    context.set_default_timeout(180_000)
    context.add_init_script(STAND_IN)
    context.add_init_script(PROBE)
    for path, body in (args.old_js or {}).items():
        context.route(f"**/{path}", _serve(body, path))
    page = context.new_page()
    try:
        page.goto(f"{base}/#/patients")
        page.locator("input[name=email]").fill(EMAIL)
        page.locator("input[name=password]").fill(PASSWORD)
        page.locator("form.login button[type=submit]").click()
        page.locator("h1").wait_for()
        sid = _session(base, token, f"LAG-{run}-{time.time_ns()}")
        bench = Bench(browser.new_browser_cdp_session(), context.new_cdp_session(page), page)
        thigh = bench.add(Peripheral(f"D4:F1:A2:B3:C4:{run:02X}", f"MetaWear-T{run}"))
        shank = bench.add(Peripheral(f"C1:D2:E3:F4:A5:{run:02X}", f"MetaWear-S{run}"))
        sensors = {"thigh": thigh, "shank": shank}
        page.goto(f"{base}/#/sessions/{sid}/record")
        page.get_by_role("heading", level=1).wait_for()
        for k, p in enumerate((thigh, shank), start=1):
            bench.choose = p.address
            page.get_by_role("button", name="Connect a sensor").click()
            bench.wait(lambda k=k: page.locator(".sensor-state[data-state=connected]").count() == k, f"{p.name} connected")
        page.get_by_role("button", name="Which is the thigh sensor?").click()
        bench.wait(lambda: thigh.is_streaming and shank.is_streaming, "both streaming to identify")
        _deliver_now(bench, page, sensors, {"thigh": _still(1.5, np.array([0.0, 1.0, 0.0]), gyr_dps=np.array([0, 0, 120.0])),
                                            "shank": _still(1.5, np.array([0.0, 1.0, 0.0]))})
        bench.wait(lambda: page.locator("ul.sensors li[data-segment]").count() == 2, "the sensors identified")
        postures = {"standing": np.array([0.0, 1.0, 0.0]), "lying": np.array([1.0, 0.0, 0.0])}
        for role, acc_g in postures.items():
            step = page.locator(f"li.record-step[data-role={role}]")
            step.get_by_role("button", name="Start").click()
            bench.wait(lambda: thigh.is_streaming and shank.is_streaming, f"{role}: both streaming")
            _deliver_now(bench, page, sensors, {"thigh": _still(6.0, acc_g), "shank": _still(6.0, acc_g)})
            step.get_by_role("button", name="Stop and upload").click()
            bench.wait(lambda step=step: step.get_attribute("data-status") == "stored", f"{role} stored")
        step = page.locator("li.record-step[data-role=task]")
        step.get_by_role("button", name="Start").click()
        bench.wait(lambda: thigh.is_streaming and shank.is_streaming, "task: both streaming")

        streams_thigh, streams_shank, switches = task_streams(args.seconds, tuple(args.hold_s), args.step_deg, seed=run)
        interval = args.interval_ms
        schedule = []
        switch_due = {}
        for name, streams in ((thigh.name, streams_thigh), (shank.name, streams_shank)):
            for kind in ("acc", "gyr", "mag"):
                t_s, values = streams[kind]
                for n in notifications(kind, t_s, values):
                    due = math.ceil(n.arrival_s * 1e3 / interval + 1e-9) * interval     # the next connection event
                    schedule.append([name, _b64(n.payload), due])
                    if name == shank.name and kind == "gyr":
                        switch_due[round(n.arrival_s * 100)] = (due, (name, due, _b64(n.payload)))
        schedule.sort(key=lambda s: s[2])
        where = {(s[0], s[2], s[1]): i for i, s in enumerate(schedule)}
        t0 = page.evaluate("(s) => window.__pace(s)", schedule)
        bench.wait(lambda: page.evaluate("window.__paceDone === true"), "the task paced", timeout_s=args.seconds * 3 + 120)
        page.wait_for_timeout(1000)
        previews = page.evaluate("window.__previews")
        dispatched = page.evaluate("Array.from(window.__dispatched)")
        long_tasks = [d for start, d in page.evaluate("window.__long") if start >= t0]
    finally:
        context.close()
    mid = args.step_deg / 2
    dom, frame, unseen, error, late = [], [], 0, [], []
    for j, (k, after) in enumerate(switches):
        due, key = switch_due[k]
        arrival = t0 + due
        up = after > mid
        shown = next((p for p in previews if p["dom"] >= arrival and (p["value"] > mid) == up), None)
        if shown is None or shown["frame"] is None:
            unseen += 1
            continue
        dom.append(shown["dom"] - arrival)
        frame.append(shown["frame"] - arrival)
        late.append(dispatched[where[key]] - arrival)
        # the content: the last value shown before the next switch against the flexion held
        end = t0 + switch_due[switches[j + 1][0]][0] if j + 1 < len(switches) else math.inf
        held = [p["value"] for p in previews if shown["dom"] <= p["dom"] < end]
        error.append(abs(held[-1] - after))
    return {"dom": dom, "frame": frame, "late": late, "unseen": unseen, "error": error, "long": long_tasks}


def _row(label: str, xs: list[float]) -> str:
    p95 = float(np.percentile(xs, 95)) if xs else float("nan")
    return f"{label:26} {statistics.median(xs):8.0f} {p95:8.0f} {max(xs):8.0f} {len(xs):6d}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="task seconds per run")
    parser.add_argument("--hold-s", type=float, nargs=2, default=[0.5, 0.8],
                        help="range of the seconds between the shank's switches (drawn uniformly)")
    parser.add_argument("--step-deg", type=float, default=40.0)
    parser.add_argument("--interval-ms", type=float, default=15.0, help="BLE connection interval")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--before", default=None, metavar="COMMIT",
                        help="serve that commit's recording page (PAGE_JS) instead of today's (an old-vs-new pair)")
    args = parser.parse_args(argv)
    args.old_js = old_page_js(args.before) if args.before else None
    chromium = chromium_path()
    if chromium is None:
        print("chromium not installed: nothing measured")
        return 1
    from playwright.sync_api import sync_playwright

    cpu0 = time.process_time()
    load0 = os.getloadavg()
    out = {"dom": [], "frame": [], "late": [], "unseen": 0, "error": [], "long": []}
    with served_app("chakamo-preview-lag-") as (base, token):
        with sync_playwright() as pw:
            for run in range(args.repeats):
                # a browser per run: its Bluetooth emulation is enabled once per browser
                browser = pw.chromium.launch(executable_path=chromium, headless=True, args=list(ARGS))
                try:
                    one = one_run(browser, base, token, run, args)
                finally:
                    browser.close()
                for key, value in one.items():
                    out[key] += value
    load1 = os.getloadavg()
    print(f"Live angle preview lag ({'recording page of ' + args.before if args.before else 'today'}), headless Chromium, {args.repeats} run(s) of {args.seconds:.0f} s of task, a "
          f"{args.step_deg:.0f}° switch every {args.hold_s[0]}–{args.hold_s[1]} s, BLE interval {args.interval_ms:.1f} ms")
    print(f"load average before {load0[0]:.1f} / {load0[1]:.1f} / {load0[2]:.1f}, after {load1[0]:.1f} / "
          f"{load1[1]:.1f} / {load1[2]:.1f} on {os.cpu_count()} CPUs; CPU time of this process (server, bench) "
          f"{time.process_time() - cpu0:.1f} s")
    print(f"{'from the packet arrival to':26} {'median':>8} {'p95':>8} {'max':>8} {'n':>6}   (ms)")
    if out["frame"]:
        print(_row("its handing to the page", out["late"]))
        print(_row("the preview's text (DOM)", out["dom"]))
        print(_row("the frame showing it", out["frame"]))
    error = out["error"]
    print(f"switches never shown: {out['unseen']}; the value held on screen until the next switch is within "
          f"{max(error) if error else float('nan'):.0f}° of the flexion the samples hold (0° or {args.step_deg:.0f}°)")
    longs = out["long"]
    print(f"the page's long tasks (> 50 ms) during the task: {len(longs)}"
          + (f", longest {max(longs):.0f} ms" if longs else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
