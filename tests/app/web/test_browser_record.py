"""Recording mode end to end: two emulated MetaMotion sensors stream a simulated session through the page into the
real app, and the session recorded in the browser gives the results of the same samples uploaded as files.

Set-up: the real app under uvicorn (``server`` of ``test_browser_e2e.py``); Debian's Chromium launched with
``--enable-experimental-web-platform-features`` (Linux Chromium exposes ``navigator.bluetooth`` only so);
Chromium's DevTools ``BluetoothEmulation`` drives two peripherals that speak the MetaWear protocol
(``metawear_peripherals.py``, whose docstring records what the emulation can and cannot do: it cannot send
notifications, so the packets cross the Web Bluetooth boundary through a documented stand-in installed in
this test's page only).  The streams are a simulated session (:func:`app.pipeline.demo.simulate_session`) framed
by the protocol's Python twin (``metawear_frames.py``).

The clinician's path, with a MetaMotion R (BMI160) on the thigh and a MetaMotion S (BMI270) on the shank:
connect the two sensors through the browser's chooser (battery and firmware shown; one blinks its LED when asked)
→ "which is the thigh sensor?": the sensor connected SECOND is moved (so the page must reorder them) → the four
steps, each started, streamed (the shank loses 1 % of its task notifications, and its link drops for 5 s in
the middle of the task: the page reconnects, re-configures and goes on), stopped and uploaded; each step is
stored only once the server's sha256 match the browser's (the network refuses one upload of the task step
once: the step stays in the browser's buffer, said so; the page is closed — it asks first — and opened again,
and "Upload again", with no sensor connected, sends only the files the server lacks); the standing step is cut short and redone (the page asks first, naming the six files it replaces; declined, nothing
changes; agreed, the first take's files are deleted only once the new take is acknowledged) → the link to processing appears.  Every sample the page received is
in the stored files, and the buffer is empty.

Then the truth: the files the browser uploaded are read back with the project's MetaBase reader and written
again with its writer (equal to the browser's text); the simulator's own samples (quantised as the boards send
them, on the true clock, none lost) are written by the project's MetaBase writer and uploaded to a second
session; both sessions are processed by the app's job: the recorded session finds the second's cycles but the
one or two the 5 s gap falls in, and its mean flexion range is within 2° of the second's; against the
simulator's motion, the cycles and their flexion range within 5°.
Waits are generous; nothing is timed.
"""

from __future__ import annotations

import hashlib
import re
import shutil
from contextlib import contextmanager

import numpy as np
import pytest

from metawear_frames import LED_PLAY, LED_STOP_AND_CLEAR, LSB, counts, led_pattern, sensor_notifications
from metawear_peripherals import STAND_IN, Bench, Peripheral
from screens import NAVY, colour_share, look_at_widths
from test_browser_e2e import (  # noqa: F401 - the fixtures are used by name
    csrf_header,
    PROCESS_WAIT_MS, SETTINGS, WAIT_MS, _api_session, log_in, server, slow_expect)

ARGS = ("--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-extensions",
        "--enable-experimental-web-platform-features")
ROLES = ("mag_calibration", "standing", "lying", "task")
CHUNK_S = 1.0          # simulated seconds of packets delivered per call
BLACKOUT_S = 5.0
#: the boards: the thigh's a MetaMotion R (BMI160), the shank's a MetaMotion S (BMI270, other data registers)
CHIP = {"thigh": "BMI160", "shank": "BMI270"}
#: the browser's time zone (UTC+14 all year, no daylight saving) and the local day of the simulated session there
TIMEZONE, UTC_OFFSET_H, LOCAL_DAY = "Pacific/Kiritimati", 14.0, "2026-11-23"
#: the still window GET /options is made to serve in this test (the pipeline's is 5 s)
SERVED_WINDOW_S = 4.0
#: what GET /options really serves as live_checks: the pipeline's still window and limits as its docstrings state them
#: (estimators.knee: 5 s, 0.05 rad/s, 0.3 m/s²), its 3 samples per cell and warning below 75 % of the 20 cells
#: (estimators.magnetometer), and the live-only values of app/choices.py (15 µT; 0.3 s, 60 °/s, 20 °/s)
SERVED_REAL = {"stillness": {"window_s": 5.0, "max_gyr_sd_rad_s": 0.05, "max_acc_sd_m_s2": 0.3},
               "coverage": {"min_cell_samples": 3, "complete_fraction": 0.75, "min_field_ut": 15.0},
               "cycles": {"average_s": 0.3, "rise_rad_s": pytest.approx(np.pi / 3), "fall_rad_s": pytest.approx(np.pi / 9)}}


@pytest.fixture
def bt_browser(browser):
    """A second Chromium of the same Playwright, with Web Bluetooth exposed (the shared one has not); one per test:
    its Bluetooth emulation can be enabled only once."""
    chromium = shutil.which("chromium")
    b = browser.browser_type.launch(executable_path=chromium, headless=True, args=list(ARGS))
    try:
        yield b
    finally:
        b.close()


@pytest.fixture(scope="module")
def simulated():
    from app.pipeline.demo import simulate_session

    return simulate_session(seed=7, side="right", n_cycles=8)


def _streams(simulated, segment, role):
    """A step's packets of one sensor; the shank's figure-eight moved onto the thigh's (both sensors record
    each step at once in the browser, while the simulator did them 80 s apart)."""
    streams = simulated.recordings[(segment, role)]
    if role == "mag_calibration" and segment == "shank":
        shift = simulated.recordings[("thigh", role)]["acc"][0][0] - streams["acc"][0][0]
        streams = {k: (t + shift, v) for k, (t, v) in streams.items()}
    return sensor_notifications(streams, CHIP[segment])


def _true_streams(simulated, segment, role, shift_s=0.0):
    """A step's samples as the board measured them (int16 counts over the sensitivity, in project units) on the
    simulator's true clock, moved as _streams moves them (and by ``shift_s``, a redo's later start)."""
    from app.pipeline.ingestion.units import unit_factor

    streams = simulated.recordings[(segment, role)]
    if role == "mag_calibration" and segment == "shank":
        shift_s += simulated.recordings[("thigh", role)]["acc"][0][0] - streams["acc"][0][0]
    board = {"acc": "g", "gyr": "deg/s", "mag": "uT"}
    return {k: (t + shift_s, counts(k, v) / LSB[k] * unit_factor(k, board[k])) for k, (t, v) in streams.items()}


def _deliver(bench, sensors, packets, blackout=None, lose_every=None):
    """Deliver both sensors' packets in arrival order, CHUNK_S at a time.  ``blackout = (sensor, t0_s)``: that
    sensor's link drops at t0_s and is back BLACKOUT_S later (its packets in between never arrive; delivery
    waits until the page has it streaming again).  ``lose_every = (sensor, n)``: every n-th packet of that
    sensor is lost in the air.  Returns the samples delivered and the samples lost per sensor."""
    delivered = {name: 0 for name in sensors}
    lost = {name: set() for name in sensors}
    if lose_every:
        # not within 1 s of a run's end or start (a loss needs 16 notifications of its stream after it)
        name, n = lose_every
        edges = [packets[name][0].arrival_s, packets[name][-1].arrival_s]
        if blackout:
            edges += [blackout[1], blackout[1] + BLACKOUT_S]
        gap = (blackout[1], blackout[1] + BLACKOUT_S) if blackout else (np.inf, np.inf)
        lost[name] = {k for k in range(n, len(packets[name]), n)
                      if min(abs(packets[name][k].arrival_s - e) for e in edges) > 1.0
                      and not gap[0] <= packets[name][k].arrival_s < gap[1]}
    start = min(p[0].arrival_s for p in packets.values())
    end = max(p[-1].arrival_s for p in packets.values())
    dropped = False
    t = start
    while t <= end:
        t_next = t + CHUNK_S
        if blackout and not dropped and t_next > blackout[1]:
            t_next = blackout[1]
        for name, p in sensors.items():
            chunk = [(k, n) for k, n in enumerate(packets[name]) if t <= n.arrival_s < t_next and k not in lost[name]]
            if blackout and name == blackout[0]:
                chunk = [(k, n) for k, n in chunk if not (blackout[1] <= n.arrival_s < blackout[1] + BLACKOUT_S)]
            if chunk:
                bench.notify(p, [n for _, n in chunk])
                delivered[name] += sum((len(n.payload) - 2) // 6 for _, n in chunk)
        bench.pump()
        t = t_next
        if blackout and not dropped and t >= blackout[1]:
            bench.disconnect(sensors[blackout[0]])
            dropped = True
            bench.pump()
        if blackout and dropped and sensors[blackout[0]].reachable is False and t >= blackout[1] + BLACKOUT_S:
            p = sensors[blackout[0]]
            p.reachable = True
            bench.wait(lambda p=p: p.is_streaming, f"{p.name} streaming again after its reconnection")
    return delivered, {name: sum((len(packets[name][k].payload) - 2) // 6 for k in v) for name, v in lost.items()}


def _identify(bench, page, simulated, thigh, shank):
    """"Which is the thigh sensor?": the thigh's packets are the task's gait (from its third second), the shank's the
    standing posture's, on one clock, 30 packets of each at a time until the page stops the streams; then both cards
    carry their segment."""
    page.get_by_role("button", name="Which is the thigh sensor?").click()
    bench.wait(lambda: thigh.is_streaming and shank.is_streaming, "both sensors streaming to identify")
    moving = [n for n in _streams(simulated, "thigh", "task") if n.arrival_s > simulated.role_epoch_s["task"] + 3]
    still = _streams(simulated, "shank", "standing")
    offset = still[0].arrival_s - moving[0].arrival_s
    for i in range(0, 600, 30):
        bench.notify(thigh, [type(n)(n.arrival_s + offset, n.kind, n.payload) for n in moving[i:i + 30]])
        bench.notify(shank, still[i:i + 30])
        bench.pump()
        if not thigh.is_streaming:
            break
    bench.wait(lambda: page.locator("ul.sensors li[data-segment]").count() == 2, "the sensors identified")


def _names(context, base, sid, role) -> set[str]:
    """The names of the files the server holds for ``role`` in session ``sid``."""
    session = context.request.get(f"{base}/api/v1/sessions/{sid}").json()
    return {r["file_name"] for r in session["recordings"] if r["role"] == role}


def _stored_files(context, base, sid):
    """The files the server stored for session ``sid``, read from its blob store: {(segment, role): [(name, bytes)]}."""
    from app.store.blobs import BlobStore

    store = BlobStore(SETTINGS[base].blob_dir)
    session = context.request.get(f"{base}/api/v1/sessions/{sid}").json()
    out: dict = {}
    for r in session["recordings"]:
        data = store.read(r["sha256"])
        assert hashlib.sha256(data).hexdigest() == r["sha256"]
        out.setdefault((r["segment"], r["role"]), []).append((r["file_name"], data))
    return out


def _upload_file(context, api: str, csrf: dict, sid: int, segment: str, role: str, path) -> None:
    """Upload the CSV at ``path`` to session ``sid`` as ``segment``'s ``role`` recording, as a clinic's file would."""
    r = context.request.post(f"{api}/sessions/{sid}/recordings", headers=csrf, multipart={
        "segment": segment, "role": role,
        "files": {"name": path.name, "mimeType": "text/csv", "buffer": path.read_bytes()}})
    assert r.status == 201, r.text()


def _process(context, base, sid) -> dict:
    api = f"{base}/api/v1"
    csrf = csrf_header(context, api)
    r = context.request.post(f"{api}/sessions/{sid}/process", data={"lang": "en"}, headers=csrf)
    assert r.status == 202, r.text()
    job_id = r.json()["job_id"]
    page = context.pages[0]
    for _ in range(PROCESS_WAIT_MS // 500):
        job = context.request.get(f"{api}/jobs/{job_id}").json()
        if job["status"] in ("done", "failed"):
            break
        page.wait_for_timeout(500)
    assert job["status"] == "done", job
    r = context.request.get(f"{api}/sessions/{sid}/results")
    assert r.status == 200, r.text()
    return r.json()


@contextmanager
def _logged_in(bt_browser, base, expect, **context_options):
    """A context of the Bluetooth Chromium (the notification stand-in installed), logged in on the patients' page:
    (context, page); closed at the end, and any JavaScript error of the page fails the test."""
    context = bt_browser.new_context(locale="en-US", viewport={"width": 1280, "height": 1000}, **context_options)
    context.set_default_timeout(WAIT_MS)
    context.add_init_script(STAND_IN)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        log_in(page, base)
        expect(page.get_by_role("heading", level=1)).to_have_text("Patients")
        yield context, page
    finally:
        context.close()
    assert not errors, f"JavaScript errors: {errors}"


def test_two_sensors_record_the_protocol_through_the_page(bt_browser, server, slow_expect, simulated, tmp_path):  # noqa: F811
    from app.pipeline.ingestion.metabase import read_metabase_csv, write_metabase_csv, write_recording_metabase

    expect = slow_expect
    # the browser 14 h east of Greenwich: the simulated session (2026-11-22 from 10:00 UTC) is recorded on the
    # 23rd there, the day MetaBase would name its files with and the report must print as the recordings' date
    with _logged_in(bt_browser, server, expect, timezone_id=TIMEZONE) as (context, page):
        sid = _api_session(context, server, "BLE-001", "right")
        bench = Bench(bt_browser.new_browser_cdp_session(), context.new_cdp_session(page), page)
        shank = bench.add(Peripheral("C1:D2:E3:F4:A5:B6", "MetaWear-S1", battery_percent=64, chip=CHIP["shank"]))
        thigh = bench.add(Peripheral("D4:F1:A2:B3:C4:E5", "MetaWear-S2", firmware="1.5.0", chip=CHIP["thigh"]))
        # the live checks take their thresholds from GET /options (app.choices.live_checks): served with another
        # still window here, the page must say that one (the real answer holds the pipeline's 5 s)
        served = {}

        def options(route):
            answer = route.fetch()
            body = answer.json()
            served["real"] = answer.json()["live_checks"]      # parsed again: the server's, untouched
            body["live_checks"]["stillness"]["window_s"] = SERVED_WINDOW_S
            route.fulfill(json=body)

        context.route("**/api/v1/options", options)
        page.goto(f"{server}/#/sessions/{sid}/record")
        expect(page.get_by_role("heading", level=1)).to_have_text("Record with the sensors")

        # --- two sensors through the browser's chooser; battery and firmware read from each
        for k, p in enumerate((shank, thigh), start=1):
            bench.choose = p.address
            page.get_by_role("button", name="Connect a sensor").click()
            bench.wait(lambda k=k: page.locator(".sensor-state[data-state=connected]").count() == k, f"{p.name} connected")
        cards = page.locator("ul.sensors li")
        expect(cards.nth(0)).to_contain_text("MetaWear-S1")
        expect(cards.nth(0)).to_contain_text("battery 64 %")
        expect(cards.nth(1)).to_contain_text("firmware 1.5.0")
        expect(page.get_by_role("button", name="Connect a sensor")).to_be_disabled()
        # looked at: both cards (name, battery, firmware, state), "Which is the thigh sensor?" offered
        look_at_widths(page, page.locator("section.record > div.card"), cards.nth(0), cards.nth(1),
                       cards.nth(0).get_by_role("button", name="Blink its light"),
                       page.get_by_role("button", name="Which is the thigh sensor?"))
        # which physical sensor is which: its card's button blinks that board's LED (the emulated board gets the
        # LED module's commands: stop and clear, the pattern, play), and only that board's
        before = (len(shank.commands), len(thigh.commands))
        cards.nth(0).get_by_role("button", name="Blink its light").click()
        blink = [LED_STOP_AND_CLEAR, led_pattern("green", 31, 0, 0, 200, 0, 500, 0, 6), LED_PLAY]
        bench.wait(lambda: shank.commands[before[0]:] == blink, "the shank's LED blinking")
        assert len(thigh.commands) == before[1]

        # --- the thigh is the sensor that moves (connected second: the page must reorder)
        _identify(bench, page, simulated, thigh, shank)
        expect(page.locator("ul.sensors li[data-segment=thigh]")).to_contain_text("MetaWear-S2")
        expect(page.locator("ul.sensors li[data-segment=shank]")).to_contain_text("MetaWear-S1")
        # looked at: the cards named by their segment, the swap offered, the first step ready to start
        look_at_widths(page, page.locator("section.record > div.card"), page.locator("ul.sensors li[data-segment=thigh] h3"),
                       page.locator("ul.sensors li[data-segment=shank] h3"),
                       page.get_by_role("button", name="Swap thigh and shank"))

        # --- the four steps
        sensors = {"thigh": thigh, "shank": shank}
        sent = {}
        # the network fails the task step's second upload (the shank's files) once: a fault outside the product
        flaky = {"role": None, "posts": 0}

        def network(route):
            if route.request.method == "POST" and flaky["role"] == "task":
                flaky["posts"] += 1
                if flaky["posts"] == 2:
                    return route.fulfill(status=503, content_type="application/json", body='{"detail": "busy"}')
            return route.continue_()

        page.route("**/api/v1/sessions/*/recordings", network)
        # standing twice: a first try cut short, then redone (its stored files are replaced)
        for attempt, role in enumerate(("mag_calibration", "standing", "standing", "lying", "task")):
            step = page.locator(f"li.record-step[data-role={role}]")
            if attempt == 2:
                # a redo asks first, naming the files it replaces and where they came from; declined: nothing
                # changes; agreed: the old files stay the step's data until the new take is acknowledged
                first_take = _names(context, server, sid, role)
                assert len(first_take) == 6
                asked = []
                page.once("dialog", lambda d, asked=asked: (asked.append(d.message), d.dismiss()))
                step.get_by_role("button", name="Redo").click()
                bench.wait(lambda asked=asked: asked, "the redo's question")
                expect(step).to_have_attribute("data-status", "stored")
                assert len(asked) == 1 and "6 file(s) on the server recorded with the sensors" in asked[0], asked
                assert all(n in asked[0] for n in first_take) and "uploaded as files" not in asked[0]
                assert not thigh.is_streaming and _names(context, server, sid, role) == first_take
                page.once("dialog", lambda d, asked=asked: (asked.append(d.message), d.accept()))
            step.get_by_role("button", name="Redo" if attempt == 2 else "Start").click()
            bench.wait(lambda: thigh.is_streaming and shank.is_streaming, f"{role}: both streaming")
            if attempt == 2:
                assert len(asked) == 2 and _names(context, server, sid, role) == first_take
            packets = {seg: _streams(simulated, seg, role) for seg in sensors}
            if attempt == 1:
                packets = {seg: p[:len(p) // 3] for seg, p in packets.items()}
            if attempt == 2:
                # the redo is recorded a moment later than the first take (its files are new files, with new names)
                packets = {seg: [type(n)(n.arrival_s + 1.0, n.kind, n.payload) for n in p] for seg, p in packets.items()}
            blackout = lose = None
            if role == "task":
                t0, t1 = packets["shank"][0].arrival_s, packets["shank"][-1].arrival_s
                blackout = ("shank", t0 + 0.5 * (t1 - t0))
                lose = ("shank", 100)
            sent[role] = _deliver(bench, sensors, packets, blackout, lose)
            if role == "task":
                assert shank.connections >= 2                      # the page reconnected on its own
                # and first quieted whatever the board still streamed (stop: acc power off, ...), then started it
                again = shank.commands[shank.dropped_at:]
                assert again[0] == bytes((0x03, 0x01, 0x00)) and bytes((0x03, 0x01, 0x01)) in again, again[:3]
            bench.wait(lambda step=step: step.locator("ul.live").count() == 1, f"{role}: live checks")
            expect(step.locator("ul.live")).to_contain_text(
                {"mag_calibration": "regions of directions", "standing": "still", "lying": "still",
                 "task": "cycles counted"}[role])
            if role in ("standing", "lying"):
                # the served still window, not a number of the page's own
                expect(step.locator("ul.live li[data-segment=thigh] .check")).to_contain_text(
                    f"{SERVED_WINDOW_S:.0f} s in a row needed")
                assert served["real"] == SERVED_REAL
            if role == "mag_calibration":
                expect(step.locator("ul.live li[data-segment=thigh] .check")).to_contain_text("(15 needed)")
            # every packet of both boards understood (none counted as bad)
            assert step.locator(".bad-packets").count() == 0, step.locator("ul.live").inner_text()
            if role == "task":
                # the angle preview runs (axes from this visit's standing and supine steps; its accuracy, and the
                # left leg's mirror: test_browser_record_results.py, tests/static/test_metawear_checks.py)
                expect(step.locator("ul.live li.preview")).to_have_text(re.compile(
                    r"Knee angles \(preview\): Flexion-extension -?\d+° · Adduction-abduction -?\d+° · "
                    r"Internal-external rotation -?\d+°"))
                # looked at: the step recording, its preview line (redrawn every 100 ms: look_at measures it again
                # when it was replaced meanwhile), each sensor's line, the stop
                look_at_widths(page, step, step.locator("ul.live li.preview"), step.locator("ul.live li[data-segment=thigh]"),
                               step.locator("ul.live li[data-segment=shank]"),
                               step.get_by_role("button", name="Stop and upload"))
            flaky["role"] = role
            step.get_by_role("button", name="Stop and upload").click()
            bench.wait(lambda step=step: step.get_attribute("data-status") in ("stored", "unsent"), f"{role} uploaded")
            if role == "task":
                # kept in the browser, said so; the page closed (it asks first) and opened again: the step is
                # offered from the buffer and uploaded again, without the sensors; the thigh's files already
                # stored are not re-sent
                assert step.get_attribute("data-status") == "unsent"
                expect(page.locator(".form-message [role=alert]")).to_contain_text("busy")
                # looked at: the refusal said at the page's top, the step kept to be sent again
                look_at_widths(page, page.locator("h1"), page.locator(".form-message [role=alert]"))
                look_at_widths(page, step, step.locator(".step-status"), step.get_by_role("button", name="Upload again"))
                assert page.evaluate("async () => (await (await import('/static/metawear/store.js'))"
                                     ".PacketStore.open()).steps(%d)" % sid) == ["task"]
                asked = []
                page.once("dialog", lambda d, asked=asked: (asked.append(d.type), d.accept()))
                page.reload()
                assert asked == ["beforeunload"]
                step = page.locator(f"li.record-step[data-role={role}]")
                expect(step).to_have_attribute("data-status", "unsent")
                step.get_by_role("button", name="Upload again").click()
                expect(step).to_have_attribute("data-status", "stored")
                assert flaky["posts"] == 3
            assert step.get_attribute("data-status") == "stored", page.locator(".form-message").inner_text()
            if role == "lying":
                # swapping thigh and shank after steps were recorded asks first, naming them; declined: unchanged
                warned = []
                page.once("dialog", lambda d, warned=warned: (warned.append(d.message), d.dismiss()))
                page.get_by_role("button", name="Swap thigh and shank").click()
                bench.wait(lambda warned=warned: warned, "the swap's warning")
                assert "Magnetometer calibration" in warned[0] and "Standing" in warned[0], warned
                expect(page.locator("ul.sensors li[data-segment=thigh]")).to_contain_text("MetaWear-S2")
            if attempt == 2:
                # the new take acknowledged: the first take's files are gone, the new take's six remain
                bench.wait(lambda role=role, old=first_take: not _names(context, server, sid, role) & old,
                           "the first take deleted")
                assert len(_names(context, server, sid, role)) == 6
        task_step = page.locator("li.record-step[data-role=task]")
        # the emulated air losses inside the shank's runs are counted (the 5 s gap is between runs, not a loss)
        expect(task_step.locator(".step-status")).to_contain_text(f"thigh 0, shank {sent['task'][1]['shank']}")
        expect(page.get_by_role("link", name="All four steps stored: process the session")).to_be_visible()
        # looked at, at both widths: the task's losses said, every step stored, the way on to processing drawn as
        # the page's primary button (navy), not a plain link under the last card (the class it had, "button", is
        # none of the stylesheet's)
        onward = page.get_by_role("link", name="All four steps stored: process the session")
        look_at_widths(page, page.locator("p.record-done"), task_step, task_step.locator(".step-status"), onward)
        assert colour_share(onward.screenshot(), NAVY) > 0.5, "the way on to processing is not drawn as a button"

        assert page.evaluate("""async () => { const s = await import('/static/metawear/store.js');
            const db = await s.PacketStore.open(); return (await db.steps(%d)).length; }""" % sid) == 0

        # --- the same samples as files: read back and written by the project's MetaBase reader and writer
        files = _stored_files(context, server, sid)
        assert sorted(files) == sorted((s, r) for s in sensors for r in ROLES)
        for (seg, role), parts in files.items():
            # every sample the page received is in the stored files (the redone standing's second take only)
            rows = sum(data.count(b"\n") - 1 for _, data in parts)
            assert rows == sent[role][0][seg], (seg, role, rows, sent[role][0][seg])
        again = tmp_path / "again"
        again.mkdir()
        for parts in files.values():
            assert len(parts) == 3
            for name, data in parts:
                (tmp_path / name).write_bytes(data)
                stream = read_metabase_csv(tmp_path / name)
                rewritten = write_metabase_csv(again / name, stream.kind, np.round(stream.t_s * 1e3).astype(np.int64),
                                               stream.values, utc_offset_h=UTC_OFFSET_H).read_bytes()
                assert rewritten == data, name                     # the browser wrote the writer's file

        # --- the truth as files: the simulator's samples (quantised as the boards send them, on the simulator's
        # true clock, none lost, no gap) written by the project's MetaBase writer, uploaded to a second session
        sid2 = _api_session(context, server, "BLE-002", "right")
        api = f"{server}/api/v1"
        csrf = csrf_header(context, api)
        truth_dir = tmp_path / "truth"
        truth_dir.mkdir()
        for seg in sensors:
            for role in ROLES:
                streams = _true_streams(simulated, seg, role, shift_s=1.0 if role == "standing" else 0.0)
                for path in write_recording_metabase(truth_dir, f"{role}-{seg}", {"thigh": "0AC0FFEE0001", "shank": "0AC0FFEE0002"}[seg],
                                                     streams, firmware="1.7.3"):
                    _upload_file(context, api, csrf, sid2, seg, role, path)

        recorded = _process(context, server, sid)
        uploaded = _process(context, server, sid2)
        # the browser named its files with its local time, as MetaBase does: the recordings' date is the local day
        # (the truth files, written at UTC+0, give the UTC day: 2026-11-22)
        assert recorded["session"]["recorded"] == {"first": LOCAL_DAY, "last": LOCAL_DAY, "zone": None}, (
            recorded["session"]["recorded"])
        assert uploaded["session"]["recorded"]["first"] == "2026-11-22"
        # the recorded session against the simulator's own samples: its stamps are rebuilt from arrival times
        # (within 12 ms of the true clock, tests/static/test_metawear_recording.py) and it lacks the shank's 5 s
        # gap and 1 % of its task packets, so: the cycles of the gap missing (at most two), and the mean flexion
        # range within 2° of the one the true samples give (tolerances fixed before the run)
        assert uploaded["cycles"]["detected"] - 2 <= recorded["cycles"]["detected"] <= uploaded["cycles"]["detected"]
        assert abs(recorded["rom_deg"]["flexion"]["range"]["mean"]
                   - uploaded["rom_deg"]["flexion"]["range"]["mean"]) < 2.0, (
            recorded["rom_deg"]["flexion"]["range"], uploaded["rom_deg"]["flexion"]["range"])
        # and against the simulator's truth: the cycles, and the flexion range over them
        truth = simulated.motion
        # (the shank's 5 s without data costs the one or two cycles it falls in)
        assert len(truth.cycles_s) - 2 <= recorded["cycles"]["detected"] <= len(truth.cycles_s), recorded["cycles"]
        true_range = np.mean([np.ptp(np.rad2deg(truth.knee_angles_at(np.linspace(a, b, 400))[:, 0]))
                              for a, b in truth.cycles_s])
        assert abs(recorded["rom_deg"]["flexion"]["range"]["mean"] - true_range) < 5.0, (
            recorded["rom_deg"]["flexion"]["range"], true_range)


def test_the_page_says_when_the_options_cannot_be_read(bt_browser, server, slow_expect):  # noqa: F811
    """GET /options failing (or answering without live_checks): the takes buffered by an earlier visit are still
    listed, the page says why nothing can be recorded (translated) and offers to ask again; "Which is the thigh
    sensor?" and "Upload again" stay disabled until the recorder exists; asked again with the server answering,
    recording is possible."""
    expect = slow_expect
    with _logged_in(bt_browser, server, expect) as (context, page):
        sid = _api_session(context, server, "BLE-003", "right")
        # a take of the lying step left in this browser's buffer by an earlier visit, never acknowledged
        assert page.evaluate("""async (sid) => { const s = await import('/static/metawear/store.js');
            const db = await s.PacketStore.open();
            db.add({ session: sid, step: 'lying', segment: 'thigh', stream: 'acc', run: 0, arrivalMs: 1,
                     bytes: new Uint8Array([3, 4, 1, 2, 3, 4, 5, 6]).buffer });
            await db.flush(); return db.steps(sid); }""", sid) == ["lying"]
        answer = {"mode": "fail"}

        def options(route):
            if answer["mode"] == "fail":
                return route.fulfill(status=503, content_type="application/json", body='{"detail": "busy"}')
            body = route.fetch().json()
            if answer["mode"] == "without":
                del body["live_checks"]
            return route.fulfill(json=body)

        context.route("**/api/v1/options", options)
        page.goto(f"{server}/#/sessions/{sid}/record")
        expect(page.get_by_role("heading", level=1)).to_have_text("Record with the sensors")
        alert = page.locator(".options-message [role=alert]")
        expect(alert).to_have_text("The recording settings could not be read from the server, so nothing can be "
                                   "recorded or uploaded yet. Check the connection and try again.")
        lying = page.locator("li.record-step[data-role=lying]")
        expect(lying).to_have_attribute("data-status", "unsent")
        expect(lying.get_by_role("button", name="Upload again")).to_be_disabled()

        bench = Bench(bt_browser.new_browser_cdp_session(), context.new_cdp_session(page), page)
        for k, address in enumerate(("C1:D2:E3:F4:A5:B6", "D4:F1:A2:B3:C4:E5"), start=1):
            bench.add(Peripheral(address, f"MetaWear-{k}"))
            bench.choose = address
            page.get_by_role("button", name="Connect a sensor").click()
            bench.wait(lambda k=k: page.locator(".sensor-state[data-state=connected]").count() == k, f"sensor {k}")
        identify = page.get_by_role("button", name="Which is the thigh sensor?")
        expect(identify).to_be_visible()
        expect(identify).to_be_disabled()

        answer["mode"] = "without"
        page.get_by_role("button", name="Try again").click()
        expect(alert).to_contain_text("lacks the live checks' thresholds")
        expect(identify).to_be_disabled()

        answer["mode"] = "real"
        page.get_by_role("button", name="Try again").click()
        expect(alert).to_have_count(0)
        expect(identify).to_be_enabled()
        expect(lying.get_by_role("button", name="Upload again")).to_be_enabled()
