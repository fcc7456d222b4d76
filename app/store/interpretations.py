"""The clinician's interpretation of an analysis and its sign-off (issue 17 §3).

One interpretation per analysis (:class:`app.store.models.Interpretation`), scoped by the session's clinic:

* **draft** — free text, saved and saved again by anyone who may change the clinic's data (clinician or
  admin: the route's role), each save stamped with who and when;
* **signed** — a logged-in *person* (an account, not an API token: a signature names someone) signs it: their
  name, their role at that moment and the time are kept.  From then on the text is **locked**: a save is
  refused (409), and the one way to change it is an **amendment** — the new text, by whom, when and a reason
  that may not be empty; the text it replaces is kept in the amendment, so the history reads oldest first and
  nothing said and signed is ever lost.

**Concurrency.**  Every write is one conditional ``UPDATE`` whose ``WHERE`` states what the writer saw
(``SELECT … FOR UPDATE`` locks nothing on SQLite, and the ORM's identity map would keep a stale row even on
PostgreSQL): a draft ``… WHERE id = ? AND signed_at IS NULL``; a signature ``… AND signed_at IS NULL AND text =
<the text the signer read>``; an amendment ``… AND signed_at IS NOT NULL AND text = <the text it replaces>``.  No
row matched means someone else wrote first: :class:`Conflict` (409), nothing changed.  Two first saves of the same
analysis at once: the second insert breaks the unique ``analysis_id`` and is answered 409 too, never 500.  The
signer names the text they sign (``expected``): a text another user saved between the signer's reading and the
signature is refused (409), never signed unseen.

Only the current analysis can be signed or amended (a superseded one was computed from recordings or facts
that have changed: :class:`app.store.analyses.SupersededResults`); a signed interpretation of an analysis that
is superseded later stays, for the record, with that analysis.  Deleting the session or its patient deletes
the interpretations with the analyses (foreign keys ``ON DELETE CASCADE``).

:func:`as_report` gives the reports' :class:`reports.model.Interpretation` (only a signed one is printed).
"""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.store.analyses import SupersededResults
from app.store.errors import Conflict, Invalid
from app.store.models import Analysis, Interpretation, InterpretationAmendment, KneeSession, User, utcnow
from reports.model import Amendment as ReportAmendment
from reports.model import Interpretation as ReportInterpretation

#: the longest interpretation or amendment reason kept (characters; a report's text, not a document store)
MAX_TEXT_CHARS = 20_000


def find(db: Session, analysis_id: int) -> Interpretation | None:
    """The interpretation of ``analysis_id`` as the database has it now (not a stale copy of this session's)."""
    return db.scalar(select(Interpretation).where(Interpretation.analysis_id == analysis_id)
                     .execution_options(populate_existing=True))


def _normal(text: str | None) -> str:
    return (text or "").replace("\r\n", "\n").replace("\r", "\n")


def _clean(text: str | None, field: str) -> str:
    text = _normal(text).strip()
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


def _signed(row: Interpretation, analysis: Analysis) -> Conflict:
    return Conflict(code="store.interpretation_signed", analysis_id=analysis.id,
                    when=f"{row.signed_at:%Y-%m-%d %H:%M}", by=row.signed_by)


def _changed(analysis_id: int) -> Conflict:
    return Conflict(code="store.interpretation_changed", analysis_id=analysis_id)


def _write(db: Session, row: Interpretation, *conditions, **values) -> bool:
    """``UPDATE interpretations SET values WHERE id = row.id AND conditions``; True when the row matched (then
    ``row`` is read again), False when another transaction changed it first (module docstring)."""
    done = db.execute(update(Interpretation).where(Interpretation.id == row.id, *conditions).values(**values)
                      .execution_options(synchronize_session=False)).rowcount
    db.refresh(row)
    return bool(done)


def save_draft(db: Session, session: KneeSession, analysis: Analysis, text: str, by: str) -> Interpretation:
    """Save the draft ``text`` of ``analysis`` (created at the first save); :class:`Conflict` once it is signed,
    or when another first save of it won the race."""
    _current(session, analysis)
    clean = _normal(text)
    if len(clean) > MAX_TEXT_CHARS:
        raise Invalid(code="store.interpretation_too_long", field="text", limit=MAX_TEXT_CHARS)
    row, analysis_id = find(db, analysis.id), analysis.id
    if row is None:
        row = Interpretation(clinic_id=session.clinic_id, session_id=session.id, analysis_id=analysis.id,
                             text=clean, updated_by=by[:320], updated_at=utcnow())
        db.add(row)
        try:  # no savepoint: pysqlite's RELEASE of a SAVEPOINT that began the transaction would commit it
            db.flush()
        except IntegrityError:  # another first save of this analysis committed meanwhile: the request rolls back
            raise _changed(analysis_id) from None
        return row
    if not _write(db, row, Interpretation.signed_at.is_(None), text=clean, updated_by=by[:320], updated_at=utcnow()):
        raise _signed(row, analysis)
    return row


#: called with the interpretation as the reports will print it once the write succeeds, before the write: what
#: must be rendered from it is rendered before the conditional UPDATE takes SQLite's write lock
Prepare = Callable[[ReportInterpretation], None]


def _settled(row: Interpretation, prospective: ReportInterpretation | None, analysis_id: int) -> None:
    """:class:`Conflict` unless the row as written is what ``prepare`` was shown (nothing slipped in between)."""
    if prospective is not None and as_report(row) != prospective:
        raise _changed(analysis_id)


def sign(db: Session, session: KneeSession, analysis: Analysis, user: User | None,
         expected: str | None, *, prepare: Prepare | None = None) -> Interpretation:
    """Sign the saved text of ``analysis`` as ``user`` (name, role, now): locked from then on.  ``expected`` is the
    text the signer read and means to sign: :class:`Conflict` when the saved text differs (saved by someone else
    meanwhile) or someone signed first.  ``prepare`` (:data:`Prepare`) sees the signed interpretation first."""
    _current(session, analysis)
    person, name = _signer(user)
    row = find(db, analysis.id)
    if row is None or not row.text.strip():
        raise Invalid(code="store.interpretation_empty", field="text")
    if row.signed_at is not None:
        raise _signed(row, analysis)
    seen = _normal(expected)
    if seen != row.text:
        raise _changed(analysis.id)
    now = utcnow()
    prospective = ReportInterpretation(text=seen, signed_by=name[:320], signed_role=person.role,
                                       signed_at=now.isoformat(timespec="seconds"))
    if prepare is not None:
        prepare(prospective)
    if not _write(db, row, Interpretation.signed_at.is_(None), Interpretation.text == seen,
                  signed_by_user_id=person.id, signed_by=name[:320], signed_role=person.role, signed_at=now):
        raise _signed(row, analysis) if row.signed_at is not None else _changed(analysis.id)
    _settled(row, prospective if prepare is not None else None, analysis.id)
    return row


def amend(db: Session, session: KneeSession, analysis: Analysis, user: User | None, text: str,
          reason: str, expected: str | None = None, *, prepare: Prepare | None = None) -> Interpretation:
    """Replace the signed text of ``analysis`` by ``text`` for ``reason``, as ``user``; the earlier text is kept in
    the amendment.  :class:`Conflict` when it is not signed yet (save the draft instead), or when the signed text
    is no longer ``expected`` (the text the amender read, when given) or changed while this ran (another
    amendment came first).  ``prepare`` (:data:`Prepare`) sees the amended interpretation first."""
    _current(session, analysis)
    person, name = _signer(user)
    new, why = _clean(text, "text"), _clean(reason, "reason")
    row = find(db, analysis.id)
    if row is None or row.signed_at is None:
        raise Conflict(code="store.interpretation_not_signed", analysis_id=analysis.id)
    previous = row.text
    if expected is not None and _normal(expected) != previous:
        raise _changed(analysis.id)
    if new == previous:
        raise Invalid(code="store.interpretation_unchanged")
    now = utcnow()
    before = as_report(row)
    prospective = ReportInterpretation(
        text=new, signed_by=before.signed_by, signed_role=before.signed_role, signed_at=before.signed_at,
        amendments=(*before.amendments, ReportAmendment(previous_text=previous, by=name[:320], role=person.role,
                                                        at=now.isoformat(timespec="seconds"), reason=why)))
    if prepare is not None:
        prepare(prospective)
    if not _write(db, row, Interpretation.signed_at.is_not(None), Interpretation.text == previous,
                  text=new, updated_by=name[:320], updated_at=now):
        raise _changed(analysis.id)
    db.add(InterpretationAmendment(interpretation_id=row.id, previous_text=previous, text=new, reason=why,
                                   user_id=person.id, by=name[:320], role=person.role, at=now))
    db.flush()
    db.refresh(row, ["amendments"])
    _settled(row, prospective if prepare is not None else None, analysis.id)
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


__all__ = ["MAX_TEXT_CHARS", "Prepare", "amend", "as_dict", "as_report", "find", "save_draft", "sign"]
