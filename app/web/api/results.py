"""``GET /sessions/{id}/results``: the results.json of an analysis (the latest finished one by default),
audited as a ``view`` of the session's patient (:mod:`app.web.audit`).

Superseded analyses (a recording deleted or a printed fact corrected since, :mod:`app.store.analyses`): the
default answers 409 saying so ("process the session again"); one asked for by ``analysis_id`` is answered,
for the record, with ``X-Analysis-Status: superseded`` (``current`` otherwise), the header every download of
:mod:`.artefacts` carries too.

``GET /sessions/{id}/warnings`` (same analysis choice): the quality warnings of that results.json in Spanish,
English and Portuguese, as the reports print them (:func:`reports.warning_text.warning_text` from their ``code``
and ``params``), for the results page to show in the reader's language (issue 14 §5); results.json itself stays
as DESIGN §4 fixes it."""

from __future__ import annotations

import json

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


@router.get("/{session_id}/warnings", responses={**{k: v for k, v in ERRORS.items() if k != 412},
                                                 409: {"description": "the latest analysis is superseded"}})
def get_warnings(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                 analysis_id: int | None = None) -> list[dict]:
    """``[{"code", "params", "message": {"es", "en", "pt"}, "technical"}]``: results.json ``quality.warnings`` in each
    language (``technical`` false), then its ``quality.technical_notes`` (true: how the files were read, which the
    results page folds away; :func:`reports.warning_text.is_technical`, which also sorts a results.json written
    before the two lists were kept apart)."""
    from reports.i18n import LANGUAGES as REPORT_LANGUAGES
    from reports.warning_text import is_technical, warning_text

    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, analysis_id)
    results = json.loads(store.read(artefact(db, analysis, "results.json").sha256))
    audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id)
    quality = results.get("quality") or {}
    every = [w for w in [*(quality.get("warnings") or []), *(quality.get("technical_notes") or [])] if isinstance(w, dict)]
    return [{"code": w.get("code"), "params": w.get("params") or {}, "technical": technical,
             "message": {lang: warning_text(w, lang, results)[0] for lang in REPORT_LANGUAGES}}
            for technical in (False, True) for w in every if is_technical(w) == technical]
