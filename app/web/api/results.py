"""``GET /sessions/{id}/results``: the results.json of an analysis (the latest finished one by default),
audited as a ``view`` of the session's patient (:mod:`app.web.audit`)."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import Response
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.web import audit
from app.web.api.deps import DbDep, Reader, StoreDep, scoped_session
from app.store.models import Analysis, Artefact, KneeSession

router = APIRouter(prefix="/sessions", tags=["results"])


def pick_analysis(db: Session, session: KneeSession, analysis_id: int | None) -> Analysis:
    """Analysis ``analysis_id`` of ``session`` (404 if it is another session's), or its latest one."""
    if analysis_id is not None:
        analysis = db.get(Analysis, analysis_id)
        if analysis is None or analysis.session_id != session.id:
            raise HTTPException(404, f"No analysis {analysis_id} in session {session.id}; check the id.")
        return analysis
    analysis = db.scalar(select(Analysis).where(Analysis.session_id == session.id).order_by(Analysis.id.desc()))
    if analysis is None:
        raise HTTPException(404, f"Session {session.id} has no results yet; process it first "
                                 f"(POST /api/v1/sessions/{session.id}/process).")
    return analysis


def artefact_row(db: Session, analysis: Analysis, name: str, lang: str = "") -> Artefact:
    row = db.scalar(select(Artefact).where(Artefact.analysis_id == analysis.id, Artefact.name == name,
                                           Artefact.lang == lang))
    if row is None:
        raise HTTPException(404, f"Analysis {analysis.id} has no {name}{' in ' + lang if lang else ''}; process "
                                 "the session again to make it.")
    return row


@router.get("/{session_id}/results", responses={200: {"content": {"application/json": {}}}})
def get_results(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                analysis_id: int | None = None):
    """The stored results.json, byte for byte (DESIGN §4)."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, analysis_id)
    data = store.read(artefact_row(db, analysis, "results.json").sha256)
    audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id)
    return Response(data, media_type="application/json")
