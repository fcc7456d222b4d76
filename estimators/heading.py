r"""Thigh–shank relative heading from the knee's approximate hinge constraint, and the choice of heading.

Why
---
A knee angle needs both segments' orientations in *one* earth frame.  A 9D filter takes each sensor's
heading from its own magnetometer; when the two sensors see different fields (steel near the floor, a
step with a metal frame, an unnoticed hard-iron change) or a filter loses its heading, the knee
quaternion :math:`q_{femur,tibia}` carries the error whole: on real walking data this read flexion
anti-correlated with the reference.  A 6D filter has no north at all: each run has its own arbitrary
heading.  In both cases the missing information is one angle per instant, the heading offset
:math:`\delta(t)` that maps the tibia filter's earth frame onto the femur filter's,

.. math:: q_{earth_f,tibia}(t) = \exp\!\big(\tfrac{\delta(t)}{2}\hat z\big)\otimes q_{earth_t,tibia}(t). \quad (C0)

The constraint (Laidig, Schauer & Seel, ICORR 2017)
---------------------------------------------------
The knee is an approximate hinge: its flexion axis is the femoral z (ISB, mediolateral) and, to the
extent that adduction and internal rotation are small, also the tibial z.  So the two segments' z axes,
each in its own filter's earth frame, :math:`\hat z_f = R_{e,f}\,e_3` and :math:`\hat z_t = R_{e,t}\,e_3`,
coincide after the heading correction: :math:`R_z(\delta)\hat z_t = \hat z_f`.  Least squares over the
samples :math:`i` of a window :math:`W`,

.. math::
    \hat\delta_W = \arg\min_\delta \sum_{i\in W} \lVert R_z(\delta)\hat z_{t,i} - \hat z_{f,i}\rVert^2
    = \operatorname{atan2}\Big(\sum_{i\in W} s_i,\ \sum_{i\in W} c_i\Big),\qquad
    s_i = N_{i,01} - N_{i,10},\ c_i = N_{i,00} + N_{i,11},\ N_i = \hat z_{t,i}\hat z_{f,i}^\top \quad (C1)

(the closed form of :func:`estimators.knee.heading_offset` ``"hinge"``, eq. H2, here per window).  Only the
horizontal parts of the axes enter: :math:`\sqrt{s_i^2 + c_i^2} = |\hat z_{t,i,xy}|\,|\hat z_{f,i,xy}|`, so a
sample weighs by how well it observes heading and a vertical axis (the leg horizontal and turned on its
side) contributes nothing: heading about a vertical flexion axis is unobservable (Laidig et al. 2017).  The
constraint needs no magnetometer and no knowledge of where the sensors sit on the segments beyond the
segment calibration (gravity postures or the functional axis), so it works on 6D orientations (arbitrary
heading per sensor) and on 9D ones alike.

Slowly varying offset (moving windows; Weygers et al., IEEE Sensors J. 2020)
---------------------------------------------------------------------------
δ is not constant: in 6D each filter's heading drifts with its residual gyroscope bias (integrated about
the vertical; Weygers et al. 2020 show that the joint constraint keeps such relative headings bounded over
long recordings), in 9D it follows the local field at each sensor.  So (C1) is solved on windows of
``window_s`` every ``hop_s``, and the per-sample offset is the linear interpolation (of the unwrapped
angle) between the centres of the *excited* windows, held constant before the first and after the last:

.. math:: \delta(t) = \operatorname{interp}\big(t;\ \{t_W, \hat\delta_W\}_{W\ \mathrm{excited}}\big). \quad (C2)

Excitation rule (stated)
~~~~~~~~~~~~~~~~~~~~~~~~
A window is *excited* when both hold:

* the knee moved: the flexion range over the window (flexion read with :math:`\hat\delta_W`) is at least
  ``min_flexion_range_rad`` (default 10°).  A still window sees one posture, whose own adduction and
  rotation bias :math:`\hat\delta_W` whole; over a movement the two axes are compared across many segment
  inclinations, which averages those departures from the hinge.  While still, the relative heading can
  only change by gyroscope drift, which interpolation holds well over seconds;
* the axes observe heading: the mean weight :math:`\overline{|\hat z_{t,xy}||\hat z_{f,xy}|}` is at least
  ``min_axis_weight`` (default 0.25, i.e. axes within ~60° of vertical would fail it on average).

Straight-knee weighting (C3)
~~~~~~~~~~~~~~~~~~~~~~~~~~~~
The knee's departure from a hinge grows with flexion (the tibia's coupled internal rotation, the
"screw-home" in reverse), and at full extension it is closest to the standing posture that defines the
segment calibration's zero.  So each window is solved a second time with the samples weighted by
:math:`\cos^k\phi_i` (:math:`\phi_i` the flexion read with the first :math:`\hat\delta_W`, clipped to
[0, 90°]): :math:`\hat\delta_W = \operatorname{atan2}(\sum w_i s_i, \sum w_i c_i)`, :math:`w_i = \cos^k\phi_i`.
With k = 2 the rotation RMSE of the constraint heading on simulated step-ups drops from 2.1° to 0.9°
(see ``extension_weight_power``); k = 2 is partly a compromise between the flexed and the straight samples
that suits the simulator's linear rotation–flexion coupling, so on real knees expect between the two.

Unexcited windows are replaced by (C2).  With no excited window at all, the whole recording's single
estimate (C1 over every sample) is used and ``constraint_heading_unexcited`` warns.

What the constraint cannot see: a true knee rotation about the tibia's long axis is indistinguishable from
heading while the long axis is vertical, so :math:`\hat\delta_W` absorbs the window's mean internal
rotation (and part of its adduction) relative to the segment calibration: on simulated step-ups
(rotation −2°…8° with flexion) a bias of 1–4°, constant from cycle to cycle.  Flexion is hardly affected
by it; rotation reads that bias lower.

The choice (:func:`choose_heading`)
-----------------------------------
``magnetometer`` applies δ = 0 to the 9D run (both sensors referenced to magnetic north); ``constraint``
applies (C2), computed on the 6D run when the caller has one (no magnetic influence at all) and otherwise on
the 9D run; ``auto`` (default) computes the constraint on the 9D run and measures the disagreement
:math:`D = \max_W |\hat\delta_W|` over the excited windows (the magnetometer's offset is 0 by definition);
when :math:`D` exceeds ``DISAGREEMENT_BOUND_RAD`` (3°) it uses the constraint heading, otherwise the
magnetometer's, unchanged; beyond ``DISTURBED_BOUND_RAD`` (6°) it also warns ``magnetic_heading_unreliable``
(a tilt cannot explain that much: see the constants' comments).  The bound and the window length
are chosen on simulated step-ups (``python -m benchmarks.heading``), numbers in the constants' comments.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import knee
from estimators import quaternion as quat
from estimators.quality import QualityWarning

FloatArray = NDArray[np.float64]

__all__ = ["DISAGREEMENT_BOUND_RAD", "DISTURBED_BOUND_RAD", "HEADING_MODES", "ConstraintHeading", "ConstraintHeadingParams", "HeadingChoice",
           "choose_heading", "constraint_heading", "disagreement_rad", "wrap"]

HEADING_MODES = ("auto", "magnetometer", "constraint")

#: auto switches to the constraint heading when D (the largest windowed constraint offset on the 9D run, over
#: the excited windows) exceeds this, on the tasks whose ``TaskSpec.heading_bound`` is ``"tilt"`` (the
#: step-up; other tasks use DISTURBED_BOUND_RAD).  History — the first bound, today's DISTURBED_BOUND_RAD: chosen
#: on the tuning seeds 0–5 of ``python -m benchmarks.heading --tune 0-5
#: --seeds 0-11 --disturb-deg 30`` (default filter, MetaMotionR error model, both legs and heights, default
#: params): clean sessions read D = 1.2–2.0° (the hinge bias of the true knee rotation), a 30° shank field
#: rotation over the middle third 10.7–14.6°; the bound is their midpoint, 6° (rounded).  Held out (seeds 6–11):
#: clean 0.8–2.4°, disturbed 10.6–14.4°: auto left every clean session unchanged and switched on every disturbed
#: one.  A 20° rotation is milder at the filter's output (its heading follows the field only in part): D 6.6–10.4°
#: (tune) and 6.5–10.2° (held out), every session switched; 40°: 14.6–18.6° held out.  The margin below a 20°
#: disturbance is thin (0.5°): milder bends are left to the magnetometers, whose error is then a few degrees.
DISAGREEMENT_BOUND_RAD = float(np.deg2rad(3.0))
#: (issue 13 §7, ``python -m benchmarks.robustness``) The bound above was 6° until the robustness seeds showed that
#: the magnetometers' relative heading is off by 2–6° on clean sessions whose accelerometers carry a realistic bias
#: (BMI160 zero-g offset, simulated N(0, 10 mg) per axis): the bias tilts each filter's vertical by up to ~1°, and the
#: 63° dip turns a tilt about north into tan(63°) ≈ 2× as much heading, differently in each sensor as it moves.  The
#: hinge constraint is blind to tilt to first order (only the horizontal parts of the axes enter C1), so it is the
#: better heading whenever the two disagree by more than its own hinge bias.  Chosen on seeds 0–99 (tuning; 100–199
#: held out): with the magnetometers the rotation curve RMSE exceeded 2° on 11 seeds (worst 5.72°), all with
#: D ≥ 1.9°; the constraint's own worst was 1.91°; D on clean sessions is 1.1–2.4°, so no bound separates a
#: tilted magnetometer from a sound one: at 1.5° auto switches on 65 of the 100 seeds and no seed's rotation
#: exceeds 2° (at 2°: 2 seeds, worst 2.16°; at 2.5°: 4, worst 2.98°).  Held-out numbers in the README.
#: 1.5° → 3° once the accelerometer bias is removed before filtering (``estimators.accelerometer``): the tilt it was
#: chosen against is gone, and on clean sessions D is the constraint's own hinge bias.  ``python -m
#: benchmarks.robustness --heading magnetometer|constraint``, tuning seeds 0–11 (chosen there) / held out 100–111:
#: on the 19 clean sessions (no field turn) the magnetometers' rotation RMSE is 0.11–0.77°, the constraint's
#: 0.70–1.47° (the magnetometers better on every one), clean D 1.0–2.4° (held out 1.1–2.7°); the turning fields read
#: D 6.1–23.7° (held out 7.4–27.0°), where the magnetometers' rotation is 3.1–19.7° and the constraint's ≤ 1.3°.  The
#: smallest bound above every clean tuning D, rounded up: 3°.  Held out, 1.5° → 3°: switched 9 → 3 of 12 (the three
#: turning fields), rotation mean 0.79 → 0.44°, worst 1.18 → 1.11°; tuning 0.71 → 0.58°, worst 1.47 → 1.32°.
#: Seeds 12–17 and 112–117 with auto at 3° (not used for the choice): clean D 0.7–3.2° (two clean sessions at 3.1° and
#: 3.2° switched, rotation 1.32° and 0.83°), every turning field switched, every goal met, worst rotation 1.32°.
#: Above DISTURBED_BOUND_RAD (the previous bound: the midpoint between clean sessions and a 30° shank field bend,
#: benchmarks/heading.py) the disagreement is more than a tilt can make: auto warns ``magnetic_heading_unreliable``
#: and :func:`estimators.diagnosis.diagnose` names a disturbed field; below it the switch is silent (the report
#: still says which heading was used).
DISTURBED_BOUND_RAD = float(np.deg2rad(6.0))


def wrap(angle_rad: ArrayLike) -> FloatArray:
    """Angles wrapped to (−π, π]."""
    a = np.asarray(angle_rad, dtype=np.float64)
    return -np.angle(np.exp(-1j * a))


@dataclass(frozen=True)
class ConstraintHeadingParams:
    r"""Settings of :func:`constraint_heading` (module docstring, C1–C2).

    window_s : moving-window length, s (default 10: two step-up cycles or more, so a window holds full flexion
        excursions even around a pause; on the tuning seeds 0–5 of ``benchmarks/heading.py --sweep`` the
        adduction + rotation RMSE of the 9D constraint on disturbed sessions read 3.62° / 3.04° / 2.99° for
        3 / 6 / 10 s, held out 3.60° / 3.03° / 2.98°; swept with plain C1, k = 0).
    hop_s : distance between window starts, s (default 0.5).
    min_flexion_range_rad : a window whose flexion range is smaller is unexcited (default 10°).
    min_axis_weight : a window whose mean horizontal-axis weight is smaller is unexcited (default 0.25).
    max_residual_rad : the RMS angle between the aligned flexion axes above which the recording warns
        ``constraint_heading_residual`` (the knee did not behave as a hinge; default 10°).
    extension_weight_power : k of (C3), the samples' weight :math:`\cos^k\phi` by flexion φ (0: plain C1;
        default 2, chosen on tuning seeds 0–5 of ``benchmarks/heading.py --sweep-power``: rotation RMSE
        2.09° / 0.93° / 1.19° for k = 0 / 2 / 8, held out 2.08° / 0.84° / 1.17°).
    """

    window_s: float = 10.0
    hop_s: float = 0.5
    min_flexion_range_rad: float = float(np.deg2rad(10.0))
    min_axis_weight: float = 0.25
    max_residual_rad: float = float(np.deg2rad(10.0))
    extension_weight_power: float = 2.0

    def __post_init__(self) -> None:
        for name in ("window_s", "hop_s", "min_flexion_range_rad", "max_residual_rad"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
        if not (np.isfinite(self.extension_weight_power) and self.extension_weight_power >= 0.0):
            raise ValueError(f"extension_weight_power must be >= 0, got {self.extension_weight_power!r}")
        if not (0.0 <= self.min_axis_weight < 1.0):
            raise ValueError(f"min_axis_weight must be in [0, 1), got {self.min_axis_weight!r}")


@dataclass(frozen=True)
class ConstraintHeading:
    """Result of :func:`constraint_heading`.

    offset_rad : (N,) δ(t) in (−π, π] to apply to the tibia (:func:`estimators.knee.apply_heading_offset`).
    window_start, window_stop : (W,) sample ranges ``[start, stop)`` of the windows.
    window_centre_s : (W,) window centres, s from the first sample.
    window_offset_rad : (W,) :math:`\\hat\\delta_W` (C1) of every window, excited or not.
    window_excited : (W,) bool, the excitation rule.   window_flexion_range_rad, window_axis_weight : its figures.
    window_residual_rad : (W,) RMS angle between the aligned axes in each window.
    excited_fraction : share of windows excited.   residual_rad : RMS angle between the axes aligned with δ(t).
    warnings : ``constraint_heading_unexcited``, ``constraint_heading_residual``.
    """

    offset_rad: FloatArray
    window_start: NDArray[np.int64]
    window_stop: NDArray[np.int64]
    window_centre_s: FloatArray
    window_offset_rad: FloatArray
    window_excited: NDArray[np.bool_]
    window_flexion_range_rad: FloatArray
    window_axis_weight: FloatArray
    window_residual_rad: FloatArray
    excited_fraction: float
    residual_rad: float
    warnings: tuple[QualityWarning, ...] = field(default=())


def _axes(q_earth_femur: ArrayLike, q_earth_tibia: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    qf = quat.as_quaternion(q_earth_femur)
    qt = quat.as_quaternion(q_earth_tibia)
    if qf.ndim != 2 or qf.shape != qt.shape or len(qf) < 2:
        raise ValueError(f"q_earth_femur and q_earth_tibia must both have shape (N, 4), N >= 2, got {qf.shape} "
                         f"and {qt.shape}")
    return qf, qt, quat.to_matrix(qf)[:, :, 2], quat.to_matrix(qt)[:, :, 2]


def _axis_angle_rad(zf: FloatArray, zt: FloatArray, offset_rad: ArrayLike) -> FloatArray:
    """Angle between ẑ_f and R_z(δ) ẑ_t per sample."""
    c, s = np.cos(offset_rad), np.sin(offset_rad)
    zt_r = np.column_stack([c * zt[:, 0] - s * zt[:, 1], s * zt[:, 0] + c * zt[:, 1], zt[:, 2]])
    return np.arctan2(np.linalg.norm(np.cross(zf, zt_r), axis=1), np.sum(zf * zt_r, axis=1))


def constraint_heading(q_earth_femur: ArrayLike, q_earth_tibia: ArrayLike, *, fs_hz: float,
                       params: ConstraintHeadingParams | None = None) -> ConstraintHeading:
    """Slowly varying heading offset δ(t) from the knee's hinge constraint (module docstring, C1–C2).

    q_earth_femur, q_earth_tibia : (N, 4) *segment* orientations (:func:`estimators.knee.segment_orientation`),
        each in its own filter's earth frame (6D: arbitrary headings; 9D: magnetic north per sensor).
        Rows with a NaN are ignored in the fits; they get the interpolated offset.
    fs_hz : sampling rate, Hz.   params : :class:`ConstraintHeadingParams`.
    """
    p = ConstraintHeadingParams() if params is None else params
    if not (np.isfinite(fs_hz) and fs_hz > 0.0):
        raise ValueError(f"fs_hz must be a positive rate in Hz, got {fs_hz!r}")
    qf, qt, zf, zt = _axes(q_earth_femur, q_earth_tibia)
    n = len(qf)
    ok = np.all(np.isfinite(qf), axis=1) & np.all(np.isfinite(qt), axis=1)
    zf0, zt0 = np.where(ok[:, None], zf, 0.0), np.where(ok[:, None], zt, 0.0)
    s_i = zt0[:, 0] * zf0[:, 1] - zt0[:, 1] * zf0[:, 0]  # N01 − N10 of N = ẑ_t ẑ_fᵀ (C1)
    c_i = zt0[:, 0] * zf0[:, 0] + zt0[:, 1] * zf0[:, 1]  # N00 + N11
    if not ok.any():
        raise ValueError("no sample has both orientations; the constraint heading needs both sensors")
    cs = np.concatenate([[0.0], np.cumsum(s_i)])
    cc = np.concatenate([[0.0], np.cumsum(c_i)])
    cw = np.concatenate([[0.0], np.cumsum(np.hypot(s_i, c_i))])
    cn = np.concatenate([[0], np.cumsum(ok)])
    w = max(2, min(n, round(p.window_s * fs_hz)))
    hop = max(1, round(p.hop_s * fs_hz))
    starts = np.arange(0, n - w + 1, hop, dtype=np.int64)
    if starts[-1] != n - w:
        starts = np.append(starts, n - w)
    stops = starts + w
    off_w = np.arctan2(cs[stops] - cs[starts], cc[stops] - cc[starts])
    n_ok = cn[stops] - cn[starts]
    weight_w = np.where(n_ok > 0, (cw[stops] - cw[starts]) / np.maximum(n_ok, 1), 0.0)
    flex_range = np.zeros(len(starts))
    resid_w = np.full(len(starts), np.nan)
    qf_c = quat.conjugate(qf)
    for k, (a, b) in enumerate(zip(starts, stops)):
        m = ok[a:b]
        if not m.any():
            continue
        q_ft = quat.multiply(qf_c[a:b][m], knee.apply_heading_offset(qt[a:b][m], off_w[k]))
        flex = knee.knee_angles(q_ft, "right")[:, 0]  # flexion does not depend on the side
        flex_range[k] = float(np.ptp(flex))
        if p.extension_weight_power > 0.0:  # (C3): lean on the straight-knee samples, refit once
            w_i = np.cos(np.clip(flex, 0.0, np.pi / 2)) ** p.extension_weight_power
            if w_i.sum() > 0.0:
                off_w[k] = float(np.arctan2(np.sum(w_i * s_i[a:b][m]), np.sum(w_i * c_i[a:b][m])))
        resid_w[k] = float(np.sqrt(np.mean(_axis_angle_rad(zf[a:b][m], zt[a:b][m], off_w[k]) ** 2)))
    excited = (flex_range >= p.min_flexion_range_rad) & (weight_w >= p.min_axis_weight)
    centre_s = (starts + stops - 1) / 2.0 / fs_hz
    t_s = np.arange(n) / fs_hz
    warnings: list[QualityWarning] = []
    frac = float(np.mean(excited))
    if excited.any():
        offs = np.unwrap(off_w[excited])
        offset = wrap(np.interp(t_s, centre_s[excited], offs))
    else:
        offset = np.full(n, float(np.arctan2(s_i.sum(), c_i.sum())))
    if frac < 0.5:
        vals = {"pct": 100.0 * frac, "window_s": float(p.window_s),
                "min_flexion_deg": float(np.rad2deg(p.min_flexion_range_rad))}
        warnings.append(QualityWarning(
            "constraint_heading_unexcited",
            f"the knee moved enough (at least {vals['min_flexion_deg']:.0f}° of flexion) in only {vals['pct']:.0f} % "
            f"of the {vals['window_s']:.0f} s windows; the joint-constraint heading was held or interpolated over "
            "the rest and may lag a changing field", vals))
    resid = _axis_angle_rad(zf[ok], zt[ok], offset[ok])
    residual = float(np.sqrt(np.mean(resid**2)))
    if residual > p.max_residual_rad:
        vals = {"angle_deg": float(np.rad2deg(residual)), "max_deg": float(np.rad2deg(p.max_residual_rad))}
        warnings.append(QualityWarning(
            "constraint_heading_residual",
            f"after the joint-constraint heading the thigh and shank flexion axes still differ by "
            f"{vals['angle_deg']:.1f}° RMS (more than {vals['max_deg']:.0f}°); the knee did not move like a hinge "
            "or a segment calibration is off, so the constraint heading is unreliable", vals))
    return ConstraintHeading(offset, starts, stops, centre_s, off_w, excited, flex_range, weight_w, resid_w, frac,
                             residual, tuple(warnings))


@dataclass(frozen=True)
class HeadingChoice:
    """Result of :func:`choose_heading`.

    mode : what was asked (``auto``/``magnetometer``/``constraint``).
    used : ``"magnetometer"`` or ``"constraint"``.   run : ``"9d"`` or ``"6d"``, the orientations the offset is for.
    offset_rad : (N,) δ(t) applied to the tibia of ``run``.
    q_earth_femur, q_earth_tibia : (N, 4) the segment orientations to compute the knee from, the tibia already
        in the femur's earth frame: ``knee.q_femur_tibia(choice.q_earth_femur, choice.q_earth_tibia)``.
    disagreement_rad : D, the largest |δ̂_W| of the constraint on the 9D run (excited windows; NaN
        without a 9D run).   bound_rad : the bound auto compared it with.
    constraint_9d, constraint_6d : the :class:`ConstraintHeading` computed (None when not computed).
    warnings : ``magnetic_heading_unreliable`` (auto switched), ``magnetic_heading_disagrees`` (magnetometer
        kept by request although D > bound) and the constraint's own warnings when it was used.
    """

    mode: str
    used: str
    run: str
    offset_rad: FloatArray
    q_earth_femur: FloatArray
    q_earth_tibia: FloatArray
    disagreement_rad: float
    bound_rad: float
    constraint_9d: ConstraintHeading | None
    constraint_6d: ConstraintHeading | None
    warnings: tuple[QualityWarning, ...]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready summary for ``results.json`` (degrees, as the report prints them; None for NaN):
        ``{"mode", "used", "run", "disagreement_deg", "bound_deg", "offset_deg": {"min", "max"},
        "excited_pct", "residual_deg"}`` (the last two of the constraint that was used, else of the 9D check)."""
        c = self.constraint_6d if self.run == "6d" else self.constraint_9d

        def deg(x: float) -> float | None:
            return float(np.rad2deg(x)) if np.isfinite(x) else None

        ref = float(np.angle(np.mean(np.exp(1j * self.offset_rad))))  # circular mean: no jump at ±180°
        rel = wrap(self.offset_rad - ref)
        return {"mode": self.mode, "used": self.used, "run": self.run,
                "disagreement_deg": deg(self.disagreement_rad), "bound_deg": deg(self.bound_rad),
                "offset_deg": {"min": deg(float(wrap(ref + rel.min()))), "max": deg(float(wrap(ref + rel.max())))},
                "excited_pct": None if c is None else 100.0 * c.excited_fraction,
                "residual_deg": None if c is None else deg(c.residual_rad)}


def disagreement_rad(ch: ConstraintHeading) -> float:
    """D = the largest |δ̂_W| over the excited windows (all windows when none is excited): on the 9D run the
    magnetometers' relative heading is 0 by definition, so this is how far they stray from the constraint."""
    offs = ch.window_offset_rad[ch.window_excited] if ch.window_excited.any() else ch.window_offset_rad
    return float(np.max(np.abs(wrap(offs))))


def choose_heading(q_earth_femur_9d: ArrayLike | None, q_earth_tibia_9d: ArrayLike | None, *, fs_hz: float,
                   mode: str = "auto", q_earth_femur_6d: ArrayLike | None = None,
                   q_earth_tibia_6d: ArrayLike | None = None, params: ConstraintHeadingParams | None = None,
                   bound_rad: float = DISAGREEMENT_BOUND_RAD) -> HeadingChoice:
    """The thigh–shank heading for ``--heading magnetometer|constraint|auto`` (module docstring).

    q_earth_femur_9d, q_earth_tibia_9d : (N, 4) segment orientations of the 9D run (magnetometer heading), or
        both None for a session without magnetometers (a 6D run only: ``auto`` then means ``constraint``, and
        ``magnetometer`` is refused).
    q_earth_femur_6d, q_earth_tibia_6d : the same samples from a 6D run, when the caller has it (both or none);
        the constraint heading is then computed on them.
    fs_hz : rate, Hz.   mode : ``"auto"`` (default), ``"magnetometer"`` or ``"constraint"``.
    params : :class:`ConstraintHeadingParams`.   bound_rad : auto's disagreement bound (``DISAGREEMENT_BOUND_RAD``).
    """
    if mode not in HEADING_MODES:
        raise ValueError(f"heading must be one of {', '.join(HEADING_MODES)}, got {mode!r}")
    if (q_earth_femur_6d is None) != (q_earth_tibia_6d is None):
        raise ValueError("pass both 6D segment orientations or neither")
    if (q_earth_femur_9d is None) != (q_earth_tibia_9d is None):
        raise ValueError("pass both 9D segment orientations or neither")
    if not (np.isfinite(bound_rad) and bound_rad > 0.0):
        raise ValueError(f"bound_rad must be a positive angle, got {bound_rad!r}")
    if q_earth_femur_9d is None:
        if q_earth_femur_6d is None:
            raise ValueError("pass the 9D run's segment orientations, the 6D run's, or both")
        if mode == "magnetometer":
            raise ValueError("the magnetometer heading needs a 9D run; without magnetometers use the constraint "
                             "heading (--heading constraint or auto)")
        qf, qt = quat.as_quaternion(q_earth_femur_6d), quat.as_quaternion(q_earth_tibia_6d)
        c6 = constraint_heading(qf, qt, fs_hz=fs_hz, params=params)
        return HeadingChoice(mode, "constraint", "6d", c6.offset_rad, qf, knee.apply_heading_offset(qt, c6.offset_rad),
                             float("nan"), float(bound_rad), None, c6, c6.warnings)
    qf9, qt9 = quat.as_quaternion(q_earth_femur_9d), quat.as_quaternion(q_earth_tibia_9d)
    c9 = constraint_heading(qf9, qt9, fs_hz=fs_hz, params=params)
    d = disagreement_rad(c9)
    vals = {"disagreement_deg": float(np.rad2deg(d)), "bound_deg": float(np.rad2deg(bound_rad))}
    use_constraint = mode == "constraint" or (mode == "auto" and d > bound_rad)
    warnings: list[QualityWarning] = []
    loud = {"disagreement_deg": vals["disagreement_deg"], "bound_deg": float(np.rad2deg(DISTURBED_BOUND_RAD))}
    if mode == "auto" and use_constraint and d > DISTURBED_BOUND_RAD:
        vals = loud
        warnings.append(QualityWarning(
            "magnetic_heading_unreliable",
            f"the thigh and shank magnetometers disagree with the knee's hinge constraint by "
            f"{vals['disagreement_deg']:.0f}° (more than {vals['bound_deg']:.0f}°); the knee angles use the "
            "joint-constraint heading instead of the magnetometers", vals))
    if mode == "magnetometer" and d > DISTURBED_BOUND_RAD:
        vals = loud
        warnings.append(QualityWarning(
            "magnetic_heading_disagrees",
            f"the thigh and shank magnetometers disagree with the knee's hinge constraint by "
            f"{vals['disagreement_deg']:.0f}° (more than {vals['bound_deg']:.0f}°) but the magnetometer heading was "
            "kept as requested; adduction, rotation and possibly flexion may be wrong", vals))
    c6 = None
    if not use_constraint:
        offset, run, qf, qt = np.zeros(len(qf9)), "9d", qf9, qt9
    elif q_earth_femur_6d is not None:
        qf, qt = quat.as_quaternion(q_earth_femur_6d), quat.as_quaternion(q_earth_tibia_6d)
        if qf.shape != qf9.shape or qt.shape != qt9.shape:
            raise ValueError(f"the 6D run must cover the 9D run's samples, got {qf.shape} and {qf9.shape}")
        c6 = constraint_heading(qf, qt, fs_hz=fs_hz, params=params)
        offset, run = c6.offset_rad, "6d"
        warnings += list(c6.warnings)
    else:
        offset, run, qf, qt = c9.offset_rad, "9d", qf9, qt9
        warnings += list(c9.warnings)
    return HeadingChoice(mode, "constraint" if use_constraint else "magnetometer", run, offset, qf,
                         knee.apply_heading_offset(qt, offset), d, float(bound_rad), c9, c6, tuple(warnings))
