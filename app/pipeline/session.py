"""One knee session, from its recordings to the numbers a physiotherapist reads (seed 004 chapter 8).

Stages (each reported to ``progress(stage, fraction)``):

1. **read** — :func:`app.pipeline.ingestion.load_session`: files → streams in SI units on one grid per recording,
   the two task recordings on one common grid;
2. **accelerometer** — per sensor, the bias (and, with enough still poses, the per-axis gain) from the still poses
   of its figure-eight, standing and supine recordings (:mod:`estimators.accelerometer`), applied once to every
   recording of that sensor before anything takes a vertical from it; without three independent gravity
   directions (no figure-eight) nothing is corrected and ``accelerometer_not_calibrated`` says so;
   **magnetometer** — per sensor, ellipsoid fit on its figure-eight (:func:`estimators.magnetometer.fit_ellipsoid`),
   applied to all its recordings;
3. **segments** — per sensor, ``q_sensor_segment`` from standing and supine (:func:`estimators.knee.calibrate_segment`),
   and the gyroscope bias measured while those postures are still, subtracted from every later recording
   (a BMI160's bias reaches ±3 °/s, which the filters would otherwise have to learn during the motion);
   with ``calibration="functional"`` the femur's z axis is then the knee's flexion axis estimated on the
   task's gyroscopes (:func:`estimators.joint_axis.estimate_axis`, checked against the filters' relative
   motion; :func:`estimators.knee.functional_calibration`) instead of the supine posture's, and the tibia is turned about its long axis so that the knee's rotation
   is zero while standing (:func:`estimators.knee.turn_about_long_axis`; in 9D, so it trusts the magnetometer
   while standing as much as the heading check does);
4. **orientation** — both sensors through the task with the chosen filter (default: the estimator
   core's default, whose offline smoother needs no convergence time, so the first cycle is not lost
   as it was in the thesis);
5. **knee** — ``q_femur_tibia`` and the clinical (Grood & Suntay) or thesis (ZYX) angles;
6. **task** — cycles, phases, normalised curves, ROM (:func:`estimators.motor_task.analyse_task`), without the cycles
   the clinician excluded (``ProcessOptions.exclusions``, :mod:`app.pipeline.exclusions`: reason
   ``excluded_by_clinician``, no quality warning; ``cycles_rejected`` counts the pipeline's own rejections).

Quality checks gathered on the way (``results["quality"]["warnings"]``): magnetometer coverage and
residual, postures not still or not distinct, a sensor mounted upside down, a large heading offset
between the two sensors while standing, their relative heading drifting between the task's straight-knee
holds (``heading_drift``, variant ``task``), magnetic disturbance during the task, cycles rejected, and every
note the ingestion made.  Each warning carries ``params`` (its values by the field names of
``reports/translations_warnings.json``); the magnetometer's, re-worded here with the sensor in front, get
``params["segment"]``, the ingestion notes the :class:`app.pipeline.ingestion.Note` params.  Sensors swapped
between thigh and shank (the task's flexion comes out negative) stop the processing with a message instead.
:func:`process_session` computes everything before anything is written;
:mod:`app.pipeline.results` turns the outcome into ``results.json``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimators import __version__, knee
from estimators.accelerometer import AccCalibration, fit_still_poses, still_poses
from estimators import quaternion as quat
from estimators.diagnosis import diagnose
from estimators.disturbance import FieldCheck, field_disturbance
from estimators.heading import DISAGREEMENT_BOUND_RAD, DISTURBED_BOUND_RAD, HeadingChoice, choose_heading
from estimators.magnetometer import MagCalibration, fit_ellipsoid
from estimators.motor_task import (EVENTS, EXCLUDED, TASKS, NotCandidateError, TaskAnalysis, UnknownCycleError,
                                   analyse_task)
from estimators.orientation import make
from estimators.quality import QualityWarning

from app.choices import (ANGLE_CONVENTION_NAMES, CALIBRATION_NAMES, DEFAULT_ANGLE_CONVENTION, DEFAULT_CALIBRATION,
                         DEFAULT_FILTER, DEFAULT_HEADING, DEFAULT_LANGUAGE, DEFAULT_TASK, HEADING_NAMES,
                         LANGUAGE_NAMES, SIDE_NAMES, TASK_NAMES)
from app.pipeline.exclusions import CycleExclusion
from app.pipeline.ingestion import SEGMENTS, IngestionError, Note, Session

FloatArray = NDArray[np.float64]
Progress = Callable[[str, float], None]

#: what an analysis was computed with: with the session and its files' version it keys the processing
#: (``chakamo reprocess`` skips sessions already analysed by this version with the same filter)
PIPELINE_VERSION = __version__
#: Seel's and the relative-velocity flexion axes further apart than this (transverse plane) → the latter, warned
FUNCTIONAL_AXIS_AGREE_RAD = float(np.deg2rad(8.0))
#: a larger constant heading offset between the two sensors' earth frames (standing) deserves a warning
HEADING_OFFSET_WARN_RAD = float(np.deg2rad(10.0))
#: the two segments' relative heading changing by more than this between the task's straight-knee holds is
#: drift (warned ``heading_drift``, variant ``task``): the rotation of the last cycles then reads that much off
#: the first ones', over twice the 2° rotation-accuracy goal; normal simulated sessions change by 0.6–2.9°
#: (10 seeds × 10 cycles, with and without accelerometer errors), a shank field turning 1°/s by 5.2°
HEADING_DRIFT_TASK_WARN_RAD = float(np.deg2rad(5.0))
#: a task-only calibration's straight window must have each sensor's +y (the protocol's "up the segment") within
#: this of gravity: the mounting tolerance (15°, the simulator's and the demo's) with margin; a still flexed
#: posture (a step-up's start posture: the thigh 60–75° from vertical) is far beyond it
TASK_ONLY_MAX_LONG_AXIS_RAD = float(np.deg2rad(30.0))
#: straight-knee holds shorter than this are left out of the task's heading check: too few samples to
#: average the sensors' noise (a turning point is one sample)
HEADING_HOLD_MIN_S = 0.2


class PipelineError(ValueError):
    """The session cannot be processed as given; the message says what to do.

    ``PipelineError(code, **params)`` with ``code`` a key of :data:`app.pipeline.messages.PIPELINE_CATALOGUE` (or
    of the ingestion's, e.g. a provenance ``check.*``): ``str(exc)`` is English, :meth:`message` renders es/en/pt,
    ``code`` and ``params`` stay on the exception for the job record and the API.  Any other string is kept as
    the text in every language (``code == "text"``)."""

    def __init__(self, code: str, /, **params: Any) -> None:
        from app.pipeline.messages import known, render_message

        if known(code):
            self.code, self.params = code, {k: _plain(v) for k, v in params.items()}
            text = render_message(code, self.params, "en")
        else:
            self.code, self.params, text = "text", {"text": code}, code
        super().__init__(text)

    def message(self, lang: str = "en") -> str:
        """The message in ``lang`` (es/en/pt; an unknown language gives English)."""
        from app.pipeline.messages import render_message

        return str(self) if self.code == "text" else render_message(self.code, self.params, lang)

    def __reduce__(self):  # pickle (job engines, the helper processes): rebuilt from code and params
        return (_rebuild_pipeline_error, (self.code, dict(self.params), str(self)))


def _plain(value: Any) -> Any:
    """A parameter as JSON carries it: numpy scalars as numbers, paths as text, fragments recursively."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value if isinstance(value, (str, int, float, bool, type(None))) else str(value)


def _rebuild_pipeline_error(code: str, params: dict, text: str) -> "PipelineError":
    return PipelineError(code, **params) if code != "text" else PipelineError(text)


def _option_error(option: str, allowed, value) -> PipelineError:
    return PipelineError("pipeline.bad_option", option=option, allowed=", ".join(allowed), value=repr(value))


@dataclass(frozen=True)
class ProcessOptions:
    """What the user chose.

    Every list of valid values is :mod:`app.choices`.
    filter_name : orientation method (``app.choices.FILTERS``).   filter_params : its parameters.
    side : ``"right"`` / ``"left"``, overriding what the files or ``session.json`` say.
    angle_method : ``"grood_suntay"`` (clinical, default) or ``"thesis_zyx"`` (the thesis' extraction).
    calibration : ``"static"`` (standing + supine, default) or ``"functional"`` (standing + the flexion axis
        of the task, for a lying posture that was not held toes-up).
    task : motor task analysed (``app.choices.TASKS``).
    heading : the thigh–shank heading (``app.choices.HEADINGS``): ``auto`` (default) uses the magnetometers unless
        they disagree with the knee's hinge constraint by more than its bound, then the constraint's (from a 6D
        run of the same filter); ``magnetometer`` / ``constraint`` force one (:func:`estimators.heading.choose_heading`).
    expected_fs_hz : rate the protocol uses; ``None`` accepts the files' own rate.
    language : report language (``es``/``en``/``pt``), recorded for the reports.
    involved : the involved knee of a two-knee session (``app.choices.SIDES``; None: the patient's side from
        ``session.json``): the numerator of the limb symmetry index (:mod:`app.pipeline.knees`).
    exclusions : the cycles the clinician excluded (:class:`app.pipeline.exclusions.CycleExclusion`): left out of
        the statistics with the reason ``excluded_by_clinician`` before the pipeline's own rejection runs.
    """

    filter_name: str = DEFAULT_FILTER
    filter_params: Mapping[str, Any] = field(default_factory=dict)
    side: str | None = None
    angle_method: str = DEFAULT_ANGLE_CONVENTION
    calibration: str = DEFAULT_CALIBRATION
    task: str = DEFAULT_TASK
    heading: str = DEFAULT_HEADING
    expected_fs_hz: float | None = 100.0
    language: str = DEFAULT_LANGUAGE
    involved: str | None = None
    exclusions: tuple[CycleExclusion, ...] = ()

    def __post_init__(self) -> None:
        if self.side is not None and self.side not in SIDE_NAMES:
            raise _option_error("side", SIDE_NAMES, self.side)
        if self.involved is not None and self.involved not in SIDE_NAMES:
            raise _option_error("involved side", SIDE_NAMES, self.involved)
        if self.angle_method not in ANGLE_CONVENTION_NAMES:
            raise _option_error("angle method", ANGLE_CONVENTION_NAMES, self.angle_method)
        if self.calibration not in CALIBRATION_NAMES:
            raise _option_error("calibration", CALIBRATION_NAMES, self.calibration)
        if self.language not in LANGUAGE_NAMES:
            raise _option_error("language", LANGUAGE_NAMES, self.language)
        if self.heading not in HEADING_NAMES:
            raise _option_error("heading", HEADING_NAMES, self.heading)
        if self.task not in TASK_NAMES:
            raise _option_error("task", TASK_NAMES, self.task)


@dataclass(frozen=True, eq=False)
class SessionOutcome:
    """Everything computed for one session (radians, seconds from the task grid's start).

    t_s : (N,) task grid.   fs_hz : its rate.   t0_s : the grid start on the files' clock.
    angles_rad : (N, 3) flexion, adduction, internal rotation (clinical signs).
    q_earth_sensor, q_earth_segment : ``{"thigh"|"shank": (N, 4)}``.   q_femur_tibia : (N, 4).
    mag : ``{segment: MagCalibration}``.   segments : ``{segment: SegmentCalibration}``.
    field : ``{segment: FieldCheck}`` on the task.   heading : the standing heading check (None without standing).
    analysis : the motor-task analysis.   warnings : every quality warning, in stage order.
    filter_params : the parameter dataclass of the filter used (defaults and overrides), written whole to
        ``results.json`` ``filter.params`` (units in the field names: ``tau_acc_s``, ``bias_clip_rad_s``) so a
        results file says how it was computed even after a default changes; ``filter.overrides`` lists what
        the user changed.
    heading_task : the heading check over the task's straight-knee holds (None when there was none).
    heading_choice : which thigh–shank heading the knee angles use and why (``--heading``), with its figures.
    acc : ``{segment: AccCalibration}`` applied to every recording of that sensor (``model == "none"``: nothing).
    """

    session: Session
    options: ProcessOptions
    side: str
    step_height_m: float | None
    t_s: FloatArray
    fs_hz: float
    t0_s: float
    angles_rad: FloatArray
    q_earth_sensor: dict[str, FloatArray]
    q_earth_segment: dict[str, FloatArray]
    q_femur_tibia: FloatArray
    mag: dict[str, MagCalibration]
    segments: dict[str, knee.SegmentCalibration]
    field: dict[str, FieldCheck]
    heading: knee.HeadingOffset | None
    analysis: TaskAnalysis
    warnings: tuple[QualityWarning, ...]
    filter_params: Any
    heading_task: TaskHeading | None = None
    heading_choice: HeadingChoice | None = None
    acc: dict[str, AccCalibration] | None = None


@dataclass(frozen=True, eq=False)
class TaskHeading:
    """Heading offset between the two segments over the task's straight-knee holds (:func:`_task_heading`).

    spans_s : (H, 2) the holds used, s on the task grid.   offsets_rad : (H,) the offset δ of each hold
        (:func:`estimators.knee.heading_offset`, ``"straight_knee"``).
    change_rad : largest minus smallest δ (NaN with fewer than two holds): how far the relative heading
        drifted during the task.   mean_offset_rad : δ over all holds together.
    warnings : ``heading_drift`` (variant ``task``) when ``change_rad`` exceeds ``HEADING_DRIFT_TASK_WARN_RAD``.
    """

    spans_s: FloatArray
    offsets_rad: FloatArray
    change_rad: float
    mean_offset_rad: float
    warnings: tuple[QualityWarning, ...]


def _no_progress(stage: str, fraction: float) -> None:
    return None


def process_session(session: Session, options: ProcessOptions | None = None, *,
                    progress: Progress = _no_progress) -> SessionOutcome:
    """Run stages 2–6 on a loaded session (see the module docstring)."""
    options = options or ProcessOptions()
    warnings: list[QualityWarning] = [QualityWarning("ingestion_note", n, n.params if isinstance(n, Note) else {})
                                      for n in session.notes]
    side = options.side or session.metadata.value("side")
    if side is None:
        raise PipelineError("pipeline.no_side", file=str(session.folder))
    warnings += _provenance(session, side, overridden=options.side is not None)
    filt = make(options.filter_name, **dict(options.filter_params))

    roles = {role for _, role in session.recordings}
    progress("accelerometer", 0.1)
    session, acc_cal = _calibrate_accelerometers(session, roles)
    warnings += [w for seg in SEGMENTS if (w := _accelerometer_warning(seg, acc_cal[seg])) is not None]
    thigh, shank = session.task_pair()
    task = {"thigh": thigh, "shank": shank}

    progress("magnetometer", 0.15)
    mag: dict[str, MagCalibration] = {}
    for seg in SEGMENTS:
        if "mag_calibration" not in roles:  # (b) factory-calibrated sensors: nothing to fit
            mag[seg] = _factory_magnetometer(task[seg].mag)
            continue
        rec = session.recording(seg, "mag_calibration")
        try:
            mag[seg] = fit_ellipsoid(rec.mag)
        except ValueError as exc:
            raise PipelineError("pipeline.magnetometer_calibration", segment={"code": f"word.{seg}"},
                                files=_files(rec), reason=str(exc)) from None
        warnings += [QualityWarning(w.code, f"{seg.capitalize()} sensor: {w.message}", {**w.params, "segment": seg})
                     for w in mag[seg].quality.warnings]

    progress("segments", 0.3)
    protocol = _protocol(roles)
    if protocol == "postures":
        segments = _static_segments(session)
        for seg, cal in segments.items():
            warnings += list(cal.warnings) + knee.mounting_warnings(cal, label=seg)
    else:  # (c) standing + task, or (d) the task alone: the bias comes from their still windows
        segments, cal_warnings = _functional_segments(session, protocol, task)
        warnings += cal_warnings
    mag_task = {seg: mag[seg].apply(rec.mag) for seg, rec in task.items()}
    gyr_task = {seg: rec.gyr - segments[seg].gyr_bias_rad_s for seg, rec in task.items()}
    q_es: dict[str, FloatArray] = {}
    for i, (seg, rec) in enumerate(task.items()):
        progress(f"orientation {seg}", 0.45 + 0.2 * i)
        q_es[seg] = filt.estimate(rec.acc, gyr_task[seg], mag_task[seg], fs_hz=rec.fs_hz).orientation_
    q_standing = _standing_orientations(session, filt, mag, segments) if "standing" in roles else None
    if protocol != "postures" and "mag_calibration" in roles:
        # the second pass: the 9D orientations fix the axes' relative sign and rotation zero.  Only with magnetometers
        # calibrated on the figure-eight: uncalibrated hard iron turns the 9D headings by tens of degrees, which
        # turned the shank's axis ~47° or flipped the hinge sign (simulated walking, tests/app/pipeline/
        # test_protocols.py); without it the sign comes from the mounting and the rotation zero from the hinge frame
        # itself (y gravity, z the hinge axis: the two segments' frames coincide at the straight window)
        segments, _ = _functional_segments(session, protocol, task, q_task=q_es, q_standing=q_standing)
    elif protocol == "postures" and options.calibration == "functional":
        # standing + task (c) and the task alone (d) are functional already (the task's hinge axes): ``functional``
        # asks nothing more of them.  On the postures the femur's axis is checked against, and the tibia's rotation
        # zero taken from, the 9D orientations, which without a figure-eight carry the uncalibrated hard iron
        # (adduction and rotation 13° RMSE on simulated step-ups, tests/app/pipeline/test_protocol_calibrations.py)
        if "mag_calibration" not in roles:
            raise PipelineError("pipeline.functional_needs_figure_eight")
        segments, functional_warnings = _functional(segments, thigh, shank, gyr_task, q_es, q_standing)
        warnings += functional_warnings
    choice = _heading_choice(options.heading, options.task, filt, task, gyr_task, segments,
                             {seg: knee.segment_orientation(q_es[seg], segments[seg].q_sensor_segment) for seg in SEGMENTS})
    warnings += list(choice.warnings)
    q_seg = {"thigh": choice.q_earth_femur, "shank": choice.q_earth_tibia}

    progress("knee", 0.85)
    heading = _standing_heading(q_standing, segments) if q_standing is not None else None
    if heading is not None:
        warnings += list(heading.warnings)
    field: dict[str, FieldCheck] = {}
    for seg in ("thigh", "shank"):
        field[seg] = field_disturbance(mag_task[seg], q_es[seg], mag[seg].field_ut, label=seg)
        warnings += list(field[seg].warnings)
    q_ft = knee.q_femur_tibia(q_seg["thigh"], q_seg["shank"])
    angles = knee.knee_angles(q_ft, side, method=options.angle_method)
    diagnosis = diagnose(q_seg["thigh"], q_seg["shank"], side, choice=choice,
                         acc_sensor={"thigh": thigh.acc, "shank": shank.acc})
    if diagnosis.refuse:  # implausible angles help nobody: refuse, naming the files and the cause's own advice
        w = diagnosis.cause.warning if diagnosis.cause is not None else diagnosis.unexplained
        cause = {"code": f"warning.{w.code}", "params": dict(w.params), "message": w.message}
        raise PipelineError("pipeline.implausible_angles" if diagnosis.cause is not None else
                            "pipeline.implausible_unexplained", thigh_files=_files(thigh), shank_files=_files(shank),
                            cause=cause)
    warnings += list(diagnosis.warnings)  # the named cause of a heading problem (lost, or a disturbed field)

    progress("task", 0.95)
    analysis = _analyse(angles, thigh, options, side, {  # what a task's analysis may use
        "gyr_shank_rad_s": gyr_task["shank"], "gyr_thigh_rad_s": gyr_task["thigh"],
        "shank_axis_sensor": quat.rotate(segments["shank"].q_sensor_segment, np.array([0.0, 0.0, 1.0])),
        "q_earth_thigh": q_es["thigh"], "q_earth_shank": q_es["shank"]})
    warnings += list(analysis.warnings)
    rejected = [r for r in analysis.rejected if r.code != EXCLUDED]  # the pipeline's own: the clinician's are no warning
    if rejected:
        warnings.append(QualityWarning(
            "cycles_rejected",
            f"{len(rejected)} of {analysis.n_detected} cycles were left out of the statistics: "
            + "; ".join(f"cycle {r.index + 1}: {r.message}" for r in rejected),
            {"rejected": len(rejected), "detected": analysis.n_detected}))
    heading_task = _task_heading(q_seg, analysis, thigh.fs_hz)
    if heading_task is not None:
        warnings += list(heading_task.warnings)
    return SessionOutcome(
        session=session, options=options, side=side, step_height_m=session.metadata.value("step_height_m"),
        t_s=thigh.t_s, fs_hz=thigh.fs_hz, t0_s=thigh.t0_s, angles_rad=angles, q_earth_sensor=q_es,
        q_earth_segment=q_seg, q_femur_tibia=q_ft, mag=mag, segments=segments, field=field, heading=heading,
        analysis=analysis, warnings=tuple(warnings), filter_params=filt.params, heading_task=heading_task,
        heading_choice=choice, acc=acc_cal)


def _analyse(angles: FloatArray, thigh, options: ProcessOptions, side: str, inputs: dict) -> TaskAnalysis:
    """The task's analysis (:func:`estimators.motor_task.analyse_task`) without the cycles the clinician excluded
    (``options.exclusions`` of this knee: those naming it or no knee; one naming the other knee is refused).
    Refused too: an exclusion of a cycle that was not detected, of one the pipeline left out already (incomplete, a
    turn...), or of every cycle the pipeline would keep."""
    other = [e for e in options.exclusions if e.knee not in (None, side)]
    if other:
        raise PipelineError("pipeline.exclude_other_knee", cycle=other[0].cycle, knee={"code": f"word.{other[0].knee}"})
    exclude = [e.index for e in options.exclusions]
    try:
        analysis = analyse_task(angles, thigh.fs_hz, task=options.task, inputs=inputs, exclude=exclude)
    except UnknownCycleError as exc:
        raise PipelineError("pipeline.exclude_unknown_cycle", cycle=exc.index + 1, detected=exc.detected) from None
    except NotCandidateError as exc:
        raise PipelineError("pipeline.exclude_rejected_cycle", cycle=exc.index + 1) from None
    except ValueError as exc:
        raise PipelineError("pipeline.task_analysis", files=_files(thigh), reason=str(exc)) from None
    if exclude and analysis.n_accepted == 0 and any(r.code == EXCLUDED for r in analysis.rejected):
        raise PipelineError("pipeline.exclude_every_cycle", excluded=len(exclude), detected=analysis.n_detected)
    return analysis


#: the recordings whose still poses calibrate a sensor's accelerometer (the task's are left out: its rests repeat
#: the postures' directions and a subject's start posture may sway)
ACC_CALIBRATION_ROLES = ("mag_calibration", "standing", "lying")


def _calibrate_accelerometers(session: Session, roles: set[str]) -> tuple[Session, dict[str, AccCalibration]]:
    """Per sensor, :func:`estimators.accelerometer.fit_still_poses` on the still poses of its calibration recordings,
    applied to all its recordings (the task pair too): the session returned carries the corrected ``acc``."""
    from dataclasses import replace

    cal: dict[str, AccCalibration] = {}
    for seg in SEGMENTS:
        poses = [still_poses(r.acc, r.gyr, fs_hz=r.fs_hz) for role in ACC_CALIBRATION_ROLES if role in roles
                 for r in (session.recording(seg, role),)]
        cal[seg] = fit_still_poses(poses)
    if all(c.model == "none" for c in cal.values()):
        return session, cal
    recordings = {(seg, role): replace(r, acc=cal[seg].apply(r.acc)) for (seg, role), r in session.recordings.items()}
    task = tuple(replace(r, acc=cal[seg].apply(r.acc)) for seg, r in zip(SEGMENTS, session.task, strict=True))
    return replace(session, recordings=recordings, task=task), cal


def _accelerometer_warning(seg: str, cal: AccCalibration) -> QualityWarning | None:
    """``accelerometer_not_calibrated`` when the sensor's accelerometer bias could not be measured (its ``note``)."""
    if cal.model != "none":
        return None
    why = {"few_poses": "its recordings hold still poses in fewer than three independent directions (record the "
                        "figure-eight with the sensor at rest before and after it)",
           "implausible_bias": "the bias the still poses give is implausibly large",
           "poses_not_still": "its still poses disagree (one of them was not at rest)"}[cal.note]
    return QualityWarning("accelerometer_not_calibrated", f"{seg.capitalize()} sensor: the accelerometer bias was "
                          f"not corrected: {why}; a bias tilts the angles by up to ~1°",
                          {"segment": seg, "variant": cal.note, "poses": len(cal.poses_m_s2)})


def _heading_choice(mode: str, task_name: str, filt, task: dict, gyr_task: dict[str, FloatArray],
                    segments: dict[str, knee.SegmentCalibration], q_seg_9d: dict[str, FloatArray]) -> HeadingChoice:
    """The thigh–shank heading for ``--heading`` (:func:`estimators.heading.choose_heading`).  The constraint is
    computed on a 6D run of the same filter (no magnetic influence at all) whenever it is used: run up front for
    ``constraint``, and for ``auto`` only once the 9D check has decided to switch (a clean session pays nothing)."""
    fs_hz = task["thigh"].fs_hz
    # the task's own auto bound (TaskSpec.heading_bound): the tilt bound only where it was measured
    bound_rad = DISAGREEMENT_BOUND_RAD if TASKS[task_name].heading_bound == "tilt" else DISTURBED_BOUND_RAD

    def choose(q_seg_6d: dict[str, FloatArray] | None) -> HeadingChoice:
        six = {} if q_seg_6d is None else {"q_earth_femur_6d": q_seg_6d["thigh"], "q_earth_tibia_6d": q_seg_6d["shank"]}
        return choose_heading(q_seg_9d["thigh"], q_seg_9d["shank"], fs_hz=fs_hz, mode=mode, bound_rad=bound_rad,
                              **six)

    def six_d() -> dict[str, FloatArray]:
        return {seg: knee.segment_orientation(filt.estimate(rec.acc, gyr_task[seg], None, fs_hz=rec.fs_hz).orientation_,
                                              segments[seg].q_sensor_segment) for seg, rec in task.items()}

    if mode == "magnetometer":
        return choose(None)
    if mode == "constraint":
        return choose(six_d())
    choice = choose(None)
    return choose(six_d()) if choice.used == "constraint" else choice


def _provenance(session: Session, side: str, *, overridden: bool) -> list[QualityWarning]:
    """What the files say of themselves against the session (:mod:`app.pipeline.ingestion.provenance`): a recording
    of the other leg is refused — adduction and rotation would flip sign — unless the side was given explicitly
    (``--side``: the clinician's override); recordings made on other days than the session, another patient's id
    in the files, or one sensor on both segments are warned."""
    from app.pipeline.ingestion.provenance import check_all

    meta = session.metadata
    warnings = []
    for f in check_all(session, patient_side=side, patient_id=meta.value("patient_id"), session_date=meta.value("date")):
        if f.severity == "refuse" and not overridden:
            raise PipelineError(f.code, **f.params)
        # a translatable word ({"code": "word.left"}) becomes the word, which the reports translate (warning.term.*)
        params = {k: v["code"].removeprefix("word.") if isinstance(v, dict) and "code" in v else v
                  for k, v in f.as_dict()["params"].items()}
        warnings.append(QualityWarning(f.code, f.message("en"), params))
    return warnings


def _protocol(roles: set[str]) -> str:
    """Which calibration the recordings allow: ``postures`` (standing + supine: the static calibration, or
    ``--calibration functional``), ``standing_task`` (no supine: issue 14 §3 c) or ``task`` (no posture: d)."""
    if {"standing", "lying"} <= roles:
        return "postures"
    return "standing_task" if "standing" in roles else "task"


def _static_segments(session: Session) -> dict[str, knee.SegmentCalibration]:
    """Per sensor, ``q_sensor_segment`` from its standing and supine recordings (:func:`estimators.knee.calibrate_segment`)."""
    segments: dict[str, knee.SegmentCalibration] = {}
    for seg in SEGMENTS:
        standing, lying = session.recording(seg, "standing"), session.recording(seg, "lying")
        try:
            segments[seg] = knee.calibrate_segment(standing.acc, standing.gyr, lying.acc, lying.gyr,
                                                   fs_hz=standing.fs_hz, label=seg)
        except ValueError as exc:
            raise PipelineError("pipeline.segment_calibration", segment={"code": f"word.{seg}"},
                                files=f"{_files(standing)}, {_files(lying)}", reason=str(exc)) from None
    return segments


def _functional_segments(session: Session, protocol: str, task: dict, *, q_task: dict | None = None,
                         q_standing: dict | None = None) -> tuple[dict[str, knee.SegmentCalibration], list]:
    """Segment axes without the supine posture (:mod:`estimators.functional`): ``standing_task`` takes y from
    standing gravity and z from the knee's hinge axes on the task; ``task`` takes y from the task's stillest
    straight-knee window.  Called twice: first for the gyroscope biases (no orientations), then with the 9D
    orientations of the bias-free task (and standing) recordings, which fix the relative sign of the two hinge
    axes and the knee's rotation zero."""
    from estimators import functional

    fs_hz = task["thigh"].fs_hz
    pairs = [(task[seg].acc, task[seg].gyr) for seg in SEGMENTS]
    try:
        if protocol == "standing_task":
            st = [session.recording(seg, "standing") for seg in SEGMENTS]
            n = min(len(st[0].acc), len(st[1].acc))  # the two standing files, paired by index
            q_st = None if q_standing is None else {seg: q[:n] for seg, q in q_standing.items()}
            cal = functional.standing_task_calibration((st[0].acc[:n], st[0].gyr[:n]), (st[1].acc[:n], st[1].gyr[:n]),
                                                       *pairs, fs_hz=fs_hz, q_standing=q_st, q_task=q_task)
        else:
            cal = functional.task_calibration(*pairs, fs_hz=fs_hz, q_task=q_task)
    except functional.SensorTurnedError:
        raise PipelineError("pipeline.sensor_turned_round", thigh_files=_files(task["thigh"]),
                            shank_files=_files(task["shank"])) from None
    except ValueError as exc:
        files = ", ".join(_files(task[seg]) for seg in SEGMENTS)
        raise PipelineError("pipeline.functional_segment_calibration", files=files, reason=str(exc)) from None
    if protocol == "task":
        _check_straight_window(cal.segments, task)
    return cal.segments, list(cal.warnings)


def _check_straight_window(segments: dict[str, knee.SegmentCalibration], task: dict) -> None:
    """The task-only calibration takes the knee's zero from the task's stillest straight-knee window, which
    gravity and the hinge axes alone cannot tell from a still *flexed* posture (a step-up's start posture, foot on
    the step: flexion then reads ~60–90° off).  The protocol wears each sensor with its +y axis up the segment
    (seed 004 §8.2, within the mounting tolerance), so a window whose gravity is further than
    ``TASK_ONLY_MAX_LONG_AXIS_RAD`` from a sensor's +y was no upright standing: refused, with what to record."""
    for seg, cal in segments.items():
        y = quat.to_matrix(cal.q_sensor_segment)[:, 1]
        off = float(np.arccos(np.clip(y[1], -1.0, 1.0)))
        if off > TASK_ONLY_MAX_LONG_AXIS_RAD:
            raise PipelineError("pipeline.task_never_straight", files=_files(task[seg]), segment={"code": f"word.{seg}"},
                                angle_deg=float(np.rad2deg(off)), max_deg=float(np.rad2deg(TASK_ONLY_MAX_LONG_AXIS_RAD)))


def _factory_magnetometer(mag_task: FloatArray) -> MagCalibration:
    """The magnetometer as recorded (factory calibration, in whatever unit it came): no offset, no soft iron, the
    local field strength the median norm over the task (quality figures that need a fit are NaN)."""
    from estimators.magnetometer import MagQuality

    norm = np.linalg.norm(mag_task, axis=1)
    field = float(np.nanmedian(norm)) if np.isfinite(norm).any() else float("nan")
    nan = float("nan")
    quality = MagQuality(field_ut=field, residual_rms_ut=nan, residual_pct=nan, coverage_fraction=nan,
                         coverage_cells=0, direction_spread=nan, offset_sd_ut=nan, n_samples=0, n_dropped_nan=0,
                         n_outliers=0)
    return MagCalibration(np.zeros(3), np.eye(3), field, "factory", quality)


def _standing_orientations(session: Session, filt, mag: dict[str, MagCalibration],
                           segments: dict[str, knee.SegmentCalibration]) -> dict[str, FloatArray]:
    """``q_earth_sensor`` of both sensors over their standing recordings, paired by index (separate files of
    one static posture)."""
    q = {}
    for seg in SEGMENTS:
        rec = session.recording(seg, "standing")
        gyr = rec.gyr - segments[seg].gyr_bias_rad_s
        q[seg] = filt.estimate(rec.acc, gyr, mag[seg].apply(rec.mag), fs_hz=rec.fs_hz).orientation_
    n = min(len(q["thigh"]), len(q["shank"]))
    return {seg: q[seg][:n] for seg in SEGMENTS}


def _standing_heading(q_standing: dict[str, FloatArray], segments: dict[str, knee.SegmentCalibration], *,
                      max_offset_rad: float | None = HEADING_OFFSET_WARN_RAD) -> knee.HeadingOffset:
    """Heading offset between the two segments' earth frames while standing (knee straight: should be ~0)."""
    q = {seg: knee.segment_orientation(q_standing[seg], segments[seg].q_sensor_segment) for seg in SEGMENTS}
    return knee.heading_offset(q["thigh"], q["shank"], method="straight_knee", max_offset_rad=max_offset_rad)


def _straight_knee_spans_s(analysis: TaskAnalysis) -> FloatArray:
    """(H, 2) spans of the accepted cycles where the knee is straight: the full-extension holds
    (``far_reached`` → ``far_left``) of tasks that extend (step-up, seated extension), the standing rest
    between repetitions (``rest_reached`` → next ``onset``) of tasks that flex (squat)."""
    ev = analysis.events_s
    if analysis.task.excursion == "extension":
        spans = ev[:, [EVENTS.index("far_reached"), EVENTS.index("far_left")]]
    else:
        spans = np.column_stack([ev[:, EVENTS.index("rest_reached")],
                                 np.append(ev[1:, EVENTS.index("onset")], np.nan)])
    spans = spans[analysis.accepted]
    return spans[np.all(np.isfinite(spans), axis=1)] if len(spans) else np.zeros((0, 2))


def _task_heading(q_seg: dict[str, FloatArray], analysis: TaskAnalysis, fs_hz: float) -> TaskHeading | None:
    """The heading-offset check of the standing posture, repeated on each straight-knee hold of the task.

    The standing check sees a constant offset but cannot see drift: the posture lasts seconds and is
    recorded apart.  On the task the two filters run for minutes; a gyroscope bias one filter did not
    learn, or a local field that turns slowly at one sensor (its norm and dip unchanged, so no
    magnetometer check flags it), moves one segment's heading against the other's.  With the knee
    straight the two headings should agree, so δ per hold (:func:`estimators.knee.heading_offset`,
    H1) follows the drift; its range over the task is compared with ``HEADING_DRIFT_TASK_WARN_RAD``.
    The true knee rotation at full extension is nearly the same in every cycle, so it cancels in the
    range.  Holds shorter than ``HEADING_HOLD_MIN_S`` are skipped; None when no hold remains.
    """
    spans = _straight_knee_spans_s(analysis)
    spans = spans[spans[:, 1] - spans[:, 0] >= HEADING_HOLD_MIN_S]
    if len(spans) == 0:
        return None
    n = len(q_seg["thigh"])
    idx = [np.arange(max(0, int(round(a * fs_hz))), min(n, int(round(b * fs_hz)))) for a, b in spans]
    keep = [i for i, ix in enumerate(idx) if len(ix)]
    spans, idx = spans[keep], [idx[i] for i in keep]
    if not idx:
        return None
    offsets = np.array([knee.heading_offset(q_seg["thigh"][ix], q_seg["shank"][ix]).offset_rad for ix in idx])
    weights = np.array([len(ix) for ix in idx], dtype=float)
    mean = float(np.angle(np.sum(weights * np.exp(1j * offsets))))  # circular mean over the holds' samples
    rel = np.angle(np.exp(1j * (offsets - mean)))  # unwrapped about the mean: no jump at ±180°
    change = float(rel.max() - rel.min()) if len(offsets) > 1 else float("nan")
    warnings: tuple[QualityWarning, ...] = ()
    if change > HEADING_DRIFT_TASK_WARN_RAD:
        p = {"variant": "task", "change_deg": float(np.rad2deg(change)), "holds": len(offsets),
             "first_deg": float(np.rad2deg(offsets[0])), "last_deg": float(np.rad2deg(offsets[-1])),
             "max_deg": float(np.rad2deg(HEADING_DRIFT_TASK_WARN_RAD))}
        warnings = (QualityWarning(
            "heading_drift", f"the relative heading of the two sensors changed by {p['change_deg']:.1f}° across "
            f"the task's {p['holds']:d} straight-knee holds (from {p['first_deg']:.1f}° to {p['last_deg']:.1f}°, "
            f"more than {p['max_deg']:.0f}°); rotation and adduction drift with it: a gyroscope bias or a "
            "magnetic disturbance near one sensor", p),)
    return TaskHeading(spans, offsets, change, mean, warnings)


def _functional(segments: dict[str, knee.SegmentCalibration], thigh, shank, gyr_task: dict[str, FloatArray],
                q_es: dict[str, FloatArray], q_standing: dict[str, FloatArray],
                ) -> tuple[dict[str, knee.SegmentCalibration], list[QualityWarning]]:
    """Femur on the task's flexion axis, the tibia's rotation zeroed while standing.

    The axis is Seel's gyroscope-only estimate (:func:`estimators.joint_axis.estimate_axis`, seed 000 eqs.
    68–69), checked against the dominant axis of the filters' relative angular velocity
    (:func:`estimators.knee.flexion_axis`): a sagittal-plane task can leave Seel's problem ill-posed (on
    simulated step-ups its axis can land far off with the same residual); when the two differ by more than ``FUNCTIONAL_AXIS_AGREE_RAD`` in the
    transverse plane the relative-velocity axis is used, with a warning (it absorbs the adduction that moves
    with flexion: ~5° of adduction RMSE on simulated step-ups against 0.2–1.7° for a well-posed Seel estimate,
    ``python -m benchmarks.pipeline_accuracy --supine-roll-out 15 --calibration functional``)."""
    from estimators.joint_axis import estimate_axis

    g_t, g_s = gyr_task["thigh"], gyr_task["shank"]  # bias removed
    ok = np.all(np.isfinite(g_t), axis=1) & np.all(np.isfinite(g_s), axis=1)
    warnings: list[QualityWarning] = []
    try:
        j_rel = knee.flexion_axis(q_es["thigh"], q_es["shank"], g_t, g_s)
        j_seel, _, _ = estimate_axis(g_t[ok], g_s[ok])
        y = quat.to_matrix(segments["thigh"].q_sensor_segment)[:, 1]
        a, b = (j - np.dot(j, y) * y for j in (j_seel, j_rel))
        gap = float(np.arccos(min(1.0, abs(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)))))
        j_t = j_seel
        if gap > FUNCTIONAL_AXIS_AGREE_RAD:
            j_t = j_rel
            gap_deg = float(np.rad2deg(gap))
            warnings.append(QualityWarning(
                "functional_axis_uncertain", f"the task's gyroscopes alone place the flexion axis {gap_deg:.0f}° "
                "from the sensors' relative motion; the latter was used, adduction may read a few degrees off",
                {"angle_deg": gap_deg}))
        femur = knee.functional_calibration(segments["thigh"], j_t, label="thigh")
    except ValueError as exc:
        raise PipelineError("pipeline.functional_calibration", thigh_files=_files(thigh), shank_files=_files(shank),
                            reason=str(exc)) from None
    out = {"thigh": femur, "shank": segments["shank"]}
    delta = _standing_heading(q_standing, out, max_offset_rad=None).offset_rad
    out["shank"] = knee.turn_about_long_axis(segments["shank"], delta, label="shank")
    return out, warnings + [w for seg in SEGMENTS for w in out[seg].warnings if w.code == "functional_axis_far"]


def _files(rec) -> str:
    return ", ".join(str(getattr(f, "name", f)) for f in rec.source.get("files", ())) or rec.segment


__all__ = ["HEADING_DRIFT_TASK_WARN_RAD", "IngestionError", "PIPELINE_VERSION", "PipelineError",
           "ProcessOptions", "SessionOutcome", "TaskHeading", "process_session"]
