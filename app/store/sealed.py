"""Secrets the server must read back (a webhook's signing key), stored encrypted under ``CHAKAMO_SECRET_KEY``.

The key is HKDF-SHA256 (RFC 5869) of ``CHAKAMO_SECRET_KEY`` with ``info = b"chakamo sealed secrets v1"``: 32
bytes for AES-256-GCM (NIST SP 800-38D), an authenticated cipher, so a stored value changed or moved to
another row's key fails to open instead of opening to garbage.  A sealed value is ``e1:`` + base64url(nonce 12 B
‖ ciphertext ‖ tag 16 B), without padding: a 43-character webhook secret seals to 99 characters (the column
holds 100).  AES-GCM rather than Fernet (AES-128-CBC + HMAC, 140 characters for the same secret) for that
length.  A database copied without the key reveals no secret; rotating ``CHAKAMO_SECRET_KEY`` makes the stored
ones unreadable (their subscriptions must be made again).  Secrets stored in plain text before sealing existed
were sealed by migration 0012 (``app/store/migrations/versions/0012_sealed_secrets_fhir_push.py``), so a value without the prefix is refused (``ValueError``), never
used as a key.  The module lives in the store because that migration seals with it (the store may not import the
web layer).
"""

from __future__ import annotations

import base64
import os

from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.ciphers.aead import AESGCM
from cryptography.hazmat.primitives.kdf.hkdf import HKDF

PREFIX = "e1:"
_INFO = b"chakamo sealed secrets v1"


def _cipher(key: bytes) -> AESGCM:
    return AESGCM(HKDF(algorithm=hashes.SHA256(), length=32, salt=None, info=_INFO).derive(key))


def seal(key: bytes, text: str) -> str:
    """``text`` encrypted under ``key`` (``CHAKAMO_SECRET_KEY``'s bytes), as stored (module docstring)."""
    nonce = os.urandom(12)
    blob = nonce + _cipher(key).encrypt(nonce, text.encode(), None)
    return PREFIX + base64.urlsafe_b64encode(blob).decode().rstrip("=")


def unseal(key: bytes, stored: str) -> str:
    """The text :func:`seal` stored (``cryptography.exceptions.InvalidTag`` under another key; ``ValueError`` for a
    value that is not sealed)."""
    if not stored.startswith(PREFIX):
        raise ValueError("not a sealed value (no e1: prefix)")
    raw = stored[len(PREFIX):]
    blob = base64.urlsafe_b64decode(raw + "=" * (-len(raw) % 4))
    return _cipher(key).decrypt(blob[:12], blob[12:], None).decode()


def sealed(stored: str) -> bool:
    """Whether ``stored`` is a value :func:`seal` made (else a plain secret stored before sealing existed)."""
    return stored.startswith(PREFIX)


__all__ = ["PREFIX", "seal", "sealed", "unseal"]
