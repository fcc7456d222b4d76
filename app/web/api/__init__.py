"""API v1 (``/api/v1``): one router per resource; :func:`api_router` assembles them.

Errors are ``{"detail": "<one sentence: what is wrong, what to do>"}`` with honest codes: 400 bad input,
401 not logged in, 403 role too low or CSRF, 404 unknown id *or another clinic's id*, 409 conflict, 412 a stale
``If-Match``, 413 too large, 415 wrong type, 422 validation, 428 ``If-Match`` required (erasures, :mod:`app.web.records`).  ``../shared/DESIGN.md`` §4 has the hospital minimum; ``/docs`` the
whole API.
Shared pieces: :mod:`.deps` (caller, roles, clinic scoping, CSRF), :mod:`.schemas` (shapes); reads and
changes of patient data are recorded by :mod:`app.web.audit` and listed by :mod:`.audit` (admins).

Routers only parse, authorise, call :mod:`app.store` and :mod:`app.jobs` services, record audit events and
answer; the services' refusals (:mod:`app.store.errors`) get their status codes in one place,
:func:`app.web.api.deps.domain_errors`, a dependency of every route below.
"""

from fastapi import APIRouter, Depends


def api_router() -> APIRouter:
    """All routers of API v1 under ``/api/v1``, each route wrapped by :func:`.deps.domain_errors`."""
    from app.web.api import (artefacts, audit, auth, clinics, fhir, interpretations, jobs, options, patients,
                             recordings, results, sessions, tokens, users, webhooks)
    from app.web.api.deps import domain_errors

    router = APIRouter(prefix="/api/v1", dependencies=[Depends(domain_errors, scope="function")])
    for module in (auth, options, clinics, users, tokens, patients, sessions, recordings, jobs, results, artefacts,
                   fhir, audit, webhooks, interpretations):
        router.include_router(module.router)
    return router


__all__ = ["api_router"]
