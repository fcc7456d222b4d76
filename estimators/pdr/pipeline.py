r"""Foot-mounted pedestrian dead reckoning: alignment → stance detection → INS/EKF → trajectory.

Methods (seed 001 Table 3, plus ChakaMo's default)
--------------------------------------------------
===============  ======  ===========  ==========================================================
name             states  updates      attitude
===============  ======  ===========  ==========================================================
``9iez``         9       ZUPT         strapdown, Padé (3.23)
``9iez_mad``     9       ZUPT         Madgwick 6D (3.18) — ``estimators.orientation`` "madgwick"
``9iez_kf``      9       ZUPT         Kalman attitude filter (§3.6.2) — ``estimators.orientation``
                                      "valenti_kf" (6D)
``15iez_zaru``   15      ZUPT+ZARU    strapdown (3.23), gyroscope and accelerometer bias states
``chakamo``      15      ZUPT+HDR     strapdown with constant bias states (no ZARU); + saturated-
                         +floor       gyroscope reconstruction and the attitude variance of the clipped runs
                                      (:mod:`estimators.pdr.desaturation`), heuristic heading
                                      updates on the stride direction (after iHDE, Jiménez et al.
                                      2011) and the flat-floor height update; process noise
                                      q_ω = 3e-6 rad²/s, q_a = 1e-3 (m/s)²/s
===============  ======  ===========  ==========================================================

Why 15 states without ZARU for the default: on the shared walks the ZARU of the 15-state filter,
applied over the whole detected stance (|ω| up to 0.6 rad/s while the foot rolls), pulls the gyroscope
bias towards the stance's mean rate and opens the loops (mean EP 4 % against 0.8 % for 9IEZ).  Without
ZARU the bias states are observed as the thesis' 15-state model intends, through the ZUPTs: the foot
changes its attitude between stances (pitch every swing, yaw at every turn), which separates the
accelerometer biases from the tilt errors (a still foot alone cannot: the usual argument for the
bias states of the ZUPT filter, Foxlin 2005, "Pedestrian tracking with shoe-mounted inertial sensors",
IEEE CG&A 25(6)), and the heading updates observe the vertical gyroscope bias.  Over a walk of a minute the biases are modelled as constants (no
random walk); the gyroscope bias starts from the still mean with σ = 1e-4 rad/s (the order of that mean's standard
error: the MPU-6050's 0.05 °/s rms noise at 100 Hz over 2 s of rest gives 6e-5 rad/s), the accelerometer
bias from 0 with σ = 0.05 m/s².  Measured with
``python -m benchmarks.pdr`` (detector c123, 14 walks): 9 states 0.50 % mean EP, these 15 states 0.45 %.
The choices of ``chakamo`` were made on these 14 walks; with so few walks they are a calibration, not an
independent validation.

Every method starts from the initial alignment (3.29) over the first still period (its gyroscope mean
is the initial gyroscope bias) and uses the same stance mask (detector ``c123`` or ``pitch``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.pdr.detectors import DETECTORS, PitchParams, ShoeParams, pitch_detector, stance_c123
from estimators.pdr.ekf import EkfOutput, EkfParams, run_ekf
from estimators.pdr.mechanisation import Alignment, align, first_still_period
from estimators.pdr.metrics import Stride, WalkMetrics, strides, walk_metrics

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

METHODS = ("9iez", "9iez_mad", "9iez_kf", "15iez_zaru", "chakamo")
DEFAULT_METHOD = "chakamo"
DEFAULT_DETECTOR = "c123"

_EKF = {
    "9iez": EkfParams(n_states=9),
    "9iez_mad": EkfParams(n_states=9),
    "9iez_kf": EkfParams(n_states=9),
    "15iez_zaru": EkfParams(n_states=15, zaru=True),
    "chakamo": EkfParams(n_states=15, gyr_noise_rad2_s=3e-6, acc_noise_m2_s3=1e-3, gyr_bias_walk_rad2_s3=0.0,
                         acc_bias_walk_m2_s5=0.0, init_gyr_bias_std_rad_s=1e-4, init_acc_bias_std_m_s2=0.05,
                         heading_update=True, height_update=True),
}
_ATTITUDE = {"9iez_mad": "madgwick", "9iez_kf": "valenti_kf"}

__all__ = ["DEFAULT_DETECTOR", "DEFAULT_METHOD", "DETECTORS", "METHODS", "PdrResult", "reconstruct"]


@dataclass(frozen=True, eq=False)
class PdrResult:
    """A reconstructed walk.

    t_s (N,) s; pos_m, vel_m_s (N, 3) ENU (x, y as the initial foot yaw 0, z up), origin at the start;
    q_earth_sensor (N, 4); stance (N,) bool; gyr_bias_rad_s (N, 3); alignment; method, detector;
    strides: list of :class:`Stride`; gyr_used (N, 3) the rates fed to the filter (after any reconstruction).
    """

    t_s: FloatArray
    pos_m: FloatArray
    vel_m_s: FloatArray
    q_earth_sensor: FloatArray
    stance: BoolArray
    gyr_bias_rad_s: FloatArray
    alignment: Alignment
    method: str
    detector: str
    strides: list[Stride]
    gyr_used: FloatArray

    def metrics(self, true_distance_m: float | None = None) -> WalkMetrics:
        """EP, ED, ED stance-to-stance, EA (:func:`estimators.pdr.metrics.walk_metrics`)."""
        return walk_metrics(self.pos_m, self.stance, true_distance_m)


def _pitch_rad(c: FloatArray) -> FloatArray:
    return np.arcsin(np.clip(-c[:, 2, 0], -1.0, 1.0))


def detect_stance(acc: FloatArray, gyr: FloatArray, fs_hz: float, alignment: Alignment, detector: str,
                  shoe: ShoeParams = ShoeParams(), pitch: PitchParams = PitchParams()) -> BoolArray:
    """Stance mask (N,) by detector name (``c123`` or ``pitch``); the pitch comes from a Madgwick 6D attitude."""
    if detector == "c123":
        return stance_c123(acc, gyr, shoe)
    if detector == "pitch":
        from estimators.orientation import make

        q = make("madgwick").estimate(acc, gyr - alignment.gyr_bias_rad_s, None, fs_hz=fs_hz, q0=alignment.q0).orientation_
        return pitch_detector(_pitch_rad(quat.to_matrix(q)), alignment.pitch_rad, pitch)
    raise ValueError(f"unknown stance detector {detector!r}; choose one of {', '.join(DETECTORS)}")


def reconstruct(t_s: ArrayLike, acc: ArrayLike, gyr: ArrayLike, *, method: str = DEFAULT_METHOD,
                detector: str = DEFAULT_DETECTOR, gyr_saturated: ArrayLike | None = None,
                gyr_range_rad_s: float | None = None, ekf_params: EkfParams | None = None,
                stance: ArrayLike | None = None) -> PdrResult:
    """Reconstruct a foot-mounted walk.

    t_s (N,) sample times, s (gaps allowed); acc (N, 3) m/s²; gyr (N, 3) rad/s; method in ``METHODS``;
    detector in ``DETECTORS``; gyr_saturated (N,) flags and gyr_range_rad_s the full scale (used by
    ``chakamo`` to rebuild clipped rates); ekf_params overrides the method's filter parameters;
    stance (N,) bool overrides the detector (e.g. the simulator's truth).
    """
    if method not in METHODS:
        raise ValueError(f"unknown PDR method {method!r}; choose one of {', '.join(METHODS)}")
    t = np.asarray(t_s, dtype=np.float64)
    acc = np.asarray(acc, dtype=np.float64)
    gyr = np.asarray(gyr, dtype=np.float64)
    n = len(t)
    if acc.shape != (n, 3) or gyr.shape != (n, 3):
        raise ValueError(f"acc and gyr must have shape ({n}, 3) like t_s, got {acc.shape} and {gyr.shape}")
    if n < 50 or np.any(np.diff(t) <= 0):
        raise ValueError("need at least 50 samples with strictly increasing t_s")
    dt = np.concatenate([[np.median(np.diff(t))], np.diff(t)])
    fs_hz = float(1.0 / np.median(dt))
    alignment = align(acc, gyr, first_still_period(gyr, fs_hz))
    gyr_used = gyr
    att_var = None
    if method == "chakamo" and gyr_saturated is not None and np.any(gyr_saturated) and gyr_range_rad_s:
        from estimators.pdr.desaturation import clipped_attitude_variance, rebuild_saturated

        sat = np.asarray(gyr_saturated, bool)
        gyr_used = rebuild_saturated(dt, gyr, sat, gyr_range_rad_s)
        att_var = clipped_attitude_variance(dt, gyr_used, sat, gyr_range_rad_s)
    if stance is None:
        stance_mask = detect_stance(acc, gyr_used, fs_hz, alignment, detector)
    else:
        stance_mask = np.asarray(stance, dtype=bool)
        detector = "given"
    params = _EKF[method] if ekf_params is None else ekf_params
    c_ext = None
    if method in _ATTITUDE:
        from estimators.orientation import make

        q_ext = make(_ATTITUDE[method]).estimate(acc, gyr_used - alignment.gyr_bias_rad_s, None, fs_hz=fs_hz,
                                                 q0=alignment.q0).orientation_
        c_ext = quat.to_matrix(q_ext)
    out: EkfOutput = run_ekf(acc, gyr_used, dt, stance_mask, alignment.c0, alignment.gyr_bias_rad_s, params,
                             c_ext=c_ext, gravity_m_s2=alignment.gravity_m_s2, att_var_body=att_var)
    q = quat.from_matrix(out.c_nav_body)
    return PdrResult(t, out.pos_m, out.vel_m_s, q, stance_mask, out.gyr_bias_rad_s, alignment, method, detector,
                     strides(t, out.pos_m, stance_mask), gyr_used)


