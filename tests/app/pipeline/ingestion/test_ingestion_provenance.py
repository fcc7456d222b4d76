"""Provenance facts from the files and the pure checks the app calls (side, dates, patient id, sensors)."""

import json

import pytest

from app.pipeline.ingestion import load_session
from app.pipeline.ingestion.model import Recognition
from app.pipeline.ingestion.provenance import (RecordingFacts, check_all, check_dates, check_patient, check_sensors,
                                               check_side, session_facts)


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory, sim_session):
    from app.pipeline.ingestion import write_session_metabase
    d = tmp_path_factory.mktemp("session")
    write_session_metabase(d, sim_session[0], patient_id="ML1", utc_offset_h=-3.0)
    return d


def _facts(date="2023-03-13", side=None, pid=None, sensor=None, segment="thigh", role="task", name="a.csv"):
    r = lambda v: None if v is None else Recognition(v, "file name", str(v))  # noqa: E731
    return RecordingFacts(segment=segment, role=role, files=(name,), fmt="metabase", side=r(side),
                          patient_id=r(pid), date=r(date), sensor_id=sensor)


def test_facts_of_a_metabase_session(session_dir):
    facts = session_facts(load_session(session_dir))
    f = facts[("thigh", "task")]
    assert f.sensor_id == "D4F1A2B3C4E5" and f.device == "MetaWear" and f.firmware == "1.5.1"
    assert f.started.value.startswith("2023-03-13T") and f.started.value.endswith("+00:00")   # UTC from the stamps
    assert f.date.value == "2023-03-13" and f.patient_id.value == "ML1" and f.side is None
    assert facts[("shank", "lying")].sensor_id == "E8C2B1A0F9D7"
    assert json.dumps(f.as_dict())                                       # JSON-ready for the app


def test_side_from_session_json_against_the_patient(folder):
    (folder / "session.json").write_text(json.dumps({"side": "izquierda"}))
    session = load_session(folder)
    found = check_all(session, patient_side="right", patient_id="ML1", session_date="2023-03-13")
    sides = [f for f in found if f.code == "check.side_mismatch"]
    assert len(sides) == 8 and all(f.severity == "refuse" for f in sides)
    assert "the left leg" in sides[0].message("en") and "pierna izquierda" in sides[0].message("es")
    assert "direito" not in sides[0].message("pt") and "direita" in sides[0].message("pt")
    assert not check_all(session, patient_side="left", patient_id="ML1", session_date="2023-03-13")


def test_side_word_in_file_names(folder):
    for p in folder.glob("step-pierna*"):
        p.rename(p.with_name(p.name.replace("step-pierna", "step-pierna-derecha")))
    found = check_side(session_facts(load_session(folder)).values(), "left")
    assert [f.params["side"] for f in found] == ["right"] and found[0].params["file"].startswith("step-pierna-derecha")


def test_dates_against_the_session_date():
    facts = [_facts("2023-03-13", name="a"), _facts("2023-03-14", name="b"), _facts("2023-01-24", name="c")]
    found = check_dates(facts, "2023-03-13")
    far = [f for f in found if f.code == "check.date_far"]
    assert [f.params["file"] for f in far] == ["c"] and far[0].params["days"] == 48      # 1 day is tolerated
    spread = [f for f in found if f.code == "check.dates_spread"]
    assert spread and spread[0].params["days"] == 49 and "49 días" in spread[0].message("es")
    assert check_dates(facts[:2], "2023-03-14") == []


def test_patient_ids_against_the_patient():
    facts = [_facts(pid="ML1", name="a"), _facts(pid="ml-1", name="b"), _facts(pid="JP7", name="c"), _facts(name="d")]
    found = check_patient(facts, "ML1")
    assert [f.params["file"] for f in found] == ["c"] and "JP7" in found[0].message("pt")


def test_one_sensor_on_both_segments_is_flagged():
    facts = [_facts(sensor="AA", segment="thigh", role="standing", name="s-muslo"),
             _facts(sensor="BB", segment="shank", role="standing", name="s-pierna"),
             _facts(sensor="BB", segment="thigh", role="task", name="t-muslo"),
             _facts(sensor="AA", segment="shank", role="task", name="t-pierna")]
    found = check_sensors(facts)
    assert {f.params["sensor"] for f in found} == {"AA", "BB"}
    assert check_sensors(facts[:2]) == []
