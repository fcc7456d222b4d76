"""What the correcting and erasing routes of :mod:`app.web.api` share (kept out of the routers, which stay
leaves): ``If-Match`` versions, their OpenAPI error answers, the erasure of the blobs a deletion left
unreferenced, and the header naming an answered analysis current or superseded.

Versions: a patient's and a session's answers carry ``ETag: "<version>"`` (the row's ``version``, bumped by
every correction).  ``PATCH`` takes an optional ``If-Match`` (a stale one answers 412: someone corrected the row
meanwhile); a ``DELETE``, which cascades (patient → sessions → recordings, jobs, analyses, artefacts → stored
files), *requires* one — the version the caller last saw, or ``*`` for "whatever it is now" — and answers 428
without it, so an erasure is always an explicit, informed request (RFC 9110 §13.1.1, RFC 6585 §3).

Erasure: the deleting route marks the blobs in its own transaction and, once that committed, erases them
(:func:`app.store.erasure.erase_pending`) before answering 204, so a 204 means the bytes are gone from the
store; a mark whose erasure fails stays pending for the runner's sweep (logged).
"""

from __future__ import annotations

import logging
import re

from fastapi import Request

from app.store.erasure import erase_pending
from app.web.messages import refusal

log = logging.getLogger("chakamo.erasure")

_TAG = re.compile(r'^\s*(?:W/)?"?(\d{1,12})"?\s*$')

#: the error answers of the correcting and erasing routes, for OpenAPI
ERRORS = {401: {"description": "not logged in, or an unknown or revoked token"},
          403: {"description": "role too low, or a browser request without its X-CSRF-Token"},
          404: {"description": "no such id in your clinic (another clinic's ids answer the same)"},
          409: {"description": "a job of the session is queued or running, or the identifier is taken"},
          412: {"description": "If-Match names a version the row no longer has: reload it"}}
DELETE_ERRORS = ERRORS | {428: {"description": "If-Match missing: send the version you saw (the ETag), or *"}}


def etag(version: int) -> str:
    return f'"{version}"'


def if_match(request: Request, required: bool) -> int | None:
    """The version ``If-Match`` names (None: absent or ``*``); 428 when ``required`` and absent, 400 when
    unreadable."""
    raw = request.headers.get("if-match")
    if raw is None or not raw.strip():
        if required:
            raise refusal(request, 428, "request.if_match_required")
        return None
    if raw.strip() == "*":
        return None
    m = _TAG.match(raw)
    if m is None:
        raise refusal(request, 400, "request.if_match_unreadable", value=raw[:40])
    return int(m.group(1))


def erase_now(request: Request, ids: list[int]) -> None:
    """Erase the marked blobs ``ids`` after the deletion committed (module docstring)."""
    if not ids:
        return
    state = request.app.state
    try:
        erase_pending(state.db, state.store, ids)
    except Exception:  # noqa: BLE001 — the deletion stands; the sweep erases what is left
        log.exception("erasure of %d stored files deferred to the sweep", len(ids))


#: the header naming an answered analysis ``current`` or ``superseded`` (results and downloads)
STATUS_HEADER = "X-Analysis-Status"


def analysis_status(analysis) -> str:
    return "current" if analysis.superseded_at is None else "superseded"


__all__ = ["DELETE_ERRORS", "ERRORS", "STATUS_HEADER", "analysis_status", "erase_now", "etag", "if_match"]
