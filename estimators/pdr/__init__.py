"""Foot-mounted pedestrian dead reckoning (seed 001): strapdown INS + error-state EKF + zero-velocity updates.

Modules: :mod:`.mechanisation` (eqs. 3.19–3.29), :mod:`.detectors` (3.2–3.4, 4.1–4.2), :mod:`.ekf`
(3.28–3.44), :mod:`.metrics` (4.3–4.5, strides), :mod:`.pipeline` (methods of Table 3 and ChakaMo's
default).  ``reconstruct(t_s, acc, gyr, method=..., detector=...)`` is the entry point.
"""

from estimators.pdr.pipeline import DEFAULT_DETECTOR, DEFAULT_METHOD, DETECTORS, METHODS, PdrResult, reconstruct

__all__ = ["DEFAULT_DETECTOR", "DEFAULT_METHOD", "DETECTORS", "METHODS", "PdrResult", "reconstruct"]
