"""Uploads: ``POST /sessions/{id}/recordings`` (multipart, streamed to storage) and ``DELETE .../{rid}``.

The request body is parsed as it arrives (python-multipart's streaming parser over ``request.stream()``; the
parsing, hashing and file writes run in the thread pool, never on the event loop): each file part is written
straight into a temporary blob file while it is hashed and counted, so nothing is held in memory and a file
over ``CHAKAMO_MAX_FILE_MB`` is refused (413) as soon as the limit is passed.  The whole body is counted as
it arrives too, whatever the headers say (a chunked body has no Content-Length): past ``CHAKAMO_MAX_FILES``
files of the largest size plus a little room for the multipart framing it is refused (413); a declared
Content-Length above that is refused before a byte is read.  A body may hold at most ``max_files + 4``
parts, and besides the files only the form fields ``segment`` and ``role`` (400 for any other).  A file
name whose type is not allowed (``.csv``, ``.xlsx``, ``.json``, ``.zip``, APDM's
``.h5``: :data:`app.settings.ALLOWED_SUFFIXES`) is refused (415) before its bytes are read;
more than ``CHAKAMO_MAX_FILES`` files per request or per session answers 413.  Only when the whole request
has been read are the blobs committed and the recordings inserted (all or none,
:func:`app.store.recordings.store_upload`), then the session's files are checked by the ingestion
(:meth:`app.store.checks.IngestionChecker.refresh`) and the result stored on the session and returned.
Uploads are thus stored and committed before any processing can start.

Resources: the caller is looked up in a short database session closed before the body is read
(:data:`app.web.api.deps.UploadClinician`), so a slow upload holds no database connection; at most
``CHAKAMO_MAX_UPLOADS`` uploads stream at once (more answer 503 with ``Retry-After``).  A client that
disconnects mid-upload is logged in one line and its partial files removed.  A full blob disk (``ENOSPC``
while a part is written or the files are committed) answers 507 with the job path's sentence, and nothing of
the upload is stored.

Multipart headers are parsed from their raw bytes (file names in any script: UTF-8, as browsers send them);
a boundary longer than RFC 2046's 70 characters, a malformed body, or a name holding Unicode bidirectional
controls (which reorder how it is shown) answers 400, each with its sentence in es/en/pt
(:class:`app.web.refusals.Refusal`).

Consistency: uploads and deletions answer 409 while a job of the session is queued or running (its files
must not change under it).  Every change bumps the session's ``files_version`` in the same transaction; the
ingestion check is stored with the version it was computed from and only if that is still the current one
(:func:`app.store.checks.save_ingestion`), so a slower, older check can never overwrite a newer one; a session
whose stored check is stale is checked again when it is read or processed.  Two uploads racing for the same
file name: one wins, the other gets 409 (the database's unique constraint decides).

``PUT /sessions/{id}/split`` stores where the clinician confirmed or moved the cuts of the continuous recordings
(:func:`app.store.recordings.set_split`) and answers the check redone with them.

Audit: an upload and a deletion each record one event (``upload`` / ``delete``, :mod:`app.web.audit`) in the
transaction that stores or removes the recordings, so the files and their event commit together.

Optional form fields ``segment`` (thigh|shank) and ``role`` (mag_calibration|standing|lying|task, or continuous:
one recording of the whole protocol, split when read) apply to every file of the request (they go into the
generated ``session.json``).  Each stored recording keeps the sensor serial its file name carries (``device``).
A ``.json`` file must be the session's ``session.json`` manifest; one larger than ``MAX_MANIFEST_KB`` (413) or
nested deeper than ``MAX_MANIFEST_DEPTH`` (400, :mod:`app.pipeline.ingestion.session`) is refused before it is
stored.
"""

from __future__ import annotations

import errno
import json
import logging
from pathlib import PurePosixPath, PureWindowsPath

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.concurrency import run_in_threadpool
from python_multipart.exceptions import FormParserError
from python_multipart.multipart import MultipartParser, parse_options_header
from starlette.requests import ClientDisconnect

from app.store import erasure, idempotency, recordings
from app.store.blobs import BlobStore, BlobWriter, TooLarge
from app.store.recordings import MANIFEST, MAX_MANIFEST_KB, SEGMENTS, UPLOAD_ROLES, manifest_problem
from app.store.sessions import clinic_session, refuse_while_processing, stored_ingestion
from app.web import audit
from app.web.api.deps import Clinician, SettingsDep, StoreDep, UploadClinician, checker_of
from app.web.records import ERRORS, erase_now
from app.web.api.schemas import IngestionOut, SplitIn, UploadOut, ingestion_out, recording_out
from app.web.idempotency import KEY_PARAMETER, LOCATION, answer, key_of, request_sha256
from app.web.refusals import Refusal

log = logging.getLogger("chakamo.uploads")
router = APIRouter(prefix="/sessions", tags=["recordings"])
_FIELD_LIMIT = 200
#: the form fields an upload may carry besides ``files``
FORM_FIELDS = ("segment", "role")
#: multipart framing allowed per file on top of its bytes (boundaries, part headers)
_PART_ROOM = 64 * 1024
#: the longest multipart boundary (RFC 2046 §5.1.1: 1 to 70 characters)
MAX_BOUNDARY = 70
#: Unicode bidirectional embeddings, overrides and isolates (UAX #9): they reorder how a name is shown
#: ("gpj.csv" shown as "vsc.jpg"), so a name holding one is refused; other letters of any script are welcome
_BIDI_CONTROLS = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def _clean_name(raw: str) -> str:
    name = PureWindowsPath(PurePosixPath(raw).name).name.strip()
    if not name or name.startswith(".") or any(ord(c) < 32 or ord(c) == 127 for c in name) or len(name) > 255:
        raise Refusal(400, "request.file_name_unusable", name=repr(raw)[:120])
    if _BIDI_CONTROLS.intersection(name):
        raise Refusal(400, "request.file_name_controls", name=ascii(name)[:80])
    return name


def _text(raw: bytes) -> str:
    """A multipart header parameter as text: UTF-8, as browsers send any file name (RFC 7578 §4.2), or
    Latin-1 from an older client (every byte string is Latin-1 text)."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` says the blob disk is full (the job path's test, :mod:`app.jobs.work`)."""
    return isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


class _Upload:
    """State of one streamed multipart request (callbacks of :class:`MultipartParser`)."""

    def __init__(self, store: BlobStore, settings) -> None:
        self.store, self.settings = store, settings
        self.files: list[tuple[str, BlobWriter]] = []
        self.fields: dict[str, str] = {}
        self.parts = 0
        self._headers: dict[bytes, bytes] = {}
        self._field = self._value = b""
        self._writer: BlobWriter | None = None
        self._form_name: str | None = None
        self._form_value = bytearray()
        self._manifest: bytearray | None = None  # the session.json's bytes, checked at its part's end

    def callbacks(self) -> dict:
        return {"on_part_begin": self._part_begin, "on_header_field": self._header_field,
                "on_header_value": self._header_value, "on_header_end": self._header_end,
                "on_headers_finished": self._headers_finished, "on_part_data": self._data,
                "on_part_end": self._part_end}

    def _part_begin(self) -> None:
        self.parts += 1
        if self.parts > self.settings.max_files + len(FORM_FIELDS) + 2:
            raise Refusal(413, "request.too_many_parts", max_files=self.settings.max_files)
        self._headers, self._writer, self._form_name = {}, None, None
        self._form_value = bytearray()
        self._manifest = None

    def _header_field(self, data: bytes, start: int, end: int) -> None:
        self._field += data[start:end]
        if len(self._field) > 1024:
            raise Refusal(400, "request.part_header_too_long")

    def _header_value(self, data: bytes, start: int, end: int) -> None:
        self._value += data[start:end]
        if len(self._value) > 8192:
            raise Refusal(400, "request.part_header_too_long")

    def _header_end(self) -> None:
        if len(self._headers) >= 16:
            raise Refusal(400, "request.too_many_part_headers")
        self._headers[self._field.lower()] = self._value  # raw bytes: decoded once, below
        self._field = self._value = b""

    def _headers_finished(self) -> None:
        # the raw bytes: python-multipart takes bytes as Latin-1, which every byte is, and gives them back
        # unchanged (a decoded str outside Latin-1 made it raise: issue 16, finding 6)
        _, params = parse_options_header(self._headers.get(b"content-disposition", b""))
        name = _text(params.get(b"name", b""))
        filename = params.get(b"filename")
        if filename is None:
            if name not in FORM_FIELDS:
                raise Refusal(400, "request.field_not_accepted", field=repr(name[:40]))
            if name in self.fields:
                raise Refusal(400, "request.field_twice", field=repr(name))
            self._form_name = name
            return
        if name != "files":
            raise Refusal(400, "request.file_in_other_field", field=repr(name[:40]))
        clean = _clean_name(_text(filename))
        suffix = PurePosixPath(clean).suffix.lower()
        if suffix not in self.settings.allowed_suffixes:
            raise Refusal(415, "request.file_type", file=clean, suffix=suffix or "(none)",
                          allowed=", ".join(self.settings.allowed_suffixes))
        if suffix == ".json" and clean != MANIFEST:
            raise Refusal(415, "request.json_not_manifest", file=clean, manifest=MANIFEST)
        if len(self.files) >= self.settings.max_files:
            raise Refusal(413, "request.too_many_files", max_files=self.settings.max_files)
        self._writer = self.store.writer(self.settings.max_file_bytes)
        self.files.append((clean, self._writer))
        if clean == MANIFEST:
            self._manifest = bytearray()

    def _data(self, data: bytes, start: int, end: int) -> None:
        if self._writer is not None:
            if self._manifest is not None:
                self._manifest += data[start:end]
                if len(self._manifest) > MAX_MANIFEST_KB * 1024:
                    raise Refusal(413, "manifest.too_large", file=MANIFEST, size_kb=f"> {MAX_MANIFEST_KB}",
                                  limit_kb=MAX_MANIFEST_KB)
            try:
                self._writer.write(data[start:end])
            except TooLarge:
                raise Refusal(413, "request.file_too_large", file=self.files[-1][0],
                              limit_mb=f"{self.settings.max_file_mb:g}") from None
        elif self._form_name is not None:
            self._form_value += data[start:end]
            if len(self._form_value) > _FIELD_LIMIT:
                raise Refusal(400, "request.field_too_long", field=repr(self._form_name))

    def _part_end(self) -> None:
        if self._manifest is not None:  # too deep or too large: refused now, never stored (issue 16, finding 5)
            exc = manifest_problem(bytes(self._manifest))
            if exc is not None:
                raise Refusal(413 if exc.code == "manifest.too_large" else 400, exc.code, **exc.params)
            self._manifest = None
        if self._form_name is not None:
            self.fields[self._form_name] = self._form_value.decode("utf-8", "replace").strip()

    def seal(self) -> None:
        """Make every file's bytes durable before the transaction that stores them (:meth:`BlobWriter.seal`)."""
        for _, w in self.files:
            w.seal()

    def discard(self) -> None:
        for _, w in self.files:
            w.discard()


def _check_session(request: Request, principal, session_id: int) -> None:
    """404 for another clinic's or an unknown session, 409 while it is being processed (before any byte)."""
    with request.app.state.db.session() as db:
        clinic_session(db, principal.clinic_id, session_id)
        refuse_while_processing(db, session_id, "upload")


def _replayed(db, request: Request, principal, session_id: int, replay: idempotency.Replay) -> Response:
    session = clinic_session(db, principal.clinic_id, session_id)
    rows = [r for r in session.recordings if r.id in set(replay.resource_ids)]
    audit.record(db, request, principal, "view", patient_id=session.patient_id, session_id=session.id)
    return answer({"recordings": [recording_out(r) for r in rows], "ingestion": stored_ingestion(session)},
                  replay.status, f"/api/v1/sessions/{session_id}", replayed=True)


def _upload_sha256(request: Request, upload: _Upload) -> str:
    """The identity an upload's ``Idempotency-Key`` is bound to: its path, form fields and every file's name,
    size and sha256 (:mod:`app.web.idempotency`), so the key reused with other files answers 409 instead of
    replaying the first upload and dropping the new files."""
    parts = sorted((name, w.size_bytes, w.sha256) for name, w in upload.files)
    return request_sha256(request, raw=json.dumps({"fields": upload.fields, "files": parts}, sort_keys=True).encode())


def _store(request: Request, principal, session_id: int, upload: _Upload, segment: str | None,
           role: str | None, key: str | None) -> Response:
    """Store the upload's files and their event in one transaction, then check the session's files.  The files
    are fsynced first, outside the transaction: under its locks they are only renamed (issue 16 finding 10h)."""
    upload.seal()
    with request.app.state.db.session() as db:
        claimed = (idempotency.claim(db, principal.clinic_id, key, _upload_sha256(request, upload), "upload")
                   if key else None)
        if isinstance(claimed, idempotency.Replay):  # a concurrent upload with this key won
            return _replayed(db, request, principal, session_id, claimed)
        session, rows = recordings.store_upload(db, principal.clinic_id, session_id, upload.files, segment=segment,
                                                role=role, max_files=request.app.state.settings.max_files)
        if claimed is not None:
            idempotency.complete(claimed, [r.id for r in rows], 201)
        audit.record(db, request, principal, "upload", patient_id=session.patient_id, session_id=session.id)
        out = [recording_out(r) for r in rows]
        split = session.split
    # the files are committed: whatever happens to their check, the upload stands
    ingestion = checker_of(request).refresh_or_defer(session_id, f"upload to session {session_id} stored")
    return answer({"recordings": out, "ingestion": ingestion_out(ingestion, split)}, 201,
                  f"/api/v1/sessions/{session_id}")


def _too_large(settings) -> Refusal:
    return Refusal(413, "request.upload_too_large", max_files=settings.max_files,
                   limit_mb=f"{settings.max_file_mb:g}")


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


#: the multipart body of an upload, for OpenAPI (the route parses the stream itself, so FastAPI cannot see it)
UPLOAD_BODY = {"required": True, "content": {"multipart/form-data": {
    "schema": {"type": "object", "required": ["files"], "properties": {
        "files": {"type": "array", "items": {"type": "string", "format": "binary"},
                  "description": "the recordings (.csv, .xlsx) and optionally the session's session.json; the file "
                                 "names carry segment and role as the ingestion rules say, unless the fields below "
                                 "name them"},
        "segment": {"type": "string", "enum": list(SEGMENTS),
                    "description": "the sensor's segment for every file of this request"},
        "role": {"type": "string", "enum": list(UPLOAD_ROLES),
                 "description": "what every file of this request records (continuous: the whole protocol in one "
                                "recording, split when read)"}}},
    "encoding": {"files": {"contentType": "text/csv, application/vnd.openxmlformats-officedocument."
                                          "spreadsheetml.sheet, application/json"}}}}}


@router.post("/{session_id}/recordings", response_model=UploadOut, status_code=201,
             openapi_extra={"requestBody": UPLOAD_BODY, "parameters": [KEY_PARAMETER]},
             responses={201: {"headers": LOCATION},
                        400: {"description": "malformed multipart body, a field other than files/segment/role, an "
                                             "unusable file name, or no file"},
                        409: {"description": "file name already stored, or the session is being processed"},
                        413: {"description": "too large or too many files"}, 415: {"description": "wrong type"},
                        507: {"description": "the server's disk is full: nothing was stored"},
                        503: {"description": "too many uploads at once; try again"}})
async def upload_recordings(session_id: int, request: Request, principal: UploadClinician, settings: SettingsDep,
                            store: StoreDep):
    """Store the files of field ``files`` (module docstring), then answer the recordings and the ingestion."""
    slots = request.app.state.upload_slots
    if not slots.acquire(blocking=False):
        raise Refusal(503, "request.uploads_busy", headers={"Retry-After": "30"})
    try:
        return await _upload(session_id, request, principal, settings, store)
    finally:
        slots.release()


async def _upload(session_id: int, request: Request, principal, settings, store: BlobStore):
    key = key_of(request)  # bound to the files too: compared once they are read (_upload_sha256)
    await run_in_threadpool(_check_session, request, principal, session_id)
    ctype, params = parse_options_header(request.headers.get("content-type"))
    if ctype != b"multipart/form-data" or not params.get(b"boundary"):
        raise Refusal(415, "request.not_multipart")
    declared = request.headers.get("content-length")
    ceiling = settings.max_files * (settings.max_file_bytes + _PART_ROOM)
    if declared and declared.isdigit() and int(declared) > ceiling:  # refused before reading a byte
        raise _too_large(settings)
    boundary = params[b"boundary"]
    if len(boundary) > MAX_BOUNDARY:
        raise Refusal(400, "request.boundary_too_long", length=len(boundary))
    upload = _Upload(store, settings)
    try:
        parser = MultipartParser(boundary, upload.callbacks())
    except FormParserError:
        raise Refusal(400, "request.multipart_malformed") from None
    try:
        await _read_body(request, parser, ceiling, settings)
    except ClientDisconnect:
        await run_in_threadpool(upload.discard)
        log.info("upload to session %s cut short: the client disconnected", session_id)
        return Response(status_code=400)  # nobody is listening any more
    except HTTPException:
        await run_in_threadpool(upload.discard)
        raise
    except FormParserError:  # python-multipart's parse errors (MultipartParseError and the rest)
        await run_in_threadpool(upload.discard)
        raise Refusal(400, "request.multipart_malformed") from None
    except OSError as exc:
        await run_in_threadpool(upload.discard)
        if _disk_full(exc):  # writing a part: 507 with the job path's sentence, nothing half-stored
            log.error("upload to session %s refused: no space left on the blob disk (%s)", session_id, exc)
            raise Refusal(507, "request.disk_full") from None
        raise
    except BaseException:
        upload.discard()
        raise
    try:
        if not upload.files:
            raise Refusal(400, "request.no_file")
        segment = upload.fields.get("segment") or None
        role = upload.fields.get("role") or None
        recordings.check_labels(segment, role)
        try:
            return await run_in_threadpool(_store, request, principal, session_id, upload, segment, role, key)
        except OSError as exc:
            if not _disk_full(exc):
                raise
            log.error("upload to session %s refused: no space left on the blob disk (%s)", session_id, exc)
            raise Refusal(507, "request.disk_full") from None
    finally:
        await run_in_threadpool(upload.discard)  # no-op for committed blobs (their temp file is gone)


def _delete(request: Request, principal, session_id: int, recording_id: int) -> list[int]:
    """Delete the recording, supersede the session's analyses, mark its blob, record the event: one transaction."""
    with request.app.state.db.session() as db:
        session, sha, _ = recordings.delete_recording(db, principal.clinic_id, session_id, recording_id)
        event = audit.record(db, request, principal, "delete", patient_id=session.patient_id, session_id=session.id, now=True)
        return erasure.mark(db, [sha], reason="recording", actor=event.actor, clinic_id=principal.clinic_id,
                            patient_id=session.patient_id, session_id=session.id, audit_event_id=event.id)


@router.delete("/{session_id}/recordings/{recording_id}", status_code=204,
               responses={k: v for k, v in ERRORS.items() if k != 412})
def delete_recording(session_id: int, recording_id: int, principal: Clinician, request: Request) -> Response:
    """Remove one recording from the session: its stored file is erased unless another recording or report
    has the same content, and the session's analyses become superseded (no longer its final report; process
    it again), as :mod:`app.store.recordings` argues."""
    erase_now(request, _delete(request, principal, session_id, recording_id))
    # the deletion is committed: whatever happens to the new check, it stands (the stale check is redone)
    checker_of(request).refresh_or_defer(session_id, f"recording deleted from session {session_id}")
    return Response(status_code=204)


def _set_split(request: Request, principal, session_id: int, split: dict | None) -> dict:
    with request.app.state.db.session() as db:
        session, _ = recordings.set_split(db, principal.clinic_id, session_id, split)
        audit.record(db, request, principal, "update", patient_id=session.patient_id, session_id=session.id,
                     detail="split moved" if split else "split reset to the automatic one")
        stored = session.split
    ingestion = checker_of(request).refresh_or_defer(session_id, f"split of session {session_id} stored")
    return ingestion_out(ingestion, stored)


@router.put("/{session_id}/split", response_model=IngestionOut,
            responses={k: v for k, v in ERRORS.items() if k != 412})
def put_split(session_id: int, body: SplitIn, principal: Clinician, request: Request):
    """Store the clinician's cuts of the session's continuous recordings (``{segment: {role: [start_s, end_s]}}``,
    seconds from each recording's start, as the check's ``splits`` show them; null: the automatic split again),
    then check the files with them and answer that check.  The processing uses the stored cuts
    (``session.json`` ``"split"``); the session's earlier analyses become superseded
    (:func:`app.store.recordings.set_split`)."""
    return _set_split(request, principal, session_id, body.split)


__all__ = ["FORM_FIELDS", "UPLOAD_BODY", "router"]
