"""The clinician's interpretation of an analysis and its sign-off (issue 17 §3).

One interpretation per analysis (:class:`app.store.models.Interpretation`), scoped by the session's clinic:

* **draft** — free text, saved and saved again by anyone who may change the clinic's data (clinician or
  admin: the route's role), each save stamped with who and when;
* **signed** — a logged-in *person* (an account, not an API token: a signature names someone) signs it: their
  name, their role at that moment and the time are kept.  From then on the text is **locked**: a save is
  refused (409), and the one way to change it is an **amendment** — the new text, by whom, when and a reason
  that may not be empty; the text it replaces is kept in the amendment, so the history reads oldest first and
  nothing said and signed is ever lost.

Only the current analysis can be signed or amended (a superseded one was computed from recordings or facts
that have changed: :class:`app.store.analyses.SupersededResults`); a signed interpretation of an analysis that
is superseded later stays, for the record, with that analysis.  Deleting the session or its patient deletes
the interpretations with the analyses (foreign keys ``ON DELETE CASCADE``).

:func:`as_report` gives the reports' :class:`reports.model.Interpretation` (only a signed one is printed).
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.store.analyses import SupersededResults
from app.store.errors import Conflict, Invalid
from app.store.models import Analysis, Interpretation, InterpretationAmendment, KneeSession, User, utcnow
from reports.model import Amendment as ReportAmendment
from reports.model import Interpretation as ReportInterpretation

#: the longest interpretation or amendment reason kept (characters; a report's text, not a document store)
MAX_TEXT_CHARS = 20_000


def find(db: Session, analysis_id: int, *, lock: bool = False) -> Interpretation | None:
    """The interpretation of ``analysis_id``, or None; ``lock`` holds its row for the transaction."""
    query = select(Interpretation).where(Interpretation.analysis_id == analysis_id)
    if lock:
        query = query.with_for_update()
    return db.scalar(query)


def _clean(text: str | None, field: str) -> str:
    text = (text or "").replace("\r\n", "\n").replace("\r", "\n").strip()
    if not text:
        raise Invalid(code="store.interpretation_empty", field=field)
    if len(text) > MAX_TEXT_CHARS:
        raise Invalid(code="store.interpretation_too_long", field=field, limit=MAX_TEXT_CHARS)
    return text


def _current(session: KneeSession, analysis: Analysis) -> None:
    if analysis.superseded_at is not None:
        raise SupersededResults(session.id, analysis)


def _signer(user: User | None) -> tuple[User, str]:
    """The person who signs: a logged-in account (an API token cannot sign: a signature names someone)."""
    if user is None:
        raise Invalid(code="store.interpretation_needs_person")
    return user, (user.name or user.email)


def save_draft(db: Session, session: KneeSession, analysis: Analysis, text: str, by: str) -> Interpretation:
    """Save the draft ``text`` of ``analysis`` (created at the first save); :class:`Conflict` once it is signed."""
    _current(session, analysis)
    clean = (text or "").replace("\r\n", "\n").replace("\r", "\n")
    if len(clean) > MAX_TEXT_CHARS:
        raise Invalid(code="store.interpretation_too_long", field="text", limit=MAX_TEXT_CHARS)
    row = find(db, analysis.id, lock=True)
    if row is None:
        row = Interpretation(clinic_id=session.clinic_id, session_id=session.id, analysis_id=analysis.id)
        db.add(row)
    elif row.signed_at is not None:
        raise Conflict(code="store.interpretation_signed", analysis_id=analysis.id,
                       when=f"{row.signed_at:%Y-%m-%d %H:%M}", by=row.signed_by)
    row.text, row.updated_by, row.updated_at = clean, by[:320], utcnow()
    db.flush()
    return row


def sign(db: Session, session: KneeSession, analysis: Analysis, user: User | None) -> Interpretation:
    """Sign the saved text of ``analysis`` as ``user`` (name, role, now): locked from then on."""
    _current(session, analysis)
    person, name = _signer(user)
    row = find(db, analysis.id, lock=True)
    if row is None or not row.text.strip():
        raise Invalid(code="store.interpretation_empty", field="text")
    if row.signed_at is not None:
        raise Conflict(code="store.interpretation_signed", analysis_id=analysis.id,
                       when=f"{row.signed_at:%Y-%m-%d %H:%M}", by=row.signed_by)
    row.signed_by_user_id, row.signed_by, row.signed_role, row.signed_at = person.id, name[:320], person.role, utcnow()
    db.flush()
    return row


def amend(db: Session, session: KneeSession, analysis: Analysis, user: User | None, text: str,
          reason: str) -> Interpretation:
    """Replace the signed text of ``analysis`` by ``text`` for ``reason``, as ``user``; the earlier text is kept in
    the amendment.  :class:`Conflict` when it is not signed yet (save the draft instead)."""
    _current(session, analysis)
    person, name = _signer(user)
    new, why = _clean(text, "text"), _clean(reason, "reason")
    row = find(db, analysis.id, lock=True)
    if row is None or row.signed_at is None:
        raise Conflict(code="store.interpretation_not_signed", analysis_id=analysis.id)
    if new == row.text:
        raise Invalid(code="store.interpretation_unchanged")
    row.amendments.append(InterpretationAmendment(previous_text=row.text, text=new, reason=why, user_id=person.id,
                                                  by=name[:320], role=person.role, at=utcnow()))
    row.text, row.updated_by, row.updated_at = new, name[:320], utcnow()
    db.flush()
    return row


def as_dict(row: Interpretation | None, analysis: Analysis) -> dict:
    """The API's shape: ``status`` ``none`` | ``draft`` | ``signed``, the text, the signature, the amendments."""
    if row is None:
        return {"analysis_id": analysis.id, "status": "none", "text": "", "updated_by": None, "updated_at": None,
                "signed_by": None, "signed_role": None, "signed_at": None, "amended": False, "amendments": []}
    return {"analysis_id": analysis.id, "status": "signed" if row.signed_at is not None else "draft",
            "text": row.text, "updated_by": row.updated_by, "updated_at": row.updated_at,
            "signed_by": row.signed_by, "signed_role": row.signed_role, "signed_at": row.signed_at,
            "amended": bool(row.amendments),
            "amendments": [{"previous_text": a.previous_text, "text": a.text, "reason": a.reason, "by": a.by,
                            "role": a.role, "at": a.at} for a in row.amendments]}


def as_report(row: Interpretation | None) -> ReportInterpretation | None:
    """What the reports print: the signed interpretation with its amendments, or None (none, or a draft)."""
    if row is None or row.signed_at is None:
        return None
    return ReportInterpretation(
        text=row.text, signed_by=row.signed_by or "", signed_role=row.signed_role or "",
        signed_at=row.signed_at.isoformat(timespec="seconds"),
        amendments=tuple(ReportAmendment(previous_text=a.previous_text, by=a.by, role=a.role,
                                         at=a.at.isoformat(timespec="seconds"), reason=a.reason)
                         for a in row.amendments))


__all__ = ["MAX_TEXT_CHARS", "amend", "as_dict", "as_report", "find", "save_draft", "sign"]
