r"""Knee kinematics from two segment-mounted sensors: sensor-to-segment calibration and knee angles.

Frames (``shared/DESIGN.md`` §3): earth ENU; segment frames ISB, x anterior, y proximal along the
long axis, z to the right of the body — for *both* legs (on the left leg z points medially).
``q_a_b`` maps frame-b coordinates to frame a.  Femur = thigh segment, tibia = shank segment.

Sensor-to-segment calibration (seed 004 §8.3, two static postures)
------------------------------------------------------------------
Standing (N-pose): the segment's long axis is vertical, so the mean specific force over the
stillest window, in sensor coordinates, is the segment's y axis (eq. 8.1):
:math:`\hat y = \bar f_{stand}/|\bar f_{stand}|`.
Supine, knees extended, toes up: the anterior axis is vertical, :math:`\hat a = \bar f_{sup}/|\bar f_{sup}|`
(the seed's :math:`Z_{aux}`, eq. 8.2).  Orthonormalised with y kept exact (eqs. 8.3–8.6):

.. math::
    \hat z = \frac{\hat a \times \hat y}{|\hat a \times \hat y|},\qquad \hat x = \hat y \times \hat z,
    \qquad R_{sensor,segment} = [\hat x\ \hat y\ \hat z] \quad (8.7\text{–}8.8)

The seed labels its segment axes (X, Y, Z) = (−z, y, x) of ISB: its ``X = Y × Z_aux`` is our −z and
its ``Z = X × Y`` our x, so this is the same construction written in ISB names.  The columns are the
segment axes in sensor coordinates, so the matrix is ``q_sensor_segment`` (segment → sensor); the
simulator's mounting ``q_segment_sensor`` is its inverse.  Nothing depends on the leg: z = x × y
points to the right of the body on both legs.  Only gravity defines the segment frame; its heading
comes from the sensor's orientation filter.  The postures are distinct when the angle between the
two gravity directions is near 90°; at 0° or 180° the anterior axis is undefined.
Sessions without the supine posture (standing + task) or without any posture (the task alone) are
calibrated from the knee's hinge axes instead: :mod:`estimators.functional`.

Knee kinematics (seed eqs. 6.1–6.3 generalised)
-----------------------------------------------
.. math::
    q_{earth,seg} = q_{earth,sensor} \otimes q_{sensor,seg} \quad (6.1'),\qquad
    q_{femur,tibia} = q_{earth,femur}^* \otimes q_{earth,tibia} \quad (6.2')

The seed's eq. 6.3 (right-multiplying by the knee quaternion of the calibration instant) is replaced
by the per-segment calibration (6.1'), which makes the knee quaternion identity in the standing posture.

Grood & Suntay angles (K1): the joint coordinate system's axes are the femoral z (flexion), the
tibial y (rotation) and the floating axis between them (ad/abduction), the intrinsic Z-X'-Y'' sequence

.. math::
    q_{femur,tibia} = \exp(-\phi\,\hat z)\otimes\exp(s\,\alpha\,\hat x)\otimes\exp(s\,\rho\,\hat y)\quad (K1)

with flexion :math:`\phi` (+ flexed: the distal tibia swings posteriorly, a negative turn about z),
adduction :math:`\alpha` (+ varus), internal rotation :math:`\rho` (+ internal), and :math:`s = +1`
right, :math:`-1` left (mirror: z is lateral on the right leg, medial on the left).  With
:math:`R = R_z(-\phi)R_x(s\alpha)R_y(s\rho)`: :math:`s\alpha = \arcsin R_{21}`,
:math:`-\phi = \operatorname{atan2}(-R_{01}, R_{11})`, :math:`s\rho = \operatorname{atan2}(-R_{20}, R_{22})` (K2).
This module is the project's single definition of K1/K2; the simulator imports it.

Thesis-compatible angles: :func:`estimators.quaternion.euler_zyx_thesis` (seed eq. 4.19) applied to
:math:`q_{femur,tibia}` gives (ψ, θ, φ) = the intrinsic ZYX angles of :math:`q_{tibia,femur}`; about
ISB axes z, y, x they read flexion = ψ, internal rotation = −sθ, adduction = −sφ (equal to K2 to first
order; at large flexion the ZYX order mixes adduction and rotation).

Relative heading (6D or disturbed magnetometer)
-----------------------------------------------
Without a shared magnetic north, the two filters' earth frames differ by a constant turn δ about
the vertical: :math:`q_{earth,femur} \approx \exp(\delta\hat z)\otimes q_{earth,tibia}` when the knee
is straight (standing, or the full-extension holds of a step-up).  Least squares over the samples,
:math:`\min_\delta\sum\|R_z(\delta)R_t - R_f\|_F^2`, has the closed form
:math:`\delta = \operatorname{atan2}(N_{01} - N_{10}, N_{00} + N_{11})`, :math:`N = \sum R_t R_f^\top` (H1).
The ``"hinge"`` variant only asks the flexion axes to be parallel (any knee flexion),
:math:`N = \sum \hat z_t \hat z_f^\top` in earth coordinates (H2).  See :func:`heading_offset` for how
the pipeline uses them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.quality import QualityWarning

FloatArray = NDArray[np.float64]

__all__ = ["STILL_MAX_ACC_SD_M_S2", "STILL_MAX_GYR_SD_RAD_S",
           "CalibrationError", "CalibrationParams", "HeadingOffset", "PostureWindow", "QualityWarning",
           "SegmentCalibration", "apply_heading_offset", "calibrate_segment", "flexion_axis", "functional_calibration",
           "heading_offset", "knee_angles", "turn_about_long_axis",
           "knee_quaternion", "mounting_warnings", "q_femur_tibia", "segment_orientation", "side_sign",
           "stillest_window", "task_warnings"]

_Z = np.array([0.0, 0.0, 1.0])


class CalibrationError(ValueError):
    """The postures cannot define a segment frame (no still data, or the two gravity directions coincide)."""


def side_sign(side: str) -> float:
    """+1 for ``"right"``, −1 for ``"left"`` (the mirror factor s of K1)."""
    if side == "right":
        return 1.0
    if side == "left":
        return -1.0
    raise ValueError(f"side must be 'right' or 'left', got {side!r}")


# ------------------------------------------------------------------------------------------ knee angles
def knee_quaternion(angles_rad: ArrayLike, side: str = "right") -> FloatArray:
    """``q_femur_tibia`` (..., 4), w >= 0, from Grood & Suntay angles (..., 3) = (flexion, adduction,
    internal rotation), rad, with clinical signs for ``side`` (K1)."""
    a = np.asarray(angles_rad, dtype=np.float64)
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"angles_rad must have shape (..., 3), got {a.shape}")
    s = side_sign(side)
    turns = np.stack([-a[..., 0], s * a[..., 1], s * a[..., 2]], axis=-1)
    return quat.positive_scalar(quat.from_intrinsic(turns, "ZXY"))  # R_z(−flex) R_x(s·add) R_y(s·rot)


def knee_angles(q_femur_tibia: ArrayLike, side: str = "right", *, method: str = "grood_suntay") -> FloatArray:
    """Knee angles (..., 3) = (flexion, adduction, internal rotation), rad, clinical signs for ``side``.

    method : ``"grood_suntay"`` (K2, the inverse of K1: the clinical convention) or ``"thesis_zyx"``
        (seed eq. 4.19 via :func:`estimators.quaternion.euler_zyx_thesis`, mapped to the same names and
        signs; kept to compare with the thesis' numbers).
    """
    q = quat.as_quaternion(q_femur_tibia)
    s = side_sign(side)
    if method == "thesis_zyx":
        psi, theta, phi = np.moveaxis(quat.euler_zyx_thesis(q), -1, 0)
        return np.stack([psi, -s * phi, -s * theta], axis=-1)
    if method != "grood_suntay":
        raise ValueError(f"method must be 'grood_suntay' or 'thesis_zyx', got {method!r}")
    r = quat.to_matrix(quat.normalize(q))
    add = np.arcsin(np.clip(r[..., 2, 1], -1.0, 1.0))
    flex = -np.arctan2(-r[..., 0, 1], r[..., 1, 1])
    rot = np.arctan2(-r[..., 2, 0], r[..., 2, 2])
    return np.stack([flex, s * add, s * rot], axis=-1)


def segment_orientation(q_earth_sensor: ArrayLike, q_sensor_segment: ArrayLike) -> FloatArray:
    """``q_earth_segment = q_earth_sensor ⊗ q_sensor_segment`` (6.1'), (N, 4)."""
    return quat.multiply(q_earth_sensor, q_sensor_segment)


def q_femur_tibia(q_earth_femur: ArrayLike, q_earth_tibia: ArrayLike,
                  heading_offset_rad: float | ArrayLike = 0.0) -> FloatArray:
    """Knee quaternion ``q_earth_femur* ⊗ exp(δ ẑ) ⊗ q_earth_tibia`` (6.2'), w >= 0.

    ``heading_offset_rad`` = δ from :func:`heading_offset` (0 when both filters share magnetic north), or δ(t),
    shape (N,), from :func:`estimators.heading.constraint_heading`.
    """
    q_t = apply_heading_offset(q_earth_tibia, heading_offset_rad)
    return quat.positive_scalar(quat.multiply(quat.conjugate(q_earth_femur), q_t))


# ------------------------------------------------------------------------------------------ calibration
#: When a window counts as still (the one definition: the postures' :class:`CalibrationParams` and the task's
#: :class:`estimators.functional.FunctionalParams` default to these): the total gyroscope SD over the window below
#: this, rad/s (0.05 ≈ 3°/s; sensor noise ≈ 0.01, quiet standing sway ≈ 0.01–0.02) ...
STILL_MAX_GYR_SD_RAD_S = 0.05
#: ... and the total accelerometer SD below this, m/s².
STILL_MAX_ACC_SD_M_S2 = 0.3


@dataclass(frozen=True)
class CalibrationParams:
    """Settings of :func:`calibrate_segment`.

    window_s : length of the still window used per posture, s (default 5; the postures last ~30 s).
    max_gyr_sd_rad_s, max_acc_sd_m_s2 : total gyro (rad/s) and accelerometer (m/s²) SD over the window above which
        a posture is "not still" (default :data:`STILL_MAX_GYR_SD_RAD_S`, :data:`STILL_MAX_ACC_SD_M_S2`: 0.05, 0.3).
    min_angle_rad, max_angle_rad : angle between the two gravity directions outside which the postures
        are "not distinct" (default 60°–120°; ideal 90°).
    min_defined_angle_rad : below this angle (or above π minus it) no anterior axis can be defined:
        :class:`CalibrationError` (default 10°).
    gravity_m_s2, gravity_tolerance : expected |specific force| at rest and the relative tolerance
        (default 9.81, 0.1) before warning about units or scale.
    """

    window_s: float = 5.0
    max_gyr_sd_rad_s: float = STILL_MAX_GYR_SD_RAD_S
    max_acc_sd_m_s2: float = STILL_MAX_ACC_SD_M_S2
    min_angle_rad: float = float(np.deg2rad(60.0))
    max_angle_rad: float = float(np.deg2rad(120.0))
    min_defined_angle_rad: float = float(np.deg2rad(10.0))
    gravity_m_s2: float = 9.81
    gravity_tolerance: float = 0.1

    def __post_init__(self) -> None:
        for name in ("window_s", "max_gyr_sd_rad_s", "max_acc_sd_m_s2", "gravity_m_s2", "gravity_tolerance"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
        if not (0.0 < self.min_defined_angle_rad < self.min_angle_rad <= np.pi / 2 <= self.max_angle_rad
                < np.pi - self.min_defined_angle_rad):
            raise ValueError("angles must satisfy 0 < min_defined_angle_rad < min_angle_rad <= π/2 <= "
                             f"max_angle_rad < π − min_defined_angle_rad, got {self.min_defined_angle_rad!r}, "
                             f"{self.min_angle_rad!r}, {self.max_angle_rad!r}")


@dataclass(frozen=True)
class PostureWindow:
    """The stillest window of one static posture: samples ``[start, stop)``, its mean and spread.

    acc_mean_m_s2 : (3,) mean specific force in sensor coordinates.   gravity_sensor : (3,) its unit vector.
    gyr_sd_rad_s, acc_sd_m_s2 : total SD (root of the summed per-axis variances) over the window.
    still : both SDs below the thresholds.
    gyr_mean_rad_s : (3,) mean gyroscope reading over the window: the gyroscope's bias, since the segment is still.
    """

    start: int
    stop: int
    fs_hz: float
    acc_mean_m_s2: FloatArray
    gravity_sensor: FloatArray
    gyr_sd_rad_s: float
    acc_sd_m_s2: float
    still: bool
    gyr_mean_rad_s: FloatArray

    @property
    def start_s(self) -> float:
        return self.start / self.fs_hz

    @property
    def duration_s(self) -> float:
        return (self.stop - self.start) / self.fs_hz


@dataclass(frozen=True)
class SegmentCalibration:
    """Result of :func:`calibrate_segment` for one sensor on one segment.

    q_sensor_segment : (4,) segment → sensor (use ``q_earth_segment = q_earth_sensor ⊗ q_sensor_segment``).
    angle_between_postures_rad : angle between the standing and supine gravity directions (ideal π/2).
    standing, supine : the :class:`PostureWindow` used.   warnings : tuple of :class:`QualityWarning`.
    method : ``"static"`` (two postures), ``"functional"`` (static refined by the joint's flexion axis),
        ``"standing_functional"`` (standing + the task's hinge axes) or ``"task_functional"`` (the task alone),
        the last two from :mod:`estimators.functional`.
    axis_change_rad : functional only, the angle between the static and the functional segment axes.
    quality : :class:`estimators.functional.FunctionalFit` for the two :mod:`estimators.functional` methods
        (hinge axes, straight-knee window, sign evidence), else None.  For those methods ``standing`` and
        ``supine`` are both the straight-knee window used, and ``angle_between_postures_rad`` is the angle
        between its gravity direction and the hinge axis (ideal π/2).
    bias_rad_s : (3,) the gyroscope bias when measured apart from ``standing``/``supine`` (else None).
    gyr_bias_rad_s : (3,) the gyroscope bias seen while still (property).
    """

    q_sensor_segment: FloatArray
    angle_between_postures_rad: float
    standing: PostureWindow
    supine: PostureWindow
    warnings: tuple[QualityWarning, ...]
    method: str = "static"
    axis_change_rad: float | None = None
    quality: object | None = None
    bias_rad_s: FloatArray | None = None

    @property
    def gyr_bias_rad_s(self) -> FloatArray:
        """(3,) gyroscope bias measured while still: the mean of both postures' windows, weighted by their length
        (or ``bias_rad_s`` when a method measured it elsewhere, e.g. the task's stillest common window).

        Subtracting it before orientation estimation removes the largest MEMS error (BMI160: up to ±3 °/s)
        that filters otherwise have to learn during the motion, where some of them (Guo's bounded
        robust corrections) cannot.
        """
        if self.bias_rad_s is not None:
            return self.bias_rad_s
        n_st = self.standing.stop - self.standing.start
        n_su = self.supine.stop - self.supine.start
        return (n_st * self.standing.gyr_mean_rad_s + n_su * self.supine.gyr_mean_rad_s) / (n_st + n_su)


def _check_imu(acc: ArrayLike, gyr: ArrayLike, what: str) -> tuple[FloatArray, FloatArray]:
    a = np.asarray(acc, dtype=np.float64)
    g = np.asarray(gyr, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or g.shape != a.shape:
        raise ValueError(f"{what}: acc and gyr must both have shape (N, 3), got {a.shape} and {g.shape}")
    return a, g


def stillest_window(acc: ArrayLike, gyr: ArrayLike, *, fs_hz: float, params: CalibrationParams | None = None,
                    what: str = "posture") -> PostureWindow:
    """The window of ``params.window_s`` (or the whole recording if shorter) with the smallest
    ``gyr_sd²/max_gyr_sd² + acc_sd²/max_acc_sd²``; windows touching a NaN row are skipped."""
    p = CalibrationParams() if params is None else params
    a, g = _check_imu(acc, gyr, what)
    if not (np.isfinite(fs_hz) and fs_hz > 0.0):
        raise ValueError(f"fs_hz must be a positive rate in Hz, got {fs_hz!r}")
    n = len(a)
    w = min(max(int(round(p.window_s * fs_hz)), 2), n)
    bad = ~(np.all(np.isfinite(a), axis=1) & np.all(np.isfinite(g), axis=1))
    if n < 2 or np.all(bad):
        raise CalibrationError(f"{what}: no finite samples; record the posture again")

    def moving(x: FloatArray) -> tuple[FloatArray, FloatArray]:  # window means and total variances
        x = np.where(bad[:, None], 0.0, x - np.mean(x[~bad], axis=0))
        c1 = np.concatenate([np.zeros((1, 3)), np.cumsum(x, axis=0)])
        c2 = np.concatenate([np.zeros((1, 3)), np.cumsum(x * x, axis=0)])
        m = (c1[w:] - c1[:-w]) / w
        var = np.maximum((c2[w:] - c2[:-w]) / w - m * m, 0.0).sum(axis=1) * w / (w - 1)
        return m, var

    _, var_g = moving(g)
    _, var_a = moving(a)
    nbad = np.concatenate([[0], np.cumsum(bad)])
    ok = (nbad[w:] - nbad[:-w]) == 0
    if not np.any(ok):
        raise CalibrationError(f"{what}: every {w / fs_hz:.1f} s window contains missing samples; "
                               "record the posture again")
    score = np.where(ok, var_g / p.max_gyr_sd_rad_s**2 + var_a / p.max_acc_sd_m_s2**2, np.inf)
    i = int(np.argmin(score))
    mean_a = a[i:i + w].mean(axis=0)
    norm = float(np.linalg.norm(mean_a))
    if norm == 0.0:
        raise CalibrationError(f"{what}: the mean specific force is zero; check the accelerometer stream")
    sd_g, sd_a = float(np.sqrt(var_g[i])), float(np.sqrt(var_a[i]))
    return PostureWindow(i, i + w, float(fs_hz), mean_a, mean_a / norm, sd_g, sd_a,
                         bool(sd_g <= p.max_gyr_sd_rad_s and sd_a <= p.max_acc_sd_m_s2), g[i:i + w].mean(axis=0))


def _window_warnings(win: PostureWindow, name: str, label: str, p: CalibrationParams, n: int) -> list[QualityWarning]:
    out = []
    where = {"segment": label, "posture": name}
    duration = n / win.fs_hz
    if duration < p.window_s:
        out.append(QualityWarning("posture_too_short", f"{label}: the {name} recording lasts {duration:.1f} s, "
                                  f"less than the {p.window_s:.0f} s still window; hold the posture ~30 s",
                                  {**where, "duration_s": duration, "window_s": p.window_s}))
    if not win.still:
        gyr_sd = float(np.rad2deg(win.gyr_sd_rad_s))
        out.append(QualityWarning(
            "posture_not_still", f"{label}: the {name} posture was not still (stillest {win.duration_s:.1f} s: gyro SD "
            f"{gyr_sd:.1f}°/s, acc SD {win.acc_sd_m_s2:.2f} m/s²); repeat it without moving",
            {**where, "still_s": win.duration_s, "gyr_sd_deg_s": gyr_sd, "acc_sd_m_s2": win.acc_sd_m_s2}))
    g = float(np.linalg.norm(win.acc_mean_m_s2))
    if abs(g - p.gravity_m_s2) > p.gravity_tolerance * p.gravity_m_s2:
        out.append(QualityWarning(
            "gravity_magnitude", f"{label}: the {name} specific force is {g:.2f} m/s², not ~{p.gravity_m_s2:.2f}; "
            "check the accelerometer units (g vs m/s²) and range",
            {**where, "g_m_s2": g, "gravity_m_s2": p.gravity_m_s2}))
    return out


def calibrate_segment(acc_standing: ArrayLike, gyr_standing: ArrayLike, acc_supine: ArrayLike,
                      gyr_supine: ArrayLike, *, fs_hz: float, params: CalibrationParams | None = None,
                      label: str = "sensor") -> SegmentCalibration:
    """Sensor-to-segment calibration from the standing and supine postures (eqs. 8.1–8.8, module docstring).

    acc_* : (N, 3) specific force, m/s²; gyr_* : (N, 3) rad/s (sensor coordinates; NaN rows allowed).
    fs_hz : sampling rate of both recordings.  label : names the sensor in warning messages ("thigh").
    Raises :class:`CalibrationError` when a posture has no usable window or the two gravity directions
    are within ``min_defined_angle_rad`` of parallel; otherwise warnings only.
    """
    p = CalibrationParams() if params is None else params
    stand = stillest_window(acc_standing, gyr_standing, fs_hz=fs_hz, params=p, what=f"{label} standing")
    sup = stillest_window(acc_supine, gyr_supine, fs_hz=fs_hz, params=p, what=f"{label} supine")
    y = stand.gravity_sensor
    a_aux = sup.gravity_sensor
    angle = float(np.arctan2(np.linalg.norm(np.cross(y, a_aux)), np.dot(y, a_aux)))
    if angle < p.min_defined_angle_rad or angle > np.pi - p.min_defined_angle_rad:
        raise CalibrationError(
            f"{label}: gravity differs by only {np.rad2deg(angle):.1f}° between the standing and supine recordings "
            "(ideal 90°), so the anterior axis is undefined; check that the two recordings are different postures")
    z = np.cross(a_aux, y)  # seed eq. 8.3 (X = Y × Z_aux) in ISB names: z = −(y × a)
    z /= np.linalg.norm(z)
    x = np.cross(y, z)  # seed eq. 8.5 (Z = X × Y) in ISB names
    q = quat.from_matrix(np.column_stack([x, y, z]))
    warnings = (_window_warnings(stand, "standing", label, p, len(np.asarray(acc_standing)))
                + _window_warnings(sup, "supine", label, p, len(np.asarray(acc_supine))))
    if not (p.min_angle_rad <= angle <= p.max_angle_rad):
        deg = {"angle_deg": float(np.rad2deg(angle)), "min_deg": float(np.rad2deg(p.min_angle_rad)),
               "max_deg": float(np.rad2deg(p.max_angle_rad))}
        warnings.append(QualityWarning(
            "postures_not_distinct", f"{label}: gravity turned {deg['angle_deg']:.0f}° between standing and supine "
            f"(expected about 90°, accepted {deg['min_deg']:.0f}–{deg['max_deg']:.0f}°); "
            "the segment axes are unreliable, repeat the lying posture flat on the back, toes up",
            {"segment": label, **deg}))
    return SegmentCalibration(q, angle, stand, sup, tuple(warnings))


def flexion_axis(q_earth_thigh: ArrayLike, q_earth_shank: ArrayLike, gyr_thigh: ArrayLike, gyr_shank: ArrayLike,
                 *, min_samples: int = 200) -> FloatArray:
    r"""The knee's dominant rotation axis in the thigh sensor's coordinates, up to sign (FA1).

    The shank's angular velocity relative to the thigh, in thigh-sensor coordinates, from both sensors'
    orientations (:math:`q_{earth,sensor}`) and bias-free gyroscopes:

    .. math:: \omega_{rel} = R_{T,S}\,\omega_S - \omega_T,\qquad R_{T,S} = R_{earth,T}^\top R_{earth,S},
        \qquad \hat j = \text{dominant eigenvector of } \textstyle\sum \omega_{rel}\omega_{rel}^\top \quad (FA1)

    Unlike the gyroscope-only constraint of Seel et al. (seed 000 eqs. 68–69), which needs the segments to
    turn about more than one axis and is ill-posed for sagittal-plane tasks such as the step-up, this uses the relative heading the orientation filters
    already provide.  Rows with a missing value are skipped."""
    qt, qs = quat.as_quaternion(q_earth_thigh), quat.as_quaternion(q_earth_shank)
    gt, gs = np.asarray(gyr_thigh, dtype=np.float64), np.asarray(gyr_shank, dtype=np.float64)
    if not (qt.shape == qs.shape and qt.ndim == 2 and gt.shape == gs.shape == (len(qt), 3)):
        raise ValueError(f"orientations (N, 4) and gyroscopes (N, 3) of one grid expected, got {qt.shape}, "
                         f"{qs.shape}, {gt.shape}, {gs.shape}")
    q_ts = quat.multiply(quat.conjugate(qt), qs)
    w = quat.rotate(q_ts, gs) - gt
    ok = np.all(np.isfinite(w), axis=1)
    if ok.sum() < min_samples:
        raise CalibrationError(f"the functional axis needs at least {min_samples} samples of motion with both "
                               f"sensors, got {int(ok.sum())}")
    w = w[ok]
    return np.linalg.eigh(w.T @ w)[1][:, -1]


def functional_calibration(cal: SegmentCalibration, axis_sensor: ArrayLike, *, label: str = "sensor",
                           max_change_rad: float = float(np.deg2rad(25.0))) -> SegmentCalibration:
    r"""The femur's frame with the knee's functional flexion axis as z instead of the supine posture's (FC1–FC2).

    ``axis_sensor`` (3,) is the flexion axis in the thigh sensor's coordinates, up to sign, e.g.
    :func:`flexion_axis` over the motor task.  The long axis
    stays the standing gravity direction :math:`\hat y`; the axis is orthogonalised against it and signed
    to agree with the static z (which points to the right of the body on both legs):

    .. math::
        \hat z = s\,\frac{j - (j\cdot\hat y)\hat y}{|j - (j\cdot\hat y)\hat y|},\quad
        s = \operatorname{sign}(j\cdot\hat z_{static}),\qquad \hat x = \hat y\times\hat z \quad (FC1)

    Only the femur: the Grood & Suntay flexion axis is fixed in the femur, while in the tibia it turns with
    internal rotation (the tibia's functional axis sits off its z by the task's mean rotation, ~10° on a
    step-up).  The tibia gets its rotation zero from the standing posture instead
    (:func:`turn_about_long_axis`).  A change above ``max_change_rad`` between the static and functional z
    warns (``functional_axis_far``) (FC2).
    """
    j = np.asarray(axis_sensor, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(j)) or np.linalg.norm(j) == 0.0:
        raise CalibrationError(f"{label}: the functional axis must be a finite non-zero vector, got {j!r}")
    r_static = quat.to_matrix(cal.q_sensor_segment)
    y, z_static = r_static[:, 1], r_static[:, 2]
    z = j - np.dot(j, y) * y
    if np.linalg.norm(z) < np.sin(np.deg2rad(30.0)) * np.linalg.norm(j):
        raise CalibrationError(f"{label}: the functional flexion axis is within 30° of the segment's long axis; "
                               "the task did not flex the knee about a mediolateral axis (use the static calibration)")
    z /= np.linalg.norm(z)
    if np.dot(z, z_static) < 0.0:
        z = -z
    change = float(np.arccos(np.clip(np.dot(z, z_static), -1.0, 1.0)))
    q = quat.from_matrix(np.column_stack([np.cross(y, z), y, z]))
    return _functional_result(cal, q, change, label, max_change_rad)


def turn_about_long_axis(cal: SegmentCalibration, angle_rad: float, *, label: str = "sensor",
                         max_change_rad: float = float(np.deg2rad(25.0))) -> SegmentCalibration:
    r"""The segment frame turned by ``angle_rad`` about its long axis y (FC3):
    :math:`q_{sensor,seg}' = q_{sensor,seg}\otimes\exp(\tfrac{\gamma}{2}\hat y)`.

    While standing y is vertical, so this turns the segment's heading by γ: with γ the femur–tibia heading
    offset over the standing posture (:func:`heading_offset`, ``"straight_knee"``) the knee's internal
    rotation is zero while standing, whatever the lying posture did (FC3)."""
    q = quat.multiply(cal.q_sensor_segment, quat.from_axis_angle([0.0, 1.0, 0.0], angle_rad))
    return _functional_result(cal, q, abs(float(np.angle(np.exp(1j * angle_rad)))), label, max_change_rad)


def _functional_result(cal: SegmentCalibration, q: FloatArray, change: float, label: str,
                       max_change_rad: float) -> SegmentCalibration:
    warnings = list(cal.warnings)
    if change > max_change_rad:
        angle_deg, max_deg = float(np.rad2deg(change)), float(np.rad2deg(max_change_rad))
        warnings.append(QualityWarning(
            "functional_axis_far", f"{label}: the functional calibration turned the segment axes by "
            f"{angle_deg:.0f}° from the supine posture's (more than {max_deg:.0f}°); "
            "check the lying posture and the task",
            {"segment": label, "angle_deg": angle_deg, "max_deg": max_deg}))
    return SegmentCalibration(q, cal.angle_between_postures_rad, cal.standing, cal.supine, tuple(warnings),
                              method="functional", axis_change_rad=change)


def mounting_warnings(cal: SegmentCalibration, expected_up_sensor: ArrayLike = (0.0, 1.0, 0.0), *,
                      label: str = "sensor", max_angle_rad: float = float(np.deg2rad(90.0))) -> list[QualityWarning]:
    """Warn when the standing gravity is more than ``max_angle_rad`` from the axis the protocol expects to
    point up (default the sensor's +y, seed 004 §8.2): the sensor is probably mounted upside down.
    The calibration itself stays valid; the warning flags a protocol deviation or swapped labels."""
    e = np.asarray(expected_up_sensor, dtype=np.float64)
    angle = float(np.arccos(np.clip(np.dot(cal.standing.gravity_sensor, e / np.linalg.norm(e)), -1.0, 1.0)))
    if angle > max_angle_rad:
        axis = f"{e[0]:.2g}, {e[1]:.2g}, {e[2]:.2g}"
        return [QualityWarning("sensor_upside_down", f"{label}: standing gravity is {np.rad2deg(angle):.0f}° from "
                               f"the sensor axis [{axis}] expected up; the sensor seems mounted upside down",
                               {"segment": label, "angle_deg": float(np.rad2deg(angle)), "axis": axis})]
    return []


# ------------------------------------------------------------------------------------------ heading
@dataclass(frozen=True)
class HeadingOffset:
    """Result of :func:`heading_offset`.

    offset_rad : δ in (−π, π]; pass it to :func:`q_femur_tibia` / :func:`apply_heading_offset`.
    residual_rad : RMS remaining angle after the correction (knee-quaternion angle for ``"straight_knee"``,
        angle between the flexion axes for ``"hinge"``): large when the assumption did not hold.
    spread_rad : circular SD of the per-sample offsets (drift between the two filters' headings).
    warnings : tuple of :class:`QualityWarning`.
    """

    offset_rad: float
    residual_rad: float
    spread_rad: float
    warnings: tuple[QualityWarning, ...]


def apply_heading_offset(q_earth_tibia: ArrayLike, offset_rad: float | ArrayLike) -> FloatArray:
    """``exp(δ ẑ) ⊗ q_earth_tibia``: the tibia orientation expressed in the femur filter's earth frame.

    ``offset_rad`` is one δ or one per sample, shape (N,) (:func:`estimators.heading.constraint_heading`)."""
    d = np.asarray(offset_rad, dtype=np.float64)
    if d.ndim > 1:
        raise ValueError(f"offset_rad must be a scalar or have shape (N,), got {d.shape}")
    return quat.multiply(quat.from_axis_angle(_Z, d), q_earth_tibia)


def heading_offset(q_earth_femur: ArrayLike, q_earth_tibia: ArrayLike, *, method: str = "straight_knee",
                   max_offset_rad: float | None = None, max_residual_rad: float = float(np.deg2rad(5.0)),
                   max_spread_rad: float = float(np.deg2rad(5.0))) -> HeadingOffset:
    """Constant heading offset δ between the femur and tibia filters' earth frames (H1/H2).

    q_earth_femur, q_earth_tibia : (N, 4) *segment* orientations (after :func:`segment_orientation`) over
        samples where the assumption holds.
    method : ``"straight_knee"`` (H1: the knee quaternion is identity — the standing posture, or the
        full-extension holds of the task) or ``"hinge"`` (H2: only the flexion axes are parallel — any
        knee flexion; biased by the true adduction and rotation, ~1–2° on a step-up).
    max_offset_rad : when given (9D, both filters referenced to magnetic north, where δ should be ~0),
        warn ``heading_mismatch`` if |δ| exceeds it (magnetic disturbance or bad magnetometer calibration).

    How the pipeline uses it: in 9D δ = 0 and this function on the standing recording is a check
    (``max_offset_rad``≈10°).  In 6D each filter run has its own arbitrary heading, so δ must come from
    the *same* run as the task: run the filters over the task, compute the segment orientations, then
    estimate δ with ``"hinge"`` over the task (or ``"straight_knee"`` over its detected full-extension
    holds) and pass it to :func:`q_femur_tibia`.  A large ``spread_rad`` means the relative heading
    drifts (gyro bias): warn ``heading_drift``.  For the task itself prefer the slowly varying δ(t) of
    :func:`estimators.heading.constraint_heading` and the magnetometer/constraint/auto choice of
    :func:`estimators.heading.choose_heading`: one constant cannot follow drift or a local field.
    """
    qf = quat.as_quaternion(q_earth_femur).reshape(-1, 4)
    qt = quat.as_quaternion(q_earth_tibia).reshape(-1, 4)
    if qf.shape != qt.shape or len(qf) == 0:
        raise ValueError(f"q_earth_femur and q_earth_tibia must have the same shape (N, 4), N >= 1, "
                         f"got {qf.shape} and {qt.shape}")
    rf, rt = quat.to_matrix(qf), quat.to_matrix(qt)
    if method == "straight_knee":
        n_i = rt @ np.swapaxes(rf, -1, -2)  # R_t R_fᵀ per sample (H1)
    elif method == "hinge":
        n_i = rt[:, :, 2, None] * rf[:, None, :, 2]  # ẑ_t ẑ_fᵀ per sample (H2)
    else:
        raise ValueError(f"method must be 'straight_knee' or 'hinge', got {method!r}")
    sin_i, cos_i = n_i[:, 0, 1] - n_i[:, 1, 0], n_i[:, 0, 0] + n_i[:, 1, 1]
    delta = float(np.arctan2(sin_i.sum(), cos_i.sum()))
    per = np.arctan2(sin_i, cos_i)
    spread = float(np.sqrt(np.mean(np.angle(np.exp(1j * (per - delta))) ** 2)))
    qt_corr = apply_heading_offset(qt, delta)
    if method == "straight_knee":
        res = quat.angle_between(qf, qt_corr)
    else:
        zf, zt = rf[:, :, 2], quat.to_matrix(qt_corr)[:, :, 2]
        res = np.arctan2(np.linalg.norm(np.cross(zf, zt), axis=1), np.sum(zf * zt, axis=1))
    residual = float(np.sqrt(np.mean(res**2)))
    warns = []
    if max_offset_rad is not None and abs(delta) > max_offset_rad:
        deg = float(np.rad2deg(delta))
        warns.append(QualityWarning("heading_mismatch", f"the thigh and shank headings differ by "
                                    f"{deg:.0f}° while the knee should be straight; the magnetometer "
                                    "calibration or the magnetic field is unreliable", {"angle_deg": deg}))
    if residual > max_residual_rad:
        deg = float(np.rad2deg(residual))
        warns.append(QualityWarning("heading_residual", f"after aligning the headings the segments still differ by "
                                    f"{deg:.1f}° RMS; the knee was not straight/hinge-like here", {"angle_deg": deg}))
    if spread > max_spread_rad:
        deg = float(np.rad2deg(spread))
        warns.append(QualityWarning("heading_drift", f"the relative heading of the two sensors varies by "
                                    f"{deg:.1f}° (SD); transverse-plane angles are unreliable", {"angle_deg": deg}))
    return HeadingOffset(delta, residual, spread, tuple(warns))


# ------------------------------------------------------------------------------------------ task checks
def task_warnings(knee_angles_rad: ArrayLike, *, min_flexion_rad: float = float(np.deg2rad(-15.0)),
                  fraction: float = 0.2) -> list[QualityWarning]:
    """Sanity of a task's angles: flexion below ``min_flexion_rad`` (hyperextension beyond −15°) in more
    than ``fraction`` of the finite samples: the angles are implausible (``flexion_negative``).

    This names the symptom only.  Its causes — sensors swapped between thigh and shank (q_femur_tibia
    becomes its inverse: flexion −), a sensor mounted upside down that the calibration did not undo, or a
    heading lost by 90–180° (the flexion axis turned round) — need opposite actions and are told apart by
    :func:`estimators.diagnosis.diagnose`."""
    a = np.asarray(knee_angles_rad, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"knee_angles_rad must have shape (N, 3), got {a.shape}")
    flex = a[np.isfinite(a[:, 0]), 0]
    if len(flex) == 0:
        return []
    frac = float(np.mean(flex < min_flexion_rad))
    if frac > fraction:
        values = {"min_deg": float(np.rad2deg(min_flexion_rad)), "pct": 100.0 * frac,
                  "median_deg": float(np.rad2deg(np.median(flex)))}
        return [QualityWarning("flexion_negative", f"knee flexion is below {values['min_deg']:.0f}° in "
                               f"{values['pct']:.0f}% of the task (median {values['median_deg']:.0f}°); "
                               "the knee angles are implausible", values)]
    return []
