"""Role, segment, side and step height from labels in Spanish, English and Portuguese; thesis names."""

import pytest

from app.pipeline.ingestion.labels import (parse_thesis_name, recognise_role, recognise_segment, recognise_side,
                                  recognise_step_height)

ROLE_CASES = [
    # Spanish
    ("calibracion-sensor-muslo-ML1-13032023-1", "mag_calibration", "thigh"),
    ("Calibración_Pierna", "mag_calibration", "shank"),
    ("de pie - muslo", "standing", "thigh"),
    ("RECOSTADO pierna", "lying", "shank"),
    ("escalón-muslo-3", "task", "thigh"),
    ("laydown-muslo-ML1-13032023-1", "lying", "thigh"),
    # English
    ("calibration thigh", "mag_calibration", "thigh"),
    ("Standing_Shank", "standing", "shank"),
    ("supine-thigh", "lying", "thigh"),
    ("Lying_Shank", "lying", "shank"),
    ("step-up shank 2", "task", "shank"),
    ("Task_Thigh", "task", "thigh"),
    # Portuguese
    ("calibração-coxa", "mag_calibration", "thigh"),
    ("em pé perna", "standing", "shank"),
    ("Deitado_Canela", "lying", "shank"),
    ("degrau-coxa-1", "task", "thigh"),
    ("mag_perna", "mag_calibration", "shank"),
]


@pytest.mark.parametrize("label,role,segment", ROLE_CASES)
def test_role_and_segment_in_three_languages(label, role, segment):
    r, s = recognise_role(label), recognise_segment(label)
    assert (r.value, s.value) == (role, segment)
    assert r.method == "file name" and r.evidence       # records the word that decided


def test_nothing_recognised_is_none_and_two_roles_are_refused():
    assert recognise_role("recording-7") is None and recognise_segment("recording-7") is None
    with pytest.raises(ValueError, match="more than one role"):
        recognise_role("standing-step-muslo")
    with pytest.raises(ValueError, match="more than one segment"):
        recognise_segment("muslo-pierna")


def test_side_and_step_height():
    assert recognise_side("step-muslo-derecha").value == "right"
    assert recognise_side("degrau coxa esquerda").value == "left"
    assert recognise_side("Left thigh").value == "left"
    assert recognise_step_height("step-pierna-ML1-13032023-1-H").value == 0.34
    assert recognise_step_height("step 17cm").value == 0.17
    assert recognise_step_height("step-pierna-ML1-13032023-1") is None


def test_thesis_name_fields():
    f = parse_thesis_name("step-pierna-ML1-13032023-2-H")
    assert f["patient_id"].value == "ML1" and f["date"].value == "2023-03-13" and f["trial"].value == 2
    assert f["step_height_m"].value == 0.34
    g = parse_thesis_name("calibracion-sensor-muslo-ML1-13032023-1")
    assert g["patient_id"].value == "ML1" and "step_height_m" not in g
    assert parse_thesis_name("my recording") is None
