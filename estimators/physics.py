"""Physical constants shared by the estimators, the simulator and ingestion (one definition each).

``GRAVITY_M_S2`` (9.81) is the local gravity magnitude the filters expect at rest (rest tests, the
accelerometer's reference, strapdown gravity removal) and the simulator generates; the pipelines that can
measure it (PDR alignment, posture windows) measure it instead.  ``STANDARD_GRAVITY_M_S2`` (9.80665, exact by
definition) converts a reading in the unit g to m/s².
"""

GRAVITY_M_S2 = 9.81
STANDARD_GRAVITY_M_S2 = 9.80665

__all__ = ["GRAVITY_M_S2", "STANDARD_GRAVITY_M_S2"]
