"""Two sessions of one patient side by side (e.g. before and after treatment): ``GET /patients/{id}/compare``.

:func:`compare_sessions` reads each session's analysis (its latest current one, or the one asked for) and puts
their numbers side by side (:func:`app.pipeline.comparison.comparison_rows`: ``change = b − a``, ``a`` the earlier
session as the caller names it).  The two analyses should come from the same orientation filter, pipeline version,
calibration and angle convention (:data:`app.store.analyses.SERIES`): a difference of method is not the patient's.  Without explicit
analyses, when the two latest analyses differ in any, the earlier session's latest analysis of the later one's
series is used when there is one; ``comparable`` says whether the pair finally shares those, task and knee (:func:`app.pipeline.comparison.mismatch`,
the rule ``chakamo process --compare-with`` applies too), and ``mismatch`` names what differs.
"""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.pipeline.comparison import comparison_rows, mismatch
from app.store.analyses import SERIES, find_artefact, pick_analysis
from app.store.blobs import BlobStore
from app.store.errors import NotFound
from app.store.models import Analysis, KneeSession
from app.store.sessions import clinic_session

def _series(analysis: Analysis) -> tuple[str, ...]:
    return tuple(getattr(analysis, k) for k in SERIES)


def _same_series(db: Session, session_id: int, like: Analysis) -> Analysis | None:
    """The session's latest current analysis of ``like``'s series (:data:`app.store.analyses.SERIES`), or None."""
    return db.scalar(select(Analysis).where(
        Analysis.session_id == session_id, Analysis.superseded_at.is_(None),
        *(getattr(Analysis, k) == getattr(like, k) for k in SERIES)).order_by(Analysis.id.desc()))


def _side(db: Session, store: BlobStore, session: KneeSession, analysis: Analysis
          ) -> tuple[dict[str, Any], dict[str, Any]]:
    """What the comparison says of one session's analysis, and its results.json."""
    results = json.loads(store.read(find_artefact(db, analysis.id, "results.json").sha256))
    return {"session_id": session.id, "date": session.date, "task": results.get("task"),
            "side": results.get("side"), "involved_side": results.get("involved_side"),
            "analysis_id": analysis.id, **dict(zip(SERIES, _series(analysis))),
            "accepted_cycles": analysis.accepted_cycles}, results


def compare_sessions(db: Session, store: BlobStore, clinic_id: int, patient_id: int, a: int, b: int,
                     a_analysis: int | None = None, b_analysis: int | None = None) -> dict[str, Any]:
    """Sessions ``a`` and ``b`` of the patient side by side (module docstring): ``{"a": {...}, "b": {...},
    "comparable", "mismatch", "rows"}``.  :class:`NotFound` when a session is not the patient's (in the clinic) or
    has no analysis; :class:`app.store.analyses.SupersededResults` when its latest analysis is superseded."""
    sessions = [clinic_session(db, clinic_id, sid) for sid in (a, b)]
    for s in sessions:
        if s.patient_id != patient_id:
            raise NotFound(code="store.not_patients_session", session_id=s.id, patient_id=patient_id)
    chosen = [pick_analysis(db, s, aid) for s, aid in zip(sessions, (a_analysis, b_analysis))]
    if a_analysis is None and _series(chosen[0]) != _series(chosen[1]):
        chosen[0] = _same_series(db, sessions[0].id, chosen[1]) or chosen[0]
    (side_a, res_a), (side_b, res_b) = (_side(db, store, s, an) for s, an in zip(sessions, chosen))
    differ = mismatch(side_a, side_b)
    return {"a": side_a, "b": side_b, "comparable": not differ, "mismatch": differ, "rows": comparison_rows(res_a, res_b)}


__all__ = ["compare_sessions"]
