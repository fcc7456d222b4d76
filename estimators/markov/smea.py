r"""SMeA: spatial Markovian system with a self-aligned joint constraint (seed 000 §2.4.3).

Two consecutive segments, thigh T and shank S, with IMUs and *no encoder*.  Differences from SMe
(:mod:`.sme`):

* a third, nominal Markov state TS in which both accelerometers correct the filter (eq. 75):

  .. math:: \Xi(t) = \begin{cases} TS, & \lambda = 2\\ \arg\min_i |\|a_i\| - g_e|, & \lambda\le 1\end{cases}

  with :math:`\lambda` the number of accelerometers with :math:`|\|a_i\|-g_e|\le\zeta` (eq. 78, SMeA
  row); every accelerometer satisfying eq. 79 is used (§3.1), so in T or S the selected one is used
  only if it is itself reliable;
* :math:`\bar C(\Xi)` of eq. 76 — :math:`[M_T\ 0;\ 0\ M_S;\ -r\ r]` with :math:`M_i = S_{RPY}` or
  :math:`0_{3\times6}` (Table 4) — and :math:`R(\Xi)` of eqs. 83–84 (the rows of T, of S, or of both,
  plus the joint variance :math:`\sigma_{g_k}^2`);
* the encoder is replaced by the self-aligned joint angle of Seel et al. (§2.4.2,
  :mod:`estimators.joint_axis`): axes and joint centre estimated from the same data, the gyroscope
  (eq. 73) and accelerometer (eq. 74) joint angles fused by an FKC (eq. 77).

The self-aligned angle is zero at the start pose; its zero is set from ``theta0_rad`` (the difference
of the two segments' joint-axis angles at the start), as an encoder's offset would be.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from estimators import joint_axis
from estimators.markov.core import FilterState
from estimators.markov.fkc import FkcParams
from estimators.markov.sme import SpatialParams, SpatialResult, run_spatial, spatial_inputs
from estimators.markov.mjls import markov_state

__all__ = ["smea", "self_aligned_joint_angle", "smea_state"]


def smea_state(acc_norm_m_s2: ArrayLike, gravity_m_s2: float, zeta_m_s2: float):
    """Eq. 75: ``(Ξ (N,) with 0 = T, 1 = S, 2 = TS, reliable (N, 2) bool)``."""
    d = np.abs(np.asarray(acc_norm_m_s2, dtype=np.float64) - gravity_m_s2)
    reliable = d <= zeta_m_s2  # NaN compares False: a missing sample is never reliable
    best, _, _ = markov_state(acc_norm_m_s2, gravity_m_s2, zeta_m_s2)
    return np.where(reliable.sum(axis=1) == 2, 2, best), reliable


def self_aligned_joint_angle(acc_t, gyr_t, acc_s, gyr_s, *, fs_hz: float, axis_index: int = 0,
                             params: FkcParams | None = None):
    """Knee angle θ_T − θ_S about the self-aligned axis (rad, zero at the start) and the axes.

    The overall sign of the axes is chosen so that ``j_T`` points along the sensor axis ``axis_index``
    (the seed's "roll" axis), making the angle comparable with the roll difference of the filter.
    """
    axes = joint_axis.estimate(acc_t, gyr_t, acc_s, gyr_s, fs_hz=fs_hz)
    if axes.j_a[axis_index] < 0:
        axes.j_a, axes.j_b = -axes.j_a, -axes.j_b
    fused, _, _ = joint_axis.joint_angle(acc_t, gyr_t, acc_s, gyr_s, fs_hz=fs_hz, axes=axes, params=params)
    return fused, axes


def smea(gyr: Sequence[ArrayLike], acc: Sequence[ArrayLike], *, fs_hz: float, params: SpatialParams | None = None,
         joint_rad: ArrayLike | None = None, gravity_ref: Sequence[ArrayLike] | None = None,
         theta0_rad: ArrayLike | None = None, state: FilterState | None = None, reference: bool = False,
         keep_gains: bool = False) -> SpatialResult:
    """SMeA on thigh and shank gyr/acc (N, 3).  ``joint_rad`` (N,) overrides the self-aligned knee angle
    (absolute, θ_T − θ_S about the joint axis); otherwise it is computed from the data (eq. 77)."""
    params = SpatialParams() if params is None else params
    if len(gyr) != 2 or len(acc) != 2:
        raise ValueError(f"SMeA models two segments (thigh, shank), got {len(gyr)}")
    w, za, proj, norms = spatial_inputs(gyr, acc, gravity_ref)
    xi, reliable = smea_state(norms, params.gravity_m_s2, params.zeta_g * params.gravity_m_s2)
    th0 = np.where(np.isfinite(za[0]), za[0], 0.0) if theta0_rad is None else \
        np.asarray(theta0_rad, dtype=np.float64).reshape(-1)
    if joint_rad is None:
        ax = params.joint_axis
        rel, _ = self_aligned_joint_angle(acc[0], gyr[0], acc[1], gyr[1], fs_hz=fs_hz, axis_index=ax)
        joint = (rel + (th0[ax] - th0[3 + ax]))[:, None]
    else:
        joint = np.asarray(joint_rad, dtype=np.float64).reshape(len(w), 1)
    use_joint = np.isfinite(joint)
    if params.encoder_rows == "with_accelerometer":
        use_joint &= reliable.any(axis=1)[:, None]
    th, jr, st, gains = run_spatial(w, za, proj, reliable, joint, use_joint, fs_hz=fs_hz, params=params,
                                    theta0_rad=th0, state=state, reference=reference, keep_gains=keep_gains)
    return SpatialResult(th, jr, xi, reliable, za.reshape(len(w), 2, 3), st, gains)
