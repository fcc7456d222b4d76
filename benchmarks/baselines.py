"""The filters the benchmarks compare, as ``estimate_fn(acc, gyr, mag_or_None, fs_hz) -> q_earth_sensor``.

* :func:`project_method` — one method of :mod:`estimators.orientation` (any parameters);
* ``COMPARISONS`` — the comparison rows of ``python -m benchmarks.broad`` (and ``benchmarks.speed``):
  our Madgwick configured as BROAD ran theirs (``madgwick_broad``), VQF offline and online (the ``vqf``
  package), and the ``ahrs`` package's Madgwick, FKF and AQUA converted from NWU to ENU.

Every function returns ``(N, 4)`` ``q_earth_sensor`` in ENU (``../shared/DESIGN.md`` §3); ``mag=None``
asks for the 6D variant.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat

FloatArray = NDArray[np.float64]
EstimateFn = Callable[[FloatArray, FloatArray, "FloatArray | None", float], ArrayLike]

MODES = ("9d", "6d")

_Q_Z90 = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])  # q_ENU_NWU: +90° about the vertical


def project_method(name: str, **params: Any) -> EstimateFn:
    """``estimate_fn`` of one method of ``estimators.orientation`` (its import errors surface on first call)."""
    from estimators import orientation

    def fn(acc: FloatArray, gyr: FloatArray, mag: FloatArray | None, fs_hz: float) -> FloatArray:
        return orientation.estimate(acc, gyr, mag, fs_hz=fs_hz, method=name, **params)

    fn.__name__ = name
    return fn


def _vqf(offline: bool) -> EstimateFn:
    def fn(acc: FloatArray, gyr: FloatArray, mag: FloatArray | None, fs_hz: float) -> FloatArray:
        import vqf  # VQF's earth frame is ENU and it returns q_earth_sensor: no conversion

        args = [np.ascontiguousarray(gyr), np.ascontiguousarray(acc)]
        m = None if mag is None else np.ascontiguousarray(mag)
        out = vqf.offlineVQF(*args, m, 1.0 / fs_hz) if offline else vqf.VQF(1.0 / fs_hz).updateBatch(*args, m)
        return out["quat6D" if mag is None else "quat9D"]

    fn.__name__ = "vqf_offline" if offline else "vqf_online"
    return fn


def _ahrs(kind: str, gain: float = 0.12) -> EstimateFn:
    """ahrs 0.4.0 filters, started like BROAD's runs (aligned on the first sample), converted to ``q_ENU_sensor``.

    Frames checked on static synthetic data: Madgwick and FKF return ``q_NWU_sensor`` (FKF not normalised),
    AQUA returns ``q_sensor_NWU``; ``q_ENU = q_z(+90°) ⊗ q_NWU``.
    """
    def fn(acc: FloatArray, gyr: FloatArray, mag: FloatArray | None, fs_hz: float) -> FloatArray:
        from ahrs import filters

        from estimators.orientation.base import align

        q0_nwu = quat.multiply(quat.conjugate(_Q_Z90), align(acc[0], None if mag is None else mag[0]))
        kw: dict[str, Any] = {"gyr": gyr, "acc": acc, "frequency": fs_hz}
        if mag is not None:
            kw["mag"] = mag
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            if kind == "madgwick":
                q = filters.Madgwick(**kw, gain=gain, q0=q0_nwu).Q
            elif kind == "fkf":
                q = filters.FKF(**kw).Q
            elif kind == "aqua":
                q = quat.conjugate(filters.AQUA(**kw).Q)
            else:
                raise ValueError(f"unknown ahrs filter {kind!r}")
        return quat.multiply(_Q_Z90, quat.normalize(q))

    fn.__name__ = f"ahrs_{kind}"
    return fn


#: comparison rows: name -> (estimate_fn, modes it supports, is it a slow pure-Python ahrs filter)
COMPARISONS: dict[str, tuple[EstimateFn, tuple[str, ...], bool]] = {
    # our Madgwick as BROAD ran theirs (β = 0.12, no warm-up): the row to hold against the published table
    "madgwick_broad": (project_method("madgwick", beta_rad_s=0.12, warmup_s=0.0, acc_lowpass_s=0.0), MODES, False),
    "vqf_offline": (_vqf(True), MODES, False),
    "vqf_online": (_vqf(False), MODES, False),
    "ahrs_madgwick": (_ahrs("madgwick"), MODES, True),  # β = 0.12 rad/s as BROAD's run (same units as ahrs' gain)
    "ahrs_fkf": (_ahrs("fkf"), ("9d",), True),  # FKF needs a magnetometer
    "ahrs_aqua": (_ahrs("aqua"), MODES, True),
}
