"""``GET /fhir/DiagnosticReport/{session_id}``: the session's latest analysis as a FHIR R4 DiagnosticReport;
``GET /fhir/DiagnosticReport?patient=`` a searchset Bundle of a patient's reports; ``GET /fhir/metadata`` the
CapabilityStatement; ``GET /fhir/pushes`` (admin) the trail of the push to the hospital's FHIR server.

The document is built by :func:`app.web.fhir.diagnostic_report` (another module of the project) from the
session, patient, results.json and the PDF in the analysis' language; ``base_url`` is the namespace of the
session and patient identifiers (:func:`fhir_base_url`: configured, never a request's host outside development);
the code system, the patient's identifier system, how the patient is named (contained or by identifier) and
the accession's system come from the settings (``CHAKAMO_FHIR_*``, ``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM``,
``CHAKAMO_ACCESSION_SYSTEM``); the session's ``service_request``, ``encounter`` and ``accession`` are passed in.  ``?analysis_id=`` picks an
earlier analysis.  Stored data the export cannot express (e.g. a patient's sex recorded before the API
restricted it to male, female, other, unknown) answers 409 with the export's sentence, not 500.  A superseded
analysis (:mod:`app.store.analyses`: a recording deleted or a printed detail corrected since) is never
exported — a DiagnosticReport says ``final`` — so it answers 409 too, also when asked for by id.  Each
export is audited (``export`` of the session's patient, :mod:`app.web.audit`).
"""

from __future__ import annotations

import json

from fastapi import APIRouter, Query, Request
from fastapi.responses import Response

from app.store import webhooks
from app.store.analyses import SupersededResults, latest_analysis, pick_analysis
from app.web import audit
from app.store.sessions import patient_sessions
from app.web.api.deps import Admin, DbDep, Reader, StoreDep, scoped_patient, scoped_session
from app.web.api.schemas import DeliveryOut, delivery_out
from app.web.fhir import FhirExportError, capability_statement, diagnostic_report, search_bundle
from app.web.fhir_push import export_options, identifier_base, report_inputs
from estimators import __version__
from app.web.messages import refusal
from app.web.refusals import Refusal

router = APIRouter(prefix="/fhir", tags=["fhir"])


def fhir_base_url(request: Request) -> str:
    """The namespace of the exported identifiers: ``CHAKAMO_FHIR_IDENTIFIER_BASE``, else ``CHAKAMO_PUBLIC_URL``/api/v1;
    in development only, this request's address; else 503.  A request's ``Host`` never names identifiers in
    production (issue 16, finding 10d; issue 17)."""
    settings = request.app.state.settings
    if (base := identifier_base(settings)) is not None:
        return base
    if settings.development:
        return str(request.base_url).rstrip("/") + "/api/v1"
    raise Refusal(503, "request.public_url_missing")


def fhir_server_url(request: Request) -> str | None:
    """This server's FHIR address for the CapabilityStatement: ``CHAKAMO_PUBLIC_URL``/api/v1/fhir (the identifier
    namespace ``CHAKAMO_FHIR_IDENTIFIER_BASE`` names identifiers, not this server); in development only, this
    request's address; else None (the statement then names none)."""
    settings = request.app.state.settings
    if settings.public_url:
        return settings.public_url + "/api/v1/fhir"
    if settings.development:
        return str(request.base_url).rstrip("/") + "/api/v1/fhir"
    return None


def _export(db, store, request: Request, session, analysis) -> dict:
    """The DiagnosticReport of ``analysis`` of ``session`` (409 with the export's sentence when the stored data
    cannot be expressed)."""
    settings = request.app.state.settings
    try:
        return diagnostic_report(**report_inputs(db, store, session, analysis), base_url=fhir_base_url(request),
                                 **export_options(settings))
    except FhirExportError as exc:  # stored data the export cannot express: say what, the caller can fix it
        raise refusal(request, 409, "request.fhir_not_exportable", session_id=session.id, reason=str(exc)) from None


def _fhir(doc: dict) -> Response:
    return Response(json.dumps(doc, ensure_ascii=False), media_type="application/fhir+json")


@router.get("/metadata", response_class=Response, responses={200: {"content": {"application/fhir+json": {}}}})
def metadata(request: Request, principal: Reader):
    """The FHIR CapabilityStatement: what this server answers (read and search of DiagnosticReport)."""
    return _fhir(capability_statement(software_version=__version__, server_url=fhir_server_url(request)))


@router.get("/DiagnosticReport", response_class=Response,
            responses={200: {"content": {"application/fhir+json": {}}}})
def search_reports(request: Request, principal: Reader, db: DbDep, store: StoreDep,
                   patient: str = Query(..., max_length=80, pattern=r"^(Patient/)?[0-9]{1,12}$",
                                        description="the patient's ChakaMo id, as 123 or Patient/123")):
    """A searchset Bundle of the patient's current reports: each session's latest analysis, newest session
    first; sessions with none or with a superseded one are left out (a superseded report is never exported)."""
    pid = int(patient.removeprefix("Patient/"))
    scoped_patient(db, principal, pid)
    reports = []
    for session in patient_sessions(db, pid):
        analysis = latest_analysis(db, session.id)
        if analysis is not None and analysis.superseded_at is None:
            reports.append(_export(db, store, request, session, analysis))
    audit.record(db, request, principal, "export", patient_id=pid)
    return _fhir(search_bundle(reports))


@router.get("/DiagnosticReport/{session_id}", response_class=Response,
            responses={200: {"content": {"application/fhir+json": {}}},
                       409: {"description": "the stored data cannot be expressed in FHIR (the sentence says why)"}})
def diagnostic_report_route(session_id: int, request: Request, principal: Reader, db: DbDep, store: StoreDep,
                            analysis_id: int | None = None):
    session = scoped_session(db, principal, session_id)
    if analysis_id is None:  # the latest: superseded, it may not be exported either
        latest = latest_analysis(db, session.id)
        if latest is not None and latest.superseded_at is not None:
            raise SupersededResults(session.id, latest, readable_by_id=False)
    analysis = pick_analysis(db, session, analysis_id)
    if analysis.superseded_at is not None:  # asked for by id
        raise SupersededResults(session.id, analysis, readable_by_id=False)
    doc = _export(db, store, request, session, analysis)
    audit.record(db, request, principal, "export", patient_id=session.patient_id, session_id=session.id)
    return _fhir(doc)


@router.get("/pushes", response_model=list[DeliveryOut])
def fhir_pushes(principal: Admin, db: DbDep):
    """The trail of the pushes of the clinic's reports to the hospital's FHIR server (``CHAKAMO_FHIR_PUSH_URL``,
    :mod:`app.web.fhir_push`), newest first: one delivery per finished job, with its attempts, last status and
    error; empty when the push is not configured."""
    return [delivery_out(d) for d in webhooks.fhir_pushes(db, principal.clinic_id)]
