"""Cursor pagination of the API's lists, and the exact lookup by identifier.

A list answers its rows as a JSON array (the contract the UI reads) and says the rest in headers:
``X-Total-Count`` (the whole filtered list), and, when more rows follow, ``X-Next-Cursor`` and ``Link: <…>;
rel="next"`` (RFC 8288) with the same query and the cursor.  A cursor is opaque to the client: the sort key of
the page's last row, base64url-encoded JSON; the store continues *after* it (keyset pagination), so rows
created or erased meanwhile neither repeat nor skip one, unlike an offset.  A cursor that does not decode
answers 400.

``identifier`` follows FHIR's token search (R4 §3.1.1.4.9): ``value`` (any system), ``system|value`` or
``|value`` (no system).  A patient's record number (``external_id``) is in the system
``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM`` when that is set, else in none; a system the clinic does not use finds
nobody.  The match is exact: "MRN-77" never finds "MRN-778899".
"""

from __future__ import annotations

import base64
import json
from typing import Any
from urllib.parse import urlencode

from fastapi import Request, Response

from app.web.refusals import Refusal

#: the headers of a page, for OpenAPI
PAGE_HEADERS = {
    "X-Total-Count": {"description": "rows in the whole filtered list", "schema": {"type": "integer"}},
    "X-Next-Cursor": {"description": "pass as ?cursor= for the next page (absent on the last page)",
                      "schema": {"type": "string"}},
    "Link": {"description": 'RFC 8288: <next page URL>; rel="next" (absent on the last page)',
             "schema": {"type": "string"}},
}
#: the largest page a client may ask for
MAX_LIMIT = 500


def encode_cursor(key: Any) -> str:
    return base64.urlsafe_b64encode(json.dumps(key, default=str, separators=(",", ":")).encode()).decode().rstrip("=")


def decode_cursor(cursor: str | None) -> Any:
    """The key ``cursor`` holds (None: no cursor); 400 when it is not one this server wrote."""
    if cursor is None or cursor == "":
        return None
    try:
        return json.loads(base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4)))
    except (ValueError, TypeError):
        raise Refusal(400, "request.cursor_invalid") from None


def page_headers(request: Request, response: Response, total: int, next_after: Any) -> None:
    """``X-Total-Count``, and ``X-Next-Cursor`` with ``Link: rel="next"`` when ``next_after`` is not None."""
    response.headers["X-Total-Count"] = str(total)
    if next_after is None:
        return
    cursor = encode_cursor(next_after)
    query = [(k, v) for k, v in request.query_params.multi_items() if k != "cursor"] + [("cursor", cursor)]
    response.headers["X-Next-Cursor"] = cursor
    response.headers["Link"] = f'<{request.url.path}?{urlencode(query)}>; rel="next"'


def identifier_value(identifier: str, system: str | None) -> str | None:
    """The record number ``identifier`` (FHIR token: ``value``, ``system|value``, ``|value``) asks for, or None
    when it names a system other than the clinic's (``system``; module docstring): nobody matches."""
    if "|" not in identifier:
        return identifier
    asked, value = identifier.split("|", 1)
    if asked == "":
        return value if system is None else None
    return value if asked == system else None


__all__ = ["MAX_LIMIT", "PAGE_HEADERS", "decode_cursor", "encode_cursor", "identifier_value", "page_headers"]
