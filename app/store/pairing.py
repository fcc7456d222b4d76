"""Two one-knee sessions of a patient paired into one of both knees (issue 15 §2, as ``session.json``
``"paired_session"`` pairs two folders for the CLI: :func:`app.pipeline.ingestion.load_knees`).

:func:`pair` records the pairing on both sessions (``paired_session_id``, each other's) with the knee each measures
(``knee``: this one's as the clinician says, default the patient's side; the partner's the other).  Processing
either session then reads both (:func:`app.store.workspace.materialise` puts the partner's files in a sibling
folder named by the manifest): ``results.json`` holds both knees, their curves overlaid and the limb symmetry
index, the patient's side the involved knee unless the request names another.  Pairing changes what the sessions'
reports describe, so it supersedes both sessions' analyses and has their ingestion checks redone (a check of a
paired session reads both); :func:`unpair` undoes it the same way.  Refused (409): a session with a job queued or
running, sessions of different patients, a session paired with itself, or one that already holds both knees
(four sensors).  The partner's id has no foreign key (migration 0014): a partner since erased reads as none.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.choices import SIDE_NAMES
from app.store.analyses import supersede
from app.store.errors import Conflict, Invalid
from app.store.models import KneeSession, Recording, utcnow
from app.store.sessions import clinic_session, refuse_while_processing


def _other_side(side: str) -> str:
    return next(s for s in SIDE_NAMES if s != side)


def partner(db: Session, session: KneeSession) -> KneeSession | None:
    """The session ``session`` is paired with (of its clinic), or None."""
    if session.paired_session_id is None:
        return None
    other = db.get(KneeSession, session.paired_session_id)
    return other if other is not None and other.clinic_id == session.clinic_id else None


def partner_files(db: Session, session: KneeSession) -> tuple[KneeSession, list[Recording]] | None:
    """The partner and its recordings (what :func:`app.store.workspace.materialise` needs), or None."""
    other = partner(db, session)
    if other is None:
        return None
    return other, list(db.scalars(select(Recording).where(Recording.session_id == other.id).order_by(Recording.id)))


def _changed(db: Session, sessions: list[KneeSession]) -> int:
    """Mark ``sessions`` changed: new version, check redone (the files they read changed), analyses superseded."""
    for s in sessions:
        s.version, s.updated_at = s.version + 1, utcnow()
        s.files_version = s.files_version + 1
    return supersede(db, [s.id for s in sessions])


def pair(db: Session, clinic_id: int, session_id: int, other_id: int, knee: str | None = None
         ) -> tuple[KneeSession, KneeSession, int]:
    """Pair session ``session_id`` (knee ``knee``, default its patient's side) with ``other_id`` (the other knee);
    returns both and how many analyses were superseded (module docstring for the refusals)."""
    if knee is not None and knee not in SIDE_NAMES:
        raise Invalid(code="store.pair_bad_knee", knee=str(knee)[:20], allowed=", ".join(SIDE_NAMES))
    if other_id == session_id:
        raise Conflict(code="store.pair_itself", session_id=session_id)
    first, second = sorted((session_id, other_id))  # locked in one order: two requests never wait on each other
    locked = {i: clinic_session(db, clinic_id, i, lock=True) for i in (first, second)}
    session, other = locked[session_id], locked[other_id]
    if session.patient_id != other.patient_id:
        raise Conflict(code="store.pair_other_patient", session_id=session_id, other_id=other_id)
    for s in (session, other):
        refuse_while_processing(db, s.id, "pair it")
        segments = (s.ingestion or {}).get("segments") or {}
        if any(str(v).startswith(("left_", "right_")) for v in segments.values()):
            raise Conflict(code="store.pair_both_knees", session_id=s.id)
    previous = [p for s in (session, other) if (p := partner(db, s)) is not None and p.id not in (session_id, other_id)]
    for p in previous:  # a session is paired with one other at a time: its former partner is set free
        p.paired_session_id, p.knee = None, None
    knee = knee or session.patient.side
    session.paired_session_id, session.knee = other.id, knee
    other.paired_session_id, other.knee = session.id, _other_side(knee)
    n = _changed(db, [session, other, *previous])
    db.flush()
    return session, other, n


def unpair(db: Session, clinic_id: int, session_id: int) -> tuple[KneeSession, KneeSession | None, int]:
    """Undo the pairing of ``session_id`` (both sides); returns the session, its former partner (or None) and how
    many analyses were superseded.  A session that is not paired is answered as it is."""
    session = clinic_session(db, clinic_id, session_id, lock=True)
    other = partner(db, session)
    if session.paired_session_id is None:
        return session, None, 0
    for s in (session, other) if other is not None else (session,):
        refuse_while_processing(db, s.id, "unpair it")
    changed = [session] + ([other] if other is not None and other.paired_session_id == session.id else [])
    for s in changed:
        s.paired_session_id, s.knee = None, None
    n = _changed(db, changed)
    db.flush()
    return session, other, n


__all__ = ["pair", "partner", "partner_files", "unpair"]
