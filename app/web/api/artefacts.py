"""Downloads of an analysis' artefacts: report.pdf (es, en, pt), angles.xlsx, quaternions.xlsx, report.html,
scene.viser, timeseries.npz (the task's angles and orientations, :func:`app.pipeline.results.timeseries_npz`), and
scene.png, the 3D view's first frame drawn from scene.viser per request (:mod:`reports.scene_still`; 404
``store.no_still`` for a recording it cannot draw; inline, not stored).
Checksums are verified on every read (:meth:`app.store.blobs.BlobStore.read`).

Files to keep (PDF, Excel, npz) come as attachments named
``chakamo-<patient reference>-<recordings' date>-s<session>-a<analysis>[-<lang>]-<stem>.<ext>`` (:func:`download_name`:
the record number, made safe for a file name, and the day the recordings were made, else the session's date, so a
downloaded file says whose it is and when; issue 17 §3); report.html and scene.viser are served inline under the
same names (the UI opens the first and viser's client plays the second).  report.pdf and report.html exist in every
language (``?lang=``; default: the job's; an analysis from before the HTML was made per language has one, in its
job's language).  With a signed interpretation, both are the signed files stored at the signature or the last
amendment (:func:`app.store.signed_reports.signed_artefact`): served as stored, never rendered per request.
The file name's recordings' date comes from the analysis' small ``patient.json`` (the identity block the job
printed), not from its results.json.
report.html carries ``Content-Security-Policy: sandbox allow-scripts; default-src 'none'; …``
(:data:`app.web.headers.REPORT_HTML_CSP`): it holds text typed by people (patient name, notes), so even if
escaping failed its scripts could not act as the logged-in user, nor reach the network.  Every download,
scene.png included, is audited (``download`` of the session's patient, :mod:`app.web.audit`), in the request's
transaction.
A superseded analysis (:mod:`app.store.analyses`) is never the default: without ``analysis_id`` the downloads
answer 409 "process the session again"; asked for by id it is served with ``X-Analysis-Status: superseded``
and a file name ending in ``-superseded`` (:mod:`.results`).
"""

from __future__ import annotations

import json
import logging
import re
import unicodedata

from fastapi import APIRouter, Request
from fastapi.responses import Response

from app.store.analyses import artefact, find_artefact, pick_analysis
from app.store.errors import NotFound
from app.store.signed_reports import PATIENT_JSON, signed_artefact
from app.web import audit
from app.web.api.deps import DbDep, Reader, StoreDep, scoped_session
from app.web.api.schemas import Lang
from app.web.records import STATUS_HEADER, analysis_status
from app.web.headers import REPORT_HTML_CSP

log = logging.getLogger(__name__)

router = APIRouter(prefix="/sessions", tags=["artefacts"],
                   responses={409: {"description": "the latest analysis is superseded (process the session again), "
                                                   "or none has finished yet"}})


def _safe(text: str, limit: int = 40) -> str:
    """``text`` as a file-name part: accents dropped (NFKD), anything but letters, digits, ``.``, ``_`` and ``-``
    turned into ``_``, at most ``limit`` characters (a header value must be plain ASCII, and no path or quote)."""
    ascii_text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    return re.sub(r"[^A-Za-z0-9._-]+", "_", ascii_text).strip("._-")[:limit]


def recorded_day(db, store, analysis) -> str:
    """The recordings' first day the analysis' reports printed (its ``patient.json``; for an analysis stored before
    that file, its results.json), or ``""``."""
    small = find_artefact(db, analysis.id, PATIENT_JSON)
    if small is not None:
        return str(json.loads(store.read(small.sha256)).get("recorded") or "")
    results = json.loads(store.read(artefact(db, analysis, "results.json").sha256))
    return str(((results.get("session") or {}).get("recorded") or {}).get("first") or "")


def download_name(session, analysis, recorded: str, name: str, lang: str, superseded: bool) -> str:
    """``chakamo-<record number>-<recordings' first day ``recorded``, else the session's date>-s<id>-a<id>[-<lang>]-
    <stem>[-superseded].<ext>`` (module docstring)."""
    stem, ext = name.rsplit(".", 1)
    day = str(recorded or session.date.isoformat())[:10]
    ref = _safe(session.patient.external_id or "") or f"patient{session.patient_id}"
    tail = "-superseded" if superseded else ""
    return f"chakamo-{ref}-{_safe(day)}-s{session.id}-a{analysis.id}{'-' + lang if lang else ''}-{stem}{tail}.{ext}"


def _send(db, store, principal, request: Request, session_id: int, name: str, analysis_id: int | None,
          lang: str = "", attachment: bool = True) -> Response:
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, analysis_id)
    if name in ("report.pdf", "report.html") and not lang:
        lang = analysis.lang
    if name == "report.html" and find_artefact(db, analysis.id, name, lang) is None \
            and lang == analysis.lang and find_artefact(db, analysis.id, name, "") is not None:
        art = artefact(db, analysis, name, "")  # an analysis from before the HTML was made in every language
    else:
        art = signed_artefact(db, analysis, name, lang) or artefact(db, analysis, name, lang)
    status = analysis_status(analysis)
    filename = download_name(session, analysis, recorded_day(db, store, analysis), name, lang, status == "superseded")
    disposition = "attachment" if attachment else "inline"
    headers = {"Content-Disposition": f'{disposition}; filename="{filename}"', STATUS_HEADER: status}  # no-store, nosniff: app/web/headers.py
    if name == "report.html":  # patient-typed text inside: scripts run, but in an opaque origin (no cookie, no API)
        headers["Content-Security-Policy"] = REPORT_HTML_CSP  # app/web/headers.py: sandboxed, no network
    data = store.read(art.sha256)
    audit.record(db, request, principal, "download", patient_id=session.patient_id, session_id=session.id)
    return Response(data, media_type=art.media_type, headers=headers)


@router.get("/{session_id}/scene.png", response_class=Response, responses={200: {"content": {"image/png": {}}}})
def scene_png(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
              analysis_id: int | None = None):
    """The 3D view's first frame as a still picture, drawn from scene.viser's first state
    (:mod:`reports.scene_still`): what the results page shows until viser's client plays the recording.  A
    recording the still cannot draw (another viser major version, no mesh, beyond the still's caps) is refused
    like a missing artefact: 404 ``store.no_still``."""
    from reports.scene_still import still_png

    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, analysis_id)
    try:
        png = still_png(store.read(artefact(db, analysis, "scene.viser").sha256))
    except ValueError as exc:  # a recording the still cannot draw (another viser major, no mesh, over a cap)
        log.warning("analysis %s: no still of its scene.viser: %s", analysis.id, exc)
        raise NotFound(code="store.no_still", analysis_id=analysis.id) from exc
    audit.record(db, request, principal, "download", patient_id=session.patient_id, session_id=session.id)
    return Response(png, media_type="image/png", headers={STATUS_HEADER: analysis_status(analysis)})


@router.get("/{session_id}/report.pdf", response_class=Response,
            responses={200: {"content": {"application/pdf": {}}}})
def report_pdf(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
               lang: Lang | None = None, analysis_id: int | None = None):
    """The clinical report (default: the language the job was started with), with the clinician's signed
    interpretation when there is one."""
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
                lang: Lang | None = None, analysis_id: int | None = None):
    """The interactive report (default: the language the job was started with), with the clinician's signed
    interpretation when there is one."""
    return _send(db, store, principal, request, session_id, "report.html", analysis_id, lang or "", attachment=False)


@router.get("/{session_id}/scene.viser", response_class=Response)
def scene_viser(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                analysis_id: int | None = None):
    return _send(db, store, principal, request, session_id, "scene.viser", analysis_id, attachment=False)


@router.get("/{session_id}/timeseries.npz", response_class=Response)
def timeseries_npz(session_id: int, principal: Reader, db: DbDep, store: StoreDep, request: Request,
                   analysis_id: int | None = None):
    """The task's time series (numpy ``.npz``: time, knee angles, orientations) for research use."""
    return _send(db, store, principal, request, session_id, "timeseries.npz", analysis_id)
