"""``/sessions/{id}/interpretation``: the clinician's interpretation of an analysis, its sign-off and amendments
(issue 17 §3; the rules are :mod:`app.store.interpretations`').

* ``GET`` (reader): the interpretation of the analysis (default: the session's current one, as every read of
  results): ``status`` ``none`` | ``draft`` | ``signed``, the text, who signed it (name, role, time), whether it was
  amended and each amendment (by whom, when, why, the text it replaced);
* ``POST`` ``{"text"}`` (clinician): save the draft; 409 once signed (locked);
* ``POST …/sign`` ``{"text"}`` (clinician, a logged-in person: an API token cannot sign): sign the saved text,
  which must be ``text`` (what the signer read): 409 when someone else saved another text meanwhile;
* ``POST …/amendments`` ``{"text", "reason", "expected_text"?}`` (clinician, a person): replace the signed text,
  the reason required, the earlier text kept; 409 when the signed text is no longer ``expected_text``.

A signature and each amendment render the PDF and HTML reports with the interpretation once, in every language,
and store them with the analysis (:mod:`app.store.signed_reports`); their sha256 goes into the audit event.

Every call is scoped to the caller's clinic (another clinic's session answers 404) and audited: ``view`` for the
read, ``update`` for a draft, ``sign`` and ``amend``.  Who may sign: the ``clinician`` role's dependency, which an
administrator also passes (an administrator of a clinic is one of its clinicians — the signature then prints their
role, "administrator", beside their name); a read-only account and an API token may not.
"""

from __future__ import annotations

import datetime as dt

from fastapi import APIRouter, Request
from pydantic import BaseModel, ConfigDict, Field

from app.store import interpretations, signed_reports
from app.store.analyses import pick_analysis
from app.store.interpretations import MAX_TEXT_CHARS
from app.web import audit
from app.web.api.deps import Clinician, DbDep, Reader, SettingsDep, StoreDep, scoped_session
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
    #: the text the signer read and signs (409 when the saved text is another: saved by someone else meanwhile)
    text: str = Field(max_length=MAX_TEXT_CHARS)
    analysis_id: int | None = None


class AmendmentIn(_In):
    text: str = Field(min_length=1, max_length=MAX_TEXT_CHARS)
    reason: str = Field(min_length=1, max_length=MAX_TEXT_CHARS)
    #: the signed text the amender read (409 when another amendment replaced it meanwhile)
    expected_text: str | None = Field(default=None, max_length=MAX_TEXT_CHARS)
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
def sign_interpretation(session_id: int, body: SignIn, principal: Clinician, db: DbDep, store: StoreDep,
                        settings: SettingsDep, request: Request):
    """Sign the saved text (which must be ``text``) as the logged-in user (name, role, time); it is locked from
    then on, and the signed reports are rendered and stored."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, body.analysis_id)
    row, stored = signed_reports.sign(db, store, session, analysis, principal.user, body.text,
                                      settings.patient_identifier_system)
    audit.record(db, request, principal, "sign", patient_id=session.patient_id, session_id=session.id,
                 detail=signed_reports.audit_detail(analysis, row, stored))
    return interpretations.as_dict(row, analysis)


@router.post("/{session_id}/interpretation/amendments", response_model=InterpretationOut, responses=_ERRORS)
def amend_interpretation(session_id: int, body: AmendmentIn, principal: Clinician, db: DbDep, store: StoreDep,
                         settings: SettingsDep, request: Request):
    """Amend the signed text: the new text and the reason; the earlier text is kept in the history, and the
    amended reports are rendered and stored."""
    session = scoped_session(db, principal, session_id)
    analysis = pick_analysis(db, session, body.analysis_id)
    row, stored = signed_reports.amend(db, store, session, analysis, principal.user, body.text, body.reason,
                                       body.expected_text, settings.patient_identifier_system)
    audit.record(db, request, principal, "amend", patient_id=session.patient_id, session_id=session.id,
                 detail=signed_reports.audit_detail(analysis, row, stored))
    return interpretations.as_dict(row, analysis)
