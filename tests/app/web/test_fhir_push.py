"""The push of finished reports to a hospital's FHIR server as a transaction Bundle (issue 17 §2), on the webhook
machinery: retried with back-off, audited, its trail in es/en/pt.

A real ChakaMo server (uvicorn on loopback, SQLite and PostgreSQL) processes a real session; a real FHIR endpoint
(``http.server`` on another loopback port) checks the bearer token, parses each Bundle with both FHIR model
packages the tests use (fhirclient's 4.0.1 models and fhir.resources' R4B ones), checks that every reference
resolves to an entry's ``fullUrl`` or to the hospital's own Patient, answers the first push 503 and the second
a transaction-response.  The Bundle's three patient forms (contained, by identifier, by the hospital's reference)
are built from a real processed session too (``test_fhir``'s).
"""

from __future__ import annotations

import json
import threading
import urllib.parse
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from fhir.resources.R4B.bundle import Bundle as R4BBundle
from fhirclient.models.bundle import Bundle as R4Bundle
from test_browser_e2e import _loopback_socket
from test_fhir import BASE, build, patient, right  # noqa: F401 — right: the processed session fixture
from web_helpers import demo_files

from app.web.fhir_push import transaction_bundle

TOKEN = "hospital-fhir-token-0123456789"
MRN = "urn:oid:2.16.724.4.9.10.2"


def _references(node, out: list[str]) -> list[str]:
    if isinstance(node, dict):
        for k, v in node.items():
            if k == "reference" and isinstance(v, str):
                out.append(v)
            else:
                _references(v, out)
    elif isinstance(node, list):
        for v in node:
            _references(v, out)
    return out


def check_transaction(doc: dict) -> dict[str, list[dict]]:
    """What a FHIR server checks of a transaction Bundle (independently of the product's code): valid for both
    model packages, ``urn:uuid`` fullUrls, conditional creates, every reference resolvable; the resources by type."""
    R4Bundle(doc, strict=True)
    R4BBundle.model_validate(doc)
    assert doc["type"] == "transaction"
    full_urls = {e["fullUrl"] for e in doc["entry"]}
    assert all(u.startswith("urn:uuid:") and len(u) == 45 for u in full_urls) and len(full_urls) == len(doc["entry"])
    by_type: dict[str, list[dict]] = {}
    for e in doc["entry"]:
        if e["request"]["method"] == "PUT":  # a conditional update on the resource's identifier (a retraction)
            assert e["request"]["url"].startswith(e["resource"]["resourceType"] + "?identifier=")
            assert e["resource"]["status"] == "entered-in-error"
        else:
            assert e["request"]["method"] == "POST" and e["request"]["url"] == e["resource"]["resourceType"]
            assert e["request"]["ifNoneExist"].startswith("identifier=")
        assert "id" not in e["resource"] and "contained" not in e["resource"]
        by_type.setdefault(e["resource"]["resourceType"], []).append(e["resource"])
        for ref in _references(e["resource"], []):
            assert ref in full_urls or ref.startswith(("Patient/", "Patient?identifier=")), ref
    return by_type


def test_the_bundle_creates_the_patient_conditionally_and_links_by_urn_uuid(right):  # noqa: F811
    results, pdf = right
    report = build(results, pdf)
    doc = transaction_bundle(report, base_url=BASE, analysis_id=31)
    assert doc == transaction_bundle(report, base_url=BASE, analysis_id=31)  # a retry sends the same bundle
    by_type = check_transaction(doc)
    assert len(by_type["Patient"]) == 1 and len(by_type["DiagnosticReport"]) == 1
    assert len(by_type["Observation"]) == len(report["contained"]) - 1
    entries = {e["resource"]["resourceType"]: e for e in doc["entry"]}
    patient_url = entries["Patient"]["fullUrl"]
    dr = by_type["DiagnosticReport"][0]
    assert dr["subject"]["reference"] == patient_url
    assert all(o["subject"]["reference"] == patient_url for o in by_type["Observation"])
    assert {r["reference"] for r in dr["result"]} == {e["fullUrl"] for e in doc["entry"]
                                                      if e["resource"]["resourceType"] == "Observation"}
    # no hospital namespace: the patient is matched by ChakaMo's own identifier
    assert entries["Patient"]["request"]["ifNoneExist"] == f"identifier={BASE}/patients%7C7"
    assert entries["DiagnosticReport"]["request"]["ifNoneExist"] == f"identifier={BASE}/analyses%7C31"
    assert {"system": f"{BASE}/analyses", "value": "31"} in dr["identifier"]
    assert report["contained"][0]["id"] == "patient"  # the export's document is left as it was


def _search(reference: str) -> tuple[str, str]:
    """The ``(system, value)`` a FHIR server reads from ``Patient?identifier=...`` (FHIR R4 §3.1.1.5.11: a
    backslash escapes the next character; an unescaped ``,`` separates alternatives, ``|`` system from value)."""
    query = urllib.parse.parse_qs(urllib.parse.urlsplit(reference).query, keep_blank_values=True)
    assert list(query) == ["identifier"] and len(query["identifier"]) == 1
    text, parts, current, i = query["identifier"][0], [], "", 0
    while i < len(text):
        if text[i] == "\\":
            current, i = current + text[i + 1], i + 2
            continue
        assert text[i] not in ",$", f"an unescaped {text[i]!r} in {text!r}"  # an OR of two identifiers
        if text[i] == "|":
            parts.append(current)
            current = ""
        else:
            current += text[i]
        i += 1
    parts.append(current)
    assert len(parts) == 2, text
    return parts[0], parts[1]


def test_the_bundle_by_identifier_names_the_hospitals_patient_and_creates_none(right):  # noqa: F811
    """Identifier mode: the hospital owns its Patients, so the subject is a conditional reference (FHIR R4
    §3.1.0.11.2): a mistyped record number fails the transaction instead of making a ghost Patient."""
    results, pdf = right
    by_mrn = transaction_bundle(build(results, pdf, patient_mode="identifier", patient_identifier_system=MRN),
                                base_url=BASE, analysis_id=5)
    by_type = check_transaction(by_mrn)
    assert "Patient" not in by_type
    subjects = {r["subject"]["reference"] for t in by_type.values() for r in t}
    assert subjects == {f"Patient?identifier={MRN}%7CMRN-0042"} and _search(subjects.pop()) == (MRN, "MRN-0042")


@pytest.mark.parametrize("mrn", ["A,B", "A|B", "A$B", "A\\B"])
def test_a_record_number_with_a_search_separator_is_escaped(right, mrn):  # noqa: F811
    """``identifier=sys|A,B`` is a search for A *or* B: the value is escaped before it is URL-encoded."""
    results, pdf = right
    doc = transaction_bundle(build(results, pdf, patient_mode="identifier", patient_identifier_system=MRN + ",x",
                                   patient=patient(external_id=mrn)), base_url=BASE, analysis_id=5)
    assert _search(doc["entry"][0]["resource"]["subject"]["reference"]) == (MRN + ",x", mrn)
    created = transaction_bundle(build(results, pdf, patient_identifier_system=MRN, patient=patient(external_id=mrn)),
                                 base_url=BASE, analysis_id=5)
    assert _search("Patient?" + created["entry"][0]["request"]["ifNoneExist"]) == (MRN, mrn)


def test_the_bundle_by_the_hospitals_patient(right):  # noqa: F811
    results, pdf = right

    report = build(results, pdf, patient_mode="reference", patient=patient(fhir_reference="Patient/H-77"))
    assert report["subject"] == {"reference": "Patient/H-77", "type": "Patient"}
    doc = transaction_bundle(report, base_url=BASE, analysis_id=6)
    by_type = check_transaction(doc)
    assert "Patient" not in by_type  # the hospital owns it: referenced, not created
    assert all(r["subject"]["reference"] == "Patient/H-77" for t in by_type.values() for r in t)
    # without a reference the patient is named by its record number, which needs the namespace
    fallback = build(results, pdf, patient_mode="reference", patient_identifier_system=MRN)
    assert fallback["subject"]["identifier"]["value"] == "MRN-0042"
    from app.web.fhir import FhirExportError

    with pytest.raises(FhirExportError, match="fhir_reference"):
        build(results, pdf, patient_mode="reference")
    with pytest.raises(FhirExportError, match="not a FHIR reference"):
        build(results, pdf, patient_mode="reference", patient=patient(fhir_reference="H-77"))


class FhirServer:
    """A FHIR endpoint at ``/fhir`` that checks each transaction (:func:`check_transaction`) and answers
    ``codes`` in turn (then 200 with a transaction-response Bundle)."""

    def __init__(self, codes: list[int]) -> None:
        self.codes, self.got, self.problems = list(codes), [], []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 — http.server's name
                body = self.rfile.read(int(self.headers["Content-Length"]))
                try:
                    assert self.path == "/fhir" and self.headers["Authorization"] == f"Bearer {TOKEN}"
                    assert self.headers["Content-Type"] == "application/fhir+json"
                    doc = json.loads(body)
                    check_transaction(doc)
                except Exception as exc:  # noqa: BLE001 — reported to the test, answered 400
                    outer.problems.append(repr(exc))
                    self.send_response(400)
                    self.end_headers()
                    return
                outer.got.append(doc)
                code = outer.codes.pop(0) if outer.codes else 200
                answer = json.dumps({"resourceType": "Bundle", "type": "transaction-response", "entry": [
                    {"response": {"status": "201 Created"}} for _ in doc["entry"]]}).encode()
                self.send_response(code)
                self.send_header("Content-Type", "application/fhir+json")
                self.send_header("Content-Length", str(len(answer)))
                self.end_headers()
                self.wfile.write(answer)

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/fhir"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()


def _until(what, timeout_s: float = 300.0):
    end = time.monotonic() + timeout_s
    while not (value := what()):
        assert time.monotonic() < end, "timed out"
        time.sleep(0.2)
    return value


def test_a_finished_job_is_pushed_as_a_transaction_retried_and_audited(tmp_path, database_url, demo_dir):
    uvicorn = pytest.importorskip("uvicorn")
    import httpx
    from web_helpers import make_settings

    from app.cli import admin as admin_cli
    from app.web.main import create_app

    fhir = FhirServer([503])
    extra = {"DATABASE_URL": database_url} if database_url else {}
    settings = make_settings(tmp_path / "data", CHAKAMO_WEBHOOK_RETRY_S=0.5, CHAKAMO_FHIR_PUSH_URL=fhir.url,
                             CHAKAMO_FHIR_PUSH_TOKEN=TOKEN, CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS="127.0.0.1",
                             CHAKAMO_PUBLIC_URL="https://chakamo.hospital.test",
                             CHAKAMO_PATIENT_IDENTIFIER_SYSTEM=MRN, CHAKAMO_FHIR_PUSH_CLINICS="Hospital Push", **extra)
    admin_cli.create_clinic(settings, "Hospital Push")
    token = admin_cli.create_token(settings, clinic="Hospital Push", role="admin")
    sock = _loopback_socket()
    srv = uvicorn.Server(uvicorn.Config(create_app(settings), log_level="warning", access_log=False))
    thread = threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    try:
        while not srv.started:
            assert thread.is_alive()
            time.sleep(0.05)
        api = httpx.Client(base_url=f"http://127.0.0.1:{sock.getsockname()[1]}/api/v1",
                           headers={"Authorization": f"Bearer {token}"}, timeout=120)
        _until(lambda: api.get("/fhir/pushes").status_code == 200)
        pid = api.post("/patients", json={"external_id": "MRN-PUSH-1", "side": "right", "sex": "female"}).json()["id"]
        sid = api.post(f"/patients/{pid}/sessions", json={"step_height_m": 0.17}).json()["id"]
        assert api.post(f"/sessions/{sid}/recordings", files=demo_files(demo_dir)).status_code == 201
        job_id = api.post(f"/sessions/{sid}/process", json={"filter": "chakamo"}).json()["job_id"]

        trail = _until(lambda: [d for d in api.get("/fhir/pushes").json() if d["state"] == "delivered"])
        assert not fhir.problems, fhir.problems
        assert len(fhir.got) == 2 and fhir.got[0] == fhir.got[1]  # the 503 retried with the same bundle
        assert trail[0]["attempts"] == 2 and trail[0]["last_status"] == 200 and trail[0]["job_id"] == job_id
        assert trail[0]["error"] is None and trail[0]["last_error"] == ""

        by_type = check_transaction(fhir.got[-1])
        pat = by_type["Patient"][0]
        assert {"system": MRN, "value": "MRN-PUSH-1"}.items() <= pat["identifier"][0].items()
        assert pat["gender"] == "female"
        dr = by_type["DiagnosticReport"][0]
        analysis_id = api.get(f"/jobs/{job_id}").json()["analysis_id"]
        assert {"system": "https://chakamo.hospital.test/api/v1/analyses", "value": str(analysis_id)} in dr["identifier"]
        # the same report as the export route answers, but for the references and identifiers the push adds
        exported = api.get(f"/fhir/DiagnosticReport/{sid}").json()
        assert dr["conclusion"] == exported["conclusion"] and dr["presentedForm"] == exported["presentedForm"]

        events = api.get("/audit", params={"action": "export"}).json()
        rows = events["events"] if isinstance(events, dict) else events
        assert any(e["actor"] == "FHIR push" and e["session_id"] == sid for e in rows), rows
        assert api.get("/webhooks").json() == []  # the push is not one of the clinic's webhooks

        _a_stored_file_altered_gives_the_push_up(settings, job_id, analysis_id, fhir.url)

        # the session's facts corrected: its analysis is superseded, and the hospital's copy is retracted
        assert api.patch(f"/sessions/{sid}", json={"step_height_m": 0.18}).status_code == 200
        retracted = _until(lambda: [d for d in api.get("/fhir/pushes").json()
                                    if d["event"] == "analysis.superseded" and d["state"] == "delivered"])
        assert retracted[0]["job_id"] == job_id and len(api.get("/fhir/pushes").json()) == 2
        assert not fhir.problems, fhir.problems
        assert len(fhir.got) == 3
        by_type = check_transaction(fhir.got[-1])
        entries = {e["resource"]["resourceType"]: e for e in fhir.got[-1]["entry"]}
        assert entries["DiagnosticReport"]["request"] == {
            "method": "PUT", "url": f"DiagnosticReport?identifier=https://chakamo.hospital.test/api/v1/analyses%7C"
                                    f"{analysis_id}"}
        assert by_type["DiagnosticReport"][0]["identifier"] == dr["identifier"]  # the report the first push made
        assert {o["status"] for o in by_type["Observation"]} == {"entered-in-error"}
        assert entries["Patient"]["request"]["method"] == "POST"  # the same Patient, found again
        events = api.get("/audit", params={"action": "export"}).json()
        rows = events["events"] if isinstance(events, dict) else events
        assert any(e["actor"] == "FHIR push" and "retracted" in e["detail"] for e in rows), rows
    finally:
        srv.should_exit = True
        thread.join(timeout=30)
        sock.close()
        fhir.server.shutdown()


def _a_stored_file_altered_gives_the_push_up(settings, job_id: int, analysis_id: int, url: str) -> None:
    """The analysis' PDF altered on disk: the push gives up as not exportable (a CorruptBlob escaped the sender's
    round before: never counted, the delivery claimed again every lease, for ever)."""
    import datetime as dt

    from app.store import webhooks
    from app.store.blobs import open_storage
    from app.store.database import Database
    from app.store.models import Analysis, Artefact, WebhookDelivery, utcnow
    from app.web.fhir_push import NOT_EXPORTABLE, FhirPush

    store, db = open_storage(settings), Database(settings.db_url)
    try:
        with db.session() as s:
            lang = s.get(Analysis, analysis_id).lang  # the PDF the push carries
            sha = s.query(Artefact).filter_by(analysis_id=analysis_id, name="report.pdf", lang=lang).one().sha256
            row = s.query(WebhookDelivery).filter_by(job_id=job_id).one()
            due = webhooks.Due(row.id, url, "", row.event, dict(row.payload), row.attempts + 1,
                               utcnow() + dt.timedelta(seconds=webhooks.LEASE_S), row.subscription_id, "fhir",
                               row.clinic_id)
        path = store.path(sha)
        original, mode = path.read_bytes(), path.stat().st_mode
        path.chmod(0o600)
        path.write_bytes(original[:-8] + b"altered!")
        try:
            assert FhirPush(settings, store).send(db, due) == (None, NOT_EXPORTABLE, True)
        finally:
            path.write_bytes(original)
            path.chmod(mode)
    finally:
        db.dispose()


def test_a_push_the_settings_cannot_keep_safe_is_refused_at_start_up(tmp_path):
    from web_helpers import make_settings

    from app.settings import Settings, SettingsError
    from app.web.fhir_push import FhirPush

    common = {"CHAKAMO_FHIR_PUSH_URL": "https://fhir.hospital.example/fhir",
              "CHAKAMO_PUBLIC_URL": "https://chakamo.hospital.example", "CHAKAMO_FHIR_PUSH_CLINICS": "Hospital"}
    with pytest.raises(SettingsError, match="CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS"):  # its host not listed
        FhirPush(make_settings(tmp_path, CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS="ris.hospital.example", **common), None)
    with pytest.raises(SettingsError, match="CHAKAMO_PUBLIC_URL"):  # no namespace for the identifiers
        FhirPush(make_settings(tmp_path, CHAKAMO_FHIR_PUSH_URL=common["CHAKAMO_FHIR_PUSH_URL"],
                               CHAKAMO_FHIR_PUSH_CLINICS="Hospital",
                               CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS="*.hospital.example"), None)
    push = FhirPush(make_settings(tmp_path, CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS="*.hospital.example", **common), None)
    assert push.base_url == "https://chakamo.hospital.example/api/v1"
    with pytest.raises(ValueError, match="https"):  # patient data never over plain http in production
        Settings(CHAKAMO_ENV="production", CHAKAMO_SECRET_KEY="k" * 40, CHAKAMO_DATA_DIR=tmp_path,
                 CHAKAMO_FHIR_PUSH_URL="http://fhir.hospital.example/fhir",
                 CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS="fhir.hospital.example")


def test_the_hospitals_patient_reference_is_given_corrected_and_checked_through_the_api(client, settings):
    from web_helpers import clinic_token

    h = clinic_token(settings, "Hospital Ref")
    r = client.post("/api/v1/patients", json={"external_id": "REF-1", "side": "left",
                                              "fhir_reference": "Patient/H-77"}, headers=h)
    assert r.status_code == 201, r.text
    pid, version = r.json()["id"], r.json()["version"]
    assert client.get(f"/api/v1/patients/{pid}", headers=h).json()["fhir_reference"] == "Patient/H-77"
    bad = client.post("/api/v1/patients", json={"external_id": "REF-2", "side": "left", "fhir_reference": "H-77"},
                      headers=h)
    assert bad.status_code == 422
    r = client.patch(f"/api/v1/patients/{pid}", json={"fhir_reference": "https://fhir.hospital.example/Patient/9"},
                     headers=h | {"If-Match": f'"{version}"'})
    assert r.status_code == 200, r.text
    assert r.json()["fhir_reference"] == "https://fhir.hospital.example/Patient/9"


@pytest.mark.parametrize(("over", "code"), [({}, "fhir.patient_unreferenced"),
                                            ({"patient": patient(fhir_reference="H-77")},
                                             "fhir.patient_reference_invalid")])
def test_a_patient_the_report_cannot_name_is_a_coded_refusal_in_three_languages(right, over, code):  # noqa: F811
    """The reference mode's refusals a clinic's user causes (and mends in the patient's record) carry a catalogue
    code, which the push's trail shows in es/en/pt (the English sentence alone reached the trail before)."""
    from app.web.fhir import FhirExportError
    from app.web.webhooks import trail_error

    results, pdf = right
    with pytest.raises(FhirExportError) as refused:
        build(results, pdf, patient_mode="reference", **over)
    assert refused.value.code == code
    error = trail_error(code, None, "failed")
    assert error["code"] == code and len(set(error["message"].values())) == 3
    assert all("FHIR" in m for m in error["message"].values())
