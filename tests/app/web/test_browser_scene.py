"""The results page's 3D view (static/views/scene.js) in real Chromium, in English: the still first frame that ChakaMo
draws from the recording (GET scene.png, reports/scene_still.py: bone-coloured pixels in it) is painted first, then
the frame gets its source (not when scrolled to: no ``loading=lazy``) and the still gives way to viser's canvas
once the recording plays, and the jump-to-cycle control seeks viser's client to the cycle's start (the task's time axis:
results.json ``cycles.boundaries_s``) and plays from there — the client's own time field then reads the cycle's
start or a little after it, and the screenshot of the frame shows femur and tibia (the bone-colour check of
tests/reports/test_browser.py).  Nothing is timed here: ``python -m benchmarks.scene_first_frame`` measures."""

from __future__ import annotations

import io
import re

import numpy as np
import pytest
from test_browser_cycles import processed_session
from screens import rgb
from test_browser_e2e import (_bone_pixels, _poll_screenshot, _tables, log_in, open_page, server,  # noqa: F401
                              slow_expect)

from app.pipeline.demo import simulate_session, write_session


@pytest.fixture(scope="module")
def demo_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scene-demo")
    paths = write_session(folder, simulate_session(seed=5, side="left", n_cycles=4))
    return [{"name": p.name, "mimeType": "text/csv", "buffer": p.read_bytes()} for p in sorted(paths)
            if p.suffix == ".csv"]


def test_the_3d_view_loads_with_the_page_and_jumps_to_a_cycle(browser, server, slow_expect, demo_files):  # noqa: F811
    en = _tables()["en"]
    context, page, errors = open_page(browser, "en-GB", height=900)
    try:
        log_in(page, server)
        slow_expect(page.locator("h1")).to_have_text(en["patients.title"])
        api = f"{server}/api/v1"
        sid, _ = processed_session(context, page, server, demo_files, "EN-SCENE", "left", "en")
        r = context.request.get(f"{api}/sessions/{sid}/results").json()

        still = context.request.get(f"{api}/sessions/{sid}/scene.png")
        assert still.ok and still.headers["content-type"] == "image/png"
        assert _bone_pixels(rgb(still.body())) > 300, \
            "no bones in the still first frame"
        page.goto(f"{server}/#/sessions/{sid}")
        frame = page.locator("#scene-frame")
        # the source is set without scrolling to the view (the page's top is shown)
        slow_expect(frame).to_have_attribute("src", re.compile(r"^/viser/index\.html\?playbackPath="))
        assert frame.get_attribute("loading") is None
        slow_expect(page.locator(".scene-box")).to_have_attribute("data-ready", "true")
        # the still was painted before viser's frame got its source, and gave way to viser's canvas
        assert page.locator(".scene-box").get_attribute("data-still") == "painted"
        assert page.locator("#scene-still").count() == 0 and page.locator("#scene-still-note").count() == 0
        jump = page.locator("#scene-cycle")
        accepted = r["cycles"]["accepted_indices"]
        slow_expect(jump.locator("option")).to_have_count(len(accepted) + 1)
        k = accepted[2]
        start = r["cycles"]["boundaries_s"][k][0]
        option = en["scene.jump_option"].format(n=k + 1, start=f"{start:.1f}")
        frame.scroll_into_view_if_needed()  # as the clinician does (Chromium slows the timers of frames out of view)
        jump.select_option(label=option)
        field = page.frame_locator("#scene-frame").locator(".mantine-NumberInput-input")
        for _ in range(100):  # the client's time field follows at its next render
            value = float(field.input_value())
            if start - 0.05 <= value <= start + 3.0:
                break
            page.wait_for_timeout(50)
        assert start - 0.05 <= value <= start + 3.0, (value, start)  # at the cycle's start, playing on from it
        img = _poll_screenshot(frame, lambda im: _bone_pixels(im) > 300)
        assert _bone_pixels(img) > 300, "femur and tibia not drawn after the jump"
        before = float(field.input_value())
        page.wait_for_timeout(1200)
        assert float(field.input_value()) != before  # it plays on (from the cycle; the recording loops at its end)
        assert not errors, errors
    finally:
        context.close()


def test_bone_check_is_not_fooled_by_a_blank_frame():
    from PIL import Image

    white = Image.new("RGB", (200, 100), "white")
    buf = io.BytesIO()
    white.save(buf, format="PNG")
    assert _bone_pixels(np.asarray(Image.open(buf).convert("RGB"))) == 0
