"""The hinge-chain simulator used by the Markov filters' tests and benchmark."""

import numpy as np

from estimators import quaternion as quat
from estimators.simulation import ImuSpec
from estimators.simulation.exoskeleton import gait_chain, hinge_pair, simulate_chain


def test_gait_chain_angles_match_orientations_and_gyroscopes():
    ch = gait_chain(6.0, n_segments=4, seed=2, wobble_rad=0.0)
    q = np.stack([s.q_earth_body for s in ch.segments], axis=1)          # (n, 4 seg, 4)
    # with no wobble each segment's long axis (y) lies in the sagittal plane (earth y-z) at angle θ from up
    y_axis = quat.rotate(q, np.array([0.0, 1.0, 0.0]))
    theta = np.arctan2(-y_axis[..., 1], y_axis[..., 2])
    assert np.allclose(theta, ch.extra["absolute_sagittal_rad"], atol=1e-9)
    assert np.allclose(ch.joint_rad, theta[:, :-1] - theta[:, 1:], atol=1e-9)
    # hinge: the rate difference about the lateral (sensor x) axis integrates to the joint angle
    g = simulate_chain(ch, 100.0, ImuSpec.perfect(), seed=0)
    rate = g[1].gyr[:, 0] - g[2].gyr[:, 0]
    knee = ch.joint_at(g[1].t_true_s)[:, 1]
    integ = knee[50] + np.cumsum(rate[51:]) / 100.0
    assert np.max(np.abs(integ - knee[51:])) < np.radians(0.5)


def test_still_start_is_upright_and_at_rest():
    ch = gait_chain(4.0, n_segments=2, still_s=1.0)
    k = ch.t_s < 0.9
    assert np.allclose(ch.extra["absolute_sagittal_rad"][k], 0.0)
    assert np.allclose(ch.joint_rad[k], 0.0)


def test_hinge_pair_shares_the_lateral_axis():
    ch = hinge_pair(3.0, seed=0)
    rel = quat.multiply(quat.conjugate(ch.segments[0].q_earth_body), ch.segments[1].q_earth_body)
    assert np.allclose(rel[:, 1:3], 0.0, atol=1e-12)                   # rotation about z only
