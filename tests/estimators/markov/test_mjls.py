"""MJLS Markovian KF (seed 002): Markov state rule, kernel == reference, invariants, simulated gait."""

import numpy as np
import pytest

from estimators import quaternion as quat
from estimators.markov import accelerometer_angles, fkc, FkcParams, run_filter_reference, initial_state
from estimators.markov import mjls
from estimators.simulation.exoskeleton import gait_chain, sagittal_mount, simulate_chain

FS = 100.0


def test_markov_state_reproduces_seed_example():
    """Seed 002 §3: the worked example of eqs. 28–30 with ζ = 0.2 (rows B, T, S, F)."""
    b = [0.8, 0.9, 0.6, 0.5, 0.4, 0.1, 0.2, 0.4, 0.3, 0.1]
    t = [0.7, 0.7, 0.4, 0.2, 0.6, 0.2, 0.2, 0.3, 0.6, 0.2]
    f = [0.3, 0.4, 0.3, 0.3, 0.3, 0.4, 0.3, 0.4, 0.9, 0.8]
    s = [0.1, 0.2, 0.7, 0.6, 0.5, 0.5, 0.1, 0.5, 0.1, 0.7]
    norms = 9.81 + np.column_stack([b, t, s, f])
    state, rho, ok = mjls.markov_state(norms, 9.81, 0.2 + 1e-9)
    assert np.allclose(rho, [0.1, 0.2, 0.3, 0.2, 0.3, 0.1, 0.1, 0.3, 0.1, 0.1])
    assert "".join(np.array(mjls.SEGMENTS)[state]) == "SSFTFBSTSB"
    assert list(np.flatnonzero(ok) + 1) == [1, 2, 4, 6, 7, 9, 10]


@pytest.fixture(scope="module")
def gait():
    ch = gait_chain(20.0, n_segments=4, seed=3)
    g = simulate_chain(ch, FS, seed=3)
    t = g[0].t_true_s
    truth = np.column_stack([np.interp(t, ch.t_s, ch.extra["absolute_sagittal_rad"][:, i]) for i in range(4)])
    gref = quat.rotate(quat.conjugate(sagittal_mount()), np.array([0.0, 9.81, 0.0]))
    w = np.column_stack([x.gyr[:, 0] for x in g])
    za = np.column_stack([accelerometer_angles(x.acc, gref)[0][:, 0] for x in g])
    an = np.column_stack([np.linalg.norm(x.acc, axis=1) for x in g])
    enc = ch.joint_at(t)
    enc[1::2] = np.nan                               # 50 Hz encoders on the 100 Hz grid
    sl = slice(50, None)                             # skip the simulator's start-up samples
    return w[sl], za[sl], an[sl], enc[sl], truth[sl]


def test_kernel_equals_reference(gait):
    w, za, an, enc, truth = (v[:300] for v in gait)
    p = mjls.MjlsParams(zeta_g=0.05)
    a = mjls.mkf(w, za, an, enc, fs_hz=FS, params=p, theta0_rad=truth[0])
    b = mjls.mkf(w, za, an, enc, fs_hz=FS, params=p, theta0_rad=truth[0], reference=True)
    assert a.corrected.any() and not a.corrected.all()
    assert np.max(np.abs(a.theta_rad - b.theta_rad)) < 1e-9
    assert np.max(np.abs(a.state.p - b.state.p)) < 1e-9


def test_covariance_stays_symmetric_positive_definite(gait):
    w, za, an, enc, truth = gait
    r = mjls.mkf(w, za, an, enc, fs_hz=FS, theta0_rad=truth[0])
    p = r.state.p
    assert np.allclose(p, p.T, atol=1e-12 * np.abs(p).max())
    assert np.linalg.eigvalsh(p).min() > 0


def test_zeta_infinite_fixed_state_equals_time_invariant_kf(gait):
    w, za, an, enc, truth = (v[:200] for v in gait)
    p = mjls.MjlsParams(zeta_g=np.inf, encoder_rows="always")
    r = mjls.mkf(w, za, an, enc, fs_hz=FS, params=p, theta0_rad=truth[0], fixed_state=2)
    use = np.zeros(w.shape, bool)
    use[:, 2] = True
    d2 = (np.pi / 180) ** 2
    th, _, _ = run_filter_reference(
        w, za, np.array(p.r_acc_deg2) * d2, use, np.nan_to_num(enc), [[0, 1], [1, 2], [2, 3]], 0.5 * d2,
        np.isfinite(enc), dt_s=1 / FS, tau_s=np.array(p.tau_gyro_s), q_angle_rad2_s=np.array(p.q_angle_deg2_s) * d2,
        q_bias_rad2_s3=np.array(p.q_bias_deg2_s3) * d2, state=initial_state(truth[0], d2, d2))
    assert np.max(np.abs(r.theta_rad - th)) < 1e-9


def test_one_segment_mkf_equals_fkc(gait):
    w, za, an, enc, truth = (v[:300, :1] for v in gait)
    p = mjls.MjlsParams(q_angle_deg2_s=(0.01,), q_bias_deg2_s3=(0.001,), r_acc_deg2=(20.0,), tau_gyro_s=(500.0,),
                        zeta_g=np.inf)
    r = mjls.mkf(w, za, an, None, fs_hz=FS, params=p, theta0_rad=truth[0])
    d2 = (np.pi / 180) ** 2
    f = fkc(w[:, 0], za[:, 0], fs_hz=FS, theta0_rad=truth[0, 0],
            params=FkcParams(0.01 * d2, 0.001 * d2, 500.0, 20.0 * d2, d2, d2))
    assert np.max(np.abs(r.theta_rad[:, 0] - f.theta_rad)) < 1e-12


def test_markov_filter_beats_standard_kf_on_simulated_gait(gait):
    w, za, an, enc, truth = gait
    m = mjls.mkf(w, za, an, enc, fs_hz=FS, theta0_rad=truth[0])
    k = mjls.standard_kf(w, za, an, fs_hz=FS, theta0_rad=truth[0])
    err_m = np.mean(np.abs(m.theta_rad - truth))
    err_k = np.mean(np.abs(k.theta_rad - truth))
    assert err_m < err_k
    # the encoders tie the segments: the MKF's relative angles follow the encoders closely
    assert np.degrees(np.sqrt(np.mean((m.joint_rad[:, 1] - (truth[:, 1] - truth[:, 2])) ** 2))) < 2.0


@pytest.mark.parametrize("kw,match", [({"zeta_g": -1.0}, "zeta_g"), ({"r_acc_deg2": (1.0, 2.0)}, "r_acc_deg2"),
                                      ({"tau_gyro_s": (1.0, 0.0, 1.0, 1.0)}, "tau_gyro_s"),
                                      ({"encoder_rows": "never"}, "encoder_rows")])
def test_parameter_validation(kw, match):
    with pytest.raises(ValueError, match=match):
        mjls.MjlsParams(**kw)


def test_shape_errors():
    with pytest.raises(ValueError, match="omega_rad_s"):
        mjls.mkf(np.zeros((10, 3)), np.zeros((10, 3)), np.zeros((10, 3)), None, fs_hz=FS)
    with pytest.raises(ValueError, match="encoder_rad"):
        mjls.mkf(np.zeros((10, 4)), np.zeros((10, 4)), np.zeros((10, 4)), np.zeros((10, 2)), fs_hz=FS)


def test_collaborative_kf_couples_segments_through_the_encoders(gait):
    w, za, an, enc, truth = gait
    p = mjls.MjlsParams(zeta_g=0.05)
    c = mjls.collaborative_kf(w, za, an, enc, fs_hz=FS, params=p, theta0_rad=truth[0])
    c_ref = mjls.collaborative_kf(w[:200], za[:200], an[:200], enc[:200], fs_hz=FS, params=p, theta0_rad=truth[0],
                                  reference=True, keep_gains=True)
    assert np.max(np.abs(c.theta_rad[:200] - c_ref.theta_rad)) < 1e-9
    # local filter: K is block-diagonal (A.1.1); global: an accelerometer row also corrects other segments
    kg, labels = next(g for g in c_ref.gains if g is not None and any(lab[0] == "rel" for lab in g[1]))
    col = labels.index(next(lab for lab in labels if lab[0] == "abs"))
    seg = labels[col][1]
    others = [2 * i for i in range(4) if i != seg]
    assert np.abs(kg[others, col]).max() > 1e-3
    # the relative angles follow the encoders (absolute accuracy is not better than the local KF here:
    # using every "reliable" accelerometer lets the poor shank/foot angles pull the shared offset)
    assert np.degrees(np.sqrt(np.mean((c.joint_rad[:, 1] - (truth[:, 1] - truth[:, 2])) ** 2))) < 2.0


def test_a_missing_sample_never_becomes_the_trusted_segment():
    """A NaN accelerometer norm must not win the argmin (SMe and SMeA once lost the guard markov_state has)."""
    from estimators.markov.smea import smea_state

    norms = np.array([[np.nan, 9.81, 12.0], [9.5, np.nan, 9.81]])
    state, _, ok = mjls.markov_state(norms, 9.81, 0.5)
    assert state.tolist() == [1, 2] and ok.all()
    xi, reliable = smea_state(np.array([[np.nan, 9.81], [9.81, 9.81]]), 9.81, 0.5)
    assert xi.tolist() == [1, 2] and not reliable[0, 0]
