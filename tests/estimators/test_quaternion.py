"""Properties of the quaternion algebra, with scipy's Rotation as an independent oracle."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from estimators import quaternion as quat

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
raw_quats = arrays(np.float64, (4,), elements=finite).filter(lambda q: np.linalg.norm(q) > 1e-3)
vectors = arrays(np.float64, (3,), elements=finite)
angles = st.floats(-np.pi, np.pi, allow_nan=False)


def unit(q):
    return quat.normalize(q)


def scipy_rot(q):
    return Rotation.from_quat(np.asarray(q)[..., [1, 2, 3, 0]])


@given(raw_quats, raw_quats, raw_quats)
def test_product_is_associative_and_norm_multiplicative(a, b, c):
    a, b, c = unit(a), unit(b), unit(c)
    left = quat.multiply(quat.multiply(a, b), c)
    right = quat.multiply(a, quat.multiply(b, c))
    np.testing.assert_allclose(left, right, atol=1e-12)
    assert np.linalg.norm(quat.multiply(a, b)) == pytest.approx(1.0, abs=1e-12)


@given(raw_quats)
def test_conjugate_is_inverse(q):
    q = unit(q)
    np.testing.assert_allclose(quat.multiply(q, quat.conjugate(q)), quat.identity(), atol=1e-12)


@given(raw_quats, vectors)
def test_rotate_matches_matrix_and_scipy(q, v):
    q = unit(q)
    expected = scipy_rot(q).apply(v)
    np.testing.assert_allclose(quat.rotate(q, v), expected, atol=1e-9 * (1 + np.abs(v).max()))
    np.testing.assert_allclose(quat.to_matrix(q) @ v, expected, atol=1e-9 * (1 + np.abs(v).max()))


@given(raw_quats, raw_quats, vectors)
def test_composition_convention(q_a_b, q_b_c, v_c):
    """``q_a_c = q_a_b ⊗ q_b_c`` maps c-coordinates to a-coordinates (DESIGN §3)."""
    q_a_b, q_b_c = unit(q_a_b), unit(q_b_c)
    v_a = quat.rotate(q_a_b, quat.rotate(q_b_c, v_c))
    np.testing.assert_allclose(quat.rotate(quat.multiply(q_a_b, q_b_c), v_c), v_a,
                               atol=1e-9 * (1 + np.abs(v_c).max()))


@given(raw_quats)
def test_matrix_round_trip(q):
    q = unit(q)
    back = quat.from_matrix(quat.to_matrix(q))
    assert back[0] >= 0.0
    assert quat.angle_between(back, q) < 1e-7


def test_from_matrix_all_branches():
    """Half turns about each axis exercise every branch of Shepperd's method."""
    for q in ([1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0.0, 0.6, 0.8, 0.0]):
        q = np.asarray(q, dtype=float)
        assert quat.angle_between(quat.from_matrix(quat.to_matrix(q)), q) < 1e-12


@given(arrays(np.float64, (3,), elements=st.floats(-3.1, 3.1)))
def test_exp_log_round_trip(r):
    if np.linalg.norm(r) > np.pi:
        r = r / np.linalg.norm(r) * 3.0
    np.testing.assert_allclose(quat.log(quat.exp(r)), r, atol=1e-9)
    np.testing.assert_allclose(quat.log(quat.exp(r)), scipy_rot(quat.exp(r)).as_rotvec(), atol=1e-9)


def test_exp_log_near_zero():
    r = np.array([1e-10, -2e-10, 3e-10])
    np.testing.assert_allclose(quat.log(quat.exp(r)), r, rtol=1e-6)
    np.testing.assert_allclose(quat.log(quat.identity()), np.zeros(3))


@given(vectors.filter(lambda v: np.linalg.norm(v) > 1e-3), angles)
def test_axis_angle_round_trip(axis, angle):
    q = quat.from_axis_angle(axis, angle)
    ax, ang = quat.to_axis_angle(q)
    assert ang == pytest.approx(abs(angle), abs=1e-9)
    if abs(angle) > 1e-6:
        np.testing.assert_allclose(ax * np.sign(angle), axis / np.linalg.norm(axis), atol=1e-7)


@given(raw_quats, raw_quats, st.floats(0.0, 1.0))
def test_slerp_ends_and_constant_speed(a, b, t):
    a, b = unit(a), unit(b)
    assert quat.angle_between(quat.slerp(a, b, 0.0), a) < 1e-9
    assert quat.angle_between(quat.slerp(a, b, 1.0), b) < 1e-7
    total = quat.angle_between(a, b)
    assert quat.angle_between(a, quat.slerp(a, b, t)) == pytest.approx(t * total, abs=1e-7)


@pytest.mark.parametrize("seq", ["ZYX", "XYZ", "YXZ", "ZXZ", "zyx", "xyz"])
def test_euler_round_trip_and_meaning(seq):
    rng = np.random.default_rng(1)
    q = quat.normalize(rng.normal(size=(200, 4)))
    ang = quat.to_euler(q, seq)
    assert np.all(quat.angle_between(quat.from_euler(ang, seq), q) < 1e-9)
    if seq == "ZYX":  # intrinsic ZYX: R = Rz(a) Ry(b) Rx(c)
        a, b, c = ang[0]
        expected = quat.multiply(quat.multiply(quat.from_axis_angle([0, 0, 1], a), quat.from_axis_angle([0, 1, 0], b)),
                                 quat.from_axis_angle([1, 0, 0], c))
        assert quat.angle_between(expected, q[0]) < 1e-9


def test_thesis_euler_is_zyx_of_conjugate():
    """Seed 004 eq. 4.19 extracts intrinsic ZYX angles of the conjugate quaternion."""
    rng = np.random.default_rng(2)
    q = quat.normalize(rng.normal(size=(100, 4)))
    np.testing.assert_allclose(quat.euler_zyx_thesis(q), quat.to_euler(quat.conjugate(q), "ZYX"), atol=1e-9)


@given(vectors.filter(lambda v: np.linalg.norm(v) > 1e-3), vectors.filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_from_two_vectors(a, b):
    q = quat.from_two_vectors(a, b)
    np.testing.assert_allclose(quat.rotate(q, a / np.linalg.norm(a)), b / np.linalg.norm(b), atol=1e-7)


def test_from_two_vectors_nearly_antiparallel():
    """Found by hypothesis: 1 + a·b cancels near π; the atan2 form keeps full precision."""
    a, b = np.array([1.0, 0.0, 0.0]), np.array([-495.0, 7e-4, 0.0])
    np.testing.assert_allclose(quat.rotate(quat.from_two_vectors(a, b), a), b / np.linalg.norm(b), atol=1e-12)


def test_from_two_vectors_antiparallel():
    q = quat.from_two_vectors([0, 0, 1.0], [0, 0, -2.0])
    np.testing.assert_allclose(quat.rotate(q, [0, 0, 1.0]), [0, 0, -1.0], atol=1e-12)


@settings(max_examples=50)
@given(raw_quats)
def test_angle_between_ignores_sign(q):
    q = unit(q)
    assert quat.angle_between(q, -q) < 1e-7


def test_broadcasting_shapes():
    q = quat.identity(5)
    assert quat.multiply(q, quat.identity()).shape == (5, 4)
    assert quat.rotate(q, np.ones(3)).shape == (5, 3)
    assert quat.to_matrix(q.reshape(5, 1, 4)).shape == (5, 1, 3, 3)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: quat.multiply(np.ones(3), np.ones(4)), "shape"),
        (lambda: quat.normalize(np.zeros(4)), "zero"),
        (lambda: quat.from_axis_angle(np.zeros(3), 1.0), "non-zero"),
        (lambda: quat.to_euler(quat.identity(), "ZZX"), "sequence"),
        (lambda: quat.from_matrix(np.eye(4)), "3, 3"),
    ],
)
def test_bad_input_messages(call, message):
    with pytest.raises(ValueError, match=message):
        call()


@pytest.mark.parametrize("seq", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX", "XYX", "XZX", "YXY", "YZY", "ZXZ", "ZYZ"])
def test_from_euler_closed_form_matches_scipy(seq):
    """The closed form agrees with scipy's Euler convention for all 12 sequences, intrinsic and extrinsic."""
    from scipy.spatial.transform import Rotation

    ang = np.random.default_rng(3).uniform(-3.0, 3.0, size=(50, 3))
    for s in (seq, seq.lower()):
        xyzw = Rotation.from_euler(s, ang).as_quat()
        assert np.all(quat.angle_between(quat.from_euler(ang, s), xyzw[:, [3, 0, 1, 2]]) < 1e-12)
        assert np.all(quat.from_euler(ang, s)[:, 0] >= 0.0)


def test_from_intrinsic_is_continuous_and_any_length():
    """No sign flip: a smooth angle series stays a smooth quaternion series (from_euler would jump at w = 0)."""
    t = np.linspace(0.0, 4.0 * np.pi, 2001)
    q = quat.from_intrinsic(np.column_stack([t, 0.3 * np.sin(t)]), "ZY")
    assert np.max(np.linalg.norm(np.diff(q, axis=0), axis=1)) < 0.01
    np.testing.assert_allclose(q[-1], [1.0, 0.0, 0.0, 0.0], atol=1e-12)  # two full turns: back to +identity
    with pytest.raises(ValueError, match="axes letters"):
        quat.from_intrinsic(np.zeros((3, 2)), "ZQ")
