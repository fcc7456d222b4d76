r"""Reference values a clinician compares a session against (issue 15 §3): one published block per task.

Each reference is typed here by hand from its source (the numbers are *transcribed*, not computed), in the units
the source prints them (degrees, % of the cycle, seconds), with the source's population and conditions.  The
pipeline compares the session's means with them (:func:`compare`) and writes the result to ``results.json``
``reference``; the reports and the UI draw the bands and show the flags.

Interpretation of one parameter (R1), with the band :math:`[lo, hi]`::

    "L" if value < lo;  "H" if value > hi;  "N" otherwise;  None when the value or the band is missing

(the HL7 v3 ObservationInterpretation codes low / high / normal, so the FHIR export can carry them as they are).

Gait (``GAIT``)
---------------
J. Perry & J. M. Burnfield, *Gait Analysis: Normal and Pathological Function*, 2nd ed., SLACK 2010, Ch. 4
("Knee"): the knee's sagittal arc of normal adults walking at their free (self-selected) speed.  The ranges
below are the key values of that chapter's mean knee curve, as the simulator's docstring
(:mod:`estimators.simulation.gait`) already lists them with D. A. Winter, *Biomechanics and Motor Control of Human
Movement*, 4th ed., Wiley 2009, Appendix A (normal cadence) beside it: they are **ranges of the mean**, not
mean ± SD of a sample, and a value outside them is "outside the typical adult pattern", not a statistical test.

===================================  =============  =====================
parameter                            range          where in the cycle
===================================  =============  =====================
loading-response peak flexion        15–20°         12–15 %
stance minimum flexion               3–5°           ~40 %
swing peak flexion                   60–65°         70–73 %
toe-off (stance %)                   ~60 %          (58–62 % used here)
===================================  =============  =====================

ROM is taken as swing peak minus stance minimum (55–62°).  ChakaMo's flexion is zero at the standing knee (its
calibrations take the standing posture as straight), the reference's at the bones' alignment: a patient who stands
with the knee flexed by a few degrees reads that much lower against the angle values (not against ROM or timing);
the simulated walker stands at 2°, so simulated sessions read their stance minimum ~2° low (1.98° against 3–5°
in ``tests/app/pipeline/test_gait_session.py``'s session).  So only what does not depend on where zero is, the
flexion ROM, the swing-peak timing and the stance %, is flagged (R1); the three absolute angles are shown beside
their bands without a flag (``Band.flag`` False).  **Limits** (stated in ``results.json`` too): no SD, no
sample size or age for this transcription; the values were *not* checked against a second published table in
this change (Kadaba et al. 1990, J Orthop Res 8:383, n = 40 young adults, and Fukuchi et al. 2018, PeerJ 6:e4640,
are the candidates), and the simulator's mean curve is built on the same key values, so simulated sessions are
not an independent check of them.

Step-up (``STEP_UP``)
---------------------
The source thesis' own measurement (seed 004 §8.7.3–8.7.4, Tables 8.1–8.4): **one subject**, 10 step-ups of
which 8 were averaged, at 17 cm and at 34 cm; MetaMotionR sensors, the thesis' own pipeline and its ZYX angles.
A *single-study* reference, labelled as such and **never flagged**: one subject's SD over its own cycles is no
spread of a population (its mean ± 2 SD, 3.36–3.40 s at 17 cm, flagged the simulated patient's correct 3.37 s
cycle "L"), so every value (cycle time, phase %, flexion ROM, maximum, minimum) is the subject's mean shown beside
the session's, without a band or L/N/H (the SD stays in ``results.json`` where the table gives one).  Table 8.1 (17 cm): cycle 3.38 ± 0.01 s; impulse 34.02 ±
0.89 %, extension 31.66 ± 2.96 %, fall 34.02 ± 2.07 %.  Table 8.3 (34 cm): cycle 3.54 ± 0.07 s; impulse
33.33 ± 1.13 %, extension 32.77 ± 2.26 %, fall 33.90 ± 1.13 %.  Tables 8.2 / 8.4: flexion range 81.96° / 115.16°,
maximum 82.96° / 111.16°, minimum 0.80° / −3.72° (the thesis' own table; its 34 cm range is not max − min,
transcribed as printed).  The step height picks the table (nearest of 0.17 and 0.34 m).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

__all__ = ["GAIT", "STEP_UP", "Band", "KeyPoint", "Reference", "compare", "interpretation", "reference_for"]


@dataclass(frozen=True)
class Band:
    """One parameter's reference: ``low``–``high`` (the band), and the source's ``mean``/``sd`` where it gives them.

    unit : ``"deg"``, ``"pct"`` (% of the cycle) or ``"s"``.   flag : False when the band is only shown (no SD)."""

    low: float | None
    high: float | None
    unit: str
    mean: float | None = None
    sd: float | None = None
    flag: bool = True


@dataclass(frozen=True)
class KeyPoint:
    """A range of the mean flexion curve at a place in the cycle (drawn on the curve figures): % and degrees."""

    name: str
    pct_low: float
    pct_high: float
    low_deg: float
    high_deg: float


@dataclass(frozen=True)
class Reference:
    """One task's reference: where it comes from, who was measured, and the bands per parameter."""

    id: str    # names the reference in results.json (the reports translate its texts by it)
    task: str
    kind: str  # "normative" (a published population) or "single_study" (one study's own subject)
    source: str
    population: str
    conditions: str
    transcription: str
    parameters: Mapping[str, Band]
    keypoints: tuple[KeyPoint, ...] = field(default_factory=tuple)


GAIT = Reference(
    id="gait_perry_winter", task="gait", kind="normative",
    source="J. Perry, J. M. Burnfield, Gait Analysis: Normal and Pathological Function, 2nd ed., SLACK 2010, "
           "Ch. 4 (knee); with D. A. Winter, Biomechanics and Motor Control of Human Movement, 4th ed., Wiley 2009, "
           "Appendix A (normal cadence)",
    population="normal adults (n and ages not part of this transcription)",
    conditions="level walking at free (self-selected) speed",
    transcription="key values of the published mean knee curve, typed by hand as ranges of the mean (no SD); "
                  "not checked against a second published table; ChakaMo reads flexion from the standing knee (0°), "
                  "the reference from the bones, so a patient who stands flexed reads that much lower: the absolute "
                  "angles are shown without a flag, only the ROM and the timing percentages are flagged",
    parameters={
        "loading_response_peak_flexion_deg": Band(15.0, 20.0, "deg", flag=False),
        "stance_min_flexion_deg": Band(3.0, 5.0, "deg", flag=False),
        "swing_peak_flexion_deg": Band(60.0, 65.0, "deg", flag=False),
        "flexion_rom_deg": Band(55.0, 62.0, "deg"),
        "swing_peak_timing_pct": Band(70.0, 73.0, "pct"),
        "stance_pct": Band(58.0, 62.0, "pct"),
    },
    keypoints=(KeyPoint("loading_response_peak", 12.0, 15.0, 15.0, 20.0),
               KeyPoint("stance_min", 38.0, 42.0, 3.0, 5.0),
               KeyPoint("swing_peak", 70.0, 73.0, 60.0, 65.0)),
)


def _shown(mean: float, sd: float | None, unit: str) -> Band:
    """A single-study value: the subject's mean (and SD over its own cycles) shown without a band or a flag.  One
    subject's cycle-to-cycle SD is no population spread (its ± 2 SD "band" of 3.36–3.40 s flagged the simulated
    patient's 3.37 s cycle "L"), so nothing is judged against it."""
    return Band(None, None, unit, mean, sd, False)


_THESIS = dict(
    kind="single_study", task="step_up",
    population="one subject (the thesis' own measurement), 8 of 10 cycles averaged",
    source="source thesis (seed 004), §8.7.3–8.7.4, Tables 8.1–8.4",
    transcription="typed by hand from the thesis' tables; one subject's means, shown beside the session's values "
                  "without a band or a flag: one subject's spread over its own cycles is no range of normal")

STEP_UP = {
    0.17: Reference(
        id="step_up_thesis_17cm", conditions="single-leg step-up, 17 cm step", **_THESIS,
        parameters={"cycle_s": _shown(3.38, 0.01, "s"), "impulse_pct": _shown(34.02, 0.89, "pct"),
                    "extension_pct": _shown(31.66, 2.96, "pct"), "fall_pct": _shown(34.02, 2.07, "pct"),
                    "flexion_rom_deg": _shown(81.96, None, "deg"),
                    "flexion_max_deg": _shown(82.96, None, "deg"),
                    "flexion_min_deg": _shown(0.80, None, "deg")}),
    0.34: Reference(
        id="step_up_thesis_34cm", conditions="single-leg step-up, 34 cm step", **_THESIS,
        parameters={"cycle_s": _shown(3.54, 0.07, "s"), "impulse_pct": _shown(33.33, 1.13, "pct"),
                    "extension_pct": _shown(32.77, 2.26, "pct"), "fall_pct": _shown(33.90, 1.13, "pct"),
                    "flexion_rom_deg": _shown(115.16, None, "deg"),
                    "flexion_max_deg": _shown(111.16, None, "deg"),
                    "flexion_min_deg": _shown(-3.72, None, "deg")}),
}


def reference_for(task: str, step_height_m: float | None = None) -> Reference | None:
    """The reference of ``task`` (None when there is none): the step-up's table nearest ``step_height_m``
    (17 cm when the height is unknown)."""
    if task == "gait":
        return GAIT
    if task == "step_up":
        h = 0.17 if step_height_m is None or not math.isfinite(step_height_m) else float(step_height_m)
        return STEP_UP[min(STEP_UP, key=lambda k: abs(k - h))]
    return None


def interpretation(value: float | None, band: Band) -> str | None:
    """R1 (module docstring): ``"L"``, ``"H"``, ``"N"``, or None (no value, no band, or a band that is only shown)."""
    if value is None or not math.isfinite(value) or not band.flag or band.low is None or band.high is None:
        return None
    return "L" if value < band.low else "H" if value > band.high else "N"


def compare(ref: Reference, values: Mapping[str, float | None]) -> dict:
    """``results.json`` ``reference`` block: the source facts and, per parameter of ``ref``, the session's value
    (``values``, in the band's unit; missing → None), the band, ``interpretation`` (R1) and ``within_band``
    (True / False, or None when not flagged)."""
    params = {}
    for name, band in ref.parameters.items():
        v = values.get(name)
        v = None if v is None or not math.isfinite(float(v)) else float(v)
        code = interpretation(v, band)
        params[name] = {"value": v, "low": band.low, "high": band.high, "mean": band.mean, "sd": band.sd,
                        "unit": band.unit, "interpretation": code, "within_band": None if code is None else code == "N"}
    return {"id": ref.id, "task": ref.task, "kind": ref.kind, "source": ref.source, "population": ref.population,
            "conditions": ref.conditions, "transcription": ref.transcription, "parameters": params,
            "outside": sorted(k for k, p in params.items() if p["within_band"] is False),
            "keypoints": [{"name": k.name, "pct": [k.pct_low, k.pct_high], "deg": [k.low_deg, k.high_deg]}
                          for k in ref.keypoints]}
