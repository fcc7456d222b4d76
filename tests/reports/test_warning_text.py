"""Quality warnings translated by code (reports.warning_text).

The warnings come from the real estimators, provoked with bad recordings, so a change of an estimator's
English wording (which the translation table reads the numbers from until warnings carry ``params``)
fails here instead of silently printing English in a Spanish report.
"""

from __future__ import annotations

import re
import string

import numpy as np
import pytest

from estimators import knee
from estimators.disturbance import field_disturbance
from estimators.magnetometer import fit_ellipsoid
from estimators.motor_task import analyse_task
from reports import i18n
from reports.warning_text import warning_text

RNG = np.random.default_rng(4)


def _random_q(n: int) -> np.ndarray:
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _produced() -> list[dict]:
    """Warnings from the estimators on deliberately bad data, with the pipeline's prefixes."""
    out = []
    # heading between two unrelated orientation streams: mismatch, residual, drift
    out += [w.to_dict() for w in knee.heading_offset(_random_q(300), _random_q(300),
                                                     max_offset_rad=np.deg2rad(1.0)).warnings]
    # magnetometer: half a sphere, few samples, off-scale field (the pipeline prefixes "<Segment> sensor: ")
    d = RNG.normal(size=(150, 3))
    d[:, 2] = np.abs(d[:, 2])
    mag = 90.0 * d / np.linalg.norm(d, axis=1, keepdims=True) + RNG.normal(scale=4.0, size=(150, 3))
    cal = fit_ellipsoid(mag, model="sphere", expected_field_ut=45.0, min_samples=50)
    out += [{"code": w.code, "message": f"Thigh sensor: {w.message}"} for w in cal.quality.warnings]
    # posture calibration from shaking, short, g-unit recordings (messages start "<segment>: ")
    fs = 100.0
    stand = np.tile([0.0, 1.0, 0.0], (500, 1)) + RNG.normal(scale=0.3, size=(500, 3))
    sup = np.tile([0.6, 0.8, 0.0], (500, 1)) + RNG.normal(scale=0.3, size=(500, 3))
    gyr = RNG.normal(scale=0.5, size=(500, 3))
    seg = knee.calibrate_segment(stand, gyr, sup, gyr, fs_hz=fs, label="shank")
    out += [w.to_dict() for w in seg.warnings]
    out += [w.to_dict() for w in knee.mounting_warnings(seg, expected_up_sensor=(0.0, -1.0, 0.0), label="shank")]
    # the field at the sensor far from the calibrated one during the task
    q = np.tile([1.0, 0.0, 0.0, 0.0], (400, 1))
    m = np.tile([0.0, 20.0, -40.0], (400, 1))
    m[100:300] *= 1.6
    out += [w.to_dict() for w in field_disturbance(m, q, 44.7, label="thigh").warnings]
    # a task recording without motion
    out += [w.to_dict() for w in analyse_task(np.zeros((2000, 3)), 100.0).warnings]
    # ingestion notes as app.ingestion words them (the demo's is tested in test_pdf)
    out += [{"code": "ingestion_note", "message": "shank lying: mag started 0.75 s before the common span (cut)"},
            {"code": "ingestion_note", "message": "thigh task: acc: 12 grid rows missing (gaps in the stream)"}]
    return out


PRODUCED = _produced()


def test_the_bad_data_provokes_the_warnings_under_test():
    codes = {w["code"] for w in PRODUCED}
    expected = {"heading_mismatch", "heading_residual", "heading_drift", "MAG_COVERAGE_LOW", "MAG_FEW_SAMPLES",
                "MAG_FIELD_IMPLAUSIBLE", "MAG_FIELD_MISMATCH", "MAG_RESIDUAL_HIGH", "MAG_OFFSET_UNCERTAIN", "posture_not_still", "gravity_magnitude",
                "postures_not_distinct", "sensor_upside_down", "magnetic_disturbance", "MOTOR_TASK_NO_MOTION",
                "ingestion_note"}
    assert expected <= codes, expected - codes


@pytest.mark.parametrize("w", PRODUCED, ids=lambda w: w["code"])
@pytest.mark.parametrize("lang", ["es", "pt"])
def test_every_produced_warning_is_translated_with_its_numbers(w, lang):
    text, translated = warning_text(w, lang)
    assert translated, (lang, w["message"])
    assert text != w["message"] and text[0].isupper()
    # every number of the English message is printed, with the decimal comma
    for number in re.findall(r"\d+\.\d+", w["message"]):
        assert number.replace(".", ",") in text, (number, text)
    assert not re.search(r"\d\.\d", text)


def test_english_prints_the_message_verbatim():
    for w in PRODUCED:
        assert warning_text(w, "en") == (w["message"], True)


def test_demo_warning_in_spanish_and_portuguese():
    w = {"code": "ingestion_note", "message": "thigh task: gyr ran on 1.53 s after the common span (cut)"}
    assert warning_text(w, "es") == ("Muslo, tarea: el giroscopio siguió registrando 1,53 s después del intervalo "
                                     "común (recortado)", True)
    assert warning_text(w, "pt") == ("Coxa, tarefa: o giroscópio continuou registrando 1,53 s após o intervalo "
                                     "comum (cortado)", True)


def test_params_are_used_when_the_warning_carries_them():
    parsed = warning_text({"code": "heading_drift", "message": "the relative heading of the two sensors varies by "
                           "7.3° (SD); transverse-plane angles are unreliable"}, "es")
    given = warning_text({"code": "heading_drift", "message": "ignored", "params": {"angle_deg": 7.26}}, "es")
    assert parsed == given == ("El rumbo relativo de los dos sensores varía 7,3° (DE); los ángulos del plano "
                               "transversal no son fiables", True)
    note = {"code": "ingestion_note", "message": "m", "params": {"variant": "no_epoch", "segment": "shank",
                                                                 "role": "standing"}}
    assert warning_text(note, "pt")[0] == ("Perna, em pé: sem marcas de tempo absolutas: supõe-se que os fluxos "
                                           "começam juntos")


def test_cycles_rejected_lists_the_translated_reasons_from_results():
    results = {"cycles": {"rejected": [{"index": 0, "reason": "incomplete_start"}, {"index": 6, "reason": "rmse"}]}}
    w = {"code": "cycles_rejected", "message": "2 of 10 cycles were left out of the statistics: cycle 1: starts "
         "before the recording; cycle 7: RMSE 9.1° > 6.0°"}
    text, ok = warning_text(w, "es", results)
    assert ok and text == ("2 de 10 ciclos quedaron fuera de las estadísticas: ciclo 1: "
                           f"{i18n.t('reason_incomplete_start', 'es')}; ciclo 7: {i18n.t('reason_rmse', 'es')}")
    assert warning_text(w, "es", None) == (w["message"], False)          # no reasons to list: English
    wrong_count = {"cycles": {"rejected": results["cycles"]["rejected"][:1]}}
    assert warning_text(w, "es", wrong_count) == (w["message"], False)


@pytest.mark.parametrize("w", [
    {"code": "a_code_nobody_translated", "message": "Something new happened"},
    {"code": "heading_drift", "message": "the heading drifted a lot"},                 # wording changed
    {"code": "heading_drift", "message": "x", "params": {"wrong_name": 3.0}},          # params incomplete
    {"code": "ingestion_note", "message": "ignored notes.txt (neither a MetaBase export nor a generic CSV)"},
    "a bare string",
], ids=["unknown-code", "changed-wording", "bad-params", "untranslated-note", "bare-string"])
def test_anything_not_fully_translatable_stays_english(w):
    message = w if isinstance(w, str) else w["message"]
    assert warning_text(w, "es") == (message, False)


def test_every_warning_text_is_well_formed():
    formatter = string.Formatter()
    keys = [k for k in i18n.table() if k.startswith("warning.")]
    assert len(keys) > 30
    for key in keys:
        specs = {lang: {(name, spec) for _, name, spec, _ in formatter.parse(i18n.table()[key][lang]) if name}
                 for lang in i18n.LANGUAGES}
        assert specs["es"] == specs["en"] == specs["pt"], key      # same fields with the same number formats
        for name, spec in specs["en"]:
            if spec:
                format(1.5 if not spec.endswith("d") else 1, spec)    # a valid number format
