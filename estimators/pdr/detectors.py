r"""Stance (zero-velocity) detectors for a foot-mounted IMU (seed 001 §3.4 eqs. 3.2–3.4, §4.4 eqs. 4.1–4.2).

Each detector returns a boolean mask, True where the foot is judged still.  The statistics are
vectorised (prefix sums), so no compiled loop is needed.  Windows are given in samples, as in the
thesis (defaults are its values at 100 Hz).

Acceleration/rate detector "C1 & C2 & C3" (after Skog et al. 2010, Jiménez et al. 2010)
---------------------------------------------------------------------------------------
.. math::
    C_1 &= [\,f_{min} < \lVert f^b_k\rVert < f_{max}\,] &\text{(3.2), 9 and 11 m/s²}\\
    C_2 &= \Big[\tfrac1n \textstyle\sum_{i \in W_k} (\lVert f^b_i\rVert - \bar f_k)^2 < \sigma^2_f\Big]
         &\text{(3.3), } n = 10,\ \sigma_f^2 = 3\ \mathrm{m^2/s^4}\\
    C_3 &= [\,\lVert \omega^b_k\rVert < \omega_{max}\,] &\text{(3.4), 0.6 rad/s (Fischer et al. 2012)}

:math:`W_k` is the window of ``var_samples`` samples centred on *k* (the variance uses the magnitude of
the specific force, as Jiménez et al.).  The combination :math:`C_1 \wedge C_2 \wedge C_3` is then smoothed
by a moving majority vote over ``smooth_samples`` = 10 samples (§4.4: "filtrado utilizando uma janela
móvel de 10 medições"): a sample is stance when at least half of its window is.

Pitch detector (the thesis' proposal, §4.4.1)
---------------------------------------------
.. math::
    C_{1,pitch} &= [\,|\theta_k - \theta_{ref}| < 6°\,] &\text{(4.1)}\\
    C_{2,pitch} &= \Big[\tfrac1n \textstyle\sum_{i \in W_k} (\theta_i - \bar\theta_k)^2 < 6\ \mathrm{deg^2}\Big]
        &\text{(4.2), } n = 20

with :math:`\theta` the foot pitch (ZYX Euler) from an attitude estimate and :math:`\theta_{ref}` its mean
over the initial still period.  The thesis writes the variance threshold as "6°"; it is a variance,
6 deg² = 1.83e-3 rad².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.windows import centred_bounds, moving_variance, true_runs

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

DETECTORS = ("c123", "pitch")

__all__ = ["DETECTORS", "PitchParams", "ShoeParams", "moving_majority", "moving_variance", "pitch_detector",
           "stance_c123", "stance_intervals"]


def moving_majority(mask: ArrayLike, n: int) -> BoolArray:
    """True where at least half of the ``n``-sample window centred on the sample is True (``n`` ≤ 1: unchanged)."""
    b = np.asarray(mask, dtype=bool)
    if n <= 1:
        return b.copy()
    lo, hi = centred_bounds(len(b), n)
    c = np.concatenate([[0], np.cumsum(b)])
    return 2 * (c[hi] - c[lo]) >= (hi - lo)


@dataclass(frozen=True)
class ShoeParams:
    """Thresholds of the C1 & C2 & C3 detector (thesis defaults).

    acc_min_m_s2, acc_max_m_s2 : band of |f| for C1 (3.2), m/s².  Default 9, 11.
    var_samples : window n of the moving variance of C2 (3.3), samples.  Default 10.
    var_threshold_m2_s4 : C2 threshold on the variance of |f|, m²/s⁴.  Default 3 (Jiménez et al. 2010).
    gyr_max_rad_s : C3 threshold on |ω| (3.4), rad/s.  Default 0.6 (Fischer et al. 2012).
    smooth_samples : majority-vote window of the combined mask, samples.  Default 10.
    """

    acc_min_m_s2: float = 9.0
    acc_max_m_s2: float = 11.0
    var_samples: int = 10
    var_threshold_m2_s4: float = 3.0
    gyr_max_rad_s: float = 0.6
    smooth_samples: int = 10

    def __post_init__(self) -> None:
        if not (0.0 <= self.acc_min_m_s2 < self.acc_max_m_s2):
            raise ValueError(f"need 0 <= acc_min_m_s2 < acc_max_m_s2, got {self.acc_min_m_s2}, {self.acc_max_m_s2}")
        if self.var_samples < 2:
            raise ValueError(f"var_samples must be >= 2, got {self.var_samples}")
        if not self.var_threshold_m2_s4 > 0.0:
            raise ValueError(f"var_threshold_m2_s4 must be > 0, got {self.var_threshold_m2_s4}")
        if not self.gyr_max_rad_s > 0.0:
            raise ValueError(f"gyr_max_rad_s must be > 0, got {self.gyr_max_rad_s}")
        if self.smooth_samples < 1:
            raise ValueError(f"smooth_samples must be >= 1, got {self.smooth_samples}")


def stance_c123(acc: ArrayLike, gyr: ArrayLike, params: ShoeParams = ShoeParams()) -> BoolArray:
    """Stance mask (N,) from C1 & C2 & C3 (eqs. 3.2–3.4), smoothed by a moving majority vote."""
    f = np.linalg.norm(np.asarray(acc, dtype=np.float64), axis=1)
    w = np.linalg.norm(np.asarray(gyr, dtype=np.float64), axis=1)
    c1 = (f > params.acc_min_m_s2) & (f < params.acc_max_m_s2)
    c2 = moving_variance(f, params.var_samples) < params.var_threshold_m2_s4
    c3 = w < params.gyr_max_rad_s
    return moving_majority(c1 & c2 & c3, params.smooth_samples)


@dataclass(frozen=True)
class PitchParams:
    """Thresholds of the pitch detector (thesis defaults).

    band_rad : half-width of the band around the reference pitch for C1pitch (4.1), rad.  Default 6°.
    var_samples : window n of the moving variance of C2pitch (4.2), samples.  Default 20.
    var_threshold_rad2 : C2pitch threshold on the pitch variance, rad².  Default 6 deg².
    smooth_samples : majority-vote window of the combined mask, samples.  Default 1 (none, as the thesis).
    """

    band_rad: float = float(np.deg2rad(6.0))
    var_samples: int = 20
    var_threshold_rad2: float = float(6.0 * np.deg2rad(1.0) ** 2)
    smooth_samples: int = 1

    def __post_init__(self) -> None:
        if not self.band_rad > 0.0:
            raise ValueError(f"band_rad must be > 0, got {self.band_rad}")
        if self.var_samples < 2:
            raise ValueError(f"var_samples must be >= 2, got {self.var_samples}")
        if not self.var_threshold_rad2 > 0.0:
            raise ValueError(f"var_threshold_rad2 must be > 0, got {self.var_threshold_rad2}")
        if self.smooth_samples < 1:
            raise ValueError(f"smooth_samples must be >= 1, got {self.smooth_samples}")


def pitch_detector(pitch_rad: ArrayLike, pitch_ref_rad: float, params: PitchParams = PitchParams()) -> BoolArray:
    """Stance mask (N,) from C1pitch & C2pitch (eqs. 4.1–4.2) on a pitch series (N,), rad."""
    th = np.asarray(pitch_rad, dtype=np.float64)
    c1 = np.abs(th - pitch_ref_rad) < params.band_rad
    c2 = moving_variance(th, params.var_samples) < params.var_threshold_rad2
    return moving_majority(c1 & c2, params.smooth_samples)


def stance_intervals(mask: ArrayLike, min_samples: int = 1) -> NDArray[np.int64]:
    """(K, 2) half-open ``[start, end)`` sample ranges of the stance runs of ``mask`` at least ``min_samples`` long."""
    return true_runs(mask, min_samples)
