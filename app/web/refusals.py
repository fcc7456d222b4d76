"""Refusals a user can cause, in the three languages: :class:`Refusal` and the body every one of them answers.

A refusal is an :class:`~fastapi.HTTPException` (so the upload parser's callbacks and the routes raise and
catch it like any other) carrying a code of :data:`app.pipeline.service_messages.CATALOGUE` (``request.*``) or, for
a file refused at upload by an ingestion rule, of :data:`app.pipeline.ingestion.messages.CATALOGUE`
(``manifest.too_deep``), and its parameters.  Its answer keeps the contract's one-sentence ``detail`` (English, as every other error) and adds
``code``, ``params`` and ``message`` ``{"es", "en", "pt"}`` (:func:`~app.pipeline.service_messages.message_dict`),
so a hospital system or the browser shows it in its reader's language.
"""

from __future__ import annotations

from typing import Any

from fastapi import HTTPException
from starlette.responses import JSONResponse

from app.pipeline.ingestion import messages as ingestion_messages
from app.pipeline.service_messages import CATALOGUE as SERVICE_CATALOGUE


class Refusal(HTTPException):
    """``Refusal(status, code, **params)``: an HTTP error whose sentence is catalogue entry ``code``."""

    def __init__(self, status_code: int, code: str, /, headers: dict[str, str] | None = None, **params: Any) -> None:
        self.code, self.params = code, params
        self._catalogue = SERVICE_CATALOGUE if code in SERVICE_CATALOGUE else ingestion_messages.CATALOGUE
        super().__init__(status_code, ingestion_messages.render(code, params, "en", self._catalogue), headers=headers)

    def body(self) -> dict[str, Any]:
        """``{"detail": English sentence, "code", "params", "message": {lang: sentence}}``."""
        return {"detail": self.detail, **ingestion_messages.message_dict(self.code, self.params, self._catalogue)}

    def response(self, extra_headers: dict[str, str] | None = None) -> JSONResponse:
        return JSONResponse(self.body(), status_code=self.status_code, headers=(self.headers or {}) | (extra_headers or {}))


__all__ = ["Refusal"]
