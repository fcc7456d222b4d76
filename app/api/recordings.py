"""Uploads: ``POST /sessions/{id}/recordings`` (multipart, streamed to storage) and ``DELETE .../{rid}``.

The request body is parsed as it arrives (python-multipart's streaming parser over ``request.stream()``):
each file part is written straight into a temporary blob file while it is hashed and counted, so nothing is
held in memory and a file over ``CHAKAMO_MAX_FILE_MB`` is refused (413) as soon as the limit is passed.  A
file name whose type is not allowed (``.csv``, ``.xlsx``, ``.json``) is refused (415) before its bytes are
read; more than ``CHAKAMO_MAX_FILES`` files per request or per session answers 413.  Only when the whole
request has been read are the blobs committed and the recordings inserted (all or none), then the session's
files are checked by the ingestion (:func:`app.workspace.check_ingestion`) and the result stored on the
session and returned.  Uploads are thus stored and committed before any processing can start.

Optional form fields ``segment`` (thigh|shank) and ``role`` (mag_calibration|standing|lying|task) apply to
every file of the request (they go into the generated ``session.json``).  A ``.json`` file must be the
session's ``session.json`` manifest.
"""

from __future__ import annotations

from pathlib import PurePosixPath, PureWindowsPath

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.concurrency import run_in_threadpool
from python_multipart.exceptions import MultipartParseError
from python_multipart.multipart import MultipartParser, parse_options_header
from sqlalchemy import func, select

from app.api.deps import Clinician, SettingsDep, StoreDep, scoped_session
from app.api.schemas import UploadOut, recording_out
from app.db.models import Blob, KneeSession, Recording
from app.ingestion import MANIFEST, ROLES, SEGMENTS
from app.storage import BlobStore, BlobWriter, TooLarge
from app.workspace import check_ingestion

router = APIRouter(prefix="/sessions", tags=["recordings"])
_FIELD_LIMIT = 200


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
        self._headers: dict[str, str] = {}
        self._field = self._value = b""
        self._writer: BlobWriter | None = None
        self._form_name: str | None = None
        self._form_value = bytearray()
        self.error: HTTPException | None = None

    def callbacks(self) -> dict:
        return {"on_part_begin": self._part_begin, "on_header_field": self._header_field,
                "on_header_value": self._header_value, "on_header_end": self._header_end,
                "on_headers_finished": self._headers_finished, "on_part_data": self._data,
                "on_part_end": self._part_end}

    def _part_begin(self) -> None:
        self._headers, self._writer, self._form_name = {}, None, None
        self._form_value = bytearray()

    def _header_field(self, data: bytes, start: int, end: int) -> None:
        self._field += data[start:end]

    def _header_value(self, data: bytes, start: int, end: int) -> None:
        self._value += data[start:end]

    def _header_end(self) -> None:
        self._headers[self._field.decode("latin-1").lower()] = self._value.decode("utf-8", "replace")
        self._field = self._value = b""

    def _headers_finished(self) -> None:
        _, params = parse_options_header(self._headers.get("content-disposition", ""))
        name = params.get(b"name", b"").decode("utf-8", "replace")
        filename = params.get(b"filename")
        if filename is None:
            self._form_name = name
            return
        if name != "files":
            raise HTTPException(400, f"File sent in form field {name!r}; send every file in the field 'files'.")
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
    with request.app.state.db.session() as db:
        scoped_session(db, principal, session_id)


def _store(request: Request, principal, session_id: int, upload: _Upload, segment: str | None,
           role: str | None) -> dict:
    db_, settings = request.app.state.db, request.app.state.settings
    names = [n for n, _ in upload.files]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise HTTPException(400, f"{', '.join(dupes)} sent twice in one upload; send each file once.")
    with db_.session() as db:
        session = scoped_session(db, principal, session_id)
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
            if db.get(Blob, sha) is None:
                db.add(Blob(sha256=sha, size_bytes=size))
                db.flush()
            rows.append(Recording(session_id=session.id, file_name=name, size_bytes=size, sha256=sha,
                                  segment=segment, role=role))
        db.add_all(rows)
        session.ingestion = None  # "being checked": processing waits for the check below
        db.flush()
        out = [recording_out(r) for r in rows]
    ingestion = _refresh_ingestion(request, session_id)
    return {"recordings": out, "ingestion": ingestion}


def _refresh_ingestion(request: Request, session_id: int) -> dict:
    """Run the ingestion over the session's stored files (no lock held meanwhile) and store the result."""
    db_, settings, store = request.app.state.db, request.app.state.settings, request.app.state.store
    with db_.session() as db:
        session = db.get(KneeSession, session_id)
        patient, recordings = session.patient, list(session.recordings)
        db.expunge_all()
    ingestion = check_ingestion(store, settings.tmp_dir, session, patient, recordings)
    with db_.session() as db:
        row = db.get(KneeSession, session_id)
        current = list(db.scalars(select(func.count()).select_from(Recording)
                                  .where(Recording.session_id == session_id)))[0]
        if current == len(recordings):  # nothing changed meanwhile (else the later request's check wins)
            row.ingestion = ingestion
    return ingestion


@router.post("/{session_id}/recordings", response_model=UploadOut, status_code=201)
async def upload_recordings(session_id: int, request: Request, principal: Clinician, settings: SettingsDep,
                            store: StoreDep):
    """Store the files of field ``files`` (module docstring), then answer the recordings and the ingestion."""
    await run_in_threadpool(_check_session, request, principal, session_id)
    ctype, params = parse_options_header(request.headers.get("content-type"))
    if ctype != b"multipart/form-data" or not params.get(b"boundary"):
        raise HTTPException(415, "Send the files as multipart/form-data in the field 'files'.")
    declared = request.headers.get("content-length")
    ceiling = settings.max_files * (settings.max_file_bytes + 64 * 1024)
    if declared and declared.isdigit() and int(declared) > ceiling:  # refused before reading a byte
        raise HTTPException(413, f"The upload is larger than {settings.max_files} files of "
                                 f"{settings.max_file_mb:g} MB; send fewer or smaller files.")
    upload = _Upload(store, settings)
    parser = MultipartParser(params[b"boundary"], upload.callbacks())
    try:
        async for chunk in request.stream():
            parser.write(chunk)
        parser.finalize()
    except HTTPException:
        upload.discard()
        raise
    except MultipartParseError:
        upload.discard()
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
        upload.discard()  # no-op for committed blobs (their temp file is gone)


@router.delete("/{session_id}/recordings/{recording_id}", status_code=204)
def delete_recording(session_id: int, recording_id: int, principal: Clinician, request: Request) -> Response:
    """Remove one recording from the session (its stored content stays if other rows use it)."""
    with request.app.state.db.session() as db:
        session = scoped_session(db, principal, session_id)
        rec = db.get(Recording, recording_id)
        if rec is None or rec.session_id != session.id:
            raise HTTPException(404, f"No recording {recording_id} in session {session_id}; check the ids.")
        db.delete(rec)
        session.ingestion = None
    _refresh_ingestion(request, session_id)
    return Response(status_code=204)

