"""A size limit on every request body but the recordings upload, as a plain ASGI middleware (:class:`BodyLimit`).

Without it a 200 MB JSON body was read in full before the route could answer 401 or 422 (issue 16, finding
3: +153 MB of server memory for one request).  The limit is ``CHAKAMO_MAX_BODY_KB`` (1024 kB); every JSON
body the API takes is a few kB.

* The upload route (``POST /api/v1/sessions/{id}/recordings``) is left out by its method and path *before*
  anything is wrapped: its body streams to storage under its own limits (``CHAKAMO_MAX_FILE_MB``,
  ``CHAKAMO_MAX_FILES``, :mod:`app.web.api.recordings`), and not one of its messages passes through here.
* A ``Content-Length`` above the limit answers 413 before a byte of the body is read.
* Without ``Content-Length`` (``Transfer-Encoding: chunked``) the body is read here, counting, up to the
  limit; one byte more answers 413.  A body within the limit is then handed to the application as it came
  (one ``http.request`` message), and later ``receive`` calls (a disconnect) go to the server.  Under
  HTTP/1.1 a declared length cannot be overrun (the server frames the body by it), so a body within its
  declared length is passed through untouched.
* A 413 is sent with ``Connection: close`` and the application is not called: the server closes the
  connection after the answer instead of reading (or waiting for) the rest of a body nobody wants, so
  the client is never left waiting.
"""

from __future__ import annotations

import re

from app.web.refusals import Refusal

#: the one route whose body is not limited here (method, path)
UPLOAD_ROUTE = ("POST", re.compile(r"^/api/v1/sessions/[^/]+/recordings/?$"))


def exempt(method: str, path: str) -> bool:
    """Whether the request ``method path`` is the recordings upload (its body is limited by the route)."""
    return method == UPLOAD_ROUTE[0] and UPLOAD_ROUTE[1].match(path) is not None


class _TooLarge(Exception):
    pass


class BodyLimit:
    """ASGI middleware refusing request bodies above ``max_bytes`` (module docstring)."""

    def __init__(self, app, *, max_bytes: int) -> None:
        self.app, self.max_bytes = app, max_bytes

    def _refuse(self):
        return Refusal(413, "request.body_too_large", limit_kb=self.max_bytes // 1024).response(
            {"Connection": "close"})

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http" or exempt(scope["method"], scope["path"]):
            await self.app(scope, receive, send)
            return
        declared = None
        chunked = False
        for name, value in scope.get("headers", ()):
            if name == b"content-length":
                declared = value
            elif name == b"transfer-encoding" and b"chunked" in value.lower():
                chunked = True
        if declared is not None and not chunked and declared.strip().isdigit():
            if int(declared) > self.max_bytes:
                await self._refuse()(scope, receive, send)
                return
            await self.app(scope, receive, send)
            return
        try:
            first = await self._read_ahead(receive)
        except _TooLarge:
            await self._refuse()(scope, receive, send)
            return
        replayed = False

        async def replay():
            nonlocal replayed
            if not replayed:
                replayed = True
                return first
            return await receive()

        await self.app(scope, replay, send)

    async def _read_ahead(self, receive) -> dict:
        """The whole body as one ``http.request`` message (or the disconnect that cut it), counting bytes:
        :class:`_TooLarge` past ``max_bytes``."""
        parts: list[bytes] = []
        size = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":
                return message  # http.disconnect: the application sees the client gone
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_bytes:
                raise _TooLarge
            parts.append(chunk)
            if not message.get("more_body", False):
                return {"type": "http.request", "body": b"".join(parts), "more_body": False}


__all__ = ["BodyLimit", "UPLOAD_ROUTE", "exempt"]
