"""``GET /sessions/{id}/results``: the results.json of an analysis (the latest finished one by default),
audited as a ``view`` of the session's patient (:mod:`app.web.audit`).

Superseded analyses (a recording deleted or a printed fact corrected since, :mod:`app.store.analyses`): the
default answers 409 saying so ("process the session again"); one asked for by ``analysis_id`` is answered,
for the record, with ``X-Analysis-Status: superseded`` (``current`` otherwise), the header every download of
:mod:`.artefacts` carries too."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response

from app.store.analyses import artefact, pick_analysis
from app.web import audit
from app.web.api.deps import DbDep, Reader, StoreDep, scoped_session
from app.web.records import ERRORS, STATUS_HEADER, analysis_status

router = APIRouter(prefix="/sessions", tags=["results"])


@router.get("/{session_id}/results", responses={200: {"content": {"application/json": {}}},
                                                **{k: v for k, v in ERRORS.items() if k != 412},
                                                409: {"description": "the latest analysis is superseded: process "
                                                                     "the session again"}})
def get_results(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                analysis_id: int | None = None):
    """The stored results.json, byte for byte (DESIGN §4)."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, analysis_id)
    data = store.read(artefact(db, analysis, "results.json").sha256)
    audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id)
    return Response(data, media_type="application/json", headers={STATUS_HEADER: analysis_status(analysis)})
