"""Looking at what a browser test's page shows (issue 17 §4: "every flow tested in Chromium with screenshots the test
looks at"): :func:`look_at` takes a screenshot of the viewport and checks it as a person glancing at it would."""

from __future__ import annotations

import io

import numpy as np

#: a page whose pixels are this share or less away from its most common colour is blank (a white or grey screen)
BLANK_SHARE = 0.01


def ink_share(png: bytes) -> float:
    """The share of a PNG's pixels that differ (by more than 30 in R + G + B) from its most common colour."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int).reshape(-1, 3)
    colours, counts = np.unique(img, axis=0, return_counts=True)
    background = colours[np.argmax(counts)]
    return float((np.abs(img - background).sum(axis=1) > 30).mean())


def look_at(page, *visible) -> bytes:
    """The viewport's screenshot, looked at: not blank (more than :data:`BLANK_SHARE` of it drawn), every locator of
    ``visible`` shown and inside the viewport's width, and no sideways scroll; returns the PNG."""
    png = page.screenshot()
    assert ink_share(png) > BLANK_SHARE, "the page looks blank"
    width = page.viewport_size["width"]
    for locator in visible:
        assert locator.is_visible(), f"{locator} is not shown"
        box = locator.bounding_box()
        assert box is not None and box["x"] >= -1 and box["x"] + box["width"] <= width + 1, (locator, box)
    scroll, inner = page.evaluate("() => [document.documentElement.scrollWidth, innerWidth]")
    assert scroll <= inner, f"the page scrolls sideways: {scroll} px wide in {inner} px"
    return png
