"""Two one-knee sessions of a patient paired into one of both knees (issue 15 §2, as ``session.json``
``"paired_session"`` pairs two folders for the CLI: :func:`app.pipeline.ingestion.load_knees`).

:func:`pair` records the pairing on both sessions (``paired_session_id``, each other's) with the knee each measures
(``knee``: this one's as the clinician says — required, never defaulted, so that a forgotten choice cannot swap the
knees — the partner's the other; when a session's own file names name a side, it must agree).  Processing either
session then reads both (:func:`app.store.workspace.materialise` puts the partner's files in a sibling folder named
by the manifest): ``results.json`` holds both knees, their curves overlaid and the limb symmetry index, the
patient's side the involved knee unless the request names another.  Pairing changes what the sessions' reports
describe, so it supersedes both sessions' analyses and has their ingestion checks redone (a check of a paired
session reads both); :func:`unpair` undoes it the same way, and so does re-pairing for a former partner (its rows
locked in id order with the others', refused while it is processed, its versions incremented by the database).
Refused (409): a session with a job queued or running, sessions of different patients or of different tasks, a
session paired with itself, one whose own files hold both knees (four sensors), a knee the files contradict.
Sessions of different dates are paired with a warning (es/en/pt, :data:`DATE_WARNING`).  The partner's id has no
foreign key (migration 0014): a pairing counts only when both rows point at each other
(:func:`app.store.sessions.partner_of`), and erasing a session unpairs its partner
(:func:`app.store.sessions.delete_sessions`).
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.choices import SIDE_NAMES
from app.pipeline.ingestion import MANIFEST
from app.pipeline.ingestion.labels import recognise_side
from app.store.errors import Conflict, Invalid
from app.store.models import KneeSession, Recording
from app.store.sessions import bump, clinic_session, partner_of, refuse_while_processing

#: the warning (app.pipeline.service_messages) of a pairing of sessions recorded on different dates
DATE_WARNING = "store.pair_other_date"


def _other_side(side: str) -> str:
    return next(s for s in SIDE_NAMES if s != side)


def partner(db: Session, session: KneeSession) -> KneeSession | None:
    """The session ``session`` is paired with (same clinic and patient, pointing back), or None."""
    return partner_of(db, session)


def own_sides(db: Session, session: KneeSession) -> set[str]:
    """The sides the session's own recordings name (file names; the manifest aside): both for four sensors."""
    sides = set()
    for name in db.scalars(select(Recording.file_name).where(Recording.session_id == session.id,
                                                             Recording.file_name != MANIFEST)):
        try:
            found = recognise_side(name)
        except ValueError:  # a name that says both sides decides nothing
            continue
        if found is not None:
            sides.add(found.value)
    if partner_of(db, session) is None:  # unpaired: its stored check read only its own files
        segments = (session.ingestion or {}).get("segments") or {}
        sides |= {side for v in segments.values() for side in SIDE_NAMES if str(v).startswith(f"{side}_")}
    return sides


def partner_files(db: Session, session: KneeSession) -> tuple[KneeSession, list[Recording]] | None:
    """The partner and its recordings (what :func:`app.store.workspace.materialise` needs), or None."""
    other = partner(db, session)
    if other is None:
        return None
    return other, list(db.scalars(select(Recording).where(Recording.session_id == other.id).order_by(Recording.id)))


def pair(db: Session, clinic_id: int, session_id: int, other_id: int, knee: str
         ) -> tuple[KneeSession, KneeSession, list[KneeSession], list[dict]]:
    """Pair session ``session_id`` (knee ``knee``) with ``other_id`` (the other knee); returns both, their former
    partners now unpaired (to audit) and the warnings (``{"code", "params"}``; module docstring for the refusals)."""
    if knee not in SIDE_NAMES:
        raise Invalid(code="store.pair_bad_knee", knee=str(knee)[:20], allowed=", ".join(SIDE_NAMES))
    if other_id == session_id:
        raise Conflict(code="store.pair_itself", session_id=session_id)
    session, other = clinic_session(db, clinic_id, session_id), clinic_session(db, clinic_id, other_id)
    former = {p.id for s in (session, other) if (p := partner_of(db, s)) is not None} - {session_id, other_id}
    # every row locked in id order: two requests never wait on each other
    locked = {i: clinic_session(db, clinic_id, i, lock=True) for i in sorted({session_id, other_id, *former})}
    session, other = locked[session_id], locked[other_id]
    previous = [locked[i] for i in sorted(former)]
    if session.patient_id != other.patient_id:
        raise Conflict(code="store.pair_other_patient", session_id=session_id, other_id=other_id)
    if session.task != other.task:
        raise Conflict(code="store.pair_other_task", session_id=session_id, other_id=other_id,
                       task=session.task, other_task=other.task)
    for s in (session, other, *previous):
        refuse_while_processing(db, s.id, "pair")
    for s, want in ((session, knee), (other, _other_side(knee))):
        sides = own_sides(db, s)
        if len(sides) > 1:
            raise Conflict(code="store.pair_both_knees", session_id=s.id)
        if sides and sides != {want}:
            raise Conflict(code="store.pair_knee_mismatch", session_id=s.id, knee=want, files=next(iter(sides)))
    for p in previous:  # a session is paired with one other at a time: its former partner is set free
        p.paired_session_id, p.knee = None, None
    session.paired_session_id, session.knee = other.id, knee
    other.paired_session_id, other.knee = session.id, _other_side(knee)
    db.flush()
    bump(db, [s.id for s in (session, other, *previous)])
    warnings = []
    if session.date != other.date:
        warnings.append({"code": DATE_WARNING, "params": {"session_id": session.id, "date": str(session.date),
                                                           "other_id": other.id, "other_date": str(other.date)}})
    return session, other, previous, warnings


def unpair(db: Session, clinic_id: int, session_id: int) -> tuple[KneeSession, KneeSession | None, int]:
    """Undo the pairing of ``session_id`` (both sides); returns the session, its former partner (or None) and how
    many analyses were superseded.  A session that is not paired is answered as it is."""
    session = clinic_session(db, clinic_id, session_id, lock=True)
    other = partner(db, session)
    if session.paired_session_id is None:
        return session, None, 0
    for s in (session, other) if other is not None else (session,):
        refuse_while_processing(db, s.id, "unpair")
    changed = [session] + ([other] if other is not None else [])
    for s in changed:
        s.paired_session_id, s.knee = None, None
    db.flush()
    n = bump(db, [s.id for s in changed])
    return session, other, n


__all__ = ["DATE_WARNING", "own_sides", "pair", "partner", "partner_files", "unpair"]
