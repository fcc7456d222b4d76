"""``GET /fhir/DiagnosticReport/{session_id}``: the session's latest analysis as a FHIR R4 DiagnosticReport.

The document is built by :func:`app.web.fhir.diagnostic_report` (another module of the project) from the
session, patient, results.json and the PDF in the analysis' language; ``base_url`` is this server's
``/api/v1`` address (the namespace of the session and patient identifiers), from ``CHAKAMO_PUBLIC_URL``
(:func:`fhir_base_url`).  ``?analysis_id=`` picks an
earlier analysis.  Stored data the export cannot express (e.g. a patient's sex recorded before the API
restricted it to male, female, other, unknown) answers 409 with the export's sentence, not 500.  A superseded
analysis (:mod:`app.store.analyses`: a recording deleted or a printed detail corrected since) is never
exported — a DiagnosticReport says ``final`` — so it answers 409 too, also when asked for by id.  Each
export is audited (``export`` of the session's patient, :mod:`app.web.audit`).
"""

from __future__ import annotations

import json

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import Response

from app.store.analyses import SupersededResults, artefact, latest_analysis, pick_analysis
from app.web import audit
from app.web.api.deps import DbDep, Reader, StoreDep, scoped_session
from app.web.api.schemas import patient_out
from app.web.fhir import FhirExportError, diagnostic_report
from app.web.refusals import Refusal

router = APIRouter(prefix="/fhir", tags=["fhir"])


def fhir_base_url(request: Request) -> str:
    """The namespace of the exported identifiers: ``CHAKAMO_PUBLIC_URL``/api/v1; else this request's address,
    only when its ``Host`` was checked against ``CHAKAMO_ALLOWED_HOSTS`` or in development; else 503 (a
    spoofed Host must never be written into a clinical document: issue 16, finding 10d)."""
    settings = request.app.state.settings
    if settings.public_url:
        return settings.public_url + "/api/v1"
    if settings.host_patterns == ("*",) and not settings.development:
        raise Refusal(503, "request.public_url_missing")
    return str(request.base_url).rstrip("/") + "/api/v1"


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
    results = json.loads(store.read(artefact(db, analysis, "results.json").sha256))
    pdf = store.read(artefact(db, analysis, "report.pdf", analysis.lang).sha256)
    sess = {"id": session.id, "patient_id": session.patient_id, "date": session.date.isoformat(),
            "task": session.task, "step_height_m": session.step_height_m, "professional": session.professional,
            "notes": session.notes, "created_at": session.created_at.isoformat(), "analysis_id": analysis.id,
            "analysis_created_at": analysis.created_at.isoformat(), "filter": analysis.filter}
    patient = {k: (v.isoformat() if hasattr(v, "isoformat") else v) for k, v in patient_out(session.patient).items()}
    base_url = fhir_base_url(request)
    try:
        doc = diagnostic_report(session=sess, patient=patient, results=results, pdf=pdf, lang=analysis.lang,
                                base_url=base_url)
    except FhirExportError as exc:  # stored data the export cannot express: say what, the caller can fix it
        raise HTTPException(409, f"Session {session_id} cannot be exported to FHIR: {exc}; correct the record and "
                                 "try again.") from None
    audit.record(db, request, principal, "export", patient_id=session.patient_id, session_id=session.id)
    return Response(json.dumps(doc, ensure_ascii=False), media_type="application/fhir+json")
