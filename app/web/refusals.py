"""Refusals a user can cause, in the three languages: :class:`Refusal` and the body every one of them answers.

A refusal is an :class:`~fastapi.HTTPException` (so the upload parser's callbacks and the routes raise and
catch it like any other) carrying a code and its parameters.  The code belongs to one of three tables:
:data:`app.pipeline.service_messages.CATALOGUE` (``request.*``, ``session.*``: a request or a session as a whole),
:data:`app.web.messages.CATALOGUE` (``login.*``, ``password.*``, ``account.*``: logins and accounts) or, for a file
refused at upload by an ingestion rule, :data:`app.pipeline.ingestion.messages.CATALOGUE` (``manifest.too_deep``).
Every answer is an RFC 7807 problem (:mod:`app.web.problems`) carrying the contract's one-sentence ``detail`` — English, or the request's language when the route
asks for it (:func:`app.web.messages.refusal`, from ``Accept-Language``) — and ``code``, ``params`` and ``message``
``{"es", "en", "pt"}`` (:func:`~app.pipeline.ingestion.messages.message_dict`), and names its code in the
``X-ChakaMo-Code`` header, so a hospital system or the browser shows it in its reader's language and a program
tells refusals apart without parsing sentences.
"""

from __future__ import annotations

from typing import Any, Mapping

from fastapi import HTTPException

from app.pipeline.ingestion import messages as ingestion_messages
from app.pipeline.service_messages import CATALOGUE as SERVICE_CATALOGUE
from app.web.messages import CATALOGUE as ACCOUNT_CATALOGUE
from app.web.messages import CODE_HEADER
from app.web.problems import ProblemJSONResponse, problem


def catalogue_of(code: str) -> Mapping[str, Mapping[str, str]]:
    """The table that defines ``code`` (the ingestion's when no other does: its lookup then names the bad code)."""
    for table in (SERVICE_CATALOGUE, ACCOUNT_CATALOGUE):
        if code in table:
            return table
    return ingestion_messages.CATALOGUE


class Refusal(HTTPException):
    """``Refusal(status, code, **params)``: an HTTP error whose sentence is catalogue entry ``code``, in ``lang``."""

    def __init__(self, status_code: int, code: str, /, headers: dict[str, str] | None = None, lang: str = "en",
                 **params: Any) -> None:
        self.code, self.params = code, params
        self._catalogue = catalogue_of(code)
        super().__init__(status_code, ingestion_messages.render(code, params, lang, self._catalogue),
                         headers={CODE_HEADER: code, **(headers or {})})

    def body(self, instance: str | None = None) -> dict[str, Any]:
        """The RFC 7807 problem (:mod:`app.web.problems`) with ``detail`` and the extension members ``code``,
        ``params`` and ``message`` ``{lang: sentence}``."""
        return problem(self.status_code, self.detail, instance=instance,
                       **ingestion_messages.message_dict(self.code, self.params, self._catalogue))

    def response(self, extra_headers: dict[str, str] | None = None, instance: str | None = None
                 ) -> ProblemJSONResponse:
        return ProblemJSONResponse(self.body(instance), status_code=self.status_code,
                                   headers=(self.headers or {}) | (extra_headers or {}))


def members(code: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """``code``, ``params`` and ``message`` ``{lang: sentence}`` of a refusal answered without a :class:`Refusal`
    (the 422 of a request FastAPI's validation refuses, :mod:`app.web.main`)."""
    return ingestion_messages.message_dict(code, params, catalogue_of(code))


__all__ = ["Refusal", "catalogue_of", "members"]
