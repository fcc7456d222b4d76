"""Uploads: ``POST /sessions/{id}/recordings`` (multipart, streamed to storage) and ``DELETE .../{rid}``.

The request body is parsed as it arrives (python-multipart's streaming parser over ``request.stream()``; the
parsing, hashing and file writes run in the thread pool, never on the event loop): each file part is written
straight into a temporary blob file while it is hashed and counted, so nothing is held in memory and a file
over ``CHAKAMO_MAX_FILE_MB`` is refused (413) as soon as the limit is passed.  The whole body is counted as
it arrives too, whatever the headers say (a chunked body has no Content-Length): past ``CHAKAMO_MAX_FILES``
files of the largest size plus a little room for the multipart framing it is refused (413); a declared
Content-Length above that is refused before a byte is read.  A body may hold at most ``max_files + 4``
parts, and besides the files only the form fields ``segment`` and ``role`` (400 for any other).  A file
name whose type is not allowed (``.csv``, ``.xlsx``, ``.json``) is refused (415) before its bytes are read;
more than ``CHAKAMO_MAX_FILES`` files per request or per session answers 413.  Only when the whole request
has been read are the blobs committed and the recordings inserted (all or none), then the session's files
are checked by the ingestion (:func:`app.store.workspace.check_ingestion`) and the result stored on the session
and returned.  Uploads are thus stored and committed before any processing can start.

Resources: the caller is looked up in a short database session closed before the body is read
(:data:`app.web.api.deps.UploadClinician`), so a slow upload holds no database connection; at most
``CHAKAMO_MAX_UPLOADS`` uploads stream at once (more answer 503 with ``Retry-After``).  A client that
disconnects mid-upload is logged in one line and its partial files removed.

Consistency: uploads and deletions answer 409 while a job of the session is queued or running (its files
must not change under it).  Every change bumps the session's ``files_version`` in the same transaction; the
ingestion check is stored with the version it was computed from and only if that is still the current one
(:func:`save_ingestion`), so a slower, older check can never overwrite a newer one; a session whose stored
check is stale is checked again when it is read or processed (:func:`refresh_ingestion`).  Two uploads
racing for the same file name: one wins, the other gets 409 (the database's unique constraint decides).

Audit: an upload and a deletion each record one event (``upload`` / ``delete``, :mod:`app.web.audit`) in the
transaction that stores or removes the recordings, so the files and their event commit together.

Optional form fields ``segment`` (thigh|shank) and ``role`` (mag_calibration|standing|lying|task) apply to
every file of the request (they go into the generated ``session.json``).  A ``.json`` file must be the
session's ``session.json`` manifest.
"""

from __future__ import annotations

import logging
import threading
from pathlib import PurePosixPath, PureWindowsPath

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.concurrency import run_in_threadpool
from python_multipart.exceptions import MultipartParseError
from python_multipart.multipart import MultipartParser, parse_options_header
from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session
from starlette.requests import ClientDisconnect

from app.web import audit
from app.web.api.deps import Clinician, SettingsDep, StoreDep, UploadClinician, refuse_while_processing, scoped_session
from app.web.api.schemas import UploadOut, ingestion_fresh, recording_out
from app.store.database import Database, ensure_blob
from app.store.models import KneeSession, Recording
from app.pipeline.ingestion import MANIFEST, ROLES, SEGMENTS
from app.store.blobs import BlobStore, BlobWriter, TooLarge
from app.store.workspace import check_ingestion

log = logging.getLogger("chakamo.uploads")
router = APIRouter(prefix="/sessions", tags=["recordings"])
_FIELD_LIMIT = 200
#: the form fields an upload may carry besides ``files``
FORM_FIELDS = ("segment", "role")
#: multipart framing allowed per file on top of its bytes (boundaries, part headers)
_PART_ROOM = 64 * 1024


def _clean_name(raw: str) -> str:
    name = PureWindowsPath(PurePosixPath(raw).name).name.strip()
    if not name or name.startswith(".") or any(ord(c) < 32 for c in name) or len(name) > 255:
        raise HTTPException(400, f"File name {raw!r} is not usable; rename the file (letters, digits, - _ .).")
    return name


class _Upload:
    """State of one streamed multipart request (callbacks of :class:`MultipartParser`)."""

    def __init__(self, store: BlobStore, settings) -> None:
        self.store, self.settings = store, settings
        self.files: list[tuple[str, BlobWriter]] = []
        self.fields: dict[str, str] = {}
        self.parts = 0
        self._headers: dict[str, str] = {}
        self._field = self._value = b""
        self._writer: BlobWriter | None = None
        self._form_name: str | None = None
        self._form_value = bytearray()

    def callbacks(self) -> dict:
        return {"on_part_begin": self._part_begin, "on_header_field": self._header_field,
                "on_header_value": self._header_value, "on_header_end": self._header_end,
                "on_headers_finished": self._headers_finished, "on_part_data": self._data,
                "on_part_end": self._part_end}

    def _part_begin(self) -> None:
        self.parts += 1
        if self.parts > self.settings.max_files + len(FORM_FIELDS) + 2:
            raise HTTPException(413, f"Too many parts in one upload; send at most {self.settings.max_files} files "
                                     "and the fields segment and role.")
        self._headers, self._writer, self._form_name = {}, None, None
        self._form_value = bytearray()

    def _header_field(self, data: bytes, start: int, end: int) -> None:
        self._field += data[start:end]
        if len(self._field) > 1024:
            raise HTTPException(400, "A multipart header is too long; send the files with a standard form upload.")

    def _header_value(self, data: bytes, start: int, end: int) -> None:
        self._value += data[start:end]
        if len(self._value) > 8192:
            raise HTTPException(400, "A multipart header is too long; send the files with a standard form upload.")

    def _header_end(self) -> None:
        if len(self._headers) >= 16:
            raise HTTPException(400, "Too many headers in one multipart part; send a standard form upload.")
        self._headers[self._field.decode("latin-1").lower()] = self._value.decode("utf-8", "replace")
        self._field = self._value = b""

    def _headers_finished(self) -> None:
        _, params = parse_options_header(self._headers.get("content-disposition", ""))
        name = params.get(b"name", b"").decode("utf-8", "replace")
        filename = params.get(b"filename")
        if filename is None:
            if name not in FORM_FIELDS:
                raise HTTPException(400, f"Form field {name[:40]!r} is not accepted; send the files in the field "
                                         "'files' and, optionally, the fields 'segment' and 'role'.")
            if name in self.fields:
                raise HTTPException(400, f"Form field {name!r} sent twice; send it once per upload.")
            self._form_name = name
            return
        if name != "files":
            raise HTTPException(400, f"File sent in form field {name[:40]!r}; send every file in the field 'files'.")
        clean = _clean_name(filename.decode("utf-8", "replace"))
        suffix = PurePosixPath(clean).suffix.lower()
        if suffix not in self.settings.allowed_suffixes:
            raise HTTPException(415, f"{clean}: files of type {suffix or '(none)'} are not accepted; upload "
                                     f"{', '.join(self.settings.allowed_suffixes)} files (MetaBase or generic CSV, "
                                     "thesis Excel, session.json).")
        if suffix == ".json" and clean != MANIFEST:
            raise HTTPException(415, f"{clean}: the only JSON file a session takes is its {MANIFEST}; rename it.")
        if len(self.files) >= self.settings.max_files:
            raise HTTPException(413, f"More than {self.settings.max_files} files in one upload; send at most "
                                     f"{self.settings.max_files} at a time.")
        self._writer = self.store.writer(self.settings.max_file_bytes)
        self.files.append((clean, self._writer))

    def _data(self, data: bytes, start: int, end: int) -> None:
        if self._writer is not None:
            try:
                self._writer.write(data[start:end])
            except TooLarge:
                raise HTTPException(413, f"{self.files[-1][0]} is larger than the {self.settings.max_file_mb:g} MB "
                                         "limit; check that it is a recording of this session (or ask the "
                                         "administrator to raise CHAKAMO_MAX_FILE_MB).") from None
        elif self._form_name is not None:
            self._form_value += data[start:end]
            if len(self._form_value) > _FIELD_LIMIT:
                raise HTTPException(400, f"Form field {self._form_name!r} is too long; it takes a short word.")

    def _part_end(self) -> None:
        if self._form_name is not None:
            self.fields[self._form_name] = self._form_value.decode("utf-8", "replace").strip()

    def discard(self) -> None:
        for _, w in self.files:
            w.discard()


def _check_session(request: Request, principal, session_id: int) -> None:
    """404 for another clinic's or an unknown session, 409 while it is being processed (before any byte)."""
    with request.app.state.db.session() as db:
        scoped_session(db, principal, session_id)
        refuse_while_processing(db, session_id, "upload the files")


def _store(request: Request, principal, session_id: int, upload: _Upload, segment: str | None,
           role: str | None) -> dict:
    db_, settings = request.app.state.db, request.app.state.settings
    names = [n for n, _ in upload.files]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise HTTPException(400, f"{', '.join(dupes)} sent twice in one upload; send each file once.")
    with db_.session() as db:
        session = scoped_session(db, principal, session_id, lock=True)
        refuse_while_processing(db, session.id, "upload the files")
        have = set(db.scalars(select(Recording.file_name).where(Recording.session_id == session.id)))
        clash = sorted(have & set(names))
        if clash:
            raise HTTPException(409, f"{', '.join(clash)} already uploaded to this session; delete the earlier "
                                     "recording first to replace it.")
        if len(have) + len(names) > settings.max_files:
            raise HTTPException(413, f"A session holds at most {settings.max_files} files ({len(have)} already "
                                     "stored); delete the ones not needed.")
        rows = []
        for name, writer in upload.files:
            size = writer.size_bytes
            sha = writer.commit()
            ensure_blob(db, sha, size)
            rows.append(Recording(session_id=session.id, file_name=name, size_bytes=size, sha256=sha,
                                  segment=segment, role=role))
        db.add_all(rows)
        session.files_version = KneeSession.files_version + 1
        try:
            db.flush()
        except IntegrityError:  # another upload stored the same file name meanwhile
            raise HTTPException(409, f"{', '.join(names)}: another upload to this session stored a file of the "
                                     "same name at the same time; reload the session and check its files.") from None
        refuse_while_processing(db, session.id, "upload the files")  # a job queued meanwhile (SQLite) wins
        audit.record(db, request, principal, "upload", patient_id=session.patient_id, session_id=session.id)
        out = [recording_out(r) for r in rows]
    try:  # the files are committed: whatever happens to their check, the upload stands
        ingestion = refresh_ingestion(db_, request.app.state.store, settings.tmp_dir, session_id,
                                      request.app.state.check_pool)
    except Exception:  # noqa: BLE001 — e.g. no database connection free: the stale check is redone later
        log.warning("upload to session %s stored; its ingestion check failed and runs again later", session_id,
                    exc_info=True)
        ingestion = {"ok": False, "messages": [], "error": CHECK_DEFERRED}
    return {"recordings": out, "ingestion": ingestion}


def save_ingestion(db_: Database, session_id: int, version: int, ingestion: dict) -> bool:
    """Store ``ingestion`` (computed from the files of ``version``) unless the files changed since; True if
    stored.  One conditional UPDATE: a check of older files never overwrites a newer one."""
    with db_.session() as db:
        res = db.execute(update(KneeSession).where(KneeSession.id == session_id, KneeSession.files_version == version)
                         .values(ingestion=ingestion, ingestion_version=version))
        return res.rowcount == 1


#: the upload's answer when its files are stored but their check could not run (it runs again later)
CHECK_DEFERRED = ("The files are stored, but the server could not check them now; the check runs again when the "
                  "session is opened or processed.")
#: ingestion checks (CPU-bound, holding the GIL most of the time) running at once in one server process; the
#: others wait their turn, holding no database connection, so that reads keep their share of the processor
CHECK_CONCURRENCY = 1
_check_slots = threading.BoundedSemaphore(CHECK_CONCURRENCY)
#: longest wait for the check in the helper process before it runs here instead
CHECK_TIMEOUT_S = 120.0


def refresh_ingestion(db_: Database, store: BlobStore, tmp_dir, session_id: int, pool=None) -> dict:
    """Run the ingestion over the session's stored files (no database connection held meanwhile; at most
    :data:`CHECK_CONCURRENCY` at once), store the result if the files did not change meanwhile
    (:func:`save_ingestion`) and return it.  With ``pool`` (the server's warm helper process,
    :class:`app.pipeline.render.RenderPool`) the check runs there, so its CPU time does not hold this process' GIL
    and the server's other requests keep answering; without it, or while it is not warm, it runs here."""
    with db_.session() as db:
        session = db.get(KneeSession, session_id)
        version = session.files_version
        patient, recordings = session.patient, list(session.recordings)
        db.expunge_all()
    with _check_slots:
        future = pool.submit(check_ingestion, store, tmp_dir, session, patient, recordings) if pool else None
        try:
            ingestion = future.result(CHECK_TIMEOUT_S) if future is not None else None
        except Exception:  # noqa: BLE001 — a hung or broken helper: replace it, and check here instead
            log.warning("ingestion check of session %s failed in the helper process; checking here", session_id,
                        exc_info=True)
            future.cancel()
            pool.restart()
            ingestion = None
        if ingestion is None:
            ingestion = check_ingestion(store, tmp_dir, session, patient, recordings)
    save_ingestion(db_, session_id, version, ingestion)
    return ingestion


def ensure_fresh_ingestion(db: Session, request: Request, session: KneeSession) -> None:
    """When the stored check of ``session`` (a row of the request's ``db``) is stale, check its files again
    (:func:`refresh_ingestion`) with no transaction of ``db`` held meanwhile, then reload ``session``."""
    if ingestion_fresh(session) or not session.recordings:
        return
    state = request.app.state
    db.rollback()  # the check may take seconds: no open transaction (nor row lock) while it runs
    refresh_ingestion(state.db, state.store, state.settings.tmp_dir, session.id, state.check_pool)
    db.refresh(session)


def _too_large(settings) -> HTTPException:
    return HTTPException(413, f"The upload is larger than {settings.max_files} files of {settings.max_file_mb:g} MB; "
                              "send fewer or smaller files.")


#: body bytes gathered before one hand-over to the parser thread (one thread hop per ~64 KB socket read cost
#: the event loop, which every other request shares, about a second per 20 uploads)
_FEED_BYTES = 1 << 20


async def _read_body(request: Request, parser: MultipartParser, ceiling: int, settings) -> None:
    """Feed the body to ``parser`` in the thread pool in pieces of about :data:`_FEED_BYTES`, counting bytes:
    413 past ``ceiling`` (whatever the headers said: a chunked body has no length)."""
    received = 0
    pending: list[bytes] = []
    size = 0
    async for chunk in request.stream():
        received += len(chunk)
        if received > ceiling:
            raise _too_large(settings)
        if chunk:
            pending.append(chunk)
            size += len(chunk)
            if size >= _FEED_BYTES:
                await run_in_threadpool(parser.write, b"".join(pending))
                pending, size = [], 0
    if pending:
        await run_in_threadpool(parser.write, b"".join(pending))
    await run_in_threadpool(parser.finalize)


@router.post("/{session_id}/recordings", response_model=UploadOut, status_code=201,
             responses={409: {"description": "file name already stored, or the session is being processed"},
                        413: {"description": "too large or too many files"}, 415: {"description": "wrong type"},
                        503: {"description": "too many uploads at once; try again"}})
async def upload_recordings(session_id: int, request: Request, principal: UploadClinician, settings: SettingsDep,
                            store: StoreDep):
    """Store the files of field ``files`` (module docstring), then answer the recordings and the ingestion."""
    slots = request.app.state.upload_slots
    if not slots.acquire(blocking=False):
        raise HTTPException(503, "Too many uploads are in progress on this server; try again in a minute.",
                            headers={"Retry-After": "30"})
    try:
        return await _upload(session_id, request, principal, settings, store)
    finally:
        slots.release()


async def _upload(session_id: int, request: Request, principal, settings, store: BlobStore):
    await run_in_threadpool(_check_session, request, principal, session_id)
    ctype, params = parse_options_header(request.headers.get("content-type"))
    if ctype != b"multipart/form-data" or not params.get(b"boundary"):
        raise HTTPException(415, "Send the files as multipart/form-data in the field 'files'.")
    declared = request.headers.get("content-length")
    ceiling = settings.max_files * (settings.max_file_bytes + _PART_ROOM)
    if declared and declared.isdigit() and int(declared) > ceiling:  # refused before reading a byte
        raise _too_large(settings)
    upload = _Upload(store, settings)
    parser = MultipartParser(params[b"boundary"], upload.callbacks())
    try:
        await _read_body(request, parser, ceiling, settings)
    except ClientDisconnect:
        await run_in_threadpool(upload.discard)
        log.info("upload to session %s cut short: the client disconnected", session_id)
        return Response(status_code=400)  # nobody is listening any more
    except HTTPException:
        await run_in_threadpool(upload.discard)
        raise
    except MultipartParseError:
        await run_in_threadpool(upload.discard)
        raise HTTPException(400, "The multipart body is malformed; send the files with a standard form upload.") \
            from None
    except BaseException:
        upload.discard()
        raise
    try:
        if not upload.files:
            raise HTTPException(400, "No file in the request; send the recordings in the multipart field 'files'.")
        segment = upload.fields.get("segment") or None
        role = upload.fields.get("role") or None
        if segment is not None and segment not in SEGMENTS:
            raise HTTPException(400, f"segment {segment!r} is unknown; use {' or '.join(SEGMENTS)}.")
        if role is not None and role not in ROLES:
            raise HTTPException(400, f"role {role!r} is unknown; use one of {', '.join(ROLES)}.")
        return await run_in_threadpool(_store, request, principal, session_id, upload, segment, role)
    finally:
        await run_in_threadpool(upload.discard)  # no-op for committed blobs (their temp file is gone)


def _delete(request: Request, principal, session_id: int, recording_id: int) -> None:
    with request.app.state.db.session() as db:
        session = scoped_session(db, principal, session_id, lock=True)
        rec = db.get(Recording, recording_id)
        if rec is None or rec.session_id != session.id:
            raise HTTPException(404, f"No recording {recording_id} in session {session_id}; check the ids.")
        refuse_while_processing(db, session.id, "delete files")
        db.delete(rec)
        session.files_version = KneeSession.files_version + 1
        db.flush()
        refuse_while_processing(db, session.id, "delete files")
        audit.record(db, request, principal, "delete", patient_id=session.patient_id, session_id=session.id)


@router.delete("/{session_id}/recordings/{recording_id}", status_code=204,
               responses={409: {"description": "the session is being processed"}})
def delete_recording(session_id: int, recording_id: int, principal: Clinician, request: Request) -> Response:
    """Remove one recording from the session (its stored content stays if other rows use it)."""
    _delete(request, principal, session_id, recording_id)
    state = request.app.state
    try:  # the deletion is committed: whatever happens to the new check, it stands (the stale check is redone)
        refresh_ingestion(state.db, state.store, state.settings.tmp_dir, session_id, state.check_pool)
    except Exception:  # noqa: BLE001
        log.warning("recording deleted from session %s; its ingestion check failed and runs again later",
                    session_id, exc_info=True)
    return Response(status_code=204)


__all__ = ["FORM_FIELDS", "ensure_fresh_ingestion", "refresh_ingestion", "router", "save_ingestion"]
