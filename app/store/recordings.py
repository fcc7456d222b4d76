"""A session's recordings: storing an upload's files (all or none) and deleting one.

Deleting a recording of a processed session marks the session's analyses superseded
(:func:`app.store.analyses.supersede`) rather than refusing: a clinician who uploaded a wrong file must be able
to correct the session without erasing it and its history, and the reports computed from the removed file are
then kept for the record but no longer served as the session's final report (the results and download routes
answer 409 for the default, and name the analysis superseded when it is asked for by id).  The deleted
recording's blob is erased when no other row names it (:mod:`app.store.erasure`: the caller marks the blob
:func:`delete_recording` returns, in the same transaction).

Storing an upload reserves (and on PostgreSQL locks) each blob's row *before* its file is moved into place, so
the eraser, which takes the same lock, never unlinks a file an upload is about to name.

Both refuse while a job of the session is queued or running (:class:`app.store.sessions.Busy`), checked
before and, for SQLite's concurrent writers, again after the change; both bump the session's
``files_version`` in the same transaction, which makes its stored ingestion check stale
(:mod:`app.store.checks`), and do the same to a paired session's partner, which reads these files too
(:func:`app.store.sessions.files_changed`).  Two uploads racing for the same file name: one wins, the other gets
:class:`Conflict` (the database's unique constraint decides).

The upload labels the ingestion understands are re-exported here for the API (:data:`SEGMENTS`,
:data:`ROLES`, the manifest's name :data:`MANIFEST`), so that the routes need not import the pipeline.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.pipeline.ingestion import MANIFEST, ROLES, SEGMENTS, IngestionError
from app.pipeline.ingestion.session import MAX_MANIFEST_KB, check_manifest_size
from app.pipeline.ingestion.provenance import sensor_of_file_name
from app.pipeline.ingestion.split import CONTINUOUS, check_split
from app.store.blobs import BlobWriter, commit_all
from app.store.analyses import supersede
from app.store.erasure import reserve_blobs
from app.store.errors import Conflict, Invalid, LimitExceeded, NotFound
from app.store.models import KneeSession, Recording
from app.store.sessions import clinic_session, files_changed, refuse_while_processing

#: the roles an upload may declare: the protocol's four, or one recording of the whole protocol (split on reading)
UPLOAD_ROLES = (*ROLES, CONTINUOUS)


def check_labels(segment: str | None, role: str | None) -> None:
    """:class:`Invalid` for an unknown segment or role (None: not given)."""
    if segment is not None and segment not in SEGMENTS:
        raise Invalid(code="store.unknown_segment", segment=str(segment), allowed=" / ".join(SEGMENTS))
    if role is not None and role not in UPLOAD_ROLES:
        raise Invalid(code="store.unknown_role", role=str(role), allowed=", ".join(UPLOAD_ROLES))


def store_upload(db: Session, clinic_id: int, session_id: int, files: list[tuple[str, BlobWriter]], *,
                 segment: str | None, role: str | None, max_files: int) -> tuple[KneeSession, list[Recording]]:
    """Commit the blobs of ``files`` (name, written blob) and add their recordings to the session (locked), each
    with the sensor serial its name carries (``device``), all or none: :class:`Invalid` for a name sent twice,
    :class:`Conflict` for a name already stored (or stored meanwhile by another upload) or while the session is
    being processed, :class:`LimitExceeded` past ``max_files`` per session."""
    names = [n for n, _ in files]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise Invalid(code="store.sent_twice", names=", ".join(dupes))
    session = clinic_session(db, clinic_id, session_id, lock=True)
    refuse_while_processing(db, session.id, "upload")
    have = set(db.scalars(select(Recording.file_name).where(Recording.session_id == session.id)))
    clash = sorted(have & set(names))
    if clash:
        raise Conflict(code="store.already_uploaded", names=", ".join(clash))
    if len(have) + len(names) > max_files:
        raise LimitExceeded(code="store.too_many_files", limit=max_files, stored=len(have))
    # every blob's row added and locked before any file is placed (module docstring), then the files placed: a
    # few statements and one wait for the disk under the lock, whatever the number of files
    reserve_blobs(db, [(w.sha256, w.size_bytes) for _, w in files])
    commit_all([w for _, w in files])
    rows = [Recording(session_id=session.id, file_name=name, size_bytes=w.size_bytes, sha256=w.sha256,
                      segment=segment, role=role, device=sensor_of_file_name(name)) for name, w in files]
    db.add_all(rows)
    session.files_version = KneeSession.files_version + 1
    files_changed(db, session, "upload")  # a paired session reads these files too
    try:
        db.flush()
    except IntegrityError:  # another upload stored the same file name meanwhile
        raise Conflict(code="store.upload_raced", names=", ".join(names)) from None
    refuse_while_processing(db, session.id, "upload")  # a job queued meanwhile (SQLite) wins
    return session, rows


def delete_recording(db: Session, clinic_id: int, session_id: int, recording_id: int) -> tuple[KneeSession, str, int]:
    """Remove one recording from the session; returns ``(session, the blob it named, analyses superseded)``
    (the caller marks the blob for erasure: its content stays while other rows name it).  :class:`NotFound`
    for an unknown id, :class:`Conflict` while the session is being processed."""
    session = clinic_session(db, clinic_id, session_id, lock=True)
    rec = db.get(Recording, recording_id)
    if rec is None or rec.session_id != session.id:
        raise NotFound(code="store.no_recording", recording_id=recording_id, session_id=session_id)
    refuse_while_processing(db, session.id, "delete_files")
    sha = rec.sha256
    db.delete(rec)
    session.files_version = KneeSession.files_version + 1
    n_superseded = supersede(db, [session.id]) + files_changed(db, session, "delete_files")
    db.flush()
    refuse_while_processing(db, session.id, "delete_files")
    return session, sha, n_superseded



def set_split(db: Session, clinic_id: int, session_id: int, split: dict | None) -> tuple[KneeSession, int]:
    """Store the clinician's cuts of the session's continuous recordings (``{segment: {role: [start_s, end_s]}}``,
    :func:`app.pipeline.ingestion.split.given_spans`), or None to go back to the automatic split; returns
    ``(session, analyses superseded)``.  Like a change of the files it bumps ``files_version`` (the check is
    redone with the new cuts, which also go into the processing's ``session.json``) and supersedes the
    session's analyses (computed from the old cuts).  :class:`Invalid` for a malformed split (the ingestion's
    sentence), :class:`Conflict` while the session is being processed."""
    if split is not None:
        try:
            check_split(split, knees=True)  # a four-sensor session's cuts are keyed by knee (left_thigh …)
        except IngestionError as exc:
            raise Invalid(code=exc.code, **exc.params) from None
    session = clinic_session(db, clinic_id, session_id, lock=True)
    refuse_while_processing(db, session.id, "move_cuts")
    session.split = split or None
    session.files_version = KneeSession.files_version + 1
    n_superseded = supersede(db, [session.id]) + files_changed(db, session, "move_cuts")
    db.flush()
    refuse_while_processing(db, session.id, "move_cuts")
    return session, n_superseded


def manifest_problem(data: bytes) -> IngestionError | None:
    """Why an uploaded ``session.json`` must be refused before it is stored (larger than ``MAX_MANIFEST_KB`` or
    nested too deep, :func:`app.pipeline.ingestion.session.check_manifest_size`; issue 16 finding 5), or None."""
    try:
        check_manifest_size(data.decode("utf-8", "replace"), MANIFEST, len(data))
    except IngestionError as exc:
        return exc
    return None

__all__ = ["MANIFEST", "MAX_MANIFEST_KB", "ROLES", "SEGMENTS", "UPLOAD_ROLES", "check_labels", "delete_recording",
           "manifest_problem", "set_split", "store_upload"]
