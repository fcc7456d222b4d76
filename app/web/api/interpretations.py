"""``/sessions/{id}/interpretation``: the clinician's interpretation of an analysis, its sign-off and amendments
(issue 17 §3; the rules are :mod:`app.store.interpretations`').

* ``GET`` (reader): the interpretation of the analysis (default: the session's current one, as every read of
  results): ``status`` ``none`` | ``draft`` | ``signed``, the text, who signed it (name, role, time), whether it was
  amended and each amendment (by whom, when, why, the text it replaced);
* ``POST`` ``{"text"}`` (clinician): save the draft; 409 once signed (locked);
* ``POST …/sign`` (clinician, a logged-in person: an API token cannot sign): sign the saved text;
* ``POST …/amendments`` ``{"text", "reason"}`` (clinician, a person): replace the signed text, the reason
  required, the earlier text kept.

Every call is scoped to the caller's clinic (another clinic's session answers 404) and audited: ``view`` for the
read, ``update`` for a draft, ``sign`` and ``amend``.  The PDF and HTML reports print the signed interpretation
(:mod:`app.store.signed_reports`).
"""

from __future__ import annotations

import datetime as dt

from fastapi import APIRouter, Request
from pydantic import BaseModel, ConfigDict, Field

from app.store import interpretations
from app.store.analyses import pick_analysis
from app.store.interpretations import MAX_TEXT_CHARS
from app.web import audit
from app.web.api.deps import Clinician, DbDep, Reader, scoped_session
from app.web.records import ERRORS

router = APIRouter(prefix="/sessions", tags=["interpretation"])
_ERRORS = ERRORS | {400: {"description": "an empty text or reason, or an API token where a person must sign"},
                    409: {"description": "signed and locked (amend it), not signed yet (no amendment), or the "
                                         "analysis is superseded"}}


class _In(BaseModel):
    model_config = ConfigDict(extra="forbid")


class InterpretationIn(_In):
    text: str = Field(max_length=MAX_TEXT_CHARS)
    analysis_id: int | None = None


class SignIn(_In):
    analysis_id: int | None = None


class AmendmentIn(_In):
    text: str = Field(min_length=1, max_length=MAX_TEXT_CHARS)
    reason: str = Field(min_length=1, max_length=MAX_TEXT_CHARS)
    analysis_id: int | None = None


class AmendmentOut(BaseModel):
    previous_text: str
    text: str
    reason: str
    by: str
    role: str
    at: dt.datetime


class InterpretationOut(BaseModel):
    analysis_id: int
    status: str
    text: str
    updated_by: str | None
    updated_at: dt.datetime | None
    signed_by: str | None
    signed_role: str | None
    signed_at: dt.datetime | None
    amended: bool
    amendments: list[AmendmentOut]


def _who(principal) -> str:
    if principal.user is not None:
        return principal.user.name or principal.user.email
    return f"token {principal.token_id}"


@router.get("/{session_id}/interpretation", response_model=InterpretationOut, responses=_ERRORS)
def get_interpretation(session_id: int, principal: Reader, db: DbDep, request: Request,
                       analysis_id: int | None = None):
    """The interpretation of the analysis (default: the session's current analysis)."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, analysis_id)
    row = interpretations.find(db, analysis.id)
    audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id,
                 detail=f"interpretation of analysis {analysis.id}")
    return interpretations.as_dict(row, analysis)


@router.post("/{session_id}/interpretation", response_model=InterpretationOut, responses=_ERRORS)
def save_interpretation(session_id: int, body: InterpretationIn, principal: Clinician, db: DbDep, request: Request):
    """Save the draft text (refused once signed: amend it instead)."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, body.analysis_id)
    row = interpretations.save_draft(db, session, analysis, body.text, _who(principal))
    audit.record(db, request, principal, "update", patient_id=session.patient_id, session_id=session.id,
                 detail=f"interpretation draft of analysis {analysis.id}")
    return interpretations.as_dict(row, analysis)


@router.post("/{session_id}/interpretation/sign", response_model=InterpretationOut, responses=_ERRORS)
def sign_interpretation(session_id: int, principal: Clinician, db: DbDep, request: Request,
                        body: SignIn | None = None):
    """Sign the saved text as the logged-in user (name, role, time); it is locked from then on."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, body.analysis_id if body else None)
    row = interpretations.sign(db, session, analysis, principal.user)
    audit.record(db, request, principal, "sign", patient_id=session.patient_id, session_id=session.id,
                 detail=f"interpretation of analysis {analysis.id}")
    return interpretations.as_dict(row, analysis)


@router.post("/{session_id}/interpretation/amendments", response_model=InterpretationOut, responses=_ERRORS)
def amend_interpretation(session_id: int, body: AmendmentIn, principal: Clinician, db: DbDep, request: Request):
    """Amend the signed text: the new text and the reason; the earlier text is kept in the history."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, body.analysis_id)
    row = interpretations.amend(db, session, analysis, principal.user, body.text, body.reason)
    audit.record(db, request, principal, "amend", patient_id=session.patient_id, session_id=session.id,
                 detail=f"interpretation of analysis {analysis.id}")
    return interpretations.as_dict(row, analysis)
