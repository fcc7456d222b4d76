"""Every option list of the product, defined once: the CLI's ``choices``, the API's schemas and
``GET /api/v1/options``, and through that answer the browser's menus, all read them from here.

Where a list belongs to a lower layer it is taken from there, never typed again:

* filters — :data:`estimators.orientation.METHOD_INFO` (the estimator registry; default
  :data:`estimators.orientation.DEFAULT_METHOD`);
* tasks — :data:`estimators.motor_task.TASK_INFO` (the motor-task registry; default ``step_up``);
* languages — :data:`reports.i18n.LANGUAGES` (the languages the reports are written in; default ``es``);
* calibrations, angle conventions, headings, sides, user roles — here.

Each option is a :class:`Choice` (``name``, an English ``label`` the UI may translate by name, ``default``);
``*_NAMES`` are the bare names in the same order.  This module imports neither numpy nor numba: the CLI's
``--help`` and the API's option list cost no numerics.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from estimators.motor_task.registry import TASK_INFO
from estimators.orientation import DEFAULT_METHOD, METHOD_INFO
from reports.i18n import LANGUAGES as _REPORT_LANGUAGES


@dataclass(frozen=True)
class Choice:
    """One option: ``name`` (the value sent and stored), ``label`` (English, for people), ``default``."""

    name: str
    label: str
    default: bool = False


def _choices(pairs: tuple[tuple[str, str], ...], default: str) -> tuple[Choice, ...]:
    names = [n for n, _ in pairs]
    if default not in names:
        raise ValueError(f"default {default!r} is not one of {names}")
    return tuple(Choice(n, label, n == default) for n, label in pairs)


def names(choices: tuple[Choice, ...]) -> tuple[str, ...]:
    """The names of ``choices``, in order."""
    return tuple(c.name for c in choices)


def default(choices: tuple[Choice, ...]) -> str:
    """The name of the default choice."""
    return next(c.name for c in choices if c.default)


FILTERS = _choices(tuple((m.name, m.label) for m in METHOD_INFO), DEFAULT_METHOD)
TASKS = _choices(tuple((t.name, t.label) for t in TASK_INFO), "step_up")
_LANGUAGE_LABELS = {"es": "Español", "en": "English", "pt": "Português"}
LANGUAGES = _choices(tuple((code, _LANGUAGE_LABELS.get(code, code)) for code in _REPORT_LANGUAGES), "es")
CALIBRATIONS = _choices((("static", "Standing + supine postures"),
                         ("functional", "Standing + the knee's flexion axis on the task")), "static")
ANGLE_CONVENTIONS = _choices((("grood_suntay", "Grood & Suntay (clinical)"),
                              ("thesis_zyx", "Thesis ZYX Euler angles")), "grood_suntay")
#: the thigh–shank heading (:mod:`estimators.heading`; ``auto`` takes the joint constraint's when the
#: magnetometers disagree with it)
HEADINGS = _choices((("auto", "Automatic (magnetometer, or the knee's hinge constraint when they disagree)"),
                     ("magnetometer", "Magnetometers"),
                     ("constraint", "The knee's hinge constraint (no magnetometer)")), "auto")
SIDES = _choices((("right", "Right"), ("left", "Left")), "right")
#: user roles, highest first (``app.web.security.ROLE_RANK`` ranks them; the database stores the names)
USER_ROLES = _choices((("admin", "Administrator"), ("clinician", "Clinician"), ("read_only", "Read only")),
                      "clinician")

#: what an API token may touch within its role (``chakamo tokens create --scope``; none given: everything its role
#: allows): a resource and ``read`` (GET) or ``write`` (POST, PATCH, DELETE); ``results`` covers the downloads
TOKEN_SCOPE_RESOURCES: tuple[str, ...] = ("patients", "sessions", "recordings", "jobs", "results", "fhir", "audit",
                                          "users")
TOKEN_SCOPES: tuple[str, ...] = tuple(f"{r}:{a}" for r in TOKEN_SCOPE_RESOURCES for a in ("read", "write"))

#: a patient's measurements the product accepts: open intervals ``(low, high)`` (the API's schemas, the store's
#: check and the patient form, which reads them from ``GET /options``)
MEASURE_RANGES: dict[str, tuple[float, float]] = {"height_cm": (30.0, 260.0), "mass_kg": (2.0, 400.0)}
#: an API token's longest lifetime, days (``chakamo tokens create --days``, ``POST /tokens``, the admin page)
TOKEN_MAX_DAYS = 3650

#: ``chakamo markov --method`` (research: not in GET /options)
MARKOV_METHODS: tuple[str, ...] = ("auto", "mjls", "kf", "sme", "smea")

FILTER_NAMES = names(FILTERS)
TASK_NAMES = names(TASKS)
LANGUAGE_NAMES = names(LANGUAGES)
CALIBRATION_NAMES = names(CALIBRATIONS)
HEADING_NAMES = names(HEADINGS)
ANGLE_CONVENTION_NAMES = names(ANGLE_CONVENTIONS)
SIDE_NAMES = names(SIDES)
#: a patient's sex as FHIR's administrative gender takes it
SEX_NAMES = ("male", "female", "other", "unknown")
USER_ROLE_NAMES = names(USER_ROLES)

DEFAULT_FILTER = default(FILTERS)
DEFAULT_TASK = default(TASKS)
DEFAULT_LANGUAGE = default(LANGUAGES)
DEFAULT_CALIBRATION = default(CALIBRATIONS)
DEFAULT_HEADING = default(HEADINGS)
DEFAULT_ANGLE_CONVENTION = default(ANGLE_CONVENTIONS)

#: the lists ``GET /api/v1/options`` answers with, by key
OPTION_LISTS: dict[str, tuple[Choice, ...]] = {
    "filters": FILTERS, "tasks": TASKS, "languages": LANGUAGES, "calibrations": CALIBRATIONS,
    "angle_conventions": ANGLE_CONVENTIONS, "headings": HEADINGS, "sides": SIDES,
}


def options() -> dict[str, list[dict[str, Any]]]:
    """The answer of ``GET /api/v1/options``: ``{"filters": [{"name", "label", "default"}], "tasks": [...], ...}``;
    a task also lists its ``phases`` (in time order)."""
    out = {key: [asdict(c) for c in choices] for key, choices in OPTION_LISTS.items()}
    phases = {t.name: list(t.phases) for t in TASK_INFO}
    for task in out["tasks"]:
        task["phases"] = phases[task["name"]]
    return out


__all__ = ["ANGLE_CONVENTIONS", "ANGLE_CONVENTION_NAMES", "CALIBRATIONS", "CALIBRATION_NAMES", "Choice",
           "DEFAULT_ANGLE_CONVENTION", "DEFAULT_CALIBRATION", "DEFAULT_FILTER", "DEFAULT_HEADING", "DEFAULT_LANGUAGE", "DEFAULT_TASK",
           "FILTERS", "FILTER_NAMES", "HEADINGS", "HEADING_NAMES", "LANGUAGES", "LANGUAGE_NAMES", "MARKOV_METHODS", "MEASURE_RANGES", "OPTION_LISTS", "SIDES", "SIDE_NAMES", "TASKS",
           "TASK_NAMES", "TOKEN_MAX_DAYS", "TOKEN_SCOPES", "TOKEN_SCOPE_RESOURCES", "USER_ROLES", "USER_ROLE_NAMES", "default", "names", "options"]
