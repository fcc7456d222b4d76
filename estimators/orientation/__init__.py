"""Orientation estimation: ``estimate(acc, gyr, mag=None, *, fs_hz, method=...) -> q_earth_sensor``.

The methods (``METHODS``) share the contract of :mod:`estimators.orientation.base`:

* ``chakamo`` (default) — ChakaMo's own filter: strapdown in a quasi-inertial frame, gyroscope bias
  estimation, magnetic-disturbance rejection and an offline forward-backward smoother; on the BROAD
  benchmark it is more accurate than the published VQF (see README, ``python -m benchmarks.broad``);
* ``guo`` — Guo, Wu, Wang, Qian (2017), fast Kalman filter (the source thesis' choice);
* ``madgwick`` — Madgwick (2011) gradient descent with magnetic distortion compensation;
* ``valenti_cf`` — Valenti, Dryanovski, Xiao (2015), complementary filter with delta quaternions;
* ``valenti_kf`` — Valenti et al. (2016), linear Kalman filter with the algebraic quaternion algorithm.

Classes are imported when first asked for, so importing this package stays cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

from numpy.typing import ArrayLike, NDArray
import numpy as np

from estimators.orientation.base import OrientationMethod, params_from_kwargs

_REGISTRY: dict[str, str] = {
    "guo": "estimators.orientation.guo:Guo",
    "madgwick": "estimators.orientation.madgwick:Madgwick",
    "valenti_cf": "estimators.orientation.valenti_cf:ValentiCF",
    "valenti_kf": "estimators.orientation.valenti_kf:ValentiKF",
    "chakamo": "estimators.orientation.chakamo:Chakamo",
}

METHODS: tuple[str, ...] = tuple(_REGISTRY)
DEFAULT_METHOD = "chakamo"


def get_method(name: str) -> type[OrientationMethod]:
    """The class of a method by name; ``ValueError`` lists the valid names."""
    try:
        module_name, class_name = _REGISTRY[name].split(":")
    except KeyError:
        raise ValueError(f"unknown orientation method {name!r}; choose one of {', '.join(METHODS)}") from None
    return getattr(importlib.import_module(module_name), class_name)


def make(name: str = DEFAULT_METHOD, **params: Any) -> OrientationMethod:
    """A configured method: ``make("madgwick", beta_rad_s=0.05)``."""
    cls = get_method(name)
    return cls(params_from_kwargs(cls.params_type, params))


def estimate(
    acc: ArrayLike,
    gyr: ArrayLike,
    mag: ArrayLike | None = None,
    *,
    fs_hz: float,
    method: str = DEFAULT_METHOD,
    **params: Any,
) -> NDArray[np.float64]:
    """``q_earth_sensor`` ``(N, 4)`` for each sample (``../shared/DESIGN.md`` §4).

    ``mag=None`` runs the 6D variant; ``params`` are the method's parameter names (its ``params_type``).
    """
    return make(method, **params).estimate(acc, gyr, mag, fs_hz=fs_hz).orientation_


__all__ = ["DEFAULT_METHOD", "METHODS", "OrientationMethod", "estimate", "get_method", "make"]
