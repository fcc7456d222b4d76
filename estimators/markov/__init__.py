r"""Markovian-jump and complementary Kalman filters for multi-segment limbs (seeds 000 and 002).

* :mod:`.core` — the switched error-state complementary Kalman filter (numba kernel + numpy reference)
  that all filters below share;
* :mod:`.fkc` — single-axis complementary Kalman filter (FKC, seed 000 §2.1.4);
* :mod:`.mjls` — planar Markov jump linear system filter (MKF) of Nogueira et al. 2014 (seed 002), the
  standard per-segment KF and the collaborative KF (seed 000 Appendix A);
* :mod:`.sme` — spatial Markovian system SMe (seed 000 §2.3, §2.4.1);
* :mod:`.smea` — SMeA: SMe with the nominal Markov state TS and the self-aligned joint angle (§2.4.3).

Self-aligned joint axes and positions (Seel et al. 2014) are in :mod:`estimators.joint_axis`.
"""

from estimators.markov.core import FilterState, initial_state, run_filter, run_filter_reference
from estimators.markov.fkc import FkcParams, FkcResult, accelerometer_angles, fkc
from estimators.markov.mjls import MjlsParams, MjlsResult, collaborative_kf, markov_state, mkf, standard_kf
from estimators.markov.sme import SpatialParams, SpatialResult, sme
from estimators.markov.smea import self_aligned_joint_angle, smea, smea_state

__all__ = ["FilterState", "initial_state", "run_filter", "run_filter_reference", "FkcParams", "FkcResult",
           "accelerometer_angles", "fkc", "MjlsParams", "MjlsResult", "collaborative_kf", "markov_state", "mkf",
           "standard_kf", "SpatialParams", "SpatialResult", "sme", "self_aligned_joint_angle", "smea", "smea_state"]
