"""The data layer's refusals: small exception classes whose message is the sentence the user reads.

The store and jobs services raise them; they know nothing of HTTP.  The API maps each class to one status
code in one place (:data:`app.web.api.deps.STATUS_OF`, applied to every route by :func:`app.web.api.api_router`):
:class:`NotFound` 404 (also for another clinic's ids), :class:`Conflict` 409, :class:`Invalid` 400,
:class:`LimitExceeded` 413, :class:`PreconditionFailed` 412.
"""

from __future__ import annotations


class DomainError(Exception):
    """A request the data cannot satisfy; ``str(error)`` says what is wrong and what to do.  ``message_code`` and
    ``params``, when set, name its es/en/pt sentence (``app.web.refusals``; ``detail`` is then its English)."""

    message_code: str | None = None

    def __init__(self, detail: str, **params) -> None:
        super().__init__(detail)
        self.detail, self.params = detail, params


class NotFound(DomainError):
    """An unknown id, or another clinic's (the same answer, so ids of other clinics cannot be probed).
    ``owner_clinic_id`` is the clinic that does own the id, when another one does (for its audit log only)."""

    def __init__(self, detail: str, owner_clinic_id: int | None = None) -> None:
        super().__init__(detail)
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
