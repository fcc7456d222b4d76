"""The screenshot check of ``screens.py`` is not fooled by a blank page and sees a drawn one."""

from __future__ import annotations

import io

from screens import BLANK_SHARE, ink_share


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
