"""The FHIR routes as a hospital configures them (issue 17, §2): identifier and code systems from the settings,
never from the request's host; the patient by identifier; the order, visit and accession passed in with the
session; ``GET /fhir/metadata`` and ``GET /fhir/DiagnosticReport?patient=``, each answer validated by both FHIR
model packages (``fhirclient`` R4 and ``fhir.resources`` R4B) here again, independently of the export's own check.
"""

from __future__ import annotations

import pytest
from fastapi import Request  # at module level: the probe route's annotation is resolved from these globals
from web_helpers import clinic_token, demo_files, make_settings, wait_job

MRN = "urn:oid:2.16.724.4.9.10.2"
IDS = "https://fhir.hospital.test/chakamo"
CODES = "https://terminology.hospital.test/CodeSystem/chakamo"
PUBLIC = "https://chakamo.hospital.test"


@pytest.fixture
def fhir_client(tmp_path):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_PATIENT_IDENTIFIER_SYSTEM=MRN,
                             CHAKAMO_FHIR_IDENTIFIER_BASE=IDS, CHAKAMO_FHIR_CODE_SYSTEM=CODES,
                             CHAKAMO_FHIR_PATIENT="identifier", CHAKAMO_ACCESSION_SYSTEM="urn:oid:1.2.3.4",
                             CHAKAMO_PUBLIC_URL=PUBLIC)
    with TestClient(create_app(settings), base_url="http://evil.example") as c:
        yield c, settings


def test_configured_export_search_and_metadata(fhir_client, demo_dir):
    from fhir.resources.R4B.bundle import Bundle as R4BBundle
    from fhir.resources.R4B.capabilitystatement import CapabilityStatement as R4BCapability
    from fhirclient.models.bundle import Bundle as R4Bundle
    from fhirclient.models.capabilitystatement import CapabilityStatement as R4Capability

    client, settings = fhir_client
    h = clinic_token(settings, "Hospital FHIR")
    pid = client.post("/api/v1/patients", json={"external_id": "MRN-5", "side": "right"}, headers=h).json()["id"]
    r = client.post(f"/api/v1/patients/{pid}/sessions", headers=h,
                    json={"step_height_m": 0.17, "service_request": "ServiceRequest/ORD-1",
                          "encounter": "Encounter/V-2", "accession": "ACC-3"})
    assert r.status_code == 201 and r.json()["service_request"] == "ServiceRequest/ORD-1"
    sid = r.json()["id"]
    bad = client.patch(f"/api/v1/sessions/{sid}", json={"encounter": "the visit"}, headers=h)
    assert bad.status_code == 422
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    job = client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "pt"}, headers=h).json()
    assert wait_job(client, job["job_id"], h)["status"] == "done"

    doc = client.get(f"/api/v1/fhir/DiagnosticReport/{sid}", headers=h).json()
    text = str(doc)
    assert "evil.example" not in text and "chakamo.example" not in text  # nothing from the request's host
    assert {"system": f"{IDS}/sessions", "value": str(sid)} in doc["identifier"]
    assert doc["subject"]["identifier"]["system"] == MRN and doc["subject"]["identifier"]["value"] == "MRN-5"
    assert doc["basedOn"] == [{"reference": "ServiceRequest/ORD-1"}]
    assert doc["encounter"] == {"reference": "Encounter/V-2"}
    assert any(i["value"] == "ACC-3" and i["system"] == "urn:oid:1.2.3.4" for i in doc["identifier"])
    assert doc["language"] == "pt" and doc["conclusion"].startswith("Joelho direito")
    assert doc["code"]["coding"][0]["system"] == CODES

    # correcting the order changes the export, and supersedes nothing (the analysis is still the current one)
    assert client.patch(f"/api/v1/sessions/{sid}", json={"accession": "ACC-4"}, headers=h).status_code == 200
    doc = client.get(f"/api/v1/fhir/DiagnosticReport/{sid}", headers=h).json()
    assert any(i["value"] == "ACC-4" for i in doc["identifier"])

    r = client.get("/api/v1/fhir/DiagnosticReport", params={"patient": f"Patient/{pid}"}, headers=h)
    assert r.status_code == 200 and r.headers["content-type"].startswith("application/fhir+json")
    bundle = r.json()
    R4Bundle(bundle, strict=True)
    R4BBundle.model_validate(bundle)
    assert bundle["type"] == "searchset" and bundle["total"] == 1
    assert bundle["entry"][0]["resource"]["id"] == str(sid)
    assert client.get("/api/v1/fhir/DiagnosticReport", params={"patient": "999999"}, headers=h).status_code == 404
    assert client.get("/api/v1/fhir/DiagnosticReport", params={"patient": "MRN-5"}, headers=h).status_code == 422

    # a configuration the export cannot follow (patients by identifier, no identifier system): 409, in the
    # reader's language, naming the session and what to do
    client.app.state.settings = settings.model_copy(update={"patient_identifier_system": None})
    try:
        for lang, words, reason in (("es", f"La sesión {sid} no se puede exportar a FHIR",
                                     "(solo se puede referir al paciente por identificador"),
                                    ("pt", f"A sessão {sid} não pode ser exportada para FHIR",
                                     "(só se pode referir o paciente por identificador")):
            r = client.get(f"/api/v1/fhir/DiagnosticReport/{sid}", headers=h | {"Accept-Language": lang})
            assert r.status_code == 409 and r.json()["code"] == "request.fhir_not_exportable", r.text
            assert r.json()["detail"].startswith(words) and r.json()["message"][lang] == r.json()["detail"]
            # the export's own reason in the reader's language too (it was the English sentence in every one)
            assert reason in r.json()["detail"] and "record number" not in r.json()["detail"]
            assert r.json()["params"]["reason"] == {"code": "fhir.no_patient_identifier", "params": {}}
    finally:
        client.app.state.settings = settings

    cap = client.get("/api/v1/fhir/metadata", headers=h).json()
    R4Capability(cap, strict=True)
    R4BCapability.model_validate(cap)
    assert cap["fhirVersion"] == "4.0.1" and cap["implementation"]["url"] == f"{PUBLIC}/api/v1/fhir"  # the server, not the ids' namespace


def test_identifier_namespace_is_never_the_requests_host_in_production(tmp_path):
    """Issue 17: with CHAKAMO_ALLOWED_HOSTS set (the Host checked) but no public URL, the export took the
    namespace from the request's Host; now it answers 503 until one is configured."""
    from fastapi import FastAPI
    from fastapi.testclient import TestClient

    from app.settings import Settings
    from app.web.api.fhir import fhir_base_url
    from app.web.refusals import Refusal

    probe = FastAPI()

    @probe.get("/base")
    def base(request: Request):
        try:
            return {"base": fhir_base_url(request)}
        except Refusal as exc:
            return {"refused": exc.status_code}

    common = {"CHAKAMO_ENV": "production", "CHAKAMO_DATA_DIR": tmp_path, "CHAKAMO_SECRET_KEY": "k" * 40,
              "CHAKAMO_ALLOWED_HOSTS": "chakamo.hospital.test"}
    probe.state.settings = Settings(**common)
    with TestClient(probe, base_url="http://chakamo.hospital.test") as c:
        assert c.get("/base").json() == {"refused": 503}
    probe.state.settings = Settings(**common, CHAKAMO_FHIR_IDENTIFIER_BASE=IDS)
    with TestClient(probe, base_url="http://chakamo.hospital.test") as c:
        assert c.get("/base").json() == {"base": IDS}
