"""What every report reads: ``results.json`` plus the task's time series, and who the patient is.

Reports present; they compute nothing clinical.  The application (``app``) builds a :class:`ReportInput`
from its pipeline outcome; ``reports`` never imports ``app`` (DESIGN §2).  Angles are in **degrees**
here (reports are where degrees live); times in seconds from the task recording's start.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: angle keys, in the order of ``angles_deg`` columns (= results.json "angles")
ANGLES = ("flexion", "adduction", "internal_rotation")
LANGUAGES = ("es", "en", "pt")


@dataclass(frozen=True)
class Patient:
    """Patient and session facts typed by people (shown as text, never evaluated).

    Every field may be empty (unknown: the reports then leave it out, they never invent it).  ``name_or_id`` is a
    name or a pseudonymous ID; ``date`` the session's date as typed (ISO); ``weight_kg``/``height_m`` are numbers
    or None; ``step_height_m`` the step used (0.17 or 0.34 in the protocol).

    The identity every page carries (issue 17 §3): ``record_number`` the hospital's record number (the patient's
    external id) and ``record_system`` the URI of its identifier namespace; ``birth_date`` (ISO ``YYYY-MM-DD``),
    ``sex`` (``male``/``female``/``other``/``unknown``, FHIR's administrative gender), ``clinic`` the clinic's name;
    ``recorded`` the recordings' own date (ISO; from their time stamps, or the thesis file name's date), the first
    day and, when they span several, ``recorded_last`` the last.  The age printed is the whole years from
    ``birth_date`` to ``recorded`` (else to ``date``): :func:`reports.labels.age_years`.
    """

    name_or_id: str = ""
    date: str = ""
    professional: str = ""
    side: str = ""
    step_height_m: float | None = None
    weight_kg: float | None = None
    height_m: float | None = None
    observations: str = ""
    record_number: str = ""
    record_system: str = ""
    birth_date: str = ""
    sex: str = ""
    clinic: str = ""
    recorded: str = ""
    recorded_last: str = ""
    #: ``""`` when ``recorded`` is the recordings' local day, ``"UTC"`` when only UTC time stamps gave it
    recorded_zone: str = ""


@dataclass(frozen=True)
class Amendment:
    """One amendment of a signed interpretation: the text it replaced (``previous_text``), by whom (``by``, their
    role ``role``), when (ISO date-time, UTC) and why (``reason``)."""

    previous_text: str
    by: str
    role: str
    at: str
    reason: str


@dataclass(frozen=True)
class Interpretation:
    """The clinician's interpretation of the session and its sign-off, as stored (:mod:`app.store.interpretations`).

    ``text`` the current text; ``signed_by``/``signed_role``/``signed_at`` (ISO date-time, UTC) who signed it first;
    ``amendments`` oldest first, each keeping the text it replaced.  Only a signed interpretation is printed."""

    text: str
    signed_by: str
    signed_role: str
    signed_at: str
    amendments: tuple[Amendment, ...] = ()


@dataclass(frozen=True, eq=False)
class ReportInput:
    """Everything a report shows.

    results : the ``results.json`` dictionary (DESIGN §4: cycles, rom_deg, phases, curves, calibration,
        quality, filter, software...).
    t_s : (N,) task time, s.   angles_deg : (N, 3) flexion, adduction, internal rotation (clinical signs).
    q_earth_sensor : ``{"thigh"|"shank": (N, 4)}`` sensor orientations (w, x, y, z), ENU.
    q_earth_segment : ``{"femur"|"tibia": (N, 4)}`` segment orientations (ISB frames), ENU.
    q_sensor_segment : ``{"thigh"|"shank": (4,)}`` the sensor-to-segment calibrations.
    patient : :class:`Patient`.   language : ``es``, ``en`` or ``pt``.
    knees_series : a session of both knees: ``{"left"|"right": {"t_s": (M,), "angles_deg": (M, 3)}}`` (each knee's
        task grid; ``results["knees"]`` holds each knee's results); ``{}`` for one knee.
    """

    results: dict[str, Any]
    t_s: FloatArray
    angles_deg: FloatArray
    q_earth_sensor: dict[str, FloatArray]
    q_earth_segment: dict[str, FloatArray]
    q_sensor_segment: dict[str, FloatArray]
    patient: Patient = field(default_factory=Patient)
    language: str = "es"
    knees_series: dict[str, dict[str, FloatArray]] = field(default_factory=dict)
    interpretation: Interpretation | None = None

    def __post_init__(self) -> None:
        if self.language not in LANGUAGES:
            raise ValueError(f"language must be one of {', '.join(LANGUAGES)}, got {self.language!r}")
        n = len(self.t_s)
        if self.angles_deg.shape != (n, 3):
            raise ValueError(f"angles_deg must have shape ({n}, 3), got {self.angles_deg.shape}")
        for name, q in {**self.q_earth_sensor, **self.q_earth_segment}.items():
            if q.shape != (n, 4):
                raise ValueError(f"quaternions {name!r} must have shape ({n}, 4), got {q.shape}")

    @property
    def fs_hz(self) -> float:
        return float(1.0 / np.median(np.diff(self.t_s))) if len(self.t_s) > 1 else float("nan")

    def cycle_bounds_s(self) -> list[tuple[float | None, float | None, bool]]:
        """``(start_s, end_s, accepted)`` per detected cycle (None where a boundary is unknown)."""
        cycles = self.results["cycles"]
        accepted = set(cycles.get("accepted_indices", []))
        return [(b[0], b[1], i in accepted) for i, b in enumerate(cycles["boundaries_s"])]
