"""Content-addressed file storage: every upload and artefact is a file named by its sha256.

Layout: ``<root>/aa/bbbbb…`` where ``aabbbbb…`` is the sha256 hex digest of the content; equal content is
stored once.  Writing goes through :class:`BlobWriter`: bytes are streamed into a temporary file in
``<root>/.incoming`` (same file system) while they are hashed and counted; going past the size limit raises
:class:`TooLarge` at once (the API answers 413 before reading the rest); :meth:`BlobWriter.commit` moves the
file to its final name with ``os.replace`` (atomic), so a blob is never seen half-written.  Durability: the
temporary file is fsynced before the rename and its folder after it, so once the database row that names a
blob is committed (and the upload acknowledged) a power cut loses neither.  A file already at the target
address is kept only if its content still hashes to that address; a damaged one is replaced by the new,
good copy (uploading the file again repairs the store).  Reading verifies the checksum
(:meth:`BlobStore.read`, :meth:`BlobStore.copy_to`): a file altered on disk raises :class:`CorruptBlob`
instead of being served or processed; its message names the blob, never the server's storage path.
:meth:`BlobStore.clear_incoming` removes temporary files a crashed server left behind (the embedded server at
start-up, before anything writes; a scaled-out API server those older than a day).

Erasure: :meth:`BlobStore.remove` unlinks one blob's file and makes the unlink durable (the folder is fsynced);
it is called only by :mod:`app.store.erasure`, which decides — under a database lock, from the rows that still
name the blob — that no reference is left (reference counting, crash-safety and the audit record are there).
:meth:`BlobStore.stored` lists what is on disk, for the sweep that finds files no row names (left by a crash
between writing a file and committing its row).  A blob's file is the only copy of its bytes this store keeps:
once removed, only a backup may still hold them (a retention policy must cover the backups too).

The application sees the store through :class:`Storage` (what uploads, jobs and downloads need) and gets
it from :func:`open_storage`; the local file system (:class:`BlobStore`, under ``CHAKAMO_DATA_DIR/blobs``,
a volume shared by the API servers and the workers in a scaled-out deployment) is the default and for now
the only implementation.  A write that fails (the disk is full: ``ENOSPC``) leaves no partial file behind.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import tempfile
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from app.settings import Settings

log = logging.getLogger("chakamo.storage")

_HEX = re.compile(r"^[0-9a-f]{64}$")
_CHUNK = 1 << 20


class TooLarge(ValueError):
    """More bytes than the limit were written."""


class CorruptBlob(OSError):
    """A stored file is missing or its content does not match its sha256."""


class BlobWriter:
    """Stream bytes into the store: ``write(chunk)`` repeatedly, then ``commit()`` (or ``discard()``)."""

    def __init__(self, store: "BlobStore", max_bytes: int | None = None) -> None:
        self._store = store
        self._max = max_bytes
        fd, name = tempfile.mkstemp(prefix="up-", dir=store.incoming)
        self._file = os.fdopen(fd, "wb")
        self._path = Path(name)
        self._hash = hashlib.sha256()
        self.size_bytes = 0
        self._stored_intact = False  # seal() found this content already stored, intact

    def write(self, chunk: bytes) -> None:
        """Append ``chunk``; raises :class:`TooLarge` (and discards the file) past ``max_bytes``."""
        self.size_bytes += len(chunk)
        if self._max is not None and self.size_bytes > self._max:
            self.discard()
            raise TooLarge(f"more than {self._max} bytes")
        self._hash.update(chunk)
        self._file.write(chunk)

    @property
    def sha256(self) -> str:
        """The hex digest of the bytes written so far (the address :meth:`commit` will use)."""
        return self._hash.hexdigest()

    def seal(self) -> None:
        """Make the written bytes durable (flush, fsync, close) without placing the file: the slow half of
        :meth:`commit`, which callers do *before* their database transaction, so that the part of :meth:`commit`
        done under the blob's lock — and, on SQLite, under the database's one write lock that every writing request
        waits for — is a rename and a folder fsync, not an fsync of the whole file (issue 16 finding 10h: a burst of
        uploads held that lock through each file's fsync).  Idempotent; no more :meth:`write` after it."""
        if self._file.closed:
            return
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.close()
        # the same content already stored: verified here, so that placing it under the locks is a look and a
        # touch, not a read of the whole stored file (only an eraser removes such a file meanwhile: looked for)
        target = self._store.path(self._hash.hexdigest())
        self._stored_intact = target.is_file() and _file_sha256(target) == self._hash.hexdigest()

    def commit(self) -> str:
        """Move the file to its content address, durably (module docstring; :meth:`seal` first if the caller did
        not); returns the sha256 hex digest.  A file already stored there is kept and its modification time
        refreshed (the eraser reads it: :mod:`app.store.erasure`)."""
        return commit_all([self])[0]

    def _place(self) -> tuple[str, Path | None]:
        """:meth:`commit` but the folder's fsync: ``(digest, the folder to fsync, or None when nothing moved)``."""
        self.seal()
        digest = self._hash.hexdigest()
        target = self._store.path(digest)
        target.parent.mkdir(parents=True, exist_ok=True)
        if target.is_file() and (self._stored_intact or _file_sha256(target) == digest):
            try:
                os.utime(target)
            except FileNotFoundError:  # erased meanwhile by a sweep that saw no row: store this copy
                pass
            else:
                self._path.unlink(missing_ok=True)  # already stored, intact
                return digest, None
        if target.exists():
            log.warning("stored file %s… was damaged; replaced by a good copy", digest[:12])
        os.replace(self._path, target)
        return digest, target.parent

    def discard(self) -> None:
        if not self._file.closed:
            try:
                self._file.close()
            except OSError:  # e.g. ENOSPC flushing the buffer: the file goes anyway
                pass
        self._path.unlink(missing_ok=True)


def _file_sha256(path: Path) -> str | None:
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            while chunk := f.read(_CHUNK):
                h.update(chunk)
    except OSError:
        return None
    return h.hexdigest()


def _fsync_dir(folder: Path) -> None:
    """Make a rename inside ``folder`` durable (no-op where folders cannot be opened, e.g. Windows)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def commit_all(writers: list[BlobWriter]) -> list[str]:
    """:meth:`BlobWriter.commit` of each of ``writers`` (their digests, in order): every file moved first, then
    the folders that received one fsynced together, in threads of their own — one wait for the disk rather than
    one per file.  Callers hold their blobs' locks (on SQLite the database's one write lock) across this, so its
    length is every other writer's wait (issue 16: an upload of 24 files fsynced 24 folders one after another
    there)."""
    placed: list[tuple[str, Path | None]] = []
    try:
        for w in writers:
            placed.append(w._place())
    finally:  # also when one failed (a full disk): the files moved so far are durable, as each was before
        folders = sorted({folder for _, folder in placed if folder is not None})
        if len(folders) > 1:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(min(len(folders), 8), thread_name_prefix="chakamo-fsync") as pool:
                list(pool.map(_fsync_dir, folders))
        elif folders:
            _fsync_dir(folders[0])
    return [digest for digest, _ in placed]


class BlobStore:
    """Files under ``root`` addressed by sha256 (module docstring)."""

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)
        self.incoming = self.root / ".incoming"
        self.incoming.mkdir(parents=True, exist_ok=True)

    def path(self, sha256: str) -> Path:
        if not _HEX.match(sha256):
            raise ValueError(f"not a sha256 hex digest: {sha256!r}")
        return self.root / sha256[:2] / sha256[2:]

    def clear_incoming(self, older_than_s: float | None = None) -> int:
        """Remove the temporary ``up-*`` files of uploads cut short by a crash; returns how many.  Without
        ``older_than_s``, call only when no upload is running (the embedded server at start-up); with it, only
        files untouched for that long go (the API servers of a scaled-out deployment share the store: another
        server's upload in progress writes its file every few milliseconds)."""
        n = 0
        cutoff = None if older_than_s is None else time.time() - older_than_s
        for p in self.incoming.glob("up-*"):
            try:
                if cutoff is not None and p.stat().st_mtime > cutoff:
                    continue
                p.unlink()
                n += 1
            except OSError:
                log.warning("could not remove the temporary upload file %s", p.name)
        return n

    def writer(self, max_bytes: int | None = None) -> BlobWriter:
        return BlobWriter(self, max_bytes)

    def remove(self, sha256: str) -> bool:
        """Unlink blob ``sha256``'s file, durably; True if there was one (an absent file is not an error: a crash
        may have come between this unlink and the commit that records it, and the erasure is then redone)."""
        target = self.path(sha256)
        try:
            target.unlink()
        except FileNotFoundError:
            return False
        _fsync_dir(target.parent)
        # the two-hex-digit folder stays, even empty: a writer of another blob with the same prefix may have made
        # it and be about to rename into it, and it holds no lock of that blob (256 folders at most)
        return True

    def stored(self) -> Iterator[tuple[str, float]]:
        """``(sha256, mtime)`` of every blob file on disk (temporary upload files are not blobs)."""
        for folder in self.root.iterdir():
            if len(folder.name) != 2 or not folder.is_dir():
                continue
            for f in folder.iterdir():
                digest = folder.name + f.name
                if _HEX.match(digest):
                    try:
                        yield digest, f.stat().st_mtime
                    except FileNotFoundError:  # removed meanwhile
                        continue

    def put(self, data: bytes) -> tuple[str, int]:
        """Store ``data``; returns ``(sha256, size_bytes)``.  On failure (e.g. ``ENOSPC``) nothing is left behind."""
        w = self.sealed(data)
        try:
            return w.commit(), w.size_bytes
        except BaseException:
            w.discard()
            raise

    def sealed(self, data: bytes) -> BlobWriter:
        """A :class:`BlobWriter` holding ``data``, durable but not yet placed (:meth:`BlobWriter.seal`): the caller
        commits it under the blob's lock, or discards it.  On failure nothing is left behind."""
        w = self.writer()
        try:
            w.write(data)
            w.seal()
        except BaseException:
            w.discard()
            raise
        return w

    def read(self, sha256: str) -> bytes:
        """The content of blob ``sha256``, verified; raises :class:`CorruptBlob` if missing or altered."""
        try:
            data = self.path(sha256).read_bytes()
        except FileNotFoundError:
            raise CorruptBlob(f"stored file {sha256[:12]}… is missing; restore it from a backup") from None
        if hashlib.sha256(data).hexdigest() != sha256:
            raise CorruptBlob(f"stored file {sha256[:12]}… does not match its checksum; restore it from a backup")
        return data

    def copy_to(self, sha256: str, target: str | os.PathLike) -> None:
        """Copy blob ``sha256`` to ``target``, verifying the checksum while copying."""
        h = hashlib.sha256()
        try:
            with open(self.path(sha256), "rb") as src, open(target, "wb") as dst:
                while chunk := src.read(_CHUNK):
                    h.update(chunk)
                    dst.write(chunk)
        except FileNotFoundError:
            raise CorruptBlob(f"stored file {sha256[:12]}… is missing; restore it from a backup") from None
        if h.hexdigest() != sha256:
            Path(target).unlink(missing_ok=True)
            raise CorruptBlob(f"stored file {sha256[:12]}… does not match its checksum; restore it from a backup")


@contextmanager
def discarding(writers: Iterable[BlobWriter]) -> Iterator[None]:
    """On leaving, discard every writer of ``writers`` (after :meth:`BlobWriter.commit` there is nothing left to
    discard: the placed file is kept), so sealed files a failed transaction never placed leave nothing behind."""
    try:
        yield
    finally:
        for w in writers:
            w.discard()


class Storage(Protocol):
    """What the application needs of a file store (module docstring)."""

    def writer(self, max_bytes: int | None = None) -> BlobWriter: ...

    def sealed(self, data: bytes) -> BlobWriter: ...

    def put(self, data: bytes) -> tuple[str, int]: ...

    def read(self, sha256: str) -> bytes: ...

    def copy_to(self, sha256: str, target: str | os.PathLike) -> None: ...

    def clear_incoming(self, older_than_s: float | None = None) -> int: ...

    def remove(self, sha256: str) -> bool: ...

    def stored(self) -> Iterator[tuple[str, float]]: ...


def open_storage(settings: "Settings") -> BlobStore:
    """The file store of ``settings``: the local file system under ``settings.blob_dir``."""
    return BlobStore(settings.blob_dir)


__all__ = ["BlobStore", "BlobWriter", "CorruptBlob", "Storage", "TooLarge", "commit_all", "open_storage"]
