"""The ``Idempotency-Key`` request header of the creating POSTs (:mod:`app.store.idempotency` keeps the keys).

A client sends any unique string (a UUID) of at most 200 printable ASCII characters; sending the same request
with the same key again — after a timeout, a lost answer, a crash — answers the resource the first request
created, with the first answer's status, its ``Location`` and ``Idempotent-Replayed: true``, and creates
nothing.  The same key with another request answers 409.  ``Location`` names the created resource on every
201 and 202 (RFC 9110 §10.2.2).
"""

from __future__ import annotations

import re
from typing import Any

from fastapi import Request
from fastapi.encoders import jsonable_encoder
from starlette.responses import JSONResponse

from app.store.idempotency import MAX_KEY_LENGTH, fingerprint
from app.web.refusals import Refusal

HEADER = "Idempotency-Key"
REPLAYED = "Idempotent-Replayed"
_KEY = re.compile(r"[\x21-\x7e]{1,%d}" % MAX_KEY_LENGTH)

#: the header, for OpenAPI (``openapi_extra`` of the creating routes)
KEY_PARAMETER = {"name": HEADER, "in": "header", "required": False,
                 "description": "any unique string (a UUID): the same request sent again with the same key answers "
                                "what the first one created, and creates nothing",
                 "schema": {"type": "string", "maxLength": MAX_KEY_LENGTH}}
#: the ``Location`` header of a 201 / 202, for OpenAPI
LOCATION = {"Location": {"description": "the path of the created resource", "schema": {"type": "string"}},
            REPLAYED: {"description": "true when this answer repeats an earlier request with the same "
                                      "Idempotency-Key", "schema": {"type": "string"}}}


def key_of(request: Request) -> str | None:
    """The request's ``Idempotency-Key`` (None: absent); 400 when it is not 1–200 printable ASCII characters."""
    raw = request.headers.get(HEADER)
    if raw is None:
        return None
    key = raw.strip()
    if not _KEY.fullmatch(key):
        raise Refusal(400, "request.idempotency_key_invalid", limit=MAX_KEY_LENGTH)
    return key


def request_sha256(request: Request, body: Any = None, raw: bytes = b"") -> str:
    """The identity the key is bound to: method, path and the parsed body (a pydantic model, or None) or
    ``raw`` (an upload's description of its parts)."""
    data = body.model_dump_json().encode() if body is not None else raw
    return fingerprint(request.method, request.url.path, data)


def answer(content: Any, status: int, location: str, replayed: bool = False) -> JSONResponse:
    headers = {"Location": location}
    if replayed:
        headers[REPLAYED] = "true"
    return JSONResponse(jsonable_encoder(content), status_code=status, headers=headers)


__all__ = ["HEADER", "KEY_PARAMETER", "LOCATION", "REPLAYED", "answer", "key_of", "request_sha256"]
