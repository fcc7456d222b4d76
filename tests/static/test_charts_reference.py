"""static/charts.js in a real (headless) browser: the flexion curve gets the reference's key ranges as boxes
(results.json ``reference.keypoints``), the other curves and a session without a reference get none.

The page and its modules are answered by Playwright's request routing from the repository's ``static/`` folder
and the installed plotly package (what ``GET /vendor/plotly.min.js`` serves), so no server runs."""

from __future__ import annotations

import json
import math
import mimetypes
from pathlib import Path

import pytest

from estimators.motor_task import reference
from reports.html import _REFERENCE_COLOUR

STATIC = Path(__file__).resolve().parents[2] / "static"
ORIGIN = "http://chakamo.test"
PAGE = ('<!doctype html><meta charset="utf-8"><div id="a" style="width:600px;height:300px"></div>'
        '<div id="b" style="width:600px;height:300px"></div>')


def _serve(route):
    path = route.request.url[len(ORIGIN):].split("?")[0]
    if path == "/page.html":
        return route.fulfill(body=PAGE, content_type="text/html")
    if path == "/vendor/plotly.min.js":
        from plotly.offline import get_plotlyjs

        return route.fulfill(body=get_plotlyjs(), content_type="text/javascript")
    file = STATIC / path.lstrip("/")
    if not file.is_file():
        return route.fulfill(status=404, body="")
    return route.fulfill(body=file.read_bytes(), content_type=mimetypes.guess_type(file.name)[0] or "text/javascript")


@pytest.fixture
def page(browser):
    context = browser.new_context()
    context.route(f"{ORIGIN}/**", _serve)
    page = context.new_page()
    page.goto(f"{ORIGIN}/page.html")
    yield page
    context.close()


def _draw(page, keypoints) -> dict:
    curve = {"mean": [30 + 30 * math.sin(i / 16) for i in range(101)], "sd": [2.0] * 101}
    return page.evaluate("""async ([curve, keys]) => {
        const m = await import('/charts.js');
        await m.drawCurve(document.getElementById('a'), 'flexion', curve, {}, keys);
        await m.drawCurve(document.getElementById('b'), 'adduction', curve, {}, null);
        const rects = (id) => document.getElementById(id).layout.shapes.filter((s) => s.type === 'rect');
        return {a: rects('a'), b: rects('b'),
                drawn: document.querySelectorAll('#a .shapelayer path').length};
    }""", [curve, keypoints])


def test_the_flexion_curve_gets_the_reference_boxes(page):
    keys = json.loads(json.dumps(reference.compare(reference.GAIT, {})["keypoints"]))
    out = _draw(page, keys)
    assert [(s["x0"], s["x1"], s["y0"], s["y1"]) for s in out["a"]] == [
        (k.pct_low, k.pct_high, k.low_deg, k.high_deg) for k in reference.GAIT.keypoints]
    assert all(s["line"]["color"] == _REFERENCE_COLOUR for s in out["a"])  # the reports' colour
    assert out["drawn"] >= len(reference.GAIT.keypoints) and out["b"] == []


def test_no_keypoints_no_boxes(page):
    out = _draw(page, None)
    assert out["a"] == [] and out["b"] == []
