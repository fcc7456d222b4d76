"""SMe and SMeA (seed 000 §2.3–2.4) on a simulated thigh + shank exoskeleton walk at 50 Hz."""

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.markov.sme import SpatialParams, sme
from estimators.markov.smea import smea, smea_state
from estimators.simulation.exoskeleton import gait_chain, sagittal_mount, simulate_chain

FS = 50.0


@pytest.fixture(scope="module")
def walk():
    ch = gait_chain(30.0, n_segments=2, seed=1, cadence_hz=0.5)
    g = simulate_chain(ch, FS, seed=1, misalign_rad=np.radians(5.0))
    sl = slice(25, None)
    t = g[0].t_true_s[sl]
    truth = np.column_stack([np.interp(t, ch.t_s, ch.extra["absolute_sagittal_rad"][:, i]) for i in range(2)])
    knee = ch.joint_at(t)[:, 0]
    gyr = [x.gyr[sl] for x in g]
    acc = [x.acc[sl] for x in g]
    gup = [quat.rotate(quat.conjugate(sagittal_mount()), np.array([0.0, 9.81, 0.0]))] * 2
    th0 = np.array([truth[0, 0], 0, 0, truth[0, 1], 0, 0])
    enc = knee + np.random.default_rng(0).normal(0.0, np.radians(0.2), len(t))
    return gyr, acc, gup, th0, enc, truth, knee


def _rmse_deg(a, b):
    return np.degrees(np.sqrt(np.mean((a - b) ** 2, axis=0)))


def test_sme_kernel_equals_reference(walk):
    gyr, acc, gup, th0, enc, truth, knee = walk
    gyr, acc, enc = [v[:250] for v in gyr], [v[:250] for v in acc], enc[:250, None]
    a = sme(gyr, acc, enc, fs_hz=FS, gravity_ref=gup, theta0_rad=th0)
    b = sme(gyr, acc, enc, fs_hz=FS, gravity_ref=gup, theta0_rad=th0, reference=True)
    assert a.acc_used.any()
    assert np.max(np.abs(a.theta_rad - b.theta_rad)) < 1e-9


def test_smea_kernel_equals_reference_and_state_rule(walk):
    gyr, acc, gup, th0, enc, truth, knee = walk
    gyr, acc = [v[:250] for v in gyr], [v[:250] for v in acc]
    a = smea(gyr, acc, fs_hz=FS, gravity_ref=gup, theta0_rad=th0, joint_rad=knee[:250])
    b = smea(gyr, acc, fs_hz=FS, gravity_ref=gup, theta0_rad=th0, joint_rad=knee[:250], reference=True)
    assert np.max(np.abs(a.theta_rad - b.theta_rad)) < 1e-9
    xi, rel = smea_state(np.array([[9.81, 9.81], [9.81, 12.0], [15.0, 9.9], [15.0, 14.0]]), 9.81, 0.5)
    assert xi.tolist() == [2, 0, 1, 1]
    assert rel.tolist() == [[True, True], [True, False], [False, True], [False, False]]


def test_sme_and_smea_track_the_sagittal_angles(walk):
    gyr, acc, gup, th0, enc, truth, knee = walk
    a = sme(gyr, acc, enc[:, None], fs_hz=FS, gravity_ref=gup, theta0_rad=th0)
    b = smea(gyr, acc, fs_hz=FS, gravity_ref=gup, theta0_rad=th0)
    k = slice(60, None)                                  # after the filters settle (seed: ~1.2 s)
    assert np.all(_rmse_deg(a.theta_rad[k, :, 0], truth[k]) < 3.0)
    assert np.all(_rmse_deg(b.theta_rad[k, :, 0], truth[k]) < 3.0)
    assert _rmse_deg(b.joint_rad[k, 0], knee[k]) < 3.0   # self-aligned knee angle, no encoder
    assert _rmse_deg(a.joint_rad[k, 0], knee[k]) < 1.0   # the encoder ties SMe's knee angle
    p = b.state.p
    assert np.allclose(p, p.T, atol=1e-12 * np.abs(p).max()) and np.linalg.eigvalsh(p).min() > 0
    assert set(np.unique(b.markov_state)) <= {0, 1, 2}


@pytest.mark.parametrize("kw,match", [({"zeta_g": -0.1}, "zeta_g"), ({"joint_axis": 3}, "joint_axis"),
                                      ({"r_acc_rad2": (0.0,)}, "r_acc_rad2"), ({"r_joint_deg2": 0.0}, "r_joint_deg2")])
def test_parameter_validation(kw, match):
    with pytest.raises(ValueError, match=match):
        SpatialParams(**kw)


def test_input_validation():
    z = np.zeros((20, 3))
    with pytest.raises(ValueError, match="segment 1"):
        sme([z, np.zeros((19, 3))], [z, z], None, fs_hz=FS)
    with pytest.raises(ValueError, match="two segments"):
        smea([z, z, z], [z, z, z], fs_hz=FS)
