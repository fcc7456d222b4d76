"""Looking at what a browser test's page shows (issue 17 §4: "every flow tested in Chromium with screenshots the test
looks at"): :func:`look_at` takes a screenshot of the viewport and checks it as a person glancing at it would.

``CHAKAMO_SCREENS_DIR`` set: every screenshot looked at is also written there (``<test>-<n>.png``), for a person to
look at too."""

from __future__ import annotations

import io
import os
import re
from pathlib import Path

import numpy as np

#: a desktop's and a tablet's width (test_browser_layout.py's two): a flow is looked at in both
WIDTHS = (1280, 768)
#: a page whose pixels are this share or less away from its most common colour is blank (a white or grey screen)
BLANK_SHARE = 0.01
#: how many times a locator is measured when its element was replaced while being measured (a line the page redraws
#: every frame, such as the recording page's angle preview), a frame apart
MEASURES = 40


def ink_share(png: bytes) -> float:
    """The share of a PNG's pixels that differ (by more than 30 in R + G + B) from its most common colour."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int).reshape(-1, 3)
    colours, counts = np.unique(img, axis=0, return_counts=True)
    background = colours[np.argmax(counts)]
    return float((np.abs(img - background).sum(axis=1) > 30).mean())


def _box(page, locator):
    """The locator's bounding box.  Playwright finds the element, then measures it: an element the page replaced in
    between is gone (None), so it is found again — the replacement — and measured, up to :data:`MEASURES` times."""
    for _ in range(MEASURES):
        box = locator.bounding_box()
        if box is not None:
            return box
        page.wait_for_timeout(16)
    return None


def _keep(png: bytes) -> None:
    folder = os.environ.get("CHAKAMO_SCREENS_DIR")
    if not folder:
        return
    test = re.sub(r"\W+", "-", os.environ.get("PYTEST_CURRENT_TEST", "screen").split(" ")[0]).strip("-")
    n = len(list(Path(folder).glob(f"{test}-*.png")))
    Path(folder).mkdir(parents=True, exist_ok=True)
    (Path(folder) / f"{test}-{n:02d}.png").write_bytes(png)


def look_at(page, *visible, on_screen: bool = False) -> bytes:
    """The viewport's screenshot, looked at: not blank (more than :data:`BLANK_SHARE` of it drawn), every locator of
    ``visible`` shown and inside the viewport's width (``on_screen``: and its height, so on the screenshot), and no
    sideways scroll; returns the PNG."""
    png = page.screenshot()
    _keep(png)
    assert ink_share(png) > BLANK_SHARE, "the page looks blank"
    width, height = page.viewport_size["width"], page.viewport_size["height"]
    for locator in visible:
        assert locator.is_visible(), f"{locator} is not shown"
        box = _box(page, locator)
        assert box is not None and box["x"] >= -1 and box["x"] + box["width"] <= width + 1, (locator, box)
        assert not on_screen or (box["y"] >= -1 and box["y"] + box["height"] <= height + 1), (locator, box, "off screen")
    scroll, inner = page.evaluate("() => [document.documentElement.scrollWidth, innerWidth]")
    assert scroll <= inner, f"the page scrolls sideways: {scroll} px wide in {inner} px"
    return png


def look_at_widths(page, at, *visible, widths=WIDTHS) -> list[bytes]:
    """:func:`look_at` at each width of ``widths`` (the viewport's height kept), with the element of locator ``at``
    scrolled into view first, by the page's own ``scrollIntoView`` (no wait for a still element: a page may redraw
    lines at any moment) and ``at`` and every locator of ``visible`` on the screenshot; the viewport's size restored
    after.  The screenshots, one a width."""
    size = dict(page.viewport_size)
    shots = []
    try:
        for width in widths:
            page.set_viewport_size({"width": width, "height": size["height"]})
            at.evaluate("(e) => e.scrollIntoView({block: 'nearest'})")
            shots.append(look_at(page, at, *visible, on_screen=True))
    finally:
        page.set_viewport_size(size)
    return shots
