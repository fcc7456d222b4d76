"""Interactive HTML report: self-contained (no URL), translated, escaped, and carrying the figures' data."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from reports.html import _json_for_script, figure_specs, render_html
from reports.model import ANGLES, Patient

try:
    from test_excel import make_report_input
except ImportError:  # pragma: no cover - when tests are a package
    from tests.reports.test_excel import make_report_input

EVIL = '<script>alert("x")</script>&"\''


@pytest.fixture(scope="module")
def pages() -> dict[str, str]:
    return {lang: render_html(make_report_input(lang)) for lang in ("es", "en", "pt")}


def _without_plotly_js(page: str) -> str:
    """The page with the inlined plotly.js library (the first <script> of <head>) cut out."""
    start = page.index("<script>", page.index("<head>"))
    end = page.index("</script>", start)
    assert end - start > 1_000_000                                      # the library really is inlined
    return page[:start] + page[end:]


def test_no_external_reference(pages):
    for page in pages.values():
        # plotly.js names URLs inside its code (logo link, map-tile attributions for map traces, unused here);
        # everything else in the document carries no URL at all
        rest = _without_plotly_js(page)
        assert "http://" not in rest and "https://" not in rest and "//cdn" not in rest
        assert not re.search(r"""(?:src|href|action|poster)\s*=""", rest, re.I)
        assert not re.search(r"""url\(|@import""", rest, re.I)
        lower = rest.lower()
        assert "<link" not in lower and "<img" not in lower and "<iframe" not in lower
        # the whole document: no script, stylesheet or CSS resource loaded from a URL
        assert not re.search(r"<script[^>]*\bsrc\s*=", page, re.I)
        assert not re.search(r"<link\b", page, re.I)
        assert not re.search(r"""url\(\s*["']?\s*(?:https?:)?//""", page, re.I)
        assert "displaylogo:false" in rest                           # no plotly.com logo link in the mode bar


def test_plotly_js_is_the_installed_one(pages):
    from plotly.offline import get_plotlyjs

    assert get_plotlyjs() in pages["en"]
    assert pages["en"].count(get_plotlyjs()[:200]) == 1                 # embedded once


@pytest.mark.parametrize("lang, headings", [
    ("es", ["Informe interactivo de cinemática de rodilla", "Tarea completa en el tiempo", "Curvas normalizadas",
            "Rango de movimiento", "Fases del ciclo", "Calidad de la medida", "Paciente y sesión", "Impulso"]),
    ("en", ["Interactive knee kinematics report", "Whole task over time", "Normalised curves (mean ± SD)",
            "Range of motion", "Cycle phases", "Measurement quality", "Patient and session", "Impulse"]),
    ("pt", ["Relatório interativo de cinemática do joelho", "Tarefa completa no tempo", "Curvas normalizadas",
            "Amplitude de movimento", "Fases do ciclo", "Qualidade da medida", "Paciente e sessão", "Queda"]),
])
def test_translated_headings(pages, lang, headings):
    page = pages[lang]
    assert f'<html lang="{lang}">' in page
    *titles, phase = headings
    for h in titles:
        assert f"<h2>{h}" in page or f"<h1>{h}" in page, h     # a heading, not just a word on the page
    assert phase in page
    assert "<h2>" + headings[3] + "</h2>" in page


def test_numbers_from_results_with_language_decimal_mark(pages):
    # rom_deg flexion range = 10.04 ± 1.26 → printed with one decimal
    assert "10,0 ± 1,3" in pages["es"] and "10,0 ± 1,3" in pages["pt"]
    assert "10.0 ± 1.3" in pages["en"]
    assert "0.50 ± 0.01" in pages["en"] and "16.7 ± 0.3" in pages["en"]     # impulse s and %
    assert "Cycles detected: 3; accepted: 2; rejected: 1." in pages["en"]
    assert "1.2 %" in pages["en"]                                          # shank disturbance 0.012


def test_user_text_is_escaped():
    patient = Patient(name_or_id=EVIL, professional=EVIL, observations=EVIL, date="<b>2024</b>")
    page = render_html(make_report_input("en", patient))
    rest = _without_plotly_js(page)
    assert EVIL not in rest and "<script>alert" not in rest and "<b>2024" not in rest
    assert rest.count("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;&amp;&quot;&#x27;") >= 4   # title, h1, 2 rows
    # results.json texts (warnings, rejection messages) are escaped too
    assert "a &lt;warning&gt; &amp; more" in rest and "differs &lt;b&gt;much&lt;/b&gt;" in rest
    # the only <script> elements are ours: plotly.js, the JSON figure blocks and the drawing code
    assert len(re.findall(r"<script\b", page)) == 4


def test_json_for_script_cannot_close_the_element():
    s = _json_for_script({"t": "</script><!-- & \u2028"})
    assert "<" not in s and ">" not in s and "&" not in s
    assert json.loads(s) == {"t": "</script><!-- & \u2028"}


def _figures(page: str) -> dict[str, dict]:
    blocks = re.findall(r'<script type="application/json" id="(fig-[a-z]+)-data">(.*?)</script>', page, re.S)
    return {fid: json.loads(text) for fid, text in blocks}


def test_figures_embed_the_data():
    ri = make_report_input("en")
    page = render_html(ri)
    figs = _figures(page)
    assert set(figs) == {"fig-task", "fig-curves"}
    for fid in figs:
        assert f'<div class="plot" id="{fid}"></div>' in page
    task = figs["fig-task"]
    shapes = task["layout"]["shapes"]
    assert len(shapes) == ri.results["cycles"]["detected"] == 3             # one shaded band per cycle
    assert [s["name"] for s in shapes] == ["accepted", "accepted", "rejected"]
    assert [(s["x0"], s["x1"]) for s in shapes] == [tuple(b) for b in ri.results["cycles"]["boundaries_s"]]
    assert [a["text"] for a in task["layout"]["annotations"]] == ["1", "2", "3"]
    lines = [d for d in task["data"] if d.get("mode") == "lines"]
    assert len(lines) == 3
    for i, d in enumerate(lines):
        assert np.allclose(d["x"], ri.t_s, rtol=0, atol=0) and np.allclose(d["y"], ri.angles_deg[:, i], rtol=0, atol=0)
    curves = figs["fig-curves"]
    means = [d for d in curves["data"] if "hovertemplate" in d]
    for d, a in zip(means, ANGLES):
        assert np.allclose(d["y"], ri.results["curves"][a]["mean"], rtol=0, atol=0)
        assert np.allclose(d["customdata"], ri.results["curves"][a]["sd"], rtol=0, atol=0)
    bounds = [s["x0"] for s in curves["layout"]["shapes"]]                 # impulse|extension, extension|fall
    assert np.allclose(bounds, [100 / 6, 100 / 6 + 50.0])
    assert [a["text"] for a in curves["layout"]["annotations"]] == ["Impulse", "Extension", "Fall"]


def test_specs_are_valid_plotly_figures():
    import plotly.graph_objects as go

    for spec in figure_specs(make_report_input("pt")).values():
        go.Figure(spec)                                                      # raises on an unknown property


def test_missing_parts_do_not_break_the_page():
    ri = make_report_input("es", per_cycle=False, nan_rows=True)
    ri.results.pop("curves")
    ri.results["quality"] = {}
    page = render_html(ri)
    assert "No disponible" in page and "Sin avisos." in page
    figs = _figures(page)
    assert figs["fig-curves"]["data"] == []
    assert figs["fig-task"]["data"][0]["y"][10] is None                     # NaN → gap, valid JSON


def test_warnings_are_translated_by_code():
    from dataclasses import replace

    ri = make_report_input("es")
    warning = {"code": "ingestion_note", "message": "thigh task: gyr ran on 1.53 s after the common span (cut)",
               "params": {"variant": "stream_cut_after", "stream": "gyr", "seconds": 1.532, "segment": "thigh",
                          "role": "task"}}
    results = {**ri.results, "quality": {**ri.results["quality"], "warnings": [warning]}}
    for lang, expected in (("es", "Muslo, tarea: el giroscopio siguió registrando 1,53 s después del intervalo "
                                  "común (recortado)"),
                           ("pt", "Coxa, tarefa: o giroscópio continuou a registar 1,53 s após o intervalo comum "
                                  "(cortado)"),
                           ("en", warning["message"])):
        page = _without_plotly_js(render_html(replace(ri, results=results, language=lang)))
        assert expected in page and (warning["message"] in page) == (lang == "en")
