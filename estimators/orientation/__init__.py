"""Orientation estimation: ``estimate(acc, gyr, mag=None, *, fs_hz, method=...) -> q_earth_sensor``.

The methods (``METHODS``, described for option lists by ``METHOD_INFO``) share the contract of
:mod:`estimators.orientation.base`:

* ``chakamo`` (default) — ChakaMo's own filter: strapdown in a quasi-inertial frame, gyroscope bias
  estimation, magnetic-disturbance rejection and an offline forward-backward smoother;
* ``guo`` — Guo, Wu, Wang, Qian (2017), fast Kalman filter (the source thesis' choice);
* ``madgwick`` — Madgwick (2011) gradient descent with magnetic distortion compensation;
* ``valenti_cf`` — Valenti, Dryanovski, Xiao (2015), complementary filter with delta quaternions;
* ``valenti_kf`` — Valenti et al. (2016), linear Kalman filter with the algebraic quaternion algorithm.

Importing this package is light: it imports neither numpy nor numba (the app builds its option lists
from ``METHODS`` / ``METHOD_INFO`` at start-up).  The classes, and with them numpy and the compiled
kernels, are imported when first asked for (``get_method``, ``make``, ``estimate``, or the attribute
``OrientationMethod``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # for type checkers only: at run time these come from numpy on first use
    from numpy.typing import ArrayLike, NDArray
    import numpy as np

    from estimators.orientation.base import OrientationMethod


@dataclass(frozen=True)
class MethodInfo:
    """What an option list shows for one method.

    name: the ``method=`` value.   label: a short human name.   reference: the paper it implements.
    has_6d: it runs without a magnetometer (``mag=None``).   has_9d: it uses a magnetometer.
    """

    name: str
    label: str
    reference: str
    has_6d: bool = True
    has_9d: bool = True


#: every method, in the order option lists show them (the default first)
METHOD_INFO: tuple[MethodInfo, ...] = (
    MethodInfo("chakamo", "ChakaMo (default)",
               "ChakaMo's own filter after Laidig & Seel (2023), VQF, Information Fusion 91:187-204"),
    MethodInfo("guo", "Guo fast Kalman filter",
               "Guo, Wu, Wang, Qian (2017), Novel MARG-sensor orientation estimation algorithm using fast "
               "Kalman filter, Journal of Sensors 2017:8542153"),
    MethodInfo("madgwick", "Madgwick gradient descent",
               "Madgwick, Harrison, Vaidyanathan (2011), Estimation of IMU and MARG orientation using a "
               "gradient descent algorithm, IEEE ICORR"),
    MethodInfo("valenti_cf", "Valenti complementary filter",
               "Valenti, Dryanovski, Xiao (2015), Keeping a good attitude: a quaternion-based orientation "
               "filter for IMUs and MARGs, Sensors 15(8):19302-19330"),
    MethodInfo("valenti_kf", "Valenti Kalman filter (AQUA)",
               "Valenti, Dryanovski, Xiao (2016), A linear Kalman filter for MARG orientation estimation "
               "using the algebraic quaternion algorithm, IEEE Trans. Instrum. Meas. 65(2):467-481"),
)

_REGISTRY: dict[str, str] = {
    "chakamo": "estimators.orientation.chakamo:Chakamo",
    "guo": "estimators.orientation.guo:Guo",
    "madgwick": "estimators.orientation.madgwick:Madgwick",
    "valenti_cf": "estimators.orientation.valenti_cf:ValentiCF",
    "valenti_kf": "estimators.orientation.valenti_kf:ValentiKF",
}

METHODS: tuple[str, ...] = tuple(info.name for info in METHOD_INFO)
DEFAULT_METHOD = "chakamo"


def method_info(name: str) -> MethodInfo:
    """The :class:`MethodInfo` of a method by name; ``ValueError`` lists the valid names."""
    for info in METHOD_INFO:
        if info.name == name:
            return info
    raise ValueError(f"unknown orientation method {name!r}; choose one of {', '.join(METHODS)}")


def get_method(name: str) -> type[OrientationMethod]:
    """The class of a method by name (imports it); ``ValueError`` lists the valid names."""
    try:
        module_name, class_name = _REGISTRY[name].split(":")
    except KeyError:
        raise ValueError(f"unknown orientation method {name!r}; choose one of {', '.join(METHODS)}") from None
    return getattr(importlib.import_module(module_name), class_name)


def make(name: str = DEFAULT_METHOD, **params: Any) -> OrientationMethod:
    """A configured method: ``make("madgwick", beta_rad_s=0.05)``."""
    from estimators.orientation.base import params_from_kwargs

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


def __getattr__(name: str) -> Any:
    """``OrientationMethod`` on first use (it needs numpy)."""
    if name == "OrientationMethod":
        from estimators.orientation.base import OrientationMethod

        return OrientationMethod
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["DEFAULT_METHOD", "METHODS", "METHOD_INFO", "MethodInfo", "OrientationMethod", "estimate",
           "get_method", "make", "method_info"]
