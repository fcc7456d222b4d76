r"""Magnetic disturbance during a recording, from the calibrated field and the estimated orientation.

An undisturbed Earth field has a constant norm :math:`|m|` (the calibration's ``field_ut``) and a
constant dip (inclination) below the horizon,

.. math::
    \delta_k = \operatorname{atan2}\big(-m^E_{z,k},\ \lVert m^E_{xy,k} \rVert\big), \qquad
    m^E_k = q_{ES,k} \otimes m^S_k \otimes q_{ES,k}^*,

so a sample is *disturbed* when :math:`\big|\,|m_k| / |m|_{ref} - 1\big| > \epsilon_n` or
:math:`|\delta_k - \delta_{ref}| > \epsilon_\delta`, with :math:`\delta_{ref}` the median dip of the
samples whose norm is right (the recording's own local dip: no geographic model is needed).  The dip
uses the *estimated* inclination, which every 9D filter takes from the accelerometer, so it sees
disturbances that rotate the field without changing its norm — the kind that bends heading.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.quality import QualityWarning

FloatArray = NDArray[np.float64]

#: share of disturbed samples above which a recording gets a warning
WARN_FRACTION = 0.05


@dataclass(frozen=True)
class FieldCheck:
    """Per-recording summary: ``disturbed`` (N,) bool, ``fraction`` of valid samples disturbed, the
    reference dip (rad), the largest norm deviation (fraction) and dip deviation (rad), and warnings."""

    disturbed: NDArray[np.bool_]
    fraction: float
    dip_ref_rad: float
    max_norm_dev: float
    max_dip_dev_rad: float
    warnings: tuple[QualityWarning, ...]


def field_disturbance(
    mag_ut: ArrayLike,
    q_earth_sensor: ArrayLike,
    field_ut: float,
    *,
    norm_tol: float = 0.1,
    dip_tol_rad: float = float(np.deg2rad(5.0)),
    label: str = "sensor",
) -> FieldCheck:
    """Flag the samples whose calibrated field departs from the Earth's (module docstring).

    mag_ut : (N, 3) calibrated field in sensor coordinates (NaN rows are ignored).
    q_earth_sensor : (N, 4) estimated orientation.   field_ut : reference norm (the calibration's).
    norm_tol : allowed relative norm deviation.   dip_tol_rad : allowed dip deviation.
    label : names the sensor in the warning message.
    """
    m = np.asarray(mag_ut, dtype=np.float64)
    q = quat.as_quaternion(q_earth_sensor)
    if m.ndim != 2 or m.shape[1] != 3 or q.shape != (m.shape[0], 4):
        raise ValueError(f"mag_ut must be (N, 3) and q_earth_sensor (N, 4); got {m.shape} and {q.shape}")
    if not (np.isfinite(field_ut) and field_ut > 0.0):
        raise ValueError(f"field_ut must be a positive field strength in µT, got {field_ut!r}")
    valid = np.isfinite(m).all(axis=1) & np.isfinite(q).all(axis=1)
    disturbed = np.zeros(len(m), dtype=bool)
    if not valid.any():
        return FieldCheck(disturbed, float("nan"), float("nan"), float("nan"), float("nan"), ())
    m_e = quat.rotate(q[valid], m[valid])
    norm_dev = np.abs(np.linalg.norm(m_e, axis=1) / field_ut - 1.0)
    dip = np.arctan2(-m_e[:, 2], np.linalg.norm(m_e[:, :2], axis=1))
    norm_ok = norm_dev <= norm_tol
    dip_ref = float(np.median(dip[norm_ok] if norm_ok.any() else dip))
    dip_dev = np.abs(dip - dip_ref)
    disturbed[valid] = ~norm_ok | (dip_dev > dip_tol_rad)
    fraction = float(disturbed[valid].mean())
    warnings = ()
    if fraction > WARN_FRACTION:
        pct, norm_pct, dip_deg = 100.0 * fraction, 100.0 * float(norm_dev.max()), float(np.rad2deg(dip_dev.max()))
        warnings = (QualityWarning(
            "magnetic_disturbance",
            f"The magnetic field at the {label} sensor was disturbed during {pct:.0f} % of the task "
            f"(norm off by up to {norm_pct:.0f} %, dip by up to {dip_deg:.0f}°): "
            "heading-dependent angles (adduction, rotation) may be less accurate. Keep metal and electronics "
            "away from the sensors.",
            {"segment": label, "pct": pct, "norm_pct": norm_pct, "dip_deg": dip_deg},
        ),)
    return FieldCheck(disturbed, fraction, dip_ref, float(norm_dev.max()), float(dip_dev.max()), warnings)
