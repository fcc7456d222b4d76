"""Quality warnings translated by code from their params (reports.warning_text).

The warnings come from the real estimators, provoked with bad recordings, so an estimator that stops
giving a field its translation needs (or renames one) fails here instead of silently printing English in
a Spanish report.  The English entry filled from the params must reproduce the estimator's message: the
params say what the message says.
"""

from __future__ import annotations

import json
import re
import string

import numpy as np
import pytest

from estimators import knee
from estimators import quaternion as quat
from estimators import simulation as sim
from estimators.disturbance import field_disturbance
from estimators.magnetometer import fit_ellipsoid
from estimators.motor_task import MotorTaskParams, analyse_task
from reports import i18n
from reports.warning_text import warning_text

RNG = np.random.default_rng(4)
FORMATTER = string.Formatter()


def _random_q(n: int) -> np.ndarray:
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _as_pipeline(w, segment: str) -> dict:
    """A magnetometer warning as app.pipeline.session re-words it: the sensor in front, ``params["segment"]``."""
    return {"code": w.code, "message": f"{segment.capitalize()} sensor: {w.message}",
            "params": {**w.params, "segment": segment}}


def _produced() -> list[dict]:
    """Warnings from the estimators on deliberately bad data, as results.json holds them (through JSON)."""
    out = []
    # heading between two unrelated orientation streams: mismatch, residual, drift
    out += [w.to_dict() for w in knee.heading_offset(_random_q(300), _random_q(300),
                                                     max_offset_rad=np.deg2rad(1.0)).warnings]
    # magnetometer: half a sphere, few samples, off-scale field
    d = RNG.normal(size=(150, 3))
    d[:, 2] = np.abs(d[:, 2])
    mag = 90.0 * d / np.linalg.norm(d, axis=1, keepdims=True) + RNG.normal(scale=4.0, size=(150, 3))
    cal = fit_ellipsoid(mag, model="sphere", expected_field_ut=45.0, min_samples=50)
    out += [_as_pipeline(w, "thigh") for w in cal.quality.warnings]
    # magnetometer: strong soft iron and bursts of disturbance
    d = RNG.normal(size=(2000, 3))
    mag = 45.0 * d / np.linalg.norm(d, axis=1, keepdims=True) @ np.diag([1.0, 1.5, 0.8])
    mag += RNG.normal(scale=0.3, size=(2000, 3))
    mag[:300] += RNG.normal(scale=40.0, size=(300, 3))
    out += [_as_pipeline(w, "shank") for w in fit_ellipsoid(mag).quality.warnings]
    # posture calibration from shaking, short, g-unit recordings (messages start "<segment>: ")
    fs = 100.0
    stand = np.tile([0.0, 1.0, 0.0], (400, 1)) + RNG.normal(scale=0.3, size=(400, 3))
    sup = np.tile([0.6, 0.8, 0.0], (400, 1)) + RNG.normal(scale=0.3, size=(400, 3))
    gyr = RNG.normal(scale=0.5, size=(400, 3))
    seg = knee.calibrate_segment(stand, gyr, sup, gyr, fs_hz=fs, label="shank")
    out += [w.to_dict() for w in seg.warnings]
    out += [w.to_dict() for w in knee.mounting_warnings(seg, expected_up_sensor=(0.0, -1.0, 0.0), label="shank")]
    # a functional flexion axis 40° from the static one
    r = quat.to_matrix(seg.q_sensor_segment)
    axis = np.cos(np.deg2rad(40.0)) * r[:, 2] + np.sin(np.deg2rad(40.0)) * r[:, 0]
    out += [w.to_dict() for w in knee.functional_calibration(seg, axis, label="thigh").warnings
            if w.code == "functional_axis_far"]
    # swapped sensors: the flexion is negative
    out += [w.to_dict() for w in knee.task_warnings(np.tile([-0.6, 0.0, 0.0], (100, 1)))]
    # the field at the sensor far from the calibrated one during the task
    q = np.tile([1.0, 0.0, 0.0, 0.0], (400, 1))
    m = np.tile([0.0, 20.0, -40.0], (400, 1))
    m[100:300] *= 1.6
    out += [w.to_dict() for w in field_disturbance(m, q, 44.7, label="thigh").warnings]
    # task recordings: no motion; a fast wobble with no cycle; one cycle; rejection stopped
    out += [w.to_dict() for w in analyse_task(np.zeros((2000, 3)), 100.0).warnings]
    t = np.arange(3000) / 100.0
    wobble = np.deg2rad(30.0 + 5.0 * np.sin(2 * np.pi * 3.0 * t))
    for task in ("step_up", "squat"):
        out += [w.to_dict() for w in analyse_task(np.column_stack([wobble, 0 * t, 0 * t]), 100.0,
                                                  task=task).warnings]
    out += [w.to_dict() for w in analyse_task(sim.step_up(1, 0.17, seed=1).knee_angles_rad, 100.0).warnings]
    out += [w.to_dict() for w in analyse_task(sim.step_up(4, 0.17, seed=1).knee_angles_rad, 100.0, params=
                                              MotorTaskParams(rejection_rmse_rad=(1e-4, None, None))).warnings]
    # ingestion notes as app.pipeline.ingestion words them (the real ones are checked in tests/app)
    out += [{"code": "ingestion_note", "message": "shank lying: mag started 0.75 s before the common span (cut)",
             "params": {"variant": "stream_cut_before", "stream": "mag", "seconds": 0.7512, "segment": "shank",
                        "role": "lying"}},
            {"code": "ingestion_note", "message": "thigh task: acc: 12 grid rows missing (gaps in the stream)",
             "params": {"variant": "rows_missing", "stream": "acc", "rows": 12, "segment": "thigh",
                        "role": "task"}}]
    return json.loads(json.dumps(out, allow_nan=False))


PRODUCED = _produced()


def _key(w: dict) -> str:
    variant = w["params"].get("variant")
    return f"warning.{w['code']}" + (f".{variant}" if variant else "")


def test_the_bad_data_provokes_the_warnings_under_test():
    codes = {w["code"] for w in PRODUCED}
    expected = {"heading_mismatch", "heading_residual", "heading_drift", "MAG_COVERAGE_LOW", "MAG_FEW_SAMPLES",
                "MAG_FIELD_IMPLAUSIBLE", "MAG_FIELD_MISMATCH", "MAG_RESIDUAL_HIGH", "MAG_OFFSET_UNCERTAIN",
                "MAG_SOFT_IRON_LARGE", "MAG_DISTURBED", "posture_not_still", "posture_too_short",
                "gravity_magnitude", "postures_not_distinct", "sensor_upside_down", "functional_axis_far",
                "flexion_negative", "magnetic_disturbance", "MOTOR_TASK_NO_MOTION", "MOTOR_TASK_NO_CYCLES",
                "MOTOR_TASK_FEW_CYCLES", "MOTOR_TASK_REJECTION_STOPPED", "ingestion_note"}
    assert expected <= codes, expected - codes


@pytest.mark.parametrize("w", PRODUCED, ids=lambda w: w["code"])
def test_params_hold_every_field_of_the_entry_in_every_language(w):
    assert isinstance(w["params"], dict)
    entry = i18n.table()[_key(w)]
    for lang in i18n.LANGUAGES:
        fields = {name for _, name, _, _ in FORMATTER.parse(entry[lang]) if name}
        assert fields <= set(w["params"]), (lang, fields - set(w["params"]))
        for name, value in w["params"].items():
            assert isinstance(value, (int, float, str)), (name, value)


@pytest.mark.parametrize("w", PRODUCED, ids=lambda w: w["code"])
def test_the_english_entry_filled_from_the_params_is_the_message(w):
    """The params carry the values the message states (so a translation states them too)."""
    body = i18n.table()[_key(w)]["en"].format(**w["params"])
    message = w["message"]
    assert message.endswith(body), (message, body)
    prefix = message[:len(message) - len(body)]
    seg, role = w["params"].get("segment"), w["params"].get("role")
    allowed = {""} if seg is None or "{segment" in i18n.table()[_key(w)]["en"] else \
        {f"{seg}: ", f"{seg.capitalize()} sensor: ", f"{seg} {role}: "}
    assert prefix in allowed, prefix


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
    if "segment" in w["params"]:                          # the segment, translated, wherever the text puts it
        assert i18n.table()[f"warning.term.{w['params']['segment']}"][lang].lower() in text.lower()


def test_english_prints_the_message_verbatim():
    for w in PRODUCED:
        assert warning_text(w, "en") == (w["message"], True)


def test_demo_warning_in_spanish_and_portuguese():
    w = {"code": "ingestion_note", "message": "thigh task: gyr ran on 1.53 s after the common span (cut)",
         "params": {"variant": "stream_cut_after", "stream": "gyr", "seconds": 1.532, "segment": "thigh",
                    "role": "task"}}
    assert warning_text(w, "es") == ("Muslo, tarea: el giroscopio siguió registrando 1,53 s después del intervalo "
                                     "común (recortado)", True)
    assert warning_text(w, "pt") == ("Coxa, tarefa: o giroscópio continuou a registar 1,53 s após o intervalo "
                                     "comum (cortado)", True)


def test_the_text_comes_from_the_params_not_the_message():
    given = warning_text({"code": "heading_drift", "message": "ignored", "params": {"angle_deg": 7.26}}, "es")
    assert given == ("El rumbo relativo de los dos sensores varía 7,3° (DE); los ángulos del plano "
                     "transversal no son fiables", True)
    note = {"code": "ingestion_note", "message": "m", "params": {"variant": "no_epoch", "segment": "shank",
                                                                 "role": "standing"}}
    assert warning_text(note, "pt")[0] == ("Perna, em pé: sem marcas de tempo absolutas: supõe-se que os fluxos "
                                           "começam juntos")
    mag = {"code": "MAG_FEW_SAMPLES", "message": "m", "params": {"n_samples": 120, "segment": "shank"}}
    assert warning_text(mag, "es") == ("Pierna: Solo se usaron 120 muestras: registre el ocho durante ~60 s.", True)
    # a text without fields needs no params (results.json written before warnings had them)
    assert warning_text({"code": "MOTOR_TASK_NO_MOTION", "message": "m"}, "es")[1]


def test_cycles_rejected_lists_the_translated_reasons_from_results():
    results = {"cycles": {"rejected": [{"index": 0, "reason": "incomplete_start"}, {"index": 6, "reason": "rmse"}]}}
    w = {"code": "cycles_rejected", "message": "2 of 10 cycles were left out of the statistics: cycle 1: starts "
         "before the recording; cycle 7: RMSE 9.1° > 6.0°", "params": {"rejected": 2, "detected": 10}}
    text, ok = warning_text(w, "es", results)
    assert ok and text == ("2 de 10 ciclos quedaron fuera de las estadísticas: ciclo 1: "
                           f"{i18n.t('reason_incomplete_start', 'es')}; ciclo 7: {i18n.t('reason_rmse', 'es')}")
    assert warning_text(w, "es", None) == (w["message"], False)          # no reasons to list: English
    wrong_count = {"cycles": {"rejected": results["cycles"]["rejected"][:1]}}
    assert warning_text(w, "es", wrong_count) == (w["message"], False)


@pytest.mark.parametrize("w", [
    {"code": "a_code_nobody_translated", "message": "Something new happened", "params": {"x": 1}},
    {"code": "heading_drift", "message": "the heading drifted 7.3° (SD)"},             # no params: not parsed
    {"code": "heading_drift", "message": "x", "params": {"wrong_name": 3.0}},          # params incomplete
    {"code": "heading_drift", "message": "x", "params": {"angle_deg": None}},          # inf/NaN in results.json
    {"code": "heading_drift", "message": "x", "params": {"angle_deg": "seven"}},       # a word for a number
    {"code": "heading_drift", "message": "x", "params": [["angle_deg", 7.0]]},          # not a mapping
    {"code": "ingestion_note", "message": "m", "params": {"variant": "new_kind", "segment": "thigh"}},
    {"code": "ingestion_note", "message": "ignored notes.txt (neither a MetaBase export nor a generic CSV)",
     "params": {}},
    "a bare string",
], ids=["unknown-code", "no-params", "bad-params", "null-number", "word-for-number", "not-a-mapping",
        "unknown-variant", "untranslated-note", "bare-string"])
def test_anything_not_fully_translatable_stays_english(w):
    message = w if isinstance(w, str) else w["message"]
    assert warning_text(w, "es") == (message, False)


def test_every_warning_text_is_well_formed():
    keys = [k for k in i18n.table() if k.startswith("warning.")]
    assert len(keys) > 30
    for key in keys:
        specs = {lang: {(name, spec) for _, name, spec, _ in FORMATTER.parse(i18n.table()[key][lang]) if name}
                 for lang in i18n.LANGUAGES}
        assert specs["es"] == specs["en"] == specs["pt"], key      # same fields with the same number formats
        for _name, spec in specs["en"]:
            if spec:
                format(1.5 if not spec.endswith("d") else 1, spec)    # a valid number format


def test_every_ingestion_note_variant_is_classified_on_purpose():
    """Each note the ingestion can write (its catalogue's ``note.*`` entries and the variants written as literals,
    e.g. align's stream cuts) is in exactly one of is_technical's two lists: a new variant fails here until someone
    decides whether the clinician must see it among the warnings.  An unlisted variant is a clinical warning."""
    import re
    from pathlib import Path

    from app.pipeline.ingestion.messages import CATALOGUE
    from reports.warning_text import CLINICAL_VARIANTS, TECHNICAL_VARIANTS, is_technical

    root = Path(__file__).resolve().parents[2] / "app" / "pipeline"
    variants = {code.removeprefix("note.") for code in CATALOGUE if code.startswith("note.")}
    for path in root.rglob("*.py"):
        variants |= set(re.findall(r'"variant":\s*"(\w+)"', path.read_text(encoding="utf-8")))
    variants -= {"task", "kept"}  # the pipeline's own calibration/heading params, not ingestion notes
    assert {"stream_cut_after", "stream_cut_before", "clock_drift", "rows_missing", "no_epoch"} <= variants
    assert not TECHNICAL_VARIANTS & CLINICAL_VARIANTS
    assert variants - TECHNICAL_VARIANTS - CLINICAL_VARIANTS == set()
    for v in variants:
        assert is_technical({"code": "ingestion_note", "params": {"variant": v}}) == (v in TECHNICAL_VARIANTS)
    assert not is_technical({"code": "ingestion_note", "params": {"variant": "a_new_one"}})
    assert not is_technical({"code": "ingestion_note", "params": {"file": "x.csv", "ambiguous": "left right"}})
    for v in ("names_disagree", "rows_missing", "no_epoch"):
        assert not is_technical({"code": "ingestion_note", "params": {"variant": v}})
