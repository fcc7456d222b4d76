r"""Spatial Markovian system SMe (seed 000 §2.3 and §2.4.1; Albuquerque, Francelino, Nogueira 2021).

The planar MJLS (:mod:`.mjls`) extended to roll, pitch and yaw: every segment ``i`` (trunk B, thigh T,
shank S; or thigh and shank) carries three single-axis error models, one per sensor axis
:math:`j\in\{R, P, Y\}` = sensor :math:`x, y, z` (eqs. 40, 42–43):

.. math:: x_i = [\Delta\theta_{iR}, \Delta b_{iR}, \Delta\theta_{iP}, \Delta b_{iP}, \Delta\theta_{iY}, \Delta b_{iY}],

18 states for three segments, 12 for two (eq. 63).  Each axis angle is the integral of that axis's
gyroscope rate, and its absolute measurement is the accelerometer angle about that axis
(:func:`estimators.markov.fkc.accelerometer_angles`): the per-axis, small-coupling model of the seed,
exact for rotations about one axis and an approximation when a segment turns about several.

Output (eqs. 41, 44, 64, 67): :math:`y = [\Delta\theta_{\Xi R}, \Delta\theta_{\Xi P}, \Delta\theta_{\Xi Y},
\Delta_h, \Delta_k]`, i.e. the three rows :math:`M_\Xi = S_{RPY}` (eq. 48, Tables 2–3) of the segment
:math:`\Xi(k) = \arg\min_i |\|a_i\|-g|` (eqs. 46–47, 60), used only when :math:`\rho(k)\le\zeta`
(eqs. 78–79), and one encoder row :math:`[r, -r]` per joint with :math:`r` selecting the joint's
axis (the seed's sensors were mounted so that the joint turns about their x axis: ``joint_axis=0``,
"roll").  Our joint angle is :math:`\alpha = \theta_{prev} - \theta_{next}` (seed 002 eq. 17; seed 000
eq. 67 writes the same row with the opposite sign of :math:`\alpha`).

:math:`R(\Xi)` (eqs. 59, 82): the three accelerometer-angle variances of the selected segment, each
scaled by :math:`(g/p_j)^2` where :math:`p_j` is the magnitude of the specific force projected on the
plane normal to axis :math:`j` (an axis near the vertical has no gravity lever, so its angle is
unobservable); the encoder variance :math:`\sigma_{e}^2`.  :math:`Q` (eqs. 56–58, 80–81) as in
:mod:`estimators.markov.core`.

Defaults (seed 000 Table 5, read as the diagonal entries of Q and R): :math:`q_\theta = q_b = 10^{-7}`
(rad²/s, rad²/s³), :math:`\tau_g = 10^{15}` s (a random-walk bias), :math:`\sigma_a^2 = 0.0014` (thigh),
0.0017 (shank) rad², :math:`\sigma^2_{enc/joint} = 0.5` deg².  ζ has no value in the seed
("ζ → 0"); default 0.05 g, which on our simulated exoskeleton walk uses the accelerometers
about as often as the seed reports (Fig. 27: 38 % thigh, 37 % shank).  The encoder rows are used
at every sample where the encoder has a value (``encoder_rows="always"``); ``"with_accelerometer"`` uses them only at corrected samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from estimators.markov.core import FilterState, FloatArray, initial_state, run_filter, run_filter_reference
from estimators.markov.fkc import GRAVITY_M_S2, accelerometer_angles
from estimators.markov.mjls import markov_state

__all__ = ["SpatialParams", "SpatialResult", "sme", "spatial_inputs", "run_spatial"]



def _seq(value, name, n=None, positive=True):
    v = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if v.ndim != 1 or (n is not None and v.size not in (1, n)):
        raise ValueError(f"{name} must be one number or one per segment ({n}), got {value!r}")
    if np.any(np.isnan(v)) or (np.any(v <= 0) if positive else np.any(v < 0)):
        raise ValueError(f"{name} must hold numbers {'> 0' if positive else '>= 0'}, got {value!r}")
    return tuple(float(x) for x in v)


@dataclass(frozen=True)
class SpatialParams:
    """Parameters of SMe / SMeA (one value for all segments or one per segment).

    q_angle_rad2_s : angle process-noise density per axis, rad²/s (1e-7, Table 5).
    q_bias_rad2_s3 : bias process-noise density per axis, rad²/s³ (1e-7).
    tau_gyro_s : bias correlation time, s (1e15).
    r_acc_rad2 : accelerometer-angle variance per segment, rad² ((0.0014, 0.0017): thigh, shank).
    r_joint_deg2 : encoder / joint-angle variance, deg² (0.5).
    zeta_g : reliability threshold on |‖a‖ − g|, in g (0.05).
    joint_axis : sensor axis of the joints, 0 = x ("roll"), 1 = y, 2 = z (0).
    encoder_rows : ``"always"`` or ``"with_accelerometer"``.
    gravity_m_s2 : g (9.81).   p0_angle_rad2, p0_bias_rad2_s2 : initial covariance (1e-4, 1e-6).
    """

    q_angle_rad2_s: tuple = (1e-7,)
    q_bias_rad2_s3: tuple = (1e-7,)
    tau_gyro_s: tuple = (1e15,)
    r_acc_rad2: tuple = (0.0014, 0.0017)
    r_joint_deg2: float = 0.5
    zeta_g: float = 0.05
    joint_axis: int = 0
    encoder_rows: str = "always"
    gravity_m_s2: float = GRAVITY_M_S2
    p0_angle_rad2: float = 1e-4
    p0_bias_rad2_s2: float = 1e-6

    def __post_init__(self) -> None:
        for name, pos in (("q_angle_rad2_s", False), ("q_bias_rad2_s3", False), ("tau_gyro_s", True),
                          ("r_acc_rad2", True)):
            object.__setattr__(self, name, _seq(getattr(self, name), name, None, pos))
        if not (np.isfinite(self.r_joint_deg2) and self.r_joint_deg2 > 0):
            raise ValueError(f"r_joint_deg2 must be > 0, got {self.r_joint_deg2!r}")
        if np.isnan(self.zeta_g) or self.zeta_g < 0:
            raise ValueError(f"zeta_g must be >= 0 (inf: always correct), got {self.zeta_g!r}")
        if self.joint_axis not in (0, 1, 2):
            raise ValueError(f"joint_axis must be 0 (x), 1 (y) or 2 (z), got {self.joint_axis!r}")
        if self.encoder_rows not in ("always", "with_accelerometer"):
            raise ValueError(f"encoder_rows must be 'always' or 'with_accelerometer', got {self.encoder_rows!r}")

    def per_segment(self, name: str, n: int) -> FloatArray:
        v = np.asarray(getattr(self, name))
        if v.size not in (1, n):
            raise ValueError(f"{name} has {v.size} values but there are {n} segments")
        return np.broadcast_to(v, (n,)).astype(np.float64)


@dataclass
class SpatialResult:
    """theta_rad : (N, n_seg, 3) roll/pitch/yaw (about sensor x, y, z).  joint_rad : (N, n_seg − 1)
    joint angles about ``joint_axis`` (θ_prev − θ_next).  markov_state : (N,) Ξ(k) (0..n_seg−1; SMeA:
    n_seg = TS).  acc_used : (N, n_seg) accelerometer rows used.  acc_angles_rad : (N, n_seg, 3) the
    accelerometer angles.  state : final filter state.  gains : see :func:`run_filter_reference`."""

    theta_rad: FloatArray
    joint_rad: FloatArray
    markov_state: FloatArray
    acc_used: FloatArray
    acc_angles_rad: FloatArray
    state: FilterState
    gains: list | None = field(default=None, repr=False)


def spatial_inputs(gyr: Sequence[ArrayLike], acc: Sequence[ArrayLike], gravity_ref: Sequence[ArrayLike] | None):
    """Stack per-segment (N, 3) arrays → rates, accelerometer angles, projections (N, 3n); norms (N, n)."""
    if len(gyr) != len(acc) or len(gyr) < 2:
        raise ValueError(f"need gyr and acc for at least two segments, got {len(gyr)} and {len(acc)}")
    g = [np.asarray(v, dtype=np.float64) for v in gyr]
    a = [np.asarray(v, dtype=np.float64) for v in acc]
    n = len(g[0])
    for i, (gi, ai) in enumerate(zip(g, a)):
        if gi.shape != (n, 3) or ai.shape != (n, 3):
            raise ValueError(f"segment {i}: gyr and acc must have shape ({n}, 3), got {gi.shape} and {ai.shape}")
        if not np.all(np.isfinite(gi)):
            raise ValueError(f"segment {i}: gyr must be finite")
    ang, proj = zip(*(accelerometer_angles(ai, None if gravity_ref is None else gravity_ref[i])
                      for i, ai in enumerate(a)))
    norms = np.column_stack([np.linalg.norm(ai, axis=1) for ai in a])
    return np.hstack(g), np.hstack(ang), np.hstack(proj), norms


def run_spatial(w, za, proj, use_seg, joint, use_joint, *, fs_hz, params: SpatialParams, theta0_rad,
                state, reference, keep_gains):
    """Shared by SMe and SMeA: rows of the segments in ``use_seg`` (N, n) and the joint rows."""
    n_seg = use_seg.shape[1]
    if not (np.isfinite(fs_hz) and fs_hz > 0):
        raise ValueError(f"fs_hz must be a positive number, got {fs_hz!r}")
    r_seg = params.per_segment("r_acc_rad2", n_seg)
    g = params.gravity_m_s2
    r_abs = np.repeat(r_seg, 3)[None, :] * (g / np.maximum(proj, 1e-3 * g)) ** 2
    use_abs = np.repeat(use_seg, 3, axis=1) & np.isfinite(za)
    if state is None:
        th0 = np.where(np.isfinite(za[0]), za[0], 0.0) if theta0_rad is None else \
            np.asarray(theta0_rad, dtype=np.float64).reshape(-1)
        state = initial_state(th0, params.p0_angle_rad2, params.p0_bias_rad2_s2)
    ax = params.joint_axis
    pairs = np.array([[3 * i + ax, 3 * (i + 1) + ax] for i in range(n_seg - 1)], dtype=np.int64)
    run = run_filter_reference if reference else run_filter
    kw = dict(dt_s=1.0 / fs_hz, tau_s=np.repeat(params.per_segment("tau_gyro_s", n_seg), 3),
              q_angle_rad2_s=np.repeat(params.per_segment("q_angle_rad2_s", n_seg), 3),
              q_bias_rad2_s3=np.repeat(params.per_segment("q_bias_rad2_s3", n_seg), 3), state=state)
    if reference:
        kw["keep_gains"] = keep_gains
    out = run(w, np.where(use_abs, za, 0.0), r_abs, use_abs, np.where(use_joint, joint, 0.0), pairs,
              params.r_joint_deg2 * (np.pi / 180) ** 2, use_joint, **kw)
    th, _, st = out[:3]
    gains = out[3] if (reference and keep_gains) else None
    th3 = th.reshape(len(th), n_seg, 3)
    return th3, th3[:, :-1, ax] - th3[:, 1:, ax], st, gains


def sme(gyr: Sequence[ArrayLike], acc: Sequence[ArrayLike], encoder_rad: ArrayLike | None, *, fs_hz: float,
        params: SpatialParams | None = None, gravity_ref: Sequence[ArrayLike] | None = None,
        theta0_rad: ArrayLike | None = None, state: FilterState | None = None, reference: bool = False,
        keep_gains: bool = False) -> SpatialResult:
    """SMe: per-segment gyr/acc (N, 3) lists (proximal first), encoders (N, n−1) rad (NaN: no sample).

    ``gravity_ref`` (one (3,) per segment): specific force at the zero angles (default: first sample);
    ``theta0_rad`` (3n,) the angles one sample before the first (default: the first accelerometer angles).
    """
    params = SpatialParams() if params is None else params
    w, za, proj, norms = spatial_inputs(gyr, acc, gravity_ref)
    n_seg = norms.shape[1]
    xi, _, ok = markov_state(norms, params.gravity_m_s2, params.zeta_g * params.gravity_m_s2)  # eqs. 47/60, 78–79
    use_seg = np.zeros((len(w), n_seg), dtype=bool)
    use_seg[np.arange(len(w)), xi] = ok
    joint = np.full((len(w), n_seg - 1), np.nan) if encoder_rad is None else \
        np.asarray(encoder_rad, dtype=np.float64).reshape(len(w), -1)
    if joint.shape != (len(w), n_seg - 1):
        raise ValueError(f"encoder_rad must have shape {(len(w), n_seg - 1)}, got {joint.shape}")
    use_joint = np.isfinite(joint)
    if params.encoder_rows == "with_accelerometer":
        use_joint &= ok[:, None]
    th, jr, st, gains = run_spatial(w, za, proj, use_seg, joint, use_joint, fs_hz=fs_hz, params=params,
                                    theta0_rad=theta0_rad, state=state, reference=reference, keep_gains=keep_gains)
    return SpatialResult(th, jr, xi, use_seg, za.reshape(len(w), n_seg, 3), st, gains)
