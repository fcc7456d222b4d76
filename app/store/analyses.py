"""Analyses and their artefacts (results.json, report.pdf per language, workbooks, scene, time series)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.store.errors import NotFound
from app.store.models import Analysis, Artefact, KneeSession


def latest_analysis(db: Session, session_id: int) -> Analysis | None:
    return db.scalar(select(Analysis).where(Analysis.session_id == session_id).order_by(Analysis.id.desc()))


def pick_analysis(db: Session, session: KneeSession, analysis_id: int | None) -> Analysis:
    """Analysis ``analysis_id`` of ``session`` (:class:`NotFound` if it is another session's), or its latest
    one (:class:`NotFound` when it has none yet)."""
    if analysis_id is not None:
        analysis = db.get(Analysis, analysis_id)
        if analysis is None or analysis.session_id != session.id:
            raise NotFound(f"No analysis {analysis_id} in session {session.id}; check the id.")
        return analysis
    analysis = latest_analysis(db, session.id)
    if analysis is None:
        raise NotFound(f"Session {session.id} has no results yet; process it first "
                       f"(POST /api/v1/sessions/{session.id}/process).")
    return analysis


def find_artefact(db: Session, analysis_id: int, name: str, lang: str = "") -> Artefact | None:
    return db.scalar(select(Artefact).where(Artefact.analysis_id == analysis_id, Artefact.name == name,
                                            Artefact.lang == lang))


def artefact(db: Session, analysis: Analysis, name: str, lang: str = "") -> Artefact:
    """The artefact ``name`` (in ``lang`` for a report) of ``analysis``, else :class:`NotFound`."""
    row = find_artefact(db, analysis.id, name, lang)
    if row is None:
        raise NotFound(f"Analysis {analysis.id} has no {name}{' in ' + lang if lang else ''}; process "
                       "the session again to make it.")
    return row


__all__ = ["artefact", "find_artefact", "latest_analysis", "pick_analysis"]
