"""The results page's summary names the sensor-to-segment calibration the pipeline used (results.json
``calibration.protocol.segment``), and the one asked for beside it when the recordings allowed another, as the
reports' method line does (reports.labels.method_items): static/views/results.js calibrationUsed in real Chromium,
in every language, against the translation files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_browser_e2e import open_page, server  # noqa: F401 - the fixtures are used by name

I18N = Path(__file__).resolve().parents[3] / "static" / "i18n"


@pytest.mark.parametrize("lang, locale", [("es", "es-ES"), ("en", "en-GB"), ("pt", "pt-PT")])
def test_the_summary_names_the_calibration_used(browser, server, lang, locale):  # noqa: F811
    texts = json.loads((I18N / f"{lang}.json").read_text(encoding="utf-8"))
    context, page, errors = open_page(browser, locale)
    try:
        page.goto(f"{server}/")
        cases = [  # (results.json, the analysis' own calibration)
            ({"calibration_method": "static", "calibration": {"protocol": {"segment": "static"}}}, "static"),
            ({"calibration_method": "static", "calibration": {"protocol": {"segment": "standing_functional"}}}, "static"),
            ({"calibration_method": "functional",
              "calibration": {"protocol": {"segment": ["task_functional", "task_functional"]}}}, "functional"),
            ({"calibration_method": "functional"}, "functional"),  # an older results.json: what was asked
        ]
        got = page.evaluate("""async ([lang, cases]) => { const m = await import('/static/views/results.js');
            await (await import('/static/i18n.js')).setLanguage(lang, { remember: false });  // its table loaded
            return cases.map(([r, cal]) => m.calibrationUsed(r, { calibration: cal })); }""", [lang, cases])
        asked = texts["results.calibration_asked"]
        assert got == [texts["calibration.static"],
                       f"{texts['calibration.standing_functional']} ({asked.format(asked=texts['calibration.static'])})",
                       texts["calibration.task_functional"]
                       + f" ({asked.format(asked=texts['calibration.functional'])})",
                       texts["calibration.functional"]]
        assert errors == []
    finally:
        context.close()
