"""Analyses and their artefacts (results.json, report.pdf per language, workbooks, scene, time series).

Superseded analyses: an analysis is computed from a session's recordings and the facts its reports print
(patient side, name, session date, step height...).  When a recording is deleted or those facts are corrected,
:func:`supersede` stamps every analysis of the session not yet superseded with ``superseded_at``.  They stay,
for the record, and can be read by id; but :func:`pick_analysis` no longer gives one as the session's current
result: asked for the latest, it raises :class:`SupersededResults` (409, "process the session again") when the
latest is superseded, so no route serves it as the final report by default.  A newer analysis (the session
processed again) is current again.

The clinical convention: a session may be processed again with the thesis' ZYX angles only to compare with them
(they read adduction 10.1° higher and rotation 19.8° lower at 90/5/15°, :mod:`app.pipeline.comparison`).  Such a run
is read by id; the session's current analysis is its latest in Grood & Suntay
(:data:`app.choices.DEFAULT_ANGLE_CONVENTION`), the latest of any convention only when it has none
(:func:`latest_analysis`).  :data:`SERIES` names the columns of the method: analyses differing in one are not
compared or trended together (:mod:`app.store.comparisons`, :func:`app.store.patients.rom_trend`).
"""

from __future__ import annotations

from collections.abc import Iterable

from sqlalchemy import case, select, update
from sqlalchemy.orm import Session

from app.choices import DEFAULT_ANGLE_CONVENTION
from app.store.errors import Conflict, NotFound
from app.store.models import Analysis, Artefact, KneeSession, utcnow


#: the analysis columns of the method that made its numbers: two analyses are of one series when all are equal
SERIES = ("filter", "pipeline_version", "calibration", "angle_method")


class SupersededResults(Conflict):
    """The session's latest analysis was computed from recordings or facts that have changed since."""

    def __init__(self, session_id: int, analysis: Analysis, readable_by_id: bool = True) -> None:
        tail = {"code": "store.superseded_tail", "params": {"analysis_id": analysis.id}} if readable_by_id else ""
        super().__init__(code="store.superseded", session_id=session_id, analysis_id=analysis.id,
                         when=f"{analysis.superseded_at:%Y-%m-%d %H:%M}", tail=tail)
        self.analysis_id = analysis.id


def supersede(db: Session, session_ids: Iterable[int], *, calibration: str | None = None,
              angle_method: str | None = None) -> int:
    """Mark every analysis of ``session_ids`` not yet superseded as superseded now; returns how many.
    ``calibration`` / ``angle_method``: only the analyses made with these (a choice of cycles revises the analyses
    of its own convention, not a ZYX or functional-calibration view of the same files)."""
    ids = list(session_ids)
    if not ids:
        return 0
    same = [getattr(Analysis, k) == v for k, v in (("calibration", calibration), ("angle_method", angle_method))
            if v is not None]
    return db.execute(update(Analysis).where(Analysis.session_id.in_(ids), Analysis.superseded_at.is_(None), *same)
                      .values(superseded_at=utcnow())).rowcount or 0


def latest_analysis(db: Session, session_id: int) -> Analysis | None:
    """The session's current analysis (superseded or not): its latest in the clinical angle convention, else its
    latest (module docstring); None when it has none."""
    clinical = case((Analysis.angle_method == DEFAULT_ANGLE_CONVENTION, 0), else_=1)
    return db.scalar(select(Analysis).where(Analysis.session_id == session_id)
                     .order_by(clinical, Analysis.id.desc()).limit(1))


def pick_analysis(db: Session, session: KneeSession, analysis_id: int | None) -> Analysis:
    """Analysis ``analysis_id`` of ``session`` (:class:`NotFound` if it is another session's; a superseded one
    too: the caller says it is superseded), or its latest one (:class:`NotFound` when it has none yet,
    :class:`SupersededResults` when the latest is superseded: module docstring)."""
    if analysis_id is not None:
        analysis = db.get(Analysis, analysis_id)
        if analysis is None or analysis.session_id != session.id:
            raise NotFound(code="store.no_analysis", analysis_id=analysis_id, session_id=session.id)
        return analysis
    analysis = latest_analysis(db, session.id)
    if analysis is None:
        raise NotFound(code="store.no_results", session_id=session.id)
    if analysis.superseded_at is not None:
        raise SupersededResults(session.id, analysis)
    return analysis


def find_artefact(db: Session, analysis_id: int, name: str, lang: str = "") -> Artefact | None:
    return db.scalar(select(Artefact).where(Artefact.analysis_id == analysis_id, Artefact.name == name,
                                            Artefact.lang == lang))


def artefact(db: Session, analysis: Analysis, name: str, lang: str = "") -> Artefact:
    """The artefact ``name`` (in ``lang`` for a report) of ``analysis``, else :class:`NotFound`."""
    row = find_artefact(db, analysis.id, name, lang)
    if row is None:
        raise NotFound(code="store.no_artefact", analysis_id=analysis.id, name=name,
                       in_lang=f" ({lang})" if lang else "")
    return row


__all__ = ["SERIES", "SupersededResults", "artefact", "find_artefact", "latest_analysis", "pick_analysis", "supersede"]
