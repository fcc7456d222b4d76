"""Downloads of an analysis' artefacts: report.pdf (es, en, pt), angles.xlsx, quaternions.xlsx, report.html,
scene.viser, timeseries.npz (the task's angles and orientations, :func:`app.pipeline.results.timeseries_npz`).
Checksums are verified on every read (:meth:`app.store.blobs.BlobStore.read`).

Files to keep (PDF, Excel, npz) come as attachments named ``chakamo-session-<id>-<analysis>[-<lang>].<ext>``;
report.html and scene.viser are served inline (the UI opens the first and viser's client plays the second);
report.html carries ``Content-Security-Policy: sandbox allow-scripts; default-src 'none'; …``
(:data:`app.web.headers.REPORT_HTML_CSP`): it holds text typed by people (patient name, notes), so even if
escaping failed its scripts could not act as the logged-in user, nor reach the network.  Every download is
audited (``download`` of the session's patient, :mod:`app.web.audit`), in the request's transaction.
A superseded analysis (:mod:`app.store.analyses`) is never the default: without ``analysis_id`` the downloads
answer 409 "process the session again"; asked for by id it is served with ``X-Analysis-Status: superseded``
and a file name ending in ``-superseded`` (:mod:`.results`).
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response

from app.store.analyses import artefact, pick_analysis
from app.web import audit
from app.web.api.deps import DbDep, Reader, StoreDep, scoped_session
from app.web.api.schemas import Lang
from app.web.records import STATUS_HEADER, analysis_status
from app.web.headers import REPORT_HTML_CSP

router = APIRouter(prefix="/sessions", tags=["artefacts"],
                   responses={409: {"description": "the latest analysis is superseded (process the session again), "
                                                   "or none has finished yet"}})


def _send(db, store, principal, request: Request, session_id: int, name: str, analysis_id: int | None,
          lang: str = "", attachment: bool = True) -> Response:
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, analysis_id)
    if name == "report.pdf" and not lang:
        lang = analysis.lang
    art = artefact(db, analysis, name, lang)
    stem, ext = name.rsplit(".", 1)
    status = analysis_status(analysis)
    tail = "-superseded" if status == "superseded" else ""
    filename = f"chakamo-session-{session.id}-{analysis.id}{'-' + lang if lang else ''}-{stem}{tail}.{ext}"
    disposition = "attachment" if attachment else "inline"
    headers = {"Content-Disposition": f'{disposition}; filename="{filename}"', STATUS_HEADER: status}  # no-store, nosniff: app/web/headers.py
    if name == "report.html":  # patient-typed text inside: scripts run, but in an opaque origin (no cookie, no API)
        headers["Content-Security-Policy"] = REPORT_HTML_CSP  # app/web/headers.py: sandboxed, no network
    data = store.read(art.sha256)
    audit.record(db, request, principal, "download", patient_id=session.patient_id, session_id=session.id)
    return Response(data, media_type=art.media_type, headers=headers)


@router.get("/{session_id}/report.pdf", response_class=Response,
            responses={200: {"content": {"application/pdf": {}}}})
def report_pdf(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
               lang: Lang | None = None, analysis_id: int | None = None):
    """The clinical report (default: the language the job was started with)."""
    return _send(db, store, principal, request, session_id, "report.pdf", analysis_id, lang or "")


@router.get("/{session_id}/angles.xlsx", response_class=Response)
def angles_xlsx(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                analysis_id: int | None = None):
    return _send(db, store, principal, request, session_id, "angles.xlsx", analysis_id)


@router.get("/{session_id}/quaternions.xlsx", response_class=Response)
def quaternions_xlsx(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                     analysis_id: int | None = None):
    return _send(db, store, principal, request, session_id, "quaternions.xlsx", analysis_id)


@router.get("/{session_id}/report.html", response_class=Response)
def report_html(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                analysis_id: int | None = None):
    return _send(db, store, principal, request, session_id, "report.html", analysis_id, attachment=False)


@router.get("/{session_id}/scene.viser", response_class=Response)
def scene_viser(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                analysis_id: int | None = None):
    return _send(db, store, principal, request, session_id, "scene.viser", analysis_id, attachment=False)


@router.get("/{session_id}/timeseries.npz", response_class=Response)
def timeseries_npz(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                   analysis_id: int | None = None):
    """The task's time series (numpy ``.npz``: time, knee angles, orientations) for research use."""
    return _send(db, store, principal, request, session_id, "timeseries.npz", analysis_id)
