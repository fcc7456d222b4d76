"""The integrator's whole flow driven by the OpenAPI document alone (issue 17, §1).

A hospital's integration team reads ``/openapi.json`` (what ``/docs`` draws) and nothing else: the test finds
each operation by what the document says about it (its request body's schema, its answers' media types), takes
field names and allowed values from the document's schemas (the enums come from :mod:`app.choices`), and
checks every answer against the schema the document declares for it — with two validators the project did not
write: ``openapi-spec-validator`` for the document, ``jsonschema`` (Draft 2020-12, OpenAPI 3.1's dialect) for the
bodies.  Errors the flow provokes (no token, an unknown id, a value outside an enum, a bad upload) must be
declared for their operation and answer ``application/problem+json`` matching the ``Problem`` schema.

Flow: patient → session → upload (multipart: ``files``, ``segment``, ``role`` as the document names them) →
webhook subscription → process → job until a terminal status (and the webhook's delivery) → results → PDF →
FHIR DiagnosticReport.
"""

from __future__ import annotations

import time

import pytest
from web_helpers import clinic_token

PROBLEM = "application/problem+json"


class Doc:
    """The OpenAPI document with the look-ups an integrator makes by eye."""

    def __init__(self, doc: dict) -> None:
        self.doc = doc
        self.ops = [(method, path, op) for path, item in doc["paths"].items() for method, op in item.items()
                    if method in ("get", "post", "put", "patch", "delete")]

    def schema(self, ref_or_schema: dict) -> dict:
        while "$ref" in ref_or_schema:
            ref_or_schema = self.doc["components"]["schemas"][ref_or_schema["$ref"].rsplit("/", 1)[1]]
        return ref_or_schema

    def find(self, method: str, pred) -> tuple[str, dict]:
        found = [(path, op) for m, path, op in self.ops if m == method and pred(path, op)]
        assert len(found) == 1, f"{method}: {len(found)} operations match: {[p for p, _ in found]}"
        return found[0]

    def body_schema(self, op: dict, media: str = "application/json") -> dict | None:
        content = op.get("requestBody", {}).get("content", {})
        if media not in content:
            return None
        schema = self.schema(content[media]["schema"])
        alternatives = [a for a in schema.get("anyOf", []) if a.get("type") != "null"]
        return self.schema(alternatives[0]) if len(alternatives) == 1 else schema  # an optional body

    def answer(self, op: dict, status: int) -> dict:
        responses = op["responses"]
        assert str(status) in responses, f"{op.get('operationId')}: status {status} not declared"
        return responses[str(status)]

    def check(self, op: dict, r) -> None:
        """``r``'s status is declared for ``op`` and its body matches the declared schema."""
        import jsonschema

        answer = self.answer(op, r.status_code)
        media = r.headers.get("content-type", "").split(";")[0]
        content = answer.get("content", {})
        if r.status_code == 204:
            return
        assert media in content, f"{op['operationId']} {r.status_code}: {media} not declared ({list(content)})"
        schema = content[media].get("schema")
        if schema and media.endswith("json"):
            root = {"$schema": "https://json-schema.org/draft/2020-12/schema", **schema,
                    "components": self.doc["components"]}
            jsonschema.Draft202012Validator(root).validate(r.json())

    def enum(self, schema: dict, prop: str) -> list:
        """The allowed values of property ``prop`` (also inside ``anyOf: [enum, null]``)."""
        s = self.schema(schema["properties"][prop])
        for alt in [s] + s.get("anyOf", []):
            alt = self.schema(alt)
            if "enum" in alt:
                return alt["enum"]
            if alt.get("type") == "array" and "enum" in self.schema(alt.get("items", {})):
                return self.schema(alt["items"])["enum"]
        raise AssertionError(f"{prop} has no enum")


def _fill(path: str, **ids) -> str:
    for key, value in ids.items():
        path = path.replace("{" + key + "}", str(value))
    assert "{" not in path, path
    return path


def _problem(doc: Doc, op: dict, r, status: int) -> dict:
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith(PROBLEM), r.headers["content-type"]
    doc.check(op, r)
    body = r.json()
    assert body["status"] == status and body["title"] and body["detail"] and body["type"]
    return body


def test_the_whole_flow_from_the_openapi_document(client, settings, demo_dir):
    from openapi_spec_validator import validate

    raw = client.get("/openapi.json").json()
    validate(raw)  # a valid OpenAPI 3.1 document
    doc = Doc(raw)
    assert raw["openapi"].startswith("3.1")
    scheme = next(s for s in raw["components"]["securitySchemes"].values() if s.get("scheme") == "bearer")
    assert scheme["type"] == "http"
    h = clinic_token(settings, "Hospital OpenAPI", role="admin")  # `chakamo tokens create`, as the description says

    # every error answer of the API is described by the Problem schema
    for method, path, op in doc.ops:
        if path.startswith("/api/v1"):
            for status, answer in op["responses"].items():
                if int(status) >= 400:
                    assert answer["content"][PROBLEM]["schema"] == {"$ref": "#/components/schemas/Problem"}, (
                        method, path, status)

    # patient: the POST whose body is the patient schema, filled from its required fields
    path, op = doc.find("post", lambda p, o: (doc.body_schema(o) or {}).get("title") == "PatientIn")
    schema = doc.body_schema(op)
    assert set(schema["required"]) == {"external_id", "side"}
    assert doc.enum(schema, "side") == ["right", "left"]
    _problem(doc, op, client.post(path, json={"external_id": "OA-1", "side": "right"}), 401)  # no token
    _problem(doc, op, client.post(path, json={"external_id": "OA-1", "side": "up"}, headers=h), 422)
    r = client.post(path, json={"external_id": "OA-1", "side": "right"}, headers=h)
    doc.check(op, r)
    patient_id = r.json()["id"]
    _problem(doc, op, client.post(path, json={"external_id": "OA-1", "side": "right"}, headers=h), 409)

    # session: the POST under the patient whose body is the session schema
    path, op = doc.find("post", lambda p, o: (doc.body_schema(o) or {}).get("title") == "SessionIn")
    assert "step_up" in doc.enum(doc.body_schema(op), "task")
    _problem(doc, op, client.post(_fill(path, patient_id=999999), json={}, headers=h), 404)
    r = client.post(_fill(path, patient_id=patient_id), json={"step_height_m": 0.17}, headers=h)
    doc.check(op, r)
    session_id = r.json()["id"]

    # upload: the multipart body names its fields and the allowed segments and roles
    path, op = doc.find("post", lambda p, o: doc.body_schema(o, "multipart/form-data") is not None)
    form = doc.body_schema(op, "multipart/form-data")
    file_field = next(k for k, v in form["properties"].items() if v.get("type") == "array"
                      and v["items"].get("format") == "binary")
    assert set(doc.enum(form, "segment")) == {"thigh", "shank"}
    assert {"mag_calibration", "standing", "lying", "task"} <= set(doc.enum(form, "role"))
    url = _fill(path, session_id=session_id)
    _problem(doc, op, client.post(url, files=[(file_field, ("a.txt", b"x", "text/plain"))], headers=h), 415)
    _problem(doc, op, client.post(url, files=[(file_field, ("a.csv", b"x", "text/csv"))],
                                  data={"segment": "knee"}, headers=h), 400)
    files = [(file_field, (p.name, p.read_bytes(), "text/csv")) for p in sorted(demo_dir.glob("*.csv"))]
    r = client.post(url, files=files, headers=h)
    doc.check(op, r)
    assert r.json()["ingestion"]["ok"] is True

    # webhook: the POST whose body is the webhook schema; its events from the document's enum
    from test_web_webhooks import Receiver

    receiver = Receiver([])
    path, op = doc.find("post", lambda p, o: (doc.body_schema(o) or {}).get("title") == "WebhookIn")
    events = doc.enum(doc.body_schema(op), "events")
    assert set(events) == {"job.done", "job.failed"}
    r = client.post(path, json={"url": receiver.url, "events": events}, headers=h)
    assert r.status_code == 201, r.text  # the token is the clinic's admin (needed to subscribe)
    doc.check(op, r)

    # process: the POST answering 202; its filter from the document's enum
    path, op = doc.find("post", lambda p, o: "202" in o["responses"])
    filters = doc.enum(doc.body_schema(op), "filter")
    assert "chakamo" in filters
    _problem(doc, op, client.post(_fill(path, session_id=session_id), json={"filter": "kalman"}, headers=h), 422)
    r = client.post(_fill(path, session_id=session_id), json={"filter": filters[0]}, headers=h)
    doc.check(op, r)
    job_id = r.json()["job_id"]

    # the job, followed until one of the terminal statuses its schema lists
    path, op = doc.find("get", lambda p, o: p.endswith("/jobs/{job_id}"))
    job_schema = doc.schema(doc.answer(op, 200)["content"]["application/json"]["schema"])
    assert set(doc.enum(job_schema, "status")) == {"queued", "running", "done", "failed"}
    end = time.monotonic() + 300
    while True:
        r = client.get(_fill(path, job_id=job_id), headers=h)
        doc.check(op, r)
        if r.json()["status"] in ("done", "failed") or time.monotonic() > end:
            break
        time.sleep(0.2)
    assert r.json()["status"] == "done", r.json()

    end = time.monotonic() + 120  # the webhook announced it (checked in detail by test_web_webhooks.py)
    while not receiver.got and time.monotonic() < end:
        time.sleep(0.2)
    assert receiver.got and b'"job.done"' in receiver.got[0][1]

    # results, PDF and FHIR: found by the media types the document declares
    path, op = doc.find("get", lambda p, o: p.endswith("/results"))
    r = client.get(_fill(path, session_id=session_id), headers=h)
    doc.check(op, r)
    assert r.json()["cycles"]["accepted"] >= 3
    path, op = doc.find("get", lambda p, o: "application/pdf" in o["responses"]["200"].get("content", {}))
    assert set(next(p for p in op["parameters"] if p["name"] == "lang")["schema"]["anyOf"][0]["enum"]) == \
        {"es", "en", "pt"}
    r = client.get(_fill(path, session_id=session_id), params={"lang": "pt"}, headers=h)
    doc.check(op, r)
    assert r.content.startswith(b"%PDF")
    path, op = doc.find("get", lambda p, o: "application/fhir+json" in o["responses"]["200"].get("content", {})
                        and "{session_id}" in p)
    r = client.get(_fill(path, session_id=session_id), headers=h)
    doc.check(op, r)
    assert r.json()["resourceType"] == "DiagnosticReport"
    _problem(doc, op, client.get(_fill(path, session_id=999999), headers=h), 404)


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_refusals_keep_their_catalogue_members(client, settings):
    """A Refusal is a problem with ``code``, ``params`` and ``message`` (es/en/pt) as extension members, the
    header names its code, and ``type`` is derived from the code."""
    h = clinic_token(settings, "Hospital Problem")
    r = client.post("/api/v1/patients", json={"external_id": "P-1", "side": "right"}, headers=h)
    sid = client.post(f"/api/v1/patients/{r.json()['id']}/sessions", json={}, headers=h).json()["id"]
    r = client.post(f"/api/v1/sessions/{sid}/recordings", files=[("files", ("x.pdf", b"%PDF", "application/pdf"))],
                    headers=h)
    assert r.status_code == 415 and r.headers["content-type"] == PROBLEM
    body = r.json()
    assert body["type"] == "urn:chakamo:problem:request.file_type" == "urn:chakamo:problem:" + body["code"]
    assert body["title"] == "Unsupported Media Type" and body["status"] == 415
    assert body["instance"] == f"/api/v1/sessions/{sid}/recordings"
    assert set(body["message"]) == {"es", "en", "pt"} and body["params"]["file"] == "x.pdf"
    assert r.headers["x-chakamo-code"] == body["code"]
    r = client.get("/api/v1/nowhere", headers=h)  # a path the app does not have: a problem too
    assert r.status_code == 404 and r.headers["content-type"] == PROBLEM and r.json()["type"] == "about:blank"
