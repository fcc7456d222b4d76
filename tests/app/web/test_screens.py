"""The screenshot checks of ``screens.py``: :func:`ink_share` is not fooled by a blank page and sees a drawn one, and
:func:`look_at` — on small pages drawn in Chromium (``page.set_content``) — refuses text cut by its box, an ellipsis
that hides text nowhere else, a menu choice cut once chosen, a page wider than the viewport and an element below
the screen, and passes an ellipsis whose ``title`` holds the whole text and a plain page.  Screenshots are written
only where ``CHAKAMO_SCREENS_DIR`` (an absolute path) says."""

from __future__ import annotations

import io

import pytest

from screens import BLANK_SHARE, NAVY, colour_share, ink_share, look_at, look_at_widths

#: a navy band (a page with ink on it) above the looked-at element
BAND = '<div style="height:150px;background:#1d3557"></div>'
LONG = "Ángulos de Euler ZYX de la tesis, rotación interna"


def _png(draw) -> bytes:
    from PIL import Image, ImageDraw

    img = Image.new("RGB", (400, 300), "white")
    draw(ImageDraw.Draw(img))
    out = io.BytesIO()
    img.save(out, format="PNG")
    return out.getvalue()


def test_a_blank_page_is_blank_and_a_drawn_one_is_not():
    assert ink_share(_png(lambda d: None)) <= BLANK_SHARE
    assert ink_share(_png(lambda d: d.rectangle((20, 20, 200, 120), fill=(30, 60, 160)))) > BLANK_SHARE
    assert ink_share(_png(lambda d: d.text((10, 10), ".", fill="black"))) <= BLANK_SHARE   # one dot is not a page


def test_colour_share_counts_the_pixels_of_a_colour():
    png = _png(lambda d: d.rectangle((0, 0, 199, 299), fill=NAVY))     # the left half
    assert colour_share(png, NAVY) == pytest.approx(0.5)
    assert colour_share(png, (255, 255, 255)) == pytest.approx(0.5)


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    try:
        yield context.new_page()
    finally:
        context.close()


def _draw(page, body: str):
    page.set_content(f"<!doctype html><html><body style='margin:8px;font:16px sans-serif'>{BAND}{body}</body></html>")
    return page.locator("#it")


@pytest.mark.parametrize("body, said", [
    (f"<p id=it style='width:120px;overflow:hidden;white-space:nowrap'>{LONG}</p>", "text cut"),
    (f"<div id=it><span style='display:block;width:120px;overflow:hidden;white-space:nowrap'>{LONG}</span></div>",
     "text cut"),                                                     # cut below the element looked at
    (f"<p id=it style='width:120px;height:20px;overflow:hidden'>{LONG}</p>", "text cut"),    # cut at its foot
    (f"<p id=it style='width:120px;overflow:hidden;white-space:nowrap;text-overflow:ellipsis'>{LONG}</p>", "text cut"),
    (f"<p id=it title='Ángulos' style='width:120px;overflow:hidden;white-space:nowrap;text-overflow:ellipsis'>{LONG}"
     "</p>", "text cut"),                                             # a title that does not hold the whole text
    (f"<form id=it><select name=c style='width:120px'><option>Grood</option><option>{LONG}</option></select></form>",
     "menu choices cut"),
    (f"<select id=it style='width:120px'><option>Grood</option><option>{LONG}</option></select>", "menu choices cut"),
    (f"<select id=it style='width:120px;text-overflow:ellipsis'><option>{LONG}</option></select>", "menu choices cut"),
    (f"<select id=it title='Grood' style='width:120px;text-overflow:ellipsis'><option>Grood</option>"
     f"<option selected>{LONG}</option></select>", "menu choices cut"),  # its title is not the chosen option
    ("<p id=it>narrow</p><p style='width:2000px'>wide</p>", "scrolls sideways"),
    ("<p id=it style='margin-top:2000px'>below</p>", "off screen"),
])
def test_look_at_refuses_what_a_person_would_not_see_whole(page, body, said):
    it = _draw(page, body)
    with pytest.raises(AssertionError, match=said):
        look_at(page, it, on_screen=True)


@pytest.mark.parametrize("body", [
    f"<p id=it>{LONG}</p>",
    f"<p id=it title='{LONG}' style='width:120px;overflow:hidden;white-space:nowrap;text-overflow:ellipsis'>{LONG}</p>",
    f"<div id=it style='width:120px;overflow:auto;white-space:nowrap'>{LONG}</div>",    # scrolls: reachable
    "<form id=it><select style='width:120px'><option>Grood</option><option>Euler</option></select></form>",
    f"<select id=it title='{LONG}' style='width:120px;text-overflow:ellipsis'><option>{LONG}</option></select>",
    "<p id=it>a<span style='position:absolute;width:1px;height:1px;overflow:hidden;clip:rect(0 0 0 0)'>"
    f"{LONG}</span></p>",                                              # a label for screen readers only
])
def test_look_at_passes_what_shows_whole(page, body):
    look_at(page, _draw(page, body), on_screen=True)


def test_look_at_widths_looks_at_each_width_and_restores_the_viewport(page):
    it = _draw(page, f"<p id=it>{LONG}</p>")
    seen = []
    assert len(look_at_widths(page, it, each=seen.append)) == 2
    assert seen == [1280, 768] and page.viewport_size == {"width": 1280, "height": 800}

    def refuse(width):
        raise AssertionError(f"refused at {width}")

    with pytest.raises(AssertionError, match="refused at 1280"):
        look_at_widths(page, it, each=refuse)
    assert page.viewport_size == {"width": 1280, "height": 800}


def test_screenshots_are_kept_only_where_chakamo_screens_dir_says(page, tmp_path, monkeypatch):
    it = _draw(page, f"<p id=it>{LONG}</p>")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("CHAKAMO_SCREENS_DIR", raising=False)
    look_at_widths(page, it)
    assert not list(tmp_path.rglob("*.png"))
    monkeypatch.setenv("CHAKAMO_SCREENS_DIR", "screens")            # relative: refused, nothing written
    with pytest.raises(ValueError, match="absolute"):
        look_at(page, it)
    assert not list(tmp_path.rglob("*.png"))
    kept = tmp_path / "kept"
    monkeypatch.setenv("CHAKAMO_SCREENS_DIR", str(kept))
    (kept / "old").mkdir(parents=True)
    look_at_widths(page, it)
    look_at(page, it)
    names = sorted(p.name for p in kept.glob("*.png"))
    assert len(names) == 3 and all("test_screenshots_are_kept" in n for n in names), names
    assert [n.rsplit("-", 1)[1] for n in names] == ["1280px.png", "768px.png", "1280px.png"], names
    assert len({n.rsplit("-", 2)[1] for n in names}) == 3, names      # numbered apart
