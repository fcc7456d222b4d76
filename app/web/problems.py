"""Error answers as RFC 7807 problem details (``application/problem+json``), and their OpenAPI description.

Every error the app answers — a :class:`app.web.refusals.Refusal`, a plain ``HTTPException``, a validation
error, the database being away — has the body

    {"type": "urn:chakamo:problem:<code>" | "about:blank", "title": <the status' phrase>, "status": <int>,
     "detail": <one sentence: what is wrong, what to do>, "instance": <the request's path>,
     "code": <catalogue code>, "params": {...}, "message": {"es": ..., "en": ..., "pt": ...}}

``type``, ``title``, ``status``, ``detail`` and ``instance`` are RFC 7807 §3.1's members (``about:blank`` with
the status' reason phrase as title when the answer has no catalogue code, §4.2); ``code``, ``params`` and
``message`` are extension members (§3.2) kept from the earlier body, so a client that read ``detail`` or
``message`` before reads them still (the browser UI, ``static/api.js``).  ``type`` is a URN rather than a URL:
the app may run without a public address, and a type must not change with the host it is reached under.
A validation error also carries ``errors`` (pydantic's list).

:func:`document_errors` completes the OpenAPI document: every operation under ``/api/v1`` declares the error
answers it can give (401 and 403 when it needs a caller, 404 when its path names an id, 422 when it takes
parameters or a body, 503 always: the database away) plus those its route declared, each with the
:class:`Problem` schema.
"""

from __future__ import annotations

from http import HTTPStatus
from typing import Any

from pydantic import BaseModel, Field
from starlette.responses import JSONResponse

#: the media type of every error answer (RFC 7807 §6.1)
PROBLEM_MEDIA_TYPE = "application/problem+json"
#: the namespace of the problem types: ``urn:chakamo:problem:`` + a catalogue code
TYPE_PREFIX = "urn:chakamo:problem:"


class ProblemJSONResponse(JSONResponse):
    media_type = PROBLEM_MEDIA_TYPE


def title_of(status: int) -> str:
    try:
        return HTTPStatus(status).phrase
    except ValueError:
        return "Error"


def problem(status: int, detail: str, *, code: str | None = None, instance: str | None = None,
            **extensions: Any) -> dict[str, Any]:
    """The problem body (module docstring); ``extensions`` are added as they are (``params``, ``message``, …)."""
    body: dict[str, Any] = {"type": TYPE_PREFIX + code if code else "about:blank", "title": title_of(status),
                            "status": status, "detail": detail}
    if instance:
        body["instance"] = instance
    if code:
        body["code"] = code
    body.update(extensions)
    return body


def problem_response(status: int, detail: str, *, headers: dict[str, str] | None = None, **members: Any
                     ) -> ProblemJSONResponse:
    return ProblemJSONResponse(problem(status, detail, **members), status_code=status, headers=headers)


class Problem(BaseModel):
    """An error answer (RFC 7807): what went wrong and what to do, in English (``detail``) and es/en/pt
    (``message``)."""

    type: str = Field(description="urn:chakamo:problem:<code>, or about:blank when the answer has no code",
                      examples=["urn:chakamo:problem:request.file_type"])
    title: str = Field(description="the HTTP status' reason phrase", examples=["Unsupported Media Type"])
    status: int = Field(description="the HTTP status code", examples=[415])
    detail: str = Field(description="one sentence: what is wrong and what to do (English, or the request's "
                                    "Accept-Language for logins and accounts)")
    instance: str | None = Field(None, description="the path of the request refused")
    code: str | None = Field(None, description="the refusal's catalogue code (also in the X-ChakaMo-Code header)")
    params: dict[str, Any] | None = Field(None, description="the values the sentence names")
    message: dict[str, str] | None = Field(None, description="the sentence in es, en and pt")
    errors: list[dict[str, Any]] | None = Field(None, description="422 only: the validation errors, one per field")


#: what each status means, where a route did not say
DEFAULT_DESCRIPTIONS = {
    400: "the request is malformed (its sentence says what to change)",
    401: "no credentials, or an unknown, revoked or expired token (send Authorization: Bearer <token>)",
    403: "the token's role or scope is too low, or a browser request lacks its X-CSRF-Token",
    404: "no such id in your clinic (another clinic's ids answer the same)",
    409: "conflict with the current state (its sentence says which)",
    412: "If-Match names a version the row no longer has: read it again",
    413: "too large",
    415: "wrong media type",
    422: "the body or a parameter does not match the schema (errors lists each field)",
    428: "If-Match missing",
    500: "a stored file is damaged (a reference id for the administrator)",
    503: "the database or the job engine is not reachable, or the server is busy: nothing was changed; retry "
         "after Retry-After",
    507: "the server's disk is full: nothing was stored",
}


def document_errors(doc: dict[str, Any], prefix: str = "/api/v1") -> dict[str, Any]:
    """``doc`` (an OpenAPI document) with every error answer of the operations under ``prefix`` described by
    the :class:`Problem` schema (module docstring).  Changes ``doc`` in place and returns it."""
    schemas = doc.setdefault("components", {}).setdefault("schemas", {})
    schemas["Problem"] = Problem.model_json_schema(ref_template="#/components/schemas/{model}")
    for name in ("HTTPValidationError", "ValidationError"):
        schemas.pop(name, None)
    content = {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}}
    for path, item in doc.get("paths", {}).items():
        if not path.startswith(prefix):
            continue
        for method, op in item.items():
            if method not in ("get", "post", "put", "patch", "delete"):
                continue
            responses = op.setdefault("responses", {})
            wanted = {503}
            if op.get("security"):
                wanted |= {401, 403}
            if "{" in path:
                wanted.add(404)
            if op.get("parameters") or op.get("requestBody"):
                wanted.add(422)
            for status in wanted:
                responses.setdefault(str(status), {})
            for status, answer in responses.items():
                if status.isdigit() and int(status) >= 400:
                    answer["description"] = answer.get("description") or DEFAULT_DESCRIPTIONS.get(
                        int(status), title_of(int(status)))
                    if answer["description"] == "Validation Error":
                        answer["description"] = DEFAULT_DESCRIPTIONS[422]
                    answer["content"] = content
    return doc


__all__ = ["DEFAULT_DESCRIPTIONS", "PROBLEM_MEDIA_TYPE", "TYPE_PREFIX", "Problem", "ProblemJSONResponse",
           "document_errors", "problem", "problem_response", "title_of"]
