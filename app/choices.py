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

#: The live checks' own thresholds, for what the pipeline has no counterpart of (the rest of :func:`live_checks` is
#: the pipeline's): a step-up cycle is counted live when one segment's rate about its main axis, averaged over
#: LIVE_CYCLE_AVERAGE_S, rises above LIVE_CYCLE_RISE_RAD_S (60 °/s) after having fallen below LIVE_CYCLE_FALL_RAD_S
#: (20 °/s); the pipeline finds cycles on the knee's flexion angle (estimators.motor_task), which the browser does
#: not compute before the task's end, so the live count only predicts it (shown as approximate);
LIVE_CYCLE_AVERAGE_S = 0.3
LIVE_CYCLE_RISE_RAD_S = 1.0471975511965976      # 60 °/s
LIVE_CYCLE_FALL_RAD_S = 0.3490658503988659      # 20 °/s
#: and a magnetometer sample nearer than this to the live hard-iron estimate (the centre of the box the samples span so
#: far) gives no direction worth binning: the pipeline bins directions after its ellipsoid fit, which the browser does
#: not make, so live coverage only predicts the pipeline's (the Earth's field is 25–65 µT; a still sensor's samples
#: sit within their noise of their own box's centre).
LIVE_MIN_FIELD_UT = 15.0

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


def live_checks() -> dict[str, dict[str, float | int]]:
    """The thresholds of the recording page's live checks (``static/metawear/checks.js``), served in
    ``GET /options`` as ``live_checks`` so that the browser holds no copy of a number the pipeline judges by:

    * ``stillness`` (postures): the pipeline's still window and limits — ``window_s`` of
      :class:`estimators.knee.CalibrationParams` (5 s), ``max_gyr_sd_rad_s`` and ``max_acc_sd_m_s2``
      (:data:`estimators.knee.STILL_MAX_GYR_SD_RAD_S`, ``STILL_MAX_ACC_SD_M_S2``), the total SD over the window with
      ddof 1 as :func:`estimators.knee.stillest_window`: live "still" is exactly the pipeline's condition on the last
      ``window_s``, so a posture that was still live has the still window the calibration needs;
    * ``coverage`` (figure-eight): the pipeline's ``min_cell_samples`` per cell (of the same 20 cells) and the share of
      cells below which it warns, ``complete_fraction`` (:data:`estimators.magnetometer.MIN_CELL_SAMPLES`, ``COVERAGE_WARN``), with the
      live-only ``min_field_ut`` (:data:`LIVE_MIN_FIELD_UT`: the live directions are only hard-iron-corrected);
    * ``cycles`` (task): live-only, ``average_s``, ``rise_rad_s``, ``fall_rad_s`` (:data:`LIVE_CYCLE_RISE_RAD_S`...:
      a prediction of the pipeline's cycles, which it finds on the knee angle).

    Imported here, not at the top: this module stays free of numpy for the CLI's ``--help``."""
    from estimators import knee, magnetometer

    still = knee.CalibrationParams()
    return {
        "stillness": {"window_s": still.window_s, "max_gyr_sd_rad_s": still.max_gyr_sd_rad_s,
                      "max_acc_sd_m_s2": still.max_acc_sd_m_s2},
        "coverage": {"min_cell_samples": magnetometer.MIN_CELL_SAMPLES,
                     "complete_fraction": magnetometer.COVERAGE_WARN, "min_field_ut": LIVE_MIN_FIELD_UT},
        "cycles": {"average_s": LIVE_CYCLE_AVERAGE_S, "rise_rad_s": LIVE_CYCLE_RISE_RAD_S,
                   "fall_rad_s": LIVE_CYCLE_FALL_RAD_S},
    }


__all__ = ["ANGLE_CONVENTIONS", "ANGLE_CONVENTION_NAMES", "CALIBRATIONS", "CALIBRATION_NAMES", "Choice",
           "DEFAULT_ANGLE_CONVENTION", "DEFAULT_CALIBRATION", "DEFAULT_FILTER", "DEFAULT_HEADING", "DEFAULT_LANGUAGE", "DEFAULT_TASK",
           "FILTERS", "FILTER_NAMES", "HEADINGS", "HEADING_NAMES", "LANGUAGES", "LANGUAGE_NAMES", "LIVE_CYCLE_AVERAGE_S",
           "LIVE_CYCLE_FALL_RAD_S", "LIVE_CYCLE_RISE_RAD_S", "LIVE_MIN_FIELD_UT", "MARKOV_METHODS", "MEASURE_RANGES", "OPTION_LISTS", "SIDES", "SIDE_NAMES", "TASKS",
           "TASK_NAMES", "TOKEN_MAX_DAYS", "TOKEN_SCOPES", "TOKEN_SCOPE_RESOURCES", "USER_ROLES", "USER_ROLE_NAMES", "default", "live_checks", "names", "options"]
