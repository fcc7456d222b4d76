r"""Sensor-to-segment calibration without the supine posture (standing + task) or without any posture (task only).

Clinics bring sessions without the supine recording, or with the motor task alone (factory-calibrated
sensors, a walking clip).  Both methods here return the :class:`estimators.knee.SegmentCalibration` the
pipeline already uses, one per segment, with ``method`` ``"standing_functional"`` or ``"task_functional"``.

Segment frames from a straight knee and the hinge axes (F1–F3)
--------------------------------------------------------------
*Hinge axes.*  Seel's joint-axis constraint on the two gyroscopes (Seel, Raisch & Schauer 2014; seed 000
§2.4.2 eqs. 68–69, :func:`estimators.joint_axis.estimate_axis`) gives the knee's flexion axis ``j_a`` in
thigh-sensor and ``j_b`` in shank-sensor coordinates, each up to sign.  Sagittal tasks make eq. 68 nearly
degenerate (the segments turn about one axis at nearly proportional rates, and a one-parameter family of axis
pairs fits equally well), so a small pull towards each sensor's principal rotation axis picks the member of
that family (``principal_weight``).

*Long axes.*  With the knee straight and the leg upright (standing posture, the top of a step-up,
standing before or after walking), gravity points along both long axes:
:math:`\hat y_i = \bar f_i / |\bar f_i|` over a still window (seed 004 eq. 8.1).

*Frames* (F1), per segment :math:`i`, with the sign :math:`s` of F2:

.. math:: \hat z_i = s_i\,\frac{j_i - (j_i\cdot\hat y_i)\hat y_i}{|\cdot|},\qquad \hat x_i = \hat y_i\times\hat z_i,
    \qquad R_{sensor,segment} = [\hat x_i\ \hat y_i\ \hat z_i] \quad (F1)

*Signs* (F2).  Seel's cost is blind to :math:`j\to -j` in each sensor.  (i) The *relative* sign (both
``j`` the same physical direction) is not observable from gravity (every sensor's own gravity and rate are
consistent with either sign) and in a sagittal task hardly from the gyroscopes; it comes, in this order,
from the task orientations when given (:math:`\operatorname{median}\,j_a\cdot R_{a,b}\,j_b > 0`,
:math:`R_{a,b} = R_{earth,a}^\top R_{earth,b}`), from the protocol (both sensors worn alike, so
:math:`j_a\cdot j_b > 0` in sensor coordinates, used when :math:`|j_a\cdot j_b| \ge` ``same_mounting_min_cos``),
else from Seel's own consistency test (:func:`estimators.joint_axis.estimate`).  (ii) The *overall* sign
makes z point to the body's right on both legs (ISB): knee flexion (K1) is a negative turn of the tibia
about the femoral z on either leg, so it does not depend on the side.  Gravity seen in each sensor, projected
on its hinge plane, turns by the knee angle between the sensors:

.. math:: \varphi_i = \operatorname{atan2}(f_i\cdot(j_i\times u_i),\ f_i\cdot u_i),\qquad
    \alpha = \varphi_b - \varphi_a \quad (F2)

(:math:`u_i` any fixed unit vector ⟂ :math:`j_i`), and with :math:`j = +\hat z` :math:`\alpha` is the
flexion plus a constant.  A knee flexes from full extension and hardly hyperextends, so with the right
sign the straight knee is the lower end of :math:`\alpha` over the task; with the wrong one the task runs
far below its straightest still moment.  The sign with the smaller *overshoot* (straight reference minus
the 0.5th percentile of the smoothed :math:`s\alpha`) wins; a margin below ``min_sign_margin_rad`` warns.

*Rotation zero* (F3).  Only gravity and the hinge fix the tibia, so its z is the shank's hinge axis: the
knee's internal rotation is zero at the pose where Seel's mean axis sits (on a step-up the tibial axis turns
~10° with the screw-home rotation, and on sagittal tasks Seel's ``j_b`` is poorly determined about the long
axis: this only shifts internal rotation by a constant, flexion and adduction are unaffected, because the
Grood & Suntay sequence ends with the tibial y turn).  When the orientations of the straight-knee window are
given, the tibia is turned about its long axis so that the knee's rotation is zero there
(:func:`estimators.knee.heading_offset` ``"straight_knee"`` then :func:`estimators.knee.turn_about_long_axis`).

Standing + task (c)
-------------------
The straight window is the standing posture's stillest window (:func:`estimators.knee.stillest_window`);
gyroscope biases from it; the hinge axes from the task.  ``bend_rad`` reports how far the standing posture is
from the task's straightest still moment (F2, should be ~0).

Task only (d)
-------------
The straight window is found on the task: the *stillest common window*—both sensors' gyro and
accelerometer SD below the thresholds over ``window_s`` at the same time—with the knee straight, i.e. its
:math:`s\alpha` within ``straight_tol_rad`` of the straightest still moment of the task; of those windows the
straightest is used (the extension holds of a step-up vary by a few degrees).  The biases come from the
stillest common window.  No common still window, or a task that extends the knee beyond every still moment by
more than ``max_overshoot_rad`` (the knee was never still while straight, e.g. walking without a standing
start), raises :class:`estimators.knee.CalibrationError` saying what to record.  What gravity cannot tell:
a task whose only still moments are *flexed* (a step-up without its extension holds) looks like a straight
reference with the wrong sign and a small overshoot (the impulse, 5–10°): above ``straight_tol_rad`` it warns
(``functional_overshoot``), above ``max_overshoot_rad`` it refuses.
When that overshoot follows a relative sign taken from the mounting rule and Seel's own test gives the other one
(on both protocols), the rule's assumption failed, not the posture: one sensor is turned round
(:class:`SensorTurnedError`; on simulated walks with the shank turned 180° about its long axis the overshoot was
25–43°, seeds 1–8, while Seel agreed with the mounting on all eight walks worn alike).  With a standing posture the
overshoot stays small (0.1–3.2°) and Seel's sign is a coin toss on step-ups (3 of 8 agreed worn alike), so there the
other relative sign is tried: one sensor turned round when its sign margin (F2) beats the mounting's by more than
``turned_margin_gap_rad`` (simulated step-ups, seeds 1–8: margin 84–87° with the right sign, 17–22° with the
wrong one; 48° of flexion RMSE went unnoticed).

How the pipeline calls them
---------------------------
Both return :class:`FunctionalCalibration`; ``.segments`` is the ``{"thigh", "shank"}`` dict of
:class:`~estimators.knee.SegmentCalibration` that ``process_session`` uses (``gyr_bias_rad_s``,
``q_sensor_segment``, ``method``, ``warnings`` with codes and params).  Orientations are optional; with 9D
orientations the relative sign is safer and the rotation zero is the standing knee's, so call twice: first
without them (biases), run the filter on bias-free gyroscopes, then again with them::

    # (c) standing + task
    cal = functional.standing_task_calibration((st_t.acc, st_t.gyr), (st_s.acc, st_s.gyr),
                                               (task_t.acc, task_t.gyr), (task_s.acc, task_s.gyr), fs_hz=fs)
    # ... q_es = filter over the task, q_standing = filter over the standing, gyr - cal.segments[seg].gyr_bias_rad_s
    cal = functional.standing_task_calibration(..., fs_hz=fs, q_standing=q_standing, q_task=q_es)
    # (d) task only
    cal = functional.task_calibration((task_t.acc, task_t.gyr), (task_s.acc, task_s.gyr), fs_hz=fs)
    cal = functional.task_calibration(..., fs_hz=fs, q_task=q_es)        # 9D q_es
    segments, warnings = cal.segments, list(cal.warnings)

``CalibrationError`` (a ``ValueError``) carries what was missing and what to record.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import knee
from estimators import quaternion as quat
from estimators.knee import CalibrationError, CalibrationParams, PostureWindow, SegmentCalibration
from estimators.quality import QualityWarning

FloatArray = NDArray[np.float64]

__all__ = ["FunctionalCalibration", "FunctionalFit", "FunctionalParams", "HingeAxes", "SensorTurnedError", "hinge_axes",
           "standing_task_calibration", "task_calibration"]

SEGMENTS = ("thigh", "shank")


class SensorTurnedError(CalibrationError):
    """The relative sign came from the mounting rule (both sensors worn alike, F2 i), Seel's own consistency test
    gives the other sign, and with the mounting's sign the task extends the knee beyond every straight reference by
    more than ``max_overshoot_rad``: one sensor is turned round (e.g. the shank's 180° about its long axis), which
    the mounting rule cannot see.  ``overshoot_deg`` is that extension."""

    def __init__(self, overshoot_rad: float, margin_gain_rad: float | None = None) -> None:
        self.overshoot_deg = float(np.rad2deg(overshoot_rad))
        self.margin_gain_deg = None if margin_gain_rad is None else float(np.rad2deg(margin_gain_rad))
        why = (f"the knee extended {self.overshoot_deg:.0f}° beyond its straight reference" if margin_gain_rad is None
               else f"the flexion's direction is {self.margin_gain_deg:.0f}° clearer with one sensor turned round")
        super().__init__(f"{why} with the hinge axes signed as if both sensors were worn alike: the thigh and shank "
                         "sensors do not seem to be worn on the same side of the leg (one is turned round); wear both "
                         "with the same face outwards and +y up the leg and record again")


def _check_mounting_sign(axes: HingeAxes, overshoot_rad: float, p: FunctionalParams) -> None:
    """Raise :class:`SensorTurnedError` when an overshoot beyond ``max_overshoot_rad`` follows a mounting-derived
    relative sign that Seel's disagrees with (F2 i): the mounting rule's assumption failed, not the posture."""
    if (overshoot_rad > p.max_overshoot_rad and axes.relative_sign_source == "mounting"
            and not axes.seel_sign_agrees):
        raise SensorTurnedError(overshoot_rad)
SIGN_PERCENTILE = 0.5  # the percentile of the knee angle that measures the overshoot (F2)


@dataclass(frozen=True)
class FunctionalParams:
    """Settings of :func:`standing_task_calibration` and :func:`task_calibration`.

    window_s : still window searched on the task, s (default 0.5: the extension holds of a step-up last ~0.8 s).
    max_gyr_sd_rad_s, max_acc_sd_m_s2 : per-sensor total SD over the window below which it is still, rad/s and
        m/s² (default :data:`estimators.knee.STILL_MAX_GYR_SD_RAD_S`, :data:`~estimators.knee.STILL_MAX_ACC_SD_M_S2`:
        the postures' definition, 0.05 and 0.3).
    straight_tol_rad : a still window is "straight" when its knee angle (F2) is within this of the task's
        straightest still moment; the task may extend beyond its straight reference by at most this much (5°).
    min_sign_margin_rad : below this difference of overshoots between the two signs (F2) warn (3°; ~6° on
        simulated step-ups without a standing posture, where the wrong sign overshoots by the impulse, 50°+ with one).
    min_axis_angle_rad : the hinge axis must be at least this far from the long axis (60°), else error.
    max_axis_residual_rad_s : Seel's RMS residual above which to warn (0.35; ~0.01 on simulated step-ups,
        ~0.23 on simulated gait with heel-strike wobble).
    same_mounting_min_cos : |j_a·j_b| (sensor coordinates) from which the sensors count as worn alike (0.5).
    max_overshoot_rad : the task may extend the knee at most this far beyond the straight reference (F2, 0.5th
        percentile) before the task-only method refuses: no still moment was straight (10°; simulated gait with a
        standing start reaches ~3°, a step-up ~1°).
    turned_margin_gap_rad : standing + task with a mounting-derived relative sign: one sensor is taken as turned round
        when the other relative sign's margin (F2) is larger by this much (30°; 62–70° on simulated step-ups with the
        shank turned round, seeds 1–8).
    principal_weight : the pull of Seel's axes towards each sensor's principal rotation axis
        (:func:`estimators.joint_axis.estimate_axis`; 1.0, chosen on simulated step-ups and gait, seeds 0–2: the
        femur's in-plane axis error fell from 1–23° to 0–4°; 0 is Seel's problem exactly).
    max_samples : the hinge fit uses at most this many evenly spread samples of the task (6000).
    smooth_s : moving circular mean applied to the knee angle of F2 before its percentiles, s (0.2).
    """

    window_s: float = 0.5
    max_gyr_sd_rad_s: float = knee.STILL_MAX_GYR_SD_RAD_S
    max_acc_sd_m_s2: float = knee.STILL_MAX_ACC_SD_M_S2
    straight_tol_rad: float = float(np.deg2rad(5.0))
    min_sign_margin_rad: float = float(np.deg2rad(3.0))
    min_axis_angle_rad: float = float(np.deg2rad(60.0))
    max_axis_residual_rad_s: float = 0.35
    same_mounting_min_cos: float = 0.5
    max_overshoot_rad: float = float(np.deg2rad(10.0))
    turned_margin_gap_rad: float = float(np.deg2rad(30.0))
    principal_weight: float = 1.0
    max_samples: int = 6000
    smooth_s: float = 0.2

    def __post_init__(self) -> None:
        for name in ("window_s", "max_gyr_sd_rad_s", "max_acc_sd_m_s2", "straight_tol_rad", "min_sign_margin_rad",
                     "min_axis_angle_rad", "max_axis_residual_rad_s", "same_mounting_min_cos", "smooth_s", "max_overshoot_rad",
                     "turned_margin_gap_rad"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
        if not (np.isfinite(self.principal_weight) and self.principal_weight >= 0.0):
            raise ValueError(f"principal_weight must be a finite number >= 0, got {self.principal_weight!r}")
        if self.max_samples < 100:
            raise ValueError(f"max_samples must be at least 100, got {self.max_samples!r}")


@dataclass(frozen=True)
class HingeAxes:
    r"""Result of :func:`hinge_axes`.

    j_thigh, j_shank : (3,) unit flexion axes in thigh / shank sensor coordinates, the same physical direction
        (the overall sign is fixed later, F2).
    residual_rad_s : RMS of Seel's residual (eq. 68).
    relative_sign_source : ``"orientation"``, ``"mounting"`` or ``"seel"`` (F2 i).
    seel_sign_agrees : Seel's own relative sign equals the one used.
    principal_thigh, principal_shank : (3,) each sensor's principal rotation axis (dominant eigenvector of
        :math:`\sum\omega\omega^\top`), signed like ``j``: the fallback of F1 when Seel's axis of a segment lands
        near its long axis (Seel's problem is nearly degenerate on sagittal tasks, where the two segments turn
        about one axis at proportional rates: a one-parameter family of axes fits equally well).
    """

    j_thigh: FloatArray
    j_shank: FloatArray
    residual_rad_s: float
    relative_sign_source: str
    seel_sign_agrees: bool
    principal_thigh: FloatArray
    principal_shank: FloatArray


@dataclass(frozen=True)
class FunctionalFit:
    """Quality figures of a functional calibration (both segments).

    axes : :class:`HingeAxes` (signed: z to the right).   straight_source : ``"standing"`` or ``"task"``.
    window : :class:`~estimators.knee.PostureWindow` per segment (``{"thigh": .., "shank": ..}``) of the straight knee,
        in the recording it comes from (standing, or task samples).
    bias_window : the windows the gyroscope biases come from (the stillest common window of the task for (d)).
    bend_rad : knee angle (F2) of the straight window minus the task's straightest still moment (0 for (d)
        by construction unless the straightest is not the chosen one).
    straight_gravity_angle_rad : angle between the two straight-knee gravity directions projected on the
        planes ⟂ their hinge axes, measured from the task's straightest still moment: the same as ``bend_rad``
        in absolute value; kept under the name the report uses.
    n_straight_windows : still windows of the task within ``straight_tol_rad`` of straight.
    overshoot_rad : how far the task's (0.5th-percentile) knee angle goes below the straight reference (F2).
    sign_margin_rad : overshoot of the rejected sign minus that of the chosen one (F2).
    task_flexion_median_rad : median of the task's smoothed knee angle from gravity relative to straight.
    heading_offset_rad : the tibia's turn about its long axis (F3), or None without orientations.
    hinge_tilt_gap_rad : |∠(ŷ_thigh, j_thigh) − ∠(ŷ_shank, j_shank)|: a turn about the hinge keeps the angle
        between gravity and the axis, so at a straight (or any) knee both sensors should see the same; a gap
        means an axis tilted out of its plane (Seel's shank axis on sagittal tasks) or a knee not straight
        in the frontal plane.
    """

    axes: HingeAxes
    straight_source: str
    window: dict
    bias_window: dict
    bend_rad: float
    n_straight_windows: int
    overshoot_rad: float
    sign_margin_rad: float
    task_flexion_median_rad: float
    heading_offset_rad: float | None
    hinge_tilt_gap_rad: float = float("nan")

    @property
    def straight_gravity_angle_rad(self) -> float:
        return abs(self.bend_rad)


@dataclass(frozen=True)
class FunctionalCalibration:
    """Result of both methods: ``thigh`` and ``shank`` :class:`~estimators.knee.SegmentCalibration`, ``fit``
    (:class:`FunctionalFit`) and ``warnings`` (both segments' and the fit's, once)."""

    thigh: SegmentCalibration
    shank: SegmentCalibration
    fit: FunctionalFit
    warnings: tuple[QualityWarning, ...]

    @property
    def segments(self) -> dict[str, SegmentCalibration]:
        return {"thigh": self.thigh, "shank": self.shank}


# ------------------------------------------------------------------------------------------ helpers
def _imu(rec, what: str) -> tuple[FloatArray, FloatArray]:
    try:
        acc, gyr = rec
    except (TypeError, ValueError):
        raise ValueError(f"{what}: pass the recording as (acc, gyr), both (N, 3)") from None
    a, g = np.asarray(acc, dtype=np.float64), np.asarray(gyr, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or g.shape != a.shape:
        raise ValueError(f"{what}: acc and gyr must both have shape (N, 3), got {a.shape} and {g.shape}")
    return a, g


def _pair(thigh, shank, what: str) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    at, gt = _imu(thigh, f"thigh {what}")
    as_, gs = _imu(shank, f"shank {what}")
    if len(at) != len(as_):
        raise ValueError(f"{what}: the thigh and shank recordings must share one time grid, got {len(at)} and "
                         f"{len(as_)} samples; resample them first")
    return at, gt, as_, gs


def _moving(x: FloatArray, w: int) -> tuple[FloatArray, FloatArray]:
    """Means (M, 3) and total variances (M,) of every window of w samples (M = N − w + 1)."""
    x = x - np.nanmean(x, axis=0)
    x = np.where(np.isfinite(x), x, 0.0)
    c1 = np.concatenate([np.zeros((1, 3)), np.cumsum(x, axis=0)])
    c2 = np.concatenate([np.zeros((1, 3)), np.cumsum(x * x, axis=0)])
    m = (c1[w:] - c1[:-w]) / w
    return m, np.maximum((c2[w:] - c2[:-w]) / w - m * m, 0.0).sum(axis=1) * w / (w - 1)


def _window(a: FloatArray, g: FloatArray, start: int, w: int, fs_hz: float, p: FunctionalParams) -> PostureWindow:
    acc, gyr = a[start:start + w], g[start:start + w]
    mean_a = acc.mean(axis=0)
    sd_g = float(np.sqrt(np.sum(gyr.var(axis=0, ddof=1))))
    sd_a = float(np.sqrt(np.sum(acc.var(axis=0, ddof=1))))
    return PostureWindow(start, start + w, float(fs_hz), mean_a, mean_a / np.linalg.norm(mean_a), sd_g, sd_a,
                         bool(sd_g <= p.max_gyr_sd_rad_s and sd_a <= p.max_acc_sd_m_s2), gyr.mean(axis=0))


def _plane_basis(j: FloatArray) -> tuple[FloatArray, FloatArray]:
    c = np.eye(3)[int(np.argmin(np.abs(j)))]
    u = np.cross(j, c)
    u /= np.linalg.norm(u)
    return u, np.cross(j, u)


def _gravity_angle(f: FloatArray, j: FloatArray) -> FloatArray:
    """φ of F2: the angle of f about j in a fixed basis of the plane ⟂ j."""
    u, v = _plane_basis(j)
    return np.arctan2(f @ v, f @ u)


def _knee_from_gravity(f_a: FloatArray, f_b: FloatArray, j_a: FloatArray, j_b: FloatArray) -> FloatArray:
    """α = φ_b − φ_a (F2) as unit complex numbers (to average and wrap safely)."""
    return np.exp(1j * (_gravity_angle(f_b, j_b) - _gravity_angle(f_a, j_a)))


def _smooth(z: FloatArray, n: int) -> FloatArray:
    if n <= 1 or len(z) <= n:
        return z
    c = np.concatenate([[0.0], np.cumsum(z)])
    out = z.copy()
    h = n // 2
    out[h:len(z) - n + 1 + h] = (c[n:] - c[:-n]) / n
    return out


def _warn(code: str, message: str, **params) -> QualityWarning:
    return QualityWarning(code, message, params)


# ------------------------------------------------------------------------------------------ hinge axes
def hinge_axes(acc_thigh: ArrayLike, gyr_thigh: ArrayLike, acc_shank: ArrayLike, gyr_shank: ArrayLike, *,
               fs_hz: float, q_earth_thigh: ArrayLike | None = None, q_earth_shank: ArrayLike | None = None,
               params: FunctionalParams | None = None) -> HingeAxes:
    """The knee's flexion axis in both sensors' coordinates, the same physical direction (F2 i).

    acc_*, gyr_* : (N, 3) task recordings on one grid, m/s² and *bias-free* rad/s (NaN rows are dropped).
    q_earth_thigh, q_earth_shank : optional (N, 4) ``q_earth_sensor`` of an orientation filter over the task, 9D
        (both referenced to magnetic north; a 6D run's arbitrary relative heading can flip the sign when it
        exceeds 90°); when given they fix the relative sign (F2 i).
    Seel's axes (seed 000 eqs. 68–69) via :func:`estimators.joint_axis.estimate` on at most
    ``params.max_samples`` evenly spread samples."""
    from estimators import joint_axis

    p = FunctionalParams() if params is None else params
    at, gt, as_, gs = _pair((acc_thigh, gyr_thigh), (acc_shank, gyr_shank), "task")
    ok = np.all(np.isfinite(np.hstack([at, gt, as_, gs])), axis=1)
    if ok.sum() < 200:
        raise CalibrationError(f"the hinge axes need at least 200 task samples with both sensors, got {int(ok.sum())}; "
                               "record the motor task (10 cycles) with both sensors")
    idx = np.flatnonzero(ok)
    idx = idx[::max(1, int(np.ceil(len(idx) / p.max_samples)))]
    fs_fit = fs_hz * len(idx) / np.count_nonzero(ok)  # the rate of the thinned samples (angular accelerations)
    fit = joint_axis.estimate(at[idx], gt[idx], as_[idx], gs[idx], fs_hz=fs_fit, principal_weight=p.principal_weight)
    j_a, j_b = fit.j_a, fit.j_b
    seel = 1.0
    source = "seel"
    sign = seel
    if q_earth_thigh is not None and q_earth_shank is not None:
        qt, qs = quat.as_quaternion(q_earth_thigh), quat.as_quaternion(q_earth_shank)
        if qt.shape != (len(at), 4) or qs.shape != (len(at), 4):
            raise ValueError(f"q_earth_thigh and q_earth_shank must have shape ({len(at)}, 4), got {qt.shape}, {qs.shape}")
        c = quat.rotate(quat.multiply(quat.conjugate(qt[ok]), qs[ok]), j_b) @ j_a
        c = c[np.isfinite(c)]
        if len(c):
            sign, source = (1.0 if np.median(c) >= 0.0 else -1.0), "orientation"
    if source == "seel" and abs(np.dot(j_a, j_b)) >= p.same_mounting_min_cos:
        sign, source = (1.0 if np.dot(j_a, j_b) >= 0.0 else -1.0), "mounting"
    j_b = sign * j_b
    pa, pb = (np.linalg.eigh(g[ok].T @ g[ok])[1][:, -1] for g in (gt, gs))
    pa, pb = pa * np.sign(np.dot(pa, j_a) or 1.0), pb * np.sign(np.dot(pb, j_b) or 1.0)
    return HingeAxes(j_a.copy(), j_b, fit.axis_rms_rad_s, source, bool(sign == seel), pa, pb)


# ------------------------------------------------------------------------------------------ common steps
def _still_windows(at, gt, as_, gs, w: int, p: FunctionalParams) -> tuple[FloatArray, FloatArray]:
    """Per window start: both sensors still (bool) and the summed stillness score (inf where a NaN is inside)."""
    bad = ~np.all(np.isfinite(np.hstack([at, gt, as_, gs])), axis=1)
    nbad = np.concatenate([[0], np.cumsum(bad)])
    finite = (nbad[w:] - nbad[:-w]) == 0
    score = np.zeros(len(at) - w + 1)
    still = finite.copy()
    for a, g in ((at, gt), (as_, gs)):
        _, vg = _moving(g, w)
        _, va = _moving(a, w)
        still &= (vg <= p.max_gyr_sd_rad_s**2) & (va <= p.max_acc_sd_m_s2**2)
        score += vg / p.max_gyr_sd_rad_s**2 + va / p.max_acc_sd_m_s2**2
    return still, np.where(finite, score, np.inf)


def _sign_and_straight(alpha: FloatArray, still_alpha: FloatArray, ref: complex | None, n_smooth: int
                       ) -> tuple[float, float, float, FloatArray, FloatArray]:
    """Overall sign (F2 ii).  alpha: (N,) unit complex knee angle over the task; still_alpha: (K,) the same
    averaged over its still windows; ref: the standing posture's (None: the straight reference is the task's
    straightest still moment).  Returns (sign, overshoot, margin, task flexion (N,) and still windows'
    flexion (K,), both relative to the straight reference)."""
    centre = np.angle(np.mean(still_alpha)) if ref is None else np.angle(ref)
    a = np.angle(_smooth(alpha, n_smooth) * np.exp(-1j * centre))
    s_still = np.angle(still_alpha * np.exp(-1j * centre))
    out = []
    for s in (1.0, -1.0):
        straight = 0.0 if ref is not None else float(np.min(s * s_still))
        out.append((straight - float(np.percentile(s * a, SIGN_PERCENTILE)), s, straight))
    out.sort()
    (over, s, straight), (over_bad, _, _) = out
    return s, over, over_bad - over, s * a - straight, s * s_still - straight


def _frame(y: FloatArray, j: FloatArray, label: str, p: FunctionalParams) -> tuple[FloatArray, float]:
    angle = float(np.arccos(np.clip(abs(np.dot(j, y)), 0.0, 1.0)))
    if angle < p.min_axis_angle_rad:
        raise CalibrationError(
            f"{label}: the knee's hinge axis is only {np.rad2deg(angle):.0f}° from the segment's long axis "
            f"(at least {np.rad2deg(p.min_axis_angle_rad):.0f}° expected); the task did not flex the knee about a "
            "mediolateral axis: record a step-up or walking, or the standing and supine postures")
    z = j - np.dot(j, y) * y
    z /= np.linalg.norm(z)
    return quat.from_matrix(np.column_stack([np.cross(y, z), y, z])), float(np.arccos(np.clip(np.dot(j, y), -1, 1)))


def _build(windows: dict, bias: dict, axes: HingeAxes, sign: float, method: str, warnings: list[QualityWarning],
           q_straight: dict | None, fit_kwargs: dict, p: FunctionalParams) -> FunctionalCalibration:
    signed = replace(axes, j_thigh=sign * axes.j_thigh, j_shank=sign * axes.j_shank,
                     principal_thigh=sign * axes.principal_thigh, principal_shank=sign * axes.principal_shank)
    cals = {}
    for seg, j, j_pc in (("thigh", signed.j_thigh, signed.principal_thigh),
                         ("shank", signed.j_shank, signed.principal_shank)):
        y = windows[seg].gravity_sensor
        near = float(np.arccos(np.clip(abs(np.dot(j, y)), 0.0, 1.0)))
        if near < p.min_axis_angle_rad:
            warnings.append(_warn("functional_axis_principal",
                                  f"{seg}: the knee's hinge axis from both gyroscopes lies {np.rad2deg(near):.0f}° from the "
                                  f"segment's long axis; the {seg} sensor's own main rotation axis was used instead "
                                  "(internal rotation may be offset by several degrees)",
                                  segment=seg, angle_deg=float(np.rad2deg(near))))
            j = j_pc
        q, angle = _frame(y, j, seg, p)
        cals[seg] = SegmentCalibration(q, angle, windows[seg], windows[seg], (), method=method,
                                       bias_rad_s=bias[seg].gyr_mean_rad_s.copy())
    delta = None
    if q_straight is not None:
        q_seg = {seg: knee.segment_orientation(q_straight[seg], cals[seg].q_sensor_segment) for seg in SEGMENTS}
        delta = knee.heading_offset(q_seg["thigh"], q_seg["shank"], method="straight_knee").offset_rad
        turned = knee.turn_about_long_axis(cals["shank"], delta, label="shank")
        cals["shank"] = replace(cals["shank"], q_sensor_segment=turned.q_sensor_segment)
    gap = abs(cals["thigh"].angle_between_postures_rad - cals["shank"].angle_between_postures_rad)
    fit = FunctionalFit(axes=signed, heading_offset_rad=delta, hinge_tilt_gap_rad=gap, **fit_kwargs)
    if signed.residual_rad_s > p.max_axis_residual_rad_s:
        warnings.append(_warn("functional_axis_residual",
                              f"the knee's hinge axis fits the task's gyroscopes with {signed.residual_rad_s:.2f} rad/s "
                              f"RMS residual (more than {p.max_axis_residual_rad_s:.2f}); the sensors may have moved on "
                              "the skin or the task was not a knee flexion: check the straps and record the task again",
                              residual_rad_s=signed.residual_rad_s, max_rad_s=p.max_axis_residual_rad_s))
    if fit.sign_margin_rad < p.min_sign_margin_rad:
        warnings.append(_warn("functional_sign_uncertain",
                              f"the direction of knee flexion is uncertain (margin {np.rad2deg(fit.sign_margin_rad):.0f}°, "
                              f"expected more than {np.rad2deg(p.min_sign_margin_rad):.0f}°); the task should flex the knee "
                              "from full extension: check that flexion is positive in the report",
                              margin_deg=float(np.rad2deg(fit.sign_margin_rad)),
                              min_deg=float(np.rad2deg(p.min_sign_margin_rad))))
    warnings = tuple(warnings)
    cals = {seg: replace(c, warnings=tuple(w for w in warnings if w.params.get("segment") in (None, seg)),
                         quality=fit) for seg, c in cals.items()}
    return FunctionalCalibration(cals["thigh"], cals["shank"], fit, warnings)


# ------------------------------------------------------------------------------------------ (c) standing + task
def standing_task_calibration(standing_thigh, standing_shank, task_thigh, task_shank, *, fs_hz: float,
                              q_standing: dict | None = None, q_task: dict | None = None,
                              params: FunctionalParams | None = None,
                              posture_params: CalibrationParams | None = None) -> FunctionalCalibration:
    """Standing + task calibration (module docstring, (c)): y from standing gravity, z from the task's hinge axes.

    standing_thigh, standing_shank : ``(acc, gyr)`` of the standing posture, each (N, 3) m/s², rad/s (raw: the
        gyroscope bias is measured here and removed from the task).  The two may have different lengths.
    task_thigh, task_shank : ``(acc, gyr)`` of the task on one grid (M, 3).   fs_hz : rate of all four.
    q_standing : optional ``{"thigh": (N, 4), "shank": (N, 4)}`` ``q_earth_sensor`` over the standing recordings
        (any filter, same length as each): zeroes the knee's rotation while standing (F3).
    q_task : optional ``{"thigh": (M, 4), "shank": (M, 4)}`` over the task: the relative sign of the axes (F2 i).
    Returns :class:`FunctionalCalibration` (``method="standing_functional"``).  Raises
    :class:`~estimators.knee.CalibrationError` when the standing has no usable window or the axis is unusable.
    """
    p = FunctionalParams() if params is None else params
    pp = CalibrationParams() if posture_params is None else posture_params
    at, gt, as_, gs = _pair(task_thigh, task_shank, "task")
    stand, warnings = {}, []
    for seg, rec in (("thigh", standing_thigh), ("shank", standing_shank)):
        a, g = _imu(rec, f"{seg} standing")
        stand[seg] = knee.stillest_window(a, g, fs_hz=fs_hz, params=pp, what=f"{seg} standing")
        warnings += knee._window_warnings(stand[seg], "standing", seg, pp, len(a))
    gt, gs = gt - stand["thigh"].gyr_mean_rad_s, gs - stand["shank"].gyr_mean_rad_s
    qt = None if q_task is None else q_task["thigh"]
    qs = None if q_task is None else q_task["shank"]
    w = max(2, int(round(p.window_s * fs_hz)))
    if len(at) < w:  # the straight-knee check compares the task's still windows of window_s
        raise CalibrationError(f"the task recording lasts {len(at) / fs_hz:.2f} s, shorter than the {p.window_s:.1f} s "
                               "still window the calibration compares with the standing posture; record the whole "
                               "motor task (10 cycles, or 10 s of walking)")
    axes = hinge_axes(at, gt, as_, gs, fs_hz=fs_hz, q_earth_thigh=qt, q_earth_shank=qs, params=p)
    still, _ = _still_windows(at, gt, as_, gs, w, p)
    starts = np.flatnonzero(still)
    alpha = _knee_from_gravity(at, as_, axes.j_thigh, axes.j_shank)
    ref = complex(_knee_from_gravity(stand["thigh"].acc_mean_m_s2[None], stand["shank"].acc_mean_m_s2[None],
                                     axes.j_thigh, axes.j_shank)[0])
    c = np.concatenate([[0.0], np.cumsum(np.where(np.isfinite(alpha), alpha, 0.0))])
    still_alpha = (c[starts + w] - c[starts]) / w
    ok = np.isfinite(alpha)
    sign, over, margin, flex, bend_still = _sign_and_straight(alpha[ok], still_alpha, ref, int(p.smooth_s * fs_hz))
    _check_mounting_sign(axes, over, p)
    if axes.relative_sign_source == "mounting":  # the other relative sign, to see whether one sensor is turned round
        alpha_f = _knee_from_gravity(at, as_, axes.j_thigh, -axes.j_shank)
        ref_f = complex(_knee_from_gravity(stand["thigh"].acc_mean_m_s2[None], stand["shank"].acc_mean_m_s2[None],
                                           axes.j_thigh, -axes.j_shank)[0])
        c_f = np.concatenate([[0.0], np.cumsum(np.where(np.isfinite(alpha_f), alpha_f, 0.0))])
        _, over_f, margin_f, _, _ = _sign_and_straight(alpha_f[ok], (c_f[starts + w] - c_f[starts]) / w, ref_f,
                                                       int(p.smooth_s * fs_hz))
        if margin_f - margin > p.turned_margin_gap_rad and over_f <= p.straight_tol_rad:
            raise SensorTurnedError(over, margin_f - margin)
    bend = float(-np.min(bend_still)) if len(bend_still) else 0.0  # standing minus the task's straightest still moment
    if abs(bend) > p.straight_tol_rad:
        warnings.append(_warn("functional_standing_not_straight",
                              f"the standing posture's knee is {np.rad2deg(bend):.0f}° from the task's straightest still "
                              f"moment (accepted {np.rad2deg(p.straight_tol_rad):.0f}°); stand with the knees fully "
                              "extended for the standing recording",
                              bend_deg=float(np.rad2deg(bend)), max_deg=float(np.rad2deg(p.straight_tol_rad))))
    fit_kwargs = dict(straight_source="standing", window=stand, bias_window=stand, bend_rad=bend,
                      n_straight_windows=_count_disjoint(starts[np.abs(bend_still) <= p.straight_tol_rad], w),
                      overshoot_rad=over, sign_margin_rad=margin, task_flexion_median_rad=float(np.median(flex)))
    q_st = None
    if q_standing is not None:
        q_st = {seg: quat.as_quaternion(q_standing[seg])[stand[seg].start:stand[seg].stop] for seg in SEGMENTS}
        n = min(len(q_st["thigh"]), len(q_st["shank"]))
        q_st = {seg: q[:n] for seg, q in q_st.items()}
    return _build(stand, stand, axes, sign, "standing_functional", warnings, q_st, fit_kwargs, p)


# ------------------------------------------------------------------------------------------ (d) task only
def task_calibration(task_thigh, task_shank, *, fs_hz: float, q_task: dict | None = None,
                     params: FunctionalParams | None = None) -> FunctionalCalibration:
    """Task-only calibration (module docstring, (d)): hinge axes for z, gravity of the straight still window for y.

    task_thigh, task_shank : ``(acc, gyr)`` raw recordings of the task on one grid, (N, 3) m/s², rad/s.
    q_task : optional ``{"thigh": (N, 4), "shank": (N, 4)}`` ``q_earth_sensor`` of any filter over the task: the
        relative sign of the axes (F2 i) and the knee's rotation zero at the straight window (F3).
    Returns :class:`FunctionalCalibration` (``method="task_functional"``).  Raises
    :class:`~estimators.knee.CalibrationError` when both sensors are never still together, or never still with
    the knee straight.
    """
    p = FunctionalParams() if params is None else params
    at, gt, as_, gs = _pair(task_thigh, task_shank, "task")
    w = max(2, int(round(p.window_s * fs_hz)))
    if len(at) < 2 * w:
        raise CalibrationError(f"the task recording lasts {len(at) / fs_hz:.1f} s; a task-only calibration needs the "
                               "whole motor task (10 cycles, or 10 s of walking) with 2 s of standing still")
    still, score = _still_windows(at, gt, as_, gs, w, p)
    starts = np.flatnonzero(still)
    if len(starts) == 0:
        i = int(np.argmin(score))
        sd = {seg: _window(a, g, i, w, fs_hz, p) for seg, a, g in (("thigh", at, gt), ("shank", as_, gs))}
        raise CalibrationError(
            f"the task has no {p.window_s:.1f} s in which both sensors are still together (stillest at "
            f"{i / fs_hz:.1f} s: gyro SD thigh {np.rad2deg(sd['thigh'].gyr_sd_rad_s):.1f}°/s, shank "
            f"{np.rad2deg(sd['shank'].gyr_sd_rad_s):.1f}°/s, limit {np.rad2deg(p.max_gyr_sd_rad_s):.1f}°/s), so no "
            "straight-knee reference exists; record 2 s of standing still with the knee straight before or after "
            "the task, or a standing posture")
    best = int(starts[np.argmin(score[starts])])
    bias = {seg: _window(a, g, best, w, fs_hz, p) for seg, a, g in (("thigh", at, gt), ("shank", as_, gs))}
    gt, gs = gt - bias["thigh"].gyr_mean_rad_s, gs - bias["shank"].gyr_mean_rad_s
    qt = None if q_task is None else q_task["thigh"]
    qs = None if q_task is None else q_task["shank"]
    axes = hinge_axes(at, gt, as_, gs, fs_hz=fs_hz, q_earth_thigh=qt, q_earth_shank=qs, params=p)
    alpha = _knee_from_gravity(at, as_, axes.j_thigh, axes.j_shank)
    c = np.concatenate([[0.0], np.cumsum(np.where(np.isfinite(alpha), alpha, 0.0))])
    still_alpha = (c[starts + w] - c[starts]) / w
    ok = np.isfinite(alpha)
    sign, over, margin, flex, bend_all = _sign_and_straight(alpha[ok], still_alpha, None, int(p.smooth_s * fs_hz))
    _check_mounting_sign(axes, over, p)
    if over > p.max_overshoot_rad:
        raise CalibrationError(
            f"the knee extended {np.rad2deg(over):.0f}° further during the task than in any moment both sensors were "
            f"still (accepted {np.rad2deg(p.max_overshoot_rad):.0f}°), so the knee was never still while straight; "
            "record 2 s of standing still with the knee straight before or after the task, or a standing posture")
    warnings = []
    if over > p.straight_tol_rad:
        warnings.append(_warn("functional_overshoot",
                              f"the knee extended {np.rad2deg(over):.0f}° further during the task than in its straightest "
                              f"still moment (expected less than {np.rad2deg(p.straight_tol_rad):.0f}°); if the knee was never "
                              "still while straight the calibration is wrong: record 2 s of standing still with the knee "
                              "straight before or after the task", overshoot_deg=float(np.rad2deg(over)),
                              max_deg=float(np.rad2deg(p.straight_tol_rad))))
    cand = starts[bend_all <= p.straight_tol_rad]
    i = int(starts[np.argmin(bend_all)])
    win = {seg: _window(a, g, i, w, fs_hz, p) for seg, a, g in (("thigh", at, gt + bias["thigh"].gyr_mean_rad_s),
                                                                ("shank", as_, gs + bias["shank"].gyr_mean_rad_s))}
    fit_kwargs = dict(straight_source="task", window=win, bias_window=bias, bend_rad=float(np.min(bend_all)),
                      n_straight_windows=_count_disjoint(cand, w), overshoot_rad=over, sign_margin_rad=margin,
                      task_flexion_median_rad=float(np.median(flex)))
    q_st = None if q_task is None else {seg: quat.as_quaternion(q_task[seg])[i:i + w] for seg in SEGMENTS}
    return _build(win, bias, axes, sign, "task_functional", warnings, q_st, fit_kwargs, p)


def _count_disjoint(starts: FloatArray, w: int) -> int:
    n, last = 0, -np.inf
    for s in starts:
        if s >= last + w:
            n, last = n + 1, s
    return n
