"""FHIR R4 DiagnosticReport export (app/web/fhir.py) on real processed sessions.

Two simulated sessions (right leg with every report rendered, left leg results only) go through
``chakamo process``'s own code path; the export is parsed back with both FHIR model packages and compared
number by number with ``results.json``.
"""

from __future__ import annotations

import base64
import copy
import hashlib
import json
from datetime import date, datetime, timedelta, timezone

import pytest
from fhir.resources.R4B.diagnosticreport import DiagnosticReport as R4BDiagnosticReport
from fhirclient.models.diagnosticreport import DiagnosticReport as R4DiagnosticReport

from app.pipeline.demo import simulate_session, write_session
from app.web.fhir import CODE_SYSTEM, FhirExportError, diagnostic_report, validate
from app.pipeline.session import ProcessOptions
from app.pipeline.process import process_folder
from reports.i18n import t

ISSUED = datetime(2026, 11, 22, 10, 30, tzinfo=timezone.utc)
BASE = "http://clinic.test/api/v1"
ROM_CODES = [f"{stat}-{m}" for stat in ("max", "min", "range") for m in ("mean", "sd")]


def _process(tmp_path_factory, side: str, seed: int, reports: bool, language: str):
    root = tmp_path_factory.mktemp(f"fhir_{side}")
    write_session(root / "session", simulate_session(seed=seed, side=side, n_cycles=3))
    process_folder(root / "session", root / "out", ProcessOptions(language=language), reports=reports)
    results = json.loads((root / "out" / "results.json").read_text(encoding="utf-8"))
    pdf = (root / "out" / "report.pdf").read_bytes() if reports else None
    return results, pdf


@pytest.fixture(scope="module")
def right(tmp_path_factory):
    return _process(tmp_path_factory, "right", seed=11, reports=True, language="en")


@pytest.fixture(scope="module")
def left_results(tmp_path_factory):
    return _process(tmp_path_factory, "left", seed=12, reports=False, language="en")[0]


def session(**over):
    return {"id": 42, "date": "2026-11-20", "task": "step_up", "professional": "Dr. Ana Ruiz",
            "notes": "Mild pain at the end of the task.", "created_at": datetime(2026, 11, 20, 9, 0)} | over


def patient(**over):
    return {"id": 7, "external_id": "MRN-0042", "side": "right", "name": "Juan Pérez <Jr>",
            "birth_date": "1971-03-05", "sex": "M"} | over


def build(results, pdf, /, **over):
    kw = {"session": session(), "patient": patient(), "results": results, "pdf": pdf, "lang": "en",
          "base_url": BASE, "issued": ISSUED} | over
    return diagnostic_report(**kw)


def contained(doc, rtype):
    return {r["id"]: r for r in doc["contained"] if r["resourceType"] == rtype}


def components(obs):
    return {c["code"]["coding"][0]["code"]: c for c in obs["component"]}


def test_parses_back_as_r4_and_r4b_unchanged(right):
    results, pdf = right
    doc = build(results, pdf)
    text = json.dumps(doc, allow_nan=False)  # JSON-ready: no NaN, no non-JSON types
    r4 = R4DiagnosticReport(json.loads(text), strict=True)  # FHIR 4.0.1 models: unknown elements rejected
    assert r4.as_json() == doc
    r4b = R4BDiagnosticReport.model_validate_json(text)
    assert r4b.id == "42" and r4b.status == "final"
    assert len(r4.contained) == 4
    assert {type(c).__name__ for c in r4.contained} == {"Patient", "Observation"}


def test_report_header(right):
    results, pdf = right
    doc = build(results, pdf)
    assert doc["resourceType"] == "DiagnosticReport" and doc["status"] == "final"
    assert doc["category"][0]["coding"][0] == {"system": "http://terminology.hl7.org/CodeSystem/v2-0074",
                                               "code": "PT", "display": "Physical Therapy"}
    assert doc["code"]["coding"][0]["system"] == CODE_SYSTEM
    assert doc["effectiveDateTime"] == "2026-11-20"
    assert doc["issued"] == "2026-11-22T10:30:00+00:00"
    assert doc["identifier"] == [{"system": f"{BASE}/sessions", "value": "42"}]
    assert doc["performer"] == [{"display": "Dr. Ana Ruiz"}]
    assert "<Jr>" not in doc["text"]["div"] and doc["text"]["div"].startswith('<div xmlns="http://www.w3.org/1999/xhtml">')


def test_patient_carries_the_hospital_identifier(right):
    results, pdf = right
    doc = build(results, pdf, patient_identifier_system="urn:oid:1.2.3.4")
    assert doc["subject"] == {"reference": "#patient"}
    p = contained(doc, "Patient")["patient"]
    mrn, own = p["identifier"]
    assert mrn["value"] == "MRN-0042" and mrn["system"] == "urn:oid:1.2.3.4"
    assert mrn["type"]["coding"][0]["code"] == "MR"
    assert own == {"use": "secondary", "system": f"{BASE}/patients", "value": "7"}
    assert p["gender"] == "male" and p["birthDate"] == "1971-03-05" and p["name"] == [{"text": "Juan Pérez <Jr>"}]


def test_every_reference_resolves_to_a_contained_resource(right):
    results, pdf = right
    doc = build(results, pdf)
    ids = [r["id"] for r in doc["contained"]]
    assert len(ids) == len(set(ids))
    observations = contained(doc, "Observation")
    assert [ref["reference"] for ref in doc["result"]] == ["#flexion", "#adduction", "#internal-rotation"]
    assert all(ref["reference"][1:] in observations for ref in doc["result"])
    assert all(o["subject"] == {"reference": "#patient"} for o in observations.values())


def test_numbers_equal_results_json(right):
    results, pdf = right
    doc = build(results, pdf)
    observations = contained(doc, "Observation")
    for angle in ("flexion", "adduction", "internal_rotation"):
        obs = observations[angle.replace("_", "-")]
        assert obs["status"] == "final" and obs["effectiveDateTime"] == "2026-11-20"
        comps = components(obs)
        for code in ROM_CODES:
            stat, m = code.split("-")
            # rounded to 0.1° as the reports print them (issue 17: 66.67807457718372 was exported)
            assert comps[code]["valueQuantity"]["value"] == round(results["rom_deg"][angle][stat][m], 1)
        assert comps["cycles-accepted"]["valueInteger"] == results["cycles"]["accepted"]
        assert comps["cycles-detected"]["valueInteger"] == results["cycles"]["detected"]
        assert comps["orientation-filter"]["valueString"] == results["filter"]["name"]
        assert comps["angle-convention"]["valueString"] == results["angle_method"]
        assert obs["method"]["coding"][0] == {"system": CODE_SYSTEM, "code": "imu-thigh-shank",
                                              "display": "Two magneto-inertial measurement units, thigh and shank"}


def test_quantities_are_ucum_degrees(right):
    results, pdf = right
    quantities = [c["valueQuantity"] for o in contained(build(results, pdf), "Observation").values()
                  for c in o["component"] if "valueQuantity" in c]
    assert len(quantities) == 3 * 6
    assert all(q["system"] == "http://unitsofmeasure.org" and q["code"] == "deg" and q["unit"] == "deg"
               for q in quantities)


def test_laterality_follows_the_measured_side(right, left_results):
    results, pdf = right
    assert results["side"] == "right" and left_results["side"] == "left"
    for res, code, text in ((results, "24028007", "Right knee joint"), (left_results, "7771000", "Left knee joint")):
        doc = build(res, pdf)
        for obs in contained(doc, "Observation").values():
            site = obs["bodySite"]
            assert site["coding"][0] == {"system": "http://snomed.info/sct", "code": f"49076000:272741003={code}"}
            assert site["coding"][1]["code"] == "49076000" and site["text"] == text
        assert doc["conclusion"].startswith(text.split()[0] + " knee")


def test_pdf_round_trips_from_base64(right):
    results, pdf = right
    for lang in ("es", "en", "pt"):
        form = build(results, pdf, lang=lang)["presentedForm"][0]
        data = base64.b64decode(form["data"], validate=True)
        assert data == pdf and data.startswith(b"%PDF-")
        assert form["contentType"] == "application/pdf" and form["language"] == lang
        assert form["size"] == len(pdf)
        assert base64.b64decode(form["hash"]) == hashlib.sha1(pdf).digest()
        assert form["title"] == t("report_title", lang)


def test_conclusion_summarises_warnings_and_notes(right):
    results, pdf = right
    res = copy.deepcopy(results)
    res["quality"]["warnings"] = [{"code": "mag_disturbed", "message": "thigh field disturbed 12 % of the task"},
                                  {"code": "few_cycles", "message": "only 3 cycles accepted"}]
    conclusion = build(res, pdf)["conclusion"]
    assert "Quality warnings (2)" in conclusion
    assert "thigh field disturbed 12 % of the task" in conclusion and "only 3 cycles accepted" in conclusion
    assert "Mild pain at the end of the task." in conclusion
    res["quality"]["warnings"] = []
    assert "Quality warnings: none." in build(res, pdf, session=session(notes=None))["conclusion"]


def test_missing_sd_becomes_data_absent_reason(right):
    results, pdf = right
    res = copy.deepcopy(results)
    res["rom_deg"]["flexion"]["range"]["sd"] = None  # what results.json holds for a single accepted cycle
    doc = build(res, pdf)
    comp = components(contained(doc, "Observation")["flexion"])["range-sd"]
    assert "valueQuantity" not in comp
    assert comp["dataAbsentReason"]["coding"][0]["code"] == "not-applicable"
    validate(doc)


def test_optional_patient_and_session_fields(right):
    results, pdf = right
    doc = build(results, pdf, patient=patient(external_id=None, sex=None, name=None, birth_date=None),
                session=session(date=None, professional=None, notes=""), issued=None)
    p = contained(doc, "Patient")["patient"]
    assert p["identifier"] == [{"use": "secondary", "system": f"{BASE}/patients", "value": "7"}]
    assert not {"gender", "name", "birthDate"} & set(p)
    assert "performer" not in doc
    assert doc["effectiveDateTime"] == "2026-11-20T09:00:00+00:00"  # created_at, naive = UTC
    issued = datetime.fromisoformat(doc["issued"])
    assert issued.tzinfo is not None and abs(datetime.now(timezone.utc) - issued) < timedelta(minutes=5)
    doc = build(results, pdf, session=session(date=date(2026, 1, 2)), patient=patient(sex="Female"))
    assert doc["effectiveDateTime"] == "2026-01-02" and contained(doc, "Patient")["patient"]["gender"] == "female"


def _drop(mapping, path):
    out = copy.deepcopy(mapping)
    node = out
    *parents, last = path.split(".")
    for key in parents:
        node = node[key]
    del node[last]
    return out


@pytest.mark.parametrize(("change", "message"), [
    (lambda r, p: {"session": _drop(session(), "created_at")}, "session is missing the key(s) created_at"),
    (lambda r, p: {"patient": _drop(patient(), "external_id")}, "patient is missing the key(s) external_id"),
    (lambda r, p: {"results": _drop(r, "rom_deg.adduction")}, "results is missing 'rom_deg.adduction.max.mean'"),
    (lambda r, p: {"results": _drop(r, "cycles.accepted")}, "results is missing 'cycles.accepted'"),
    (lambda r, p: {"results": _drop(r, "quality")}, "results is missing 'quality.warnings'"),
    (lambda r, p: {"results": r | {"side": "both"}}, "results['side'] must be 'right' or 'left'"),
    (lambda r, p: {"results": []}, "results must be the session's results.json as a dict"),
    (lambda r, p: {"lang": "de"}, "lang must be one of es, en, pt"),
    (lambda r, p: {"pdf": b"<html>"}, "pdf must be the bytes of the PDF report"),
    (lambda r, p: {"base_url": "/api/v1"}, "base_url must be an absolute http(s) URL"),
    (lambda r, p: {"session": session(id="a_b")}, "cannot be a FHIR id"),
    (lambda r, p: {"session": session(date="20/11/2026")}, "is not an ISO date"),
    (lambda r, p: {"session": session(date=None, created_at=None)}, "session date (or created_at"),
    (lambda r, p: {"patient": patient(sex="x")}, "patient sex 'x' is not one of"),
    (lambda r, p: {"issued": datetime(2026, 1, 1)}, "issued must be a timezone-aware datetime"),
])
def test_bad_input_gives_a_clear_error(right, change, message):
    results, pdf = right
    with pytest.raises(FhirExportError) as err:
        build(results, pdf, **change(results, pdf))
    assert message in str(err.value)


def test_validate_rejects_what_r4_does_not_have(right):
    results, pdf = right
    doc = build(results, pdf)
    with pytest.raises(FhirExportError, match=r"not valid FHIR R4 \(4\.0\.1"):
        validate(doc | {"note": [{"text": "R5 added DiagnosticReport.note"}]})
    with pytest.raises(FhirExportError, match="fhir.resources R4B"):
        validate(doc | {"effectivePeriod": {"start": "2026-11-20"}})  # two choices of effective[x]


def test_a_flagged_flexion_range_carries_the_reference_interpretation(right):
    """results.json ``reference`` (issue 15 §3): a flexion range the reference flags gets the v3 L/N/H code and
    the band as referenceRange on the range-mean component; the step-up's thesis ROM has no band, so none."""
    results, pdf = right
    assert "interpretation" not in components(contained(build(results, pdf), "Observation")["flexion"])["range-mean"]
    value = results["rom_deg"]["flexion"]["range"]["mean"]
    flagged = copy.deepcopy(results)
    flagged["reference"]["parameters"]["flexion_rom_deg"] = {"value": value, "low": value + 5.0, "high": value + 10.0,
                                                              "unit": "deg", "interpretation": "L", "within_band": False}
    doc = build(flagged, pdf)
    validate(doc)
    comp = components(contained(doc, "Observation")["flexion"])["range-mean"]
    assert comp["interpretation"][0]["coding"][0] == {
        "system": "http://terminology.hl7.org/CodeSystem/v3-ObservationInterpretation", "code": "L", "display": "Low"}
    assert (comp["referenceRange"][0]["low"]["value"], comp["referenceRange"][0]["high"]["value"]) == (
        round(value + 5, 1), round(value + 10, 1))
    assert all("interpretation" not in c for o in contained(doc, "Observation").values() for c in o["component"]
               if c is not comp)


def test_the_flag_is_the_one_the_exported_numbers_show(right):
    """The L/N/H code is decided on the value and band as exported (one decimal): a range of 59.96° reads 60.0
    in the export, so against a low of 60 it is N, not the L results.json computed on 59.96; the band is rounded
    alike (59.96 > 59.951 → 60.0 ≥ 60.0)."""
    results, pdf = right
    flagged = copy.deepcopy(results)
    flagged["rom_deg"]["flexion"]["range"]["mean"] = 59.96
    flagged["reference"]["parameters"]["flexion_rom_deg"] = {"value": 59.96, "low": 60.0, "high": 70.04,
                                                              "unit": "deg", "interpretation": "L", "within_band": False}
    doc = build(flagged, pdf)
    validate(doc)
    comp = components(contained(doc, "Observation")["flexion"])["range-mean"]
    assert comp["valueQuantity"]["value"] == 60.0 and comp["interpretation"][0]["coding"][0]["code"] == "N"
    assert comp["referenceRange"][0]["high"]["value"] == 70.0
    flagged["rom_deg"]["flexion"]["range"]["mean"] = 59.94  # reads 59.9: below 60.0
    comp = components(contained(build(flagged, pdf), "Observation")["flexion"])["range-mean"]
    assert comp["valueQuantity"]["value"] == 59.9 and comp["interpretation"][0]["coding"][0]["code"] == "L"


def test_an_identifier_base_that_cannot_be_extended_is_refused_at_start_up(tmp_path):
    from app.settings import Settings

    with pytest.raises(ValueError, match="CHAKAMO_FHIR_IDENTIFIER_BASE='urn:oid:1.2.3' is not an http"):
        Settings(CHAKAMO_ENV="development", CHAKAMO_DATA_DIR=tmp_path, CHAKAMO_FHIR_IDENTIFIER_BASE="urn:oid:1.2.3")


# ------------------------------------------------------------------------------ issue 17: integration choices
def test_no_placeholder_domain_and_configurable_code_system(right):
    results, pdf = right
    text = json.dumps(build(results, pdf))
    assert "chakamo.example" not in text and CODE_SYSTEM.startswith("urn:uuid:")
    doc = build(results, pdf, code_system="https://terminology.hospital.test/CodeSystem/knee")
    codings = [c for o in contained(doc, "Observation").values() for c in o["code"]["coding"]]
    assert codings and all(c["system"] == "https://terminology.hospital.test/CodeSystem/knee" for c in codings)
    assert CODE_SYSTEM not in json.dumps(doc)


def test_language_follows_the_pdf_and_conclusion_is_clinical_only(right):
    results, pdf = right
    res = copy.deepcopy(results)
    res["quality"]["warnings"] = [
        {"code": "ingestion_note", "message": "thigh task: gyr ran on 1.55 s after the common span (cut)",
         "params": {"variant": "stream_cut_after", "stream": "gyr", "seconds": 1.55, "segment": "thigh",
                    "role": "task"}},
        {"code": "few_cycles", "message": "only 3 cycles accepted"}]
    for lang, side in (("pt", "Joelho direito"), ("es", "Rodilla derecha"), ("en", "Right knee")):
        doc = build(res, pdf, lang=lang)
        assert doc["language"] == lang == doc["presentedForm"][0]["language"]
        assert doc["conclusion"].startswith(side), doc["conclusion"]
        assert "1.55" not in doc["conclusion"] and "gyr" not in doc["conclusion"]  # no ingestion notes
        assert "(1)" in doc["conclusion"]  # one clinical warning
        assert "1.55" not in doc["text"]["div"]


def test_patient_by_identifier_order_encounter_and_accession(right):
    results, pdf = right
    mrn = "urn:oid:2.16.724.4.9.10.2"
    doc = build(results, pdf, patient_mode="identifier", patient_identifier_system=mrn,
                accession_system="urn:oid:1.2.3.4.5",
                session=session(service_request="ServiceRequest/RX-9", encounter="Encounter/E-4", accession="ACC-77"))
    assert not contained(doc, "Patient")
    subject = doc["subject"]
    assert subject["identifier"]["system"] == mrn and subject["identifier"]["value"] == "MRN-0042"
    assert all(o["subject"] == subject for o in contained(doc, "Observation").values())
    assert doc["basedOn"] == [{"reference": "ServiceRequest/RX-9"}]
    assert doc["encounter"] == {"reference": "Encounter/E-4"}
    acsn = [i for i in doc["identifier"] if i.get("type", {}).get("coding", [{}])[0].get("code") == "ACSN"]
    assert acsn == [{"use": "official", "system": "urn:oid:1.2.3.4.5", "value": "ACC-77",
                     "type": {"coding": [{"system": "http://terminology.hl7.org/CodeSystem/v2-0203", "code": "ACSN",
                                          "display": "Accession ID"}]}}]
    validate(doc)
    with pytest.raises(FhirExportError, match="CHAKAMO_PATIENT_IDENTIFIER_SYSTEM"):
        build(results, pdf, patient_mode="identifier")
    with pytest.raises(FhirExportError, match="not a FHIR reference"):
        build(results, pdf, session=session(encounter="visit 4"))


def test_search_bundle_and_capability_statement_validate():
    from app.web.fhir import capability_statement, search_bundle

    cap = capability_statement(software_version="1.0", server_url="https://chakamo.hospital.test/api/v1/fhir")
    assert cap["fhirVersion"] == "4.0.1"
    assert cap["rest"][0]["resource"][0]["searchParam"][0]["name"] == "patient"
    assert search_bundle([]) == {"resourceType": "Bundle", "type": "searchset", "total": 0}
