"""``/options``: every option list of the product (:func:`app.choices.options`), for any authenticated caller.

The browser builds its menus (filters, tasks, languages, calibrations, angle conventions, sides) from this
answer, and the CLI's choices and the API's schemas come from the same :mod:`app.choices`, so a filter or a
task added to its estimator registry appears in every layer at once.  Two plain name lists ride along for the
patient form and the admin pages: ``sexes`` (:data:`app.choices.SEX_NAMES`), ``measure_ranges``
(:data:`app.choices.MEASURE_RANGES`, ``{"height_cm": {"min", "max"}}``, both excluded), ``roles``
(:data:`app.choices.USER_ROLE_NAMES`), ``token_scopes`` (:data:`app.choices.TOKEN_SCOPES`), ``token_max_days``
(:data:`app.choices.TOKEN_MAX_DAYS`), ``audit_actions`` (:data:`app.web.audit.ACTIONS`, the audit log's filter) and
``live_checks`` (:func:`app.choices.live_checks`: the recording page's live checks' thresholds, the pipeline's).
"""

from fastapi import APIRouter

from app.choices import MEASURE_RANGES, SEX_NAMES, TOKEN_MAX_DAYS, TOKEN_SCOPES, USER_ROLE_NAMES, live_checks
from app.choices import options as option_lists
from app.web.audit import ACTIONS
from app.web.api.deps import Reader
from app.web.api.schemas import OptionsOut

router = APIRouter(tags=["options"])


@router.get("/options", response_model=OptionsOut)
def options(principal: Reader):
    return option_lists() | {"sexes": list(SEX_NAMES), "token_scopes": list(TOKEN_SCOPES), "audit_actions": list(ACTIONS),
                             "measure_ranges": {k: {"min": lo, "max": hi} for k, (lo, hi) in MEASURE_RANGES.items()},
                             "roles": list(USER_ROLE_NAMES), "token_max_days": TOKEN_MAX_DAYS,
                             "live_checks": live_checks()}
