"""The data layer's refusals: small exception classes whose message is the sentence the user reads.

The store and jobs services raise them; they know nothing of HTTP.  The API maps each class to one status
code in one place (:data:`app.web.api.deps.STATUS_OF`, applied to every route by :func:`app.web.api.api_router`):
:class:`NotFound` 404 (also for another clinic's ids), :class:`Conflict` 409, :class:`Invalid` 400,
:class:`LimitExceeded` 413, :class:`PreconditionFailed` 412.
"""

from __future__ import annotations

from typing import Any


class DomainError(Exception):
    """A request the data cannot satisfy; ``str(error)`` says what is wrong and what to do.

    ``DomainError(code=..., **params)``: the sentence is entry ``code`` of
    :data:`app.pipeline.service_messages.CATALOGUE` or of the ingestion's (English here; the API answers it in es/en/pt, issue 14 §5).
    A bare ``detail`` is English only: ``tests/app/pipeline/test_check_messages.py`` refuses one in the store."""

    def __init__(self, detail: str | None = None, *, code: str | None = None, **params: Any) -> None:
        self.code, self.params = code, params
        detail = self.message("en") if code is not None else detail
        super().__init__(detail)
        self.detail = detail

    def message(self, lang: str = "en") -> str:
        """The sentence in ``lang`` (es/en/pt): entry ``code`` of the service table, else of the ingestion's (a
        file's refusal passed on); a bare ``detail`` as it is (``chakamo`` prints it in ``--lang``:
        :func:`app.cli.main.main`)."""
        if self.code is None:
            return self.detail
        from app.pipeline.ingestion.messages import render as ingestion_render
        from app.pipeline.service_messages import CATALOGUE, render

        if self.code in CATALOGUE:
            return render(self.code, self.params, lang)
        return ingestion_render(self.code, self.params, lang)


class NotFound(DomainError):
    """An unknown id, or another clinic's (the same answer, so ids of other clinics cannot be probed).
    ``owner_clinic_id`` is the clinic that does own the id, when another one does (for its audit log only)."""

    def __init__(self, detail: str | None = None, owner_clinic_id: int | None = None, *, code: str | None = None,
                 **params: Any) -> None:
        super().__init__(detail, code=code, **params)
        self.owner_clinic_id = owner_clinic_id


class Conflict(DomainError):
    """The data's current state forbids the change (a duplicate, a session being processed, files not ready)."""


class Invalid(DomainError):
    """Input the data layer refuses (e.g. the same file twice in one upload)."""


class LimitExceeded(DomainError):
    """More than a configured limit allows (e.g. files per session)."""


class PreconditionFailed(DomainError):
    """The caller's ``If-Match`` names a version the row no longer has (someone changed it meanwhile)."""


__all__ = ["Conflict", "DomainError", "Invalid", "LimitExceeded", "NotFound", "PreconditionFailed"]
