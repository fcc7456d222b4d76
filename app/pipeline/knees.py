"""Both knees of one patient: each processed as its own session, and the limb symmetry index between them.

A session holds one knee (two sensors) or both (four sensors, or two one-knee sessions paired:
:func:`app.pipeline.ingestion.load_knees`).  Each knee goes through :func:`app.pipeline.session.process_session`
with its own side, so its adduction and rotation take that side's clinical sign (the left leg mirrored,
DESIGN §3).

Limb symmetry index (LSI), per parameter :math:`p` with the involved side chosen by the clinician:

.. math::  \\mathrm{LSI}(p) = 100\\,\\% \\times p_{\\mathrm{involved}} / p_{\\mathrm{uninvolved}}

as the knee literature defines it for strength and hop tests (e.g. Noyes, Barber & Mangine, Am J Sports Med
19:513, 1991; ≥ 85–90 % is the usual return-to-sport threshold) and as commercial gait systems report it per
parameter.  It is taken only on parameters that are magnitudes far from zero *and* measured with an error small against them (flexion peaks
and range, time fractions, stride time, cadence).  A ratio of two values near zero (stance minimum flexion
~3–5°, the extension a knee reaches ~0°) says nothing about symmetry; nor does one of the adduction or rotation
ranges: in walking they span 4–10°, against 1.5–2° of measurement error per knee (issue 13's held-out worst),
so their ratio can read anything from 50 % to 200 % on two identical knees (a simulated walk with the left
flexion at 80 % read adduction 196 % and rotation 51 %, truth 100 % and 80 %): those are left out.  Each knee's value is its
mean over its accepted cycles (``results.json`` ``rom_deg`` and ``gait.parameters``); an LSI is ``None`` when a
value is missing or the uninvolved one is not positive.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from app.pipeline.comparison import at, number
from app.pipeline.ingestion import Session
from app.pipeline.session import PipelineError, Progress, ProcessOptions, SessionOutcome, _no_progress, process_session

#: the parameters of the tasks other than gait: ``(name, path in one knee's results.json, unit)``
LSI_COMMON: tuple[tuple[str, tuple[str, ...], str], ...] = (
    ("flexion_max", ("rom_deg", "flexion", "max", "mean"), "deg"),
    ("flexion_range", ("rom_deg", "flexion", "range", "mean"), "deg"),
)
#: the gait task's (its own flexion peaks and ROM, timing), in report order
LSI_GAIT: tuple[tuple[str, tuple[str, ...], str], ...] = tuple(
    (name, ("gait", "parameters", f"{name}_{unit}", "mean"), unit) for name, unit in (
        ("loading_response_peak_flexion", "deg"), ("swing_peak_flexion", "deg"), ("flexion_rom", "deg"),
        ("swing_peak_timing", "pct"), ("stance", "pct"), ("swing", "pct"), ("stride_time", "s"),
        ("cadence", "steps_min")))


@dataclass(frozen=True, eq=False)
class KneesOutcome:
    """The outcome of every knee of a session.

    knees : ``{side: SessionOutcome}`` (one entry for a one-knee session).
    involved : the side the clinician chose as involved (or the patient's side), None when not known.
    """

    knees: dict[str, SessionOutcome]
    involved: str | None

    @property
    def primary(self) -> SessionOutcome:
        """The knee ``results.json``'s top level describes: the involved one, else the only one, else the right."""
        if self.involved in self.knees:
            return self.knees[self.involved]
        return self.knees.get("right") or next(iter(self.knees.values()))

    @property
    def bilateral(self) -> bool:
        return len(self.knees) == 2


def process_knees(knees: Mapping[str, Session], options: ProcessOptions | None = None, *,
                  progress: Progress = _no_progress, web: bool = False) -> KneesOutcome:
    """Process each knee of ``knees`` (:func:`app.pipeline.ingestion.load_knees`) with its own side.

    With two knees the side comes from each knee's recordings (``options.side`` would give both the same sign:
    refused); ``options.involved`` (else the session's ``side``: the patient's, in ``session.json``) picks the
    involved knee.  With one knee, everything is as :func:`process_session`.  ``options.exclusions`` (cycles the
    clinician excluded) go each to its knee; with two knees each must name one.  ``web``: the caller is the web
    application, whose refusal of ``options.side`` names its form and request fields, not the CLI's options.
    """
    options = options or ProcessOptions()
    if len(knees) == 1:
        outcome = process_session(next(iter(knees.values())), options, progress=progress)
        return KneesOutcome({outcome.side: outcome}, options.involved or None)
    if options.side is not None:
        raise PipelineError("pipeline.side_with_two_knees.web" if web else "pipeline.side_with_two_knees",
                            side=options.side)
    if (nameless := next((e for e in options.exclusions if e.knee is None), None)) is not None:
        raise PipelineError("pipeline.exclude_no_knee", cycle=nameless.cycle)
    out: dict[str, SessionOutcome] = {}
    for i, (side, session) in enumerate(sorted(knees.items())):
        def part(stage: str, fraction: float, i: int = i, side: str = side) -> None:
            progress(f"{side} {stage}", 0.96 * (i + fraction) / 2.0)

        mine = replace(options, exclusions=tuple(e for e in options.exclusions if e.knee == side))
        out[side] = process_session(session, mine, progress=part)
    involved = options.involved or _patient_side(knees)
    return KneesOutcome(out, involved)


def _patient_side(knees: Mapping[str, Session]) -> str | None:
    """The patient's side of a two-knee session (``session.json``'s ``side``, as the web application writes it):
    :attr:`Session.patient_side`, kept by :func:`app.pipeline.ingestion.load_knees` apart from each knee's own."""
    return next((s.patient_side for s in knees.values() if s.patient_side is not None), None)


def lsi_parameters(task: str) -> tuple[tuple[str, tuple[str, ...], str], ...]:
    """The LSI parameters of ``task``: :data:`LSI_GAIT` for gait, :data:`LSI_COMMON` for the other tasks."""
    return LSI_GAIT if task == "gait" else LSI_COMMON


def limb_symmetry(knees: Mapping[str, Mapping[str, Any]], involved: str | None) -> dict[str, Any] | None:
    """``results.json`` ``symmetry`` from each knee's results: ``{"involved", "uninvolved", "parameters": [{"name",
    "unit", "involved", "uninvolved", "lsi_pct"}]}`` (module docstring), None without two knees and an involved side."""
    if len(knees) != 2 or involved not in knees:
        return None
    uninvolved = next(side for side in knees if side != involved)
    task = knees[involved].get("task", "")
    rows = []
    for name, path, unit in lsi_parameters(task):
        a, b = number(at(knees[involved], *path)), number(at(knees[uninvolved], *path))
        lsi = 100.0 * a / b if a is not None and b is not None and b > 0.0 else None
        rows.append({"name": name, "unit": unit, "involved": a, "uninvolved": b, "lsi_pct": lsi})
    return {"involved": involved, "uninvolved": uninvolved, "parameters": rows}


__all__ = ["KneesOutcome", "LSI_COMMON", "LSI_GAIT", "limb_symmetry", "lsi_parameters", "process_knees"]
