"""Content-addressed file storage: every upload and artefact is a file named by its sha256.

Layout: ``<root>/aa/bbbbb…`` where ``aabbbbb…`` is the sha256 hex digest of the content; equal content is
stored once.  Writing goes through :class:`BlobWriter`: bytes are streamed into a temporary file in
``<root>/.incoming`` (same file system) while they are hashed and counted; going past the size limit raises
:class:`TooLarge` at once (the API answers 413 before reading the rest); :meth:`BlobWriter.commit` moves the
file to its final name with ``os.replace`` (atomic), so a blob is never seen half-written.  Reading verifies
the checksum (:meth:`BlobStore.read`, :meth:`BlobStore.copy_to`): a file altered on disk raises
:class:`CorruptBlob` instead of being served or processed.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from pathlib import Path

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

    def write(self, chunk: bytes) -> None:
        """Append ``chunk``; raises :class:`TooLarge` (and discards the file) past ``max_bytes``."""
        self.size_bytes += len(chunk)
        if self._max is not None and self.size_bytes > self._max:
            self.discard()
            raise TooLarge(f"more than {self._max} bytes")
        self._hash.update(chunk)
        self._file.write(chunk)

    def commit(self) -> str:
        """Move the file to its content address; returns the sha256 hex digest."""
        self._file.close()
        digest = self._hash.hexdigest()
        target = self._store.path(digest)
        target.parent.mkdir(parents=True, exist_ok=True)
        if target.is_file() and target.stat().st_size == self.size_bytes:
            self._path.unlink(missing_ok=True)  # already stored (same content)
        else:
            os.replace(self._path, target)
        return digest

    def discard(self) -> None:
        if not self._file.closed:
            self._file.close()
        self._path.unlink(missing_ok=True)


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

    def writer(self, max_bytes: int | None = None) -> BlobWriter:
        return BlobWriter(self, max_bytes)

    def put(self, data: bytes) -> tuple[str, int]:
        """Store ``data``; returns ``(sha256, size_bytes)``."""
        w = self.writer()
        w.write(data)
        return w.commit(), w.size_bytes

    def read(self, sha256: str) -> bytes:
        """The content of blob ``sha256``, verified; raises :class:`CorruptBlob` if missing or altered."""
        try:
            data = self.path(sha256).read_bytes()
        except FileNotFoundError:
            raise CorruptBlob(f"stored file {sha256[:12]}… is missing from {self.root}; restore it from a backup") from None
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
            raise CorruptBlob(f"stored file {sha256[:12]}… is missing from {self.root}; restore it from a backup") from None
        if h.hexdigest() != sha256:
            Path(target).unlink(missing_ok=True)
            raise CorruptBlob(f"stored file {sha256[:12]}… does not match its checksum; restore it from a backup")


__all__ = ["BlobStore", "BlobWriter", "CorruptBlob", "TooLarge"]
