r"""Accelerometer bias (and scale) from the protocol's still poses: the accelerometer's analogue of
:mod:`estimators.magnetometer`.

Why
---
A constant accelerometer bias :math:`\mathbf b` tilts every vertical the pipeline takes from gravity:
the standing and supine calibration's axes (:func:`estimators.knee.calibrate_segment`) and each
orientation filter's tilt, by about :math:`|\mathbf b_\perp| / g` (0.6° for 0.1 m/s², the BMI160's
zero-g offset reaching ±40 mg ≈ 0.39 m/s²).  The two tilts cancel only while the segment holds the
pose it was calibrated in, so the knee angles of a flexed knee carry them; through the 63° magnetic dip
a tilt also turns into relative heading.  On the simulated sessions of ``benchmarks/robustness.py``
whose flexion or rotation missed its goal (seeds 25, 140, 184; 127) removing the *true* constant bias
alone brought flexion from 1.04–1.18° to 0.19–0.35° and rotation from 2.15° to 1.19°; removing the scale
and cross-axis errors alone changed little.

Model (eq. A1)
--------------
.. math::  \mathbf a = T\,\mathbf f + \mathbf b + \mathbf n,\qquad
           \hat{\mathbf f} = K(\mathbf a - \mathbf b),\quad K = \operatorname{diag}(\mathbf k)

with :math:`\mathbf f` the specific force, :math:`T \approx I` the scale and axis errors and
:math:`K \approx T^{-1}` the per-axis gain of the correction (cross-axis terms are not estimated).  At rest
:math:`\lVert\mathbf f\rVert = g`, so every still pose *i* with mean reading :math:`\bar{\mathbf a}_i`
gives one equation (the autocalibration of Frosio, Pedersini & Borghese, "Autocalibration of MEMS
accelerometers", IEEE Trans. Instrum. Meas. 58(6), 2009, eq. 4; Skog & Händel, "Calibration of a MEMS
inertial measurement unit", IMEKO XVIII World Congress, 2006, §3):

.. math::  r_i(\boldsymbol\theta) = \lVert K(\bar{\mathbf a}_i - \mathbf b)\rVert - g = 0 \qquad (A2)

solved by Gauss–Newton from :math:`\mathbf b = 0, K = I` (eq. A3:
:math:`\partial r_i/\partial\mathbf b = -\hat{\mathbf v}_i^\top K`,
:math:`\partial r_i/\partial k_j = \hat v_{ij}(\bar a_{ij} - b_j)`, :math:`\hat{\mathbf v}_i` the unit vector of
:math:`K(\bar{\mathbf a}_i - \mathbf b)`).  Linearised at the start, (A2) reads
:math:`\mathbf u_i^\top\mathbf b - g\sum_j u_{ij}^2 (k_j - 1) = \lVert\bar{\mathbf a}_i\rVert - g`
(:math:`\mathbf u_i` the pose's gravity direction): a pose observes the bias *along its own gravity* only.

Observability (the conditioning check, eq. A4)
---------------------------------------------
The bias needs gravity in three independent directions; bias and gain together need at least six poses
whose normalised Jacobian :math:`\tilde J` (bias columns as they are, gain columns divided by
:math:`g`, so both are in m/s² per m/s²) is well conditioned.  The Gauss–Newton covariance is
:math:`\sigma^2(\tilde J^\top\tilde J)^{-1}` for a pose error :math:`\sigma`, so the check is the *information*
:math:`\lambda_{min}(\tilde J^\top\tilde J)`, the smallest eigenvalue, taken over the **distinct directions**:
poses whose gravity directions lie within ``SAME_DIRECTION_DEG`` (5°) of each other are one direction (their mean
reading is its row).  Copies of one pose add no information about the directions they do not see, and the error
the bias model folds into :math:`\mathbf b` (the scale error along that pose's axis, about 0.5 % of g ≈
0.05 m/s²) is the same in every copy, so it does not average out: three copies of a pose weigh as one.

For the bias model the information is :math:`\lambda_{min}(\sum_c \mathbf u_c\mathbf u_c^\top)` over the
directions :math:`\mathbf u_c`: 1 for three orthogonal directions, 0 when all lie in one plane.  Two orthogonal
directions and a third :math:`\alpha` out of their plane give exactly (eq. A4a)

.. math::  \lambda_{min} = 1 - \cos\alpha

(rotate the plane so :math:`\mathbf u_3 = (\cos\alpha, 0, \sin\alpha)`; the x–z block
:math:`\begin{pmatrix}1+\cos^2\alpha & \cos\alpha\sin\alpha\\ \cos\alpha\sin\alpha & \sin^2\alpha\end{pmatrix}`
has trace 2 and determinant :math:`\sin^2\alpha`), whatever the third direction's azimuth.  A pose's error
reaches the estimate amplified by :math:`1/\sqrt{\lambda_{min}}` in the weakest direction; below
``MIN_INFORMATION`` (0.3: an amplification above 1.8, i.e. by A4a a third direction less than
:math:`\arccos 0.7` = 45.6° out of the plane of two orthogonal ones) the estimate's error is as large as the bias
it should remove, so the recording is "too poor" and nothing is corrected (``model == "none"`` with a ``note``).
The gain model is used only with :data:`MIN_POSES_SCALE` distinct directions or more (redundancy to check it)
and the same information over its six columns; otherwise the bias model (three parameters) is used.

Validation (eq. A5): with more distinct directions than parameters the fitted poses' RMS residual
:math:`\sqrt{\tfrac1P\sum_i r_i^2}` must stay under ``MAX_RESIDUAL_M_S2`` (else a pose moved: nothing is
corrected).  With no spare direction (the protocol's usual three: figure-eight rest, standing, supine) the fit
passes through one point per direction exactly: the residual then only says whether copies of one direction
(the figure-eight's rests before and after) agree, nothing checks the fit itself but
:math:`|\mathbf b| \le` ``MAX_BIAS_M_S2``, and the result says so: ``validated`` False (``results.json``
``calibration.accelerometer.<segment>.validated``).

The protocol's still poses
--------------------------
The figure-eight's rests (the sensor lying in the hand or on the table before and after the figure: one
orientation), the standing posture (gravity along the segment's long axis) and the supine one (along its
anterior axis): three nearly orthogonal directions per sensor, so the bias model is well conditioned.  The
figure-eight's motion itself never holds still — its accelerations (~1.5 m/s² for a 0.3 m figure of 4 s)
are far above the bias — so only its rests count.  Without a figure-eight (factory-calibrated sensors) the
two postures span one plane: the bias is not corrected, and the note says so.  A pose is a run of at least
``min_pose_s`` over which the centred ``window_s`` windows stay below the one stillness definition
(:data:`estimators.knee.STILL_MAX_GYR_SD_RAD_S`, :data:`~estimators.knee.STILL_MAX_ACC_SD_M_S2`), its mean
taken with half a window trimmed at each end.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.knee import STILL_MAX_ACC_SD_M_S2, STILL_MAX_GYR_SD_RAD_S
from estimators.physics import GRAVITY_M_S2
from estimators.windows import moving_variance, true_runs

FloatArray = NDArray[np.float64]

#: the smallest eigenvalue of the information matrix (eq. A4) below which the fit is too poor
MIN_INFORMATION = 0.3
#: the gain (scale) model needs this many still poses (six parameters plus redundancy)
MIN_POSES_SCALE = 8
#: a bias above this is no MEMS offset (the BMI160's zero-g offset reaches ±40 mg ≈ 0.39 m/s²; 2.5×): the
#: poses were not still or the stream is not in m/s², nothing is corrected
MAX_BIAS_M_S2 = 1.0
#: the fitted poses' RMS norm residual above this (m/s²) says a pose was not at rest: nothing is corrected
MAX_RESIDUAL_M_S2 = 0.1
#: poses whose gravity directions lie within this angle (degrees) are one direction (module docstring, eq. A4)
SAME_DIRECTION_DEG = 5.0

__all__ = ["AccCalibration", "fit_still_poses", "still_poses"]


@dataclass(frozen=True, eq=False)
class AccCalibration:
    """Result of :func:`fit_still_poses` for one sensor (eq. A1).

    bias_m_s2 : (3,) :math:`\\mathbf b`.   gain : (3,) the diagonal of :math:`K` (ones for the bias model).
    model : ``"bias_scale"``, ``"bias"`` or ``"none"`` (not corrected: ``note`` says why).
    poses_m_s2 : (P, 3) the still poses' mean readings.   directions : how many distinct gravity directions they
        hold (eq. A4).   information : the smallest eigenvalue of eq. A4 for the bias model's columns over the
        distinct directions (≥ ``MIN_INFORMATION`` to correct).   residual_rms_m_s2 : RMS of :math:`r_i` at the
        solution (NaN without a spare pose).
    validated : True when the residual (eq. A5) checked the fit, False when there was no spare direction to check
        it with (the correction is still applied) or nothing was corrected.
    note : ``""``, ``"few_poses"`` (gravity in fewer than three independent directions: e.g. no figure-eight),
        ``"implausible_bias"`` or ``"poses_not_still"`` (the fit's residual or size says a pose moved).
    """

    bias_m_s2: FloatArray
    gain: FloatArray
    model: str
    poses_m_s2: FloatArray
    information: float
    residual_rms_m_s2: float
    note: str = ""
    directions: int = 0
    validated: bool = False

    def apply(self, acc: ArrayLike) -> FloatArray:
        """Corrected specific force :math:`K(\\mathbf a - \\mathbf b)` of ``acc`` (N, 3), m/s²."""
        return (np.asarray(acc, dtype=np.float64) - self.bias_m_s2) * self.gain

    def to_dict(self) -> dict:
        return {"model": self.model, "bias_m_s2": self.bias_m_s2.tolist(), "gain": self.gain.tolist(),
                "poses": len(self.poses_m_s2), "directions": self.directions, "information": self.information,
                "residual_rms_m_s2": self.residual_rms_m_s2, "validated": self.validated, "note": self.note}


def still_poses(acc: ArrayLike, gyr: ArrayLike, *, fs_hz: float, window_s: float = 0.5,
                min_pose_s: float = 0.5) -> FloatArray:
    """(P, 3) mean readings of the still runs of one recording (module docstring): runs of ``min_pose_s`` or more
    whose centred ``window_s`` windows have total gyroscope SD ≤ ``STILL_MAX_GYR_SD_RAD_S`` and total
    accelerometer SD ≤ ``STILL_MAX_ACC_SD_M_S2``; rows with NaN never count as still."""
    a, g = np.asarray(acc, dtype=np.float64), np.asarray(gyr, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or g.shape != a.shape:
        raise ValueError(f"acc and gyr must both have shape (N, 3), got {a.shape} and {g.shape}")
    n = max(int(round(window_s * fs_hz)), 2)
    if len(a) < n:
        return np.zeros((0, 3))
    finite = np.all(np.isfinite(a), axis=1) & np.all(np.isfinite(g), axis=1)
    a0, g0 = np.where(finite[:, None], a, 0.0), np.where(finite[:, None], g, 0.0)
    var_g = sum(moving_variance(g0[:, j], n) for j in range(3))
    var_a = sum(moving_variance(a0[:, j], n) for j in range(3))
    bad = np.convolve(~finite, np.ones(n), mode="same") > 0  # a window touching a NaN row
    still = (var_g <= STILL_MAX_GYR_SD_RAD_S ** 2) & (var_a <= STILL_MAX_ACC_SD_M_S2 ** 2) & ~bad
    runs = true_runs(still, max(int(round(min_pose_s * fs_hz)), n))
    out = [a[s + n // 2:e - n // 2].mean(axis=0) for s, e in runs if e - n // 2 > s + n // 2]
    return np.array(out).reshape(-1, 3)


def _residuals(poses: FloatArray, b: FloatArray, k: FloatArray, g: float) -> tuple[FloatArray, FloatArray]:
    """r_i (eq. A2) and the Jacobian (P, 6) over (b, k) (eq. A3)."""
    d = poses - b
    v = d * k
    norm = np.linalg.norm(v, axis=1)
    vh = v / norm[:, None]
    return norm - g, np.hstack([-vh * k, vh * d])


def _directions(poses: FloatArray) -> FloatArray:
    """(C, 3) one mean reading per distinct gravity direction (eq. A4): each pose joins the first direction whose
    first pose lies within ``SAME_DIRECTION_DEG`` of its own, else starts a new one."""
    u = poses / np.linalg.norm(poses, axis=1)[:, None]
    cos_same = np.cos(np.deg2rad(SAME_DIRECTION_DEG))
    heads: list[int] = []
    label = np.empty(len(poses), dtype=int)
    for i in range(len(poses)):
        c = next((j for j, h in enumerate(heads) if u[h] @ u[i] >= cos_same), None)
        if c is None:
            heads.append(i)
            c = len(heads) - 1
        label[i] = c
    return np.array([poses[label == c].mean(axis=0) for c in range(len(heads))]).reshape(-1, 3)


def _information(jac: FloatArray, g: float) -> float:
    """Smallest eigenvalue of the information matrix (eq. A4), the gain columns (4–6) divided by g."""
    j = jac.copy()
    j[:, 3:] /= g
    return float(np.linalg.eigvalsh(j.T @ j)[0])


def fit_still_poses(poses: ArrayLike | Iterable[ArrayLike], *, gravity_m_s2: float = GRAVITY_M_S2,
                    iterations: int = 20) -> AccCalibration:
    """Bias (and gain, with enough poses) from still poses' mean readings (P, 3) (eqs. A2–A4).

    ``poses`` may be one (P, 3) array or several (from :func:`still_poses` of each recording), stacked.  Never
    raises on too few or too poor poses: returns ``model == "none"`` with the reason in ``note``.
    """
    arrs: Sequence = [poses] if isinstance(poses, np.ndarray) else list(poses)
    p = np.vstack([np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in arrs]) if arrs else np.zeros((0, 3))
    p = p[np.all(np.isfinite(p), axis=1)]
    g = float(gravity_m_s2)
    p = p[np.linalg.norm(p, axis=1) > 0]
    dirs = _directions(p) if len(p) else np.zeros((0, 3))
    none = dict(bias_m_s2=np.zeros(3), gain=np.ones(3), model="none", poses_m_s2=p, residual_rms_m_s2=float("nan"),
                directions=len(dirs))
    if len(dirs) < 3:
        return AccCalibration(information=0.0, note="few_poses", **none)
    _, jac0 = _residuals(dirs, np.zeros(3), np.ones(3), g)  # one row per distinct direction (eq. A4)
    info = _information(jac0[:, :3], g)
    if info < MIN_INFORMATION:
        return AccCalibration(information=info, note="few_poses", **none)
    scale = len(dirs) >= MIN_POSES_SCALE and _information(jac0, g) >= MIN_INFORMATION
    cols = slice(0, 6 if scale else 3)
    b, k = np.zeros(3), np.ones(3)
    for _ in range(iterations):
        r, jac = _residuals(p, b, k, g)
        step = np.linalg.lstsq(jac[:, cols], -r, rcond=None)[0]
        b = b + step[:3]
        if scale:
            k = k + step[3:]
        if np.max(np.abs(step)) < 1e-9:
            break
    r, _ = _residuals(p, b, k, g)
    n_par = 6 if scale else 3
    validated = len(dirs) > n_par  # a spare direction checks the fit (eq. A5)
    rms = float(np.sqrt(np.mean(r ** 2))) if len(p) > n_par else float("nan")
    if not np.linalg.norm(b) <= MAX_BIAS_M_S2:
        return AccCalibration(information=info, note="implausible_bias", **none)
    if rms > MAX_RESIDUAL_M_S2:  # NaN (no spare pose) never exceeds: then only |b| is checked
        return AccCalibration(information=info, note="poses_not_still", **none)
    return AccCalibration(b, k, "bias_scale" if scale else "bias", p, info, rms, directions=len(dirs),
                          validated=validated)
