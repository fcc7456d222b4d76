r"""Why a knee session reads wrong: swapped sensors, an upside-down sensor, a lost heading, a disturbed field.

Four causes produce implausible or wrong knee angles and call for opposite actions.  Each is told apart by
its own evidence in the data, and each has its own warning code:

======================== ===================================================== ============ =====================
code                     evidence                                              clinician    what ChakaMo does
                                                                               can fix it?
======================== ===================================================== ============ =====================
``sensors_swapped``      flexion below −15° in > 20 % of the task (D1), the    yes          refuse, with advice
                         hinge heading consistent (D3 not met), both sensors
                         upright (D2 not met), and the *exchanged* pair reads
                         plausible flexion: a swap turns q_femur_tibia into
                         its inverse (flexion → −flexion), nothing else does
``sensor_upside_down_    D1, and the mean specific force over the task is      yes          refuse, with advice
task``                   more than 90° from the sensor axis the protocol
                         expects up (D2): the calibration did not undo it
``heading_lost``         the 9D relative heading is more than 90° off the      no           correct with the
                         knee's hinge constraint in ≥ 10 % of the task's       (a filter    constraint heading,
                         samples (δ(t), D3): a local field bends a heading     diverged)    warn
                         by tens of degrees, a filter that lost its heading
                         sits anywhere (140–180° on the real clip of issue 13)
``magnetic_field_        the magnetometers stray from the constraint by more   no           correct with the
disturbed``              than 6° (more than a tilt makes), nowhere 90° (D4)    (the room)   constraint heading,
                                                                                            warn
======================== ===================================================== ============ =====================

(D1) is :func:`estimators.knee.task_warnings`; (D2) :math:`\angle(\bar f_{task}, \hat u) > 90°` with
:math:`\hat u` the expected-up sensor axis (seed 004 §8.2: +y): thigh and shank spend a step-up within
~70° of vertical, so their mean specific force points up their long axis unless the sensor is inverted;
(D3, D4) use the constraint offset δ(t) of :func:`estimators.heading.constraint_heading` on the 9D run (the
magnetometers' relative heading is 0 by definition): D3 the share of samples with |δ(t)| > 90°, D4 the
choice's disagreement D and the share of samples with |δ(t)| above ``estimators.heading.DISTURBED_BOUND_RAD`` (6°).

Order: the heading is judged first, on the 9D run, because a lost heading (180° about the vertical turns the
flexion axis round) also makes flexion negative; the angles D1 is applied to are those computed with the
heading actually used, so a lost heading corrected by the constraint no longer looks like a swap.  An
upside-down sensor whose posture calibration undid it (angles plausible) is no finding here: the standing
check :func:`estimators.knee.mounting_warnings` reports it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import knee
from estimators import quaternion as quat
from estimators.heading import DISTURBED_BOUND_RAD, HeadingChoice, wrap
from estimators.quality import QualityWarning

FloatArray = NDArray[np.float64]

__all__ = ["CAUSES", "LOST_HEADING_FRACTION", "LOST_HEADING_RAD", "Diagnosis", "Finding", "diagnose"]

#: code → can the clinician fix it (and so the session is refused with advice)?
CAUSES = {"sensors_swapped": True, "sensor_upside_down_task": True, "heading_lost": False,
          "magnetic_field_disturbed": False}
#: a relative heading further than this from the constraint is a lost heading, not a bent one (D3)
LOST_HEADING_RAD = float(np.pi / 2)
#: share of the task's samples beyond ``LOST_HEADING_RAD`` (the 9D run's δ(t)) that makes the heading lost (D3)
LOST_HEADING_FRACTION = 0.1


@dataclass(frozen=True)
class Finding:
    """One cause: ``code`` (a key of ``CAUSES``), ``fixable`` by the clinician, and its ``warning``."""

    code: str
    fixable: bool
    warning: QualityWarning


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`.

    findings : the causes found, heading first.   refuse : the angles are implausible (D1) and cannot be
    reported.   cause : the finding that explains a refusal (None: no refusal, or no cause found, then
    ``unexplained`` holds the ``flexion_negative`` warning).
    """

    findings: tuple[Finding, ...]
    refuse: bool
    cause: Finding | None
    unexplained: QualityWarning | None = None

    @property
    def warnings(self) -> tuple[QualityWarning, ...]:
        return tuple(f.warning for f in self.findings)


def _upside_down(acc: ArrayLike, up: FloatArray, label: str) -> QualityWarning | None:
    a = np.asarray(acc, dtype=np.float64)
    a = a[np.all(np.isfinite(a), axis=1)]
    if len(a) == 0:
        return None
    m = a.mean(axis=0)
    if np.linalg.norm(m) == 0.0:
        return None
    angle = float(np.arccos(np.clip(np.dot(m / np.linalg.norm(m), up), -1.0, 1.0)))
    if angle <= np.pi / 2:
        return None
    vals = {"segment": label, "angle_deg": float(np.rad2deg(angle)), "axis": f"{up[0]:.2g}, {up[1]:.2g}, {up[2]:.2g}"}
    return QualityWarning(
        "sensor_upside_down_task",
        f"{label}: during the task gravity was on average {vals['angle_deg']:.0f}° from the sensor axis "
        f"[{vals['axis']}] the protocol expects up, so the sensor is mounted upside down and the knee angles are "
        "implausible; mount it with that axis up, or record the standing and lying postures with the sensor as "
        "worn, and record again", vals)


def _heading_findings(choice: HeadingChoice) -> list[Finding]:
    c9 = choice.constraint_9d
    if c9 is None:
        return []
    offs = np.abs(wrap(c9.offset_rad))  # δ(t) on the 9D run: how far the magnetometers stray, per sample
    # with --heading magnetometer the angles keep the magnetometers' heading: the message then says how to correct it
    kept = {} if choice.used == "constraint" else {"variant": "kept"}
    lost = offs > LOST_HEADING_RAD
    if np.mean(lost) >= LOST_HEADING_FRACTION:
        vals = {"angle_deg": float(np.rad2deg(np.median(offs[lost]))), "pct": 100.0 * float(np.mean(lost)),
                "min_deg": float(np.rad2deg(LOST_HEADING_RAD)), **kept}
        return [Finding("heading_lost", False, QualityWarning(
            "heading_lost",
            f"the thigh and shank headings from the magnetometers are more than {vals['min_deg']:.0f}° off the "
            f"knee's hinge constraint in {vals['pct']:.0f} % of the task (median {vals['angle_deg']:.0f}°): an "
            "orientation filter lost its heading. This is not a sensor placement problem; "
            + ("the joint-constraint heading corrects it" if choice.used == "constraint" else
               "process again with --heading auto (or constraint) to correct it"), vals))]
    if choice.disagreement_rad > DISTURBED_BOUND_RAD:  # beyond what an accelerometer's tilt makes of the dip
        vals = {"angle_deg": float(np.rad2deg(choice.disagreement_rad)),
                "bound_deg": float(np.rad2deg(DISTURBED_BOUND_RAD)),
                "pct": 100.0 * float(np.mean(offs > DISTURBED_BOUND_RAD)), **kept}
        return [Finding("magnetic_field_disturbed", False, QualityWarning(
            "magnetic_field_disturbed",
            f"the magnetometer heading strays up to {vals['angle_deg']:.0f}° from the knee's hinge constraint "
            f"(more than {vals['bound_deg']:.0f}°) in {vals['pct']:.0f} % of the task: the magnetic field differs "
            "between the thigh and shank sensors (metal or electronics nearby). Nothing needs fixing on the "
            "sensors; " + ("the joint-constraint heading corrects it" if choice.used == "constraint" else
                           "process again with --heading auto (or constraint) to correct it"), vals))]
    return []


def diagnose(q_earth_femur: ArrayLike, q_earth_tibia: ArrayLike, side: str, *, choice: HeadingChoice | None = None,
             acc_sensor: Mapping[str, ArrayLike] | None = None,
             expected_up_sensor: ArrayLike = (0.0, 1.0, 0.0)) -> Diagnosis:
    """Name the cause of wrong knee angles (module docstring, D1–D4).

    q_earth_femur, q_earth_tibia : (N, 4) the segment orientations the knee angles are computed from, the tibia
        already in the femur's earth frame (``choice.q_earth_femur``, ``choice.q_earth_tibia``).
    side : ``"right"``/``"left"``.   choice : the :class:`estimators.heading.HeadingChoice` that produced them
        (its 9D constraint judges the heading: D3, D4).
    acc_sensor : ``{"thigh": (N, 3), "shank": (N, 3)}`` the task's specific force in sensor coordinates (D2).
    expected_up_sensor : (3,) the sensor axis the protocol points up the segment (default +y).
    """
    qf, qt = quat.as_quaternion(q_earth_femur), quat.as_quaternion(q_earth_tibia)
    q_ft = knee.q_femur_tibia(qf, qt)
    findings: list[Finding] = _heading_findings(choice) if choice is not None else []
    implausible = knee.task_warnings(knee.knee_angles(q_ft, side))
    if not implausible:
        return Diagnosis(tuple(findings), False, None)
    heading_lost_uncorrected = any(f.code == "heading_lost" for f in findings) and (
        choice is not None and choice.used != "constraint")
    if heading_lost_uncorrected:  # the lost heading explains the negative flexion; a swap test would be misled
        cause = next(f for f in findings if f.code == "heading_lost")
        return Diagnosis(tuple(findings), True, cause)
    up = np.asarray(expected_up_sensor, dtype=np.float64)
    up = up / np.linalg.norm(up)
    for seg, acc in (acc_sensor or {}).items():
        w = _upside_down(acc, up, seg)
        if w is not None:
            f = Finding("sensor_upside_down_task", True, w)
            findings.append(f)
    upside = [f for f in findings if f.code == "sensor_upside_down_task"]
    if upside:
        return Diagnosis(tuple(findings), True, upside[0])
    swapped = knee.knee_angles(quat.conjugate(q_ft), side)
    if not knee.task_warnings(swapped):
        p = implausible[0].params
        vals = {"pct": p["pct"], "median_deg": p["median_deg"],
                "swapped_median_deg": float(np.rad2deg(np.median(swapped[np.isfinite(swapped[:, 0]), 0])))}
        f = Finding("sensors_swapped", True, QualityWarning(
            "sensors_swapped",
            f"knee flexion reads below −15° in {vals['pct']:.0f} % of the task (median {vals['median_deg']:.0f}°) "
            f"and a plausible {vals['swapped_median_deg']:.0f}° with the two sensors exchanged: the thigh and shank "
            "sensors (or their recordings) are swapped. Check which recording belongs to which segment and process "
            "again", vals))
        findings.append(f)
        return Diagnosis(tuple(findings), True, f)
    return Diagnosis(tuple(findings), True, None, implausible[0])
