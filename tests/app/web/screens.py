"""Looking at what a browser test's page shows (issue 17 §4: "every flow tested in Chromium with screenshots the test
looks at"): :func:`look_at` takes a screenshot of the viewport and checks it as a person glancing at it would.

``CHAKAMO_SCREENS_DIR`` set (an absolute path): every screenshot looked at is also written there, as
``<test>-<n>-<width>px.png`` (``n`` counts this process's screenshots), for a person to look at too."""

from __future__ import annotations

import io
import itertools
import os
import re
from pathlib import Path

import numpy as np

#: a desktop's and a tablet's width: every page is looked at in both (test_browser_layout.py, look_at_widths)
WIDTHS = (1280, 768)
#: the header's band and the primary button's fill (static/style.css --navy)
NAVY = (0x1D, 0x35, 0x57)
#: a page whose pixels are this share or less away from its most common colour is blank (a white or grey screen)
BLANK_SHARE = 0.01
#: how many times a locator is measured when its element was replaced while being measured (a line the page redraws
#: every frame, such as the recording page's angle preview), a frame apart
MEASURES = 40
#: this process's screenshots written to ``CHAKAMO_SCREENS_DIR`` so far (numbers them: files already in the folder,
#: of an earlier run or another process, do not)
_KEPT = itertools.count()


def rgb(image) -> np.ndarray:
    """A PNG's bytes or an RGB array, as an RGB array of ints."""
    if isinstance(image, (bytes, bytearray)):
        from PIL import Image

        image = np.asarray(Image.open(io.BytesIO(image)).convert("RGB"))
    return np.asarray(image).astype(int)


def ink_share(png: bytes) -> float:
    """The share of a PNG's pixels that differ (by more than 30 in R + G + B) from its most common colour."""
    img = rgb(png).reshape(-1, 3)
    colours, counts = np.unique(img, axis=0, return_counts=True)
    background = colours[np.argmax(counts)]
    return float((np.abs(img - background).sum(axis=1) > 30).mean())


def colour_share(image, colour: tuple[int, int, int], tolerance: int = 30) -> float:
    """The share of an image's pixels (a PNG's bytes or an RGB array) within ``tolerance`` (in R + G + B) of
    ``colour``."""
    return float((np.abs(rgb(image) - colour).sum(axis=-1) < tolerance).mean())


def _box(page, locator):
    """The locator's bounding box.  Playwright finds the element, then measures it: an element the page replaced in
    between is gone (None), so it is found again — the replacement — and measured, up to :data:`MEASURES` times."""
    for _ in range(MEASURES):
        box = locator.bounding_box()
        if box is not None:
            return box
        page.wait_for_timeout(16)
    return None


def _keep(png: bytes, width: int) -> None:
    folder = os.environ.get("CHAKAMO_SCREENS_DIR")
    if not folder:
        return
    if not Path(folder).is_absolute():   # a relative one wrote into whatever folder pytest ran from: the repo
        raise ValueError(f"CHAKAMO_SCREENS_DIR must be an absolute path, not {folder!r}")
    test = re.sub(r"\W+", "-", os.environ.get("PYTEST_CURRENT_TEST", "screen").split(" ")[0]).strip("-")
    Path(folder).mkdir(parents=True, exist_ok=True)
    (Path(folder) / f"{test}-{next(_KEPT):03d}-{width}px.png").write_bytes(png)


#: the elements of a locator (itself and what it holds) whose content overflows a box that does not show overflow
#: (``overflow: hidden`` or ``clip``): text cut off.  Passed over: a box that scrolls (``auto``, ``scroll``: what
#: overflows is reached by scrolling, the layout's way for wide tables and long lists), form fields (a field scrolls
#: its own typed text; a menu is checked by :data:`_CUT_OPTIONS`), what is not drawn or drawn 1 px or less (the
#: ``.visually-hidden`` labels), and the deliberate exception: a line cut with an ellipsis (``text-overflow:
#: ellipsis``) whose ``title`` holds its whole text (a pointer on it shows the rest), such as the wizard's
#: ``.file-name[title]``.
_CUT_TEXT = """(root) => [root, ...root.querySelectorAll('*')].flatMap((e) => {
    if (!(e instanceof HTMLElement) || !e.getClientRects().length || e.matches('input, textarea, select, option'))
      return [];
    const s = getComputedStyle(e);
    const shut = (o) => o === 'hidden' || o === 'clip';
    const x = shut(s.overflowX) && e.scrollWidth > e.clientWidth + 1;
    const y = shut(s.overflowY) && e.scrollHeight > e.clientHeight + 1;
    if (!(x || y) || (e.clientWidth <= 1 && e.clientHeight <= 1)) return [];
    if (s.textOverflow === 'ellipsis' && e.title && e.title.trim() === e.textContent.trim()) return [];
    const what = `${e.tagName.toLowerCase()}${e.className && typeof e.className === 'string' ? '.' + e.className.trim().split(/\\s+/).join('.') : ''}`;
    return [`${what} "${e.textContent.trim().slice(0, 60)}": ${e.scrollWidth}x${e.scrollHeight} in ${e.clientWidth}x${e.clientHeight}`];
  })"""

#: the options of the menus of a locator (itself or those it holds) whose text, once chosen, would not show whole in
#: the closed menu: each option goes in a copy of its menu sized to its content (Chromium sizes such a menu to its text
#: and arrow), which must be no wider than the menu.  (Step 3's menus were cut so: "De pie + eje de flexión de l".)
#: Passed over, as :data:`_CUT_TEXT`'s deliberate exception: a menu cut with an ellipsis whose ``title`` holds its
#: chosen option whole (the results page's analysis menu at 768 px; choosing another draws the page again).
_CUT_OPTIONS = """(root) => [...(root.matches('select') ? [root] : []), ...root.querySelectorAll('select')]
  .filter((s) => s.getClientRects().length)
  .filter((s) => !(getComputedStyle(s).textOverflow === 'ellipsis' && s.title && s.selectedIndex >= 0
                   && s.title.trim() === s.options[s.selectedIndex].text.trim()))
  .flatMap((s) => [...s.options].filter((o) => {
    const probe = s.cloneNode(false);
    probe.removeAttribute('id');
    probe.append(new Option(o.text));
    Object.assign(probe.style, { width: 'auto', minWidth: '0', maxWidth: 'none', position: 'absolute', visibility: 'hidden' });
    s.parentNode.append(probe);
    const need = probe.getBoundingClientRect().width;
    probe.remove();
    return need > s.getBoundingClientRect().width + 0.5;
  }).map((o) => `${s.name || s.id}: ${o.text}`))"""


def cut_text(locator) -> list[str]:
    """What :data:`_CUT_TEXT` finds cut in the element of ``locator`` and below it."""
    return locator.evaluate(_CUT_TEXT)


def cut_options(locator) -> list[str]:
    """What :data:`_CUT_OPTIONS` finds cut among the menus of ``locator`` (``name: option``)."""
    return locator.evaluate(_CUT_OPTIONS)


def look_at(page, *visible, on_screen: bool = False) -> bytes:
    """The viewport's screenshot, looked at: not blank (more than :data:`BLANK_SHARE` of it drawn), every locator of
    ``visible`` shown and inside the viewport's width (``on_screen``: and its height, so on the screenshot), no text
    cut inside it (:func:`cut_text`), no choice of its menus cut (:func:`cut_options`), and no sideways scroll;
    returns the PNG."""
    png = page.screenshot()
    width, height = page.viewport_size["width"], page.viewport_size["height"]
    _keep(png, width)
    assert ink_share(png) > BLANK_SHARE, "the page looks blank"
    for locator in visible:
        assert locator.is_visible(), f"{locator} is not shown"
        box = _box(page, locator)
        assert box is not None and box["x"] >= -1 and box["x"] + box["width"] <= width + 1, (locator, box)
        assert not on_screen or (box["y"] >= -1 and box["y"] + box["height"] <= height + 1), (locator, box, "off screen")
        cut = cut_text(locator)
        assert not cut, f"text cut at {width} px in {locator}: {cut}"
        cut = cut_options(locator)
        assert not cut, f"menu choices cut at {width} px in {locator}: {cut}"
    scroll, inner = page.evaluate("() => [document.documentElement.scrollWidth, innerWidth]")
    assert scroll <= inner, f"the page scrolls sideways: {scroll} px wide in {inner} px"
    return png


def look_at_widths(page, at, *visible, widths=WIDTHS, each=None) -> list[bytes]:
    """:func:`look_at` at each width of ``widths`` (the viewport's height kept), with the element of locator ``at``
    scrolled into view first, by the page's own ``scrollIntoView`` (no wait for a still element: a page may redraw
    lines at any moment) and ``at`` and every locator of ``visible`` on the screenshot; then ``each(width)``, a
    test's own look at that width, if given.  The viewport's size restored after, whatever failed.  The
    screenshots, one a width."""
    size = dict(page.viewport_size)
    shots = []
    try:
        for width in widths:
            page.set_viewport_size({"width": width, "height": size["height"]})
            at.evaluate("(e) => e.scrollIntoView({block: 'nearest'})")
            shots.append(look_at(page, at, *visible, on_screen=True))
            if each is not None:
                each(width)
    finally:
        page.set_viewport_size(size)
    return shots
