r"""Vectorised Hamilton quaternion algebra, scalar first ``(w, x, y, z)``.

Conventions (``../shared/DESIGN.md`` §3)
-----------------------------------------
* A quaternion array has shape ``(..., 4)``; every function broadcasts over the leading axes.
* Hamilton product: :math:`i^2 = j^2 = k^2 = ijk = -1`.
* ``q_a_b`` maps coordinates in frame *b* to frame *a*:
  :math:`v_a = q_{ab} \otimes v_b \otimes q_{ab}^*` and :math:`q_{ac} = q_{ab} \otimes q_{bc}`.
  The rotation matrix returned by :func:`to_matrix` satisfies ``R @ v_b == v_a``.
* Rotation vectors (``rotvec``) are axis × angle in radians; :func:`exp` and :func:`log` are the
  maps between rotation vectors and unit quaternions,
  :math:`\exp(\mathbf r) = (\cos\tfrac{|\mathbf r|}{2}, \tfrac{\mathbf r}{|\mathbf r|}\sin\tfrac{|\mathbf r|}{2})`.

Euler angles
------------
:func:`to_euler` / :func:`from_euler` accept any of the 12 sequences.  Upper-case letters are
intrinsic rotations (about the moving axes), lower-case extrinsic, as in ``scipy``:
``from_euler([a, b, c], "ZYX")`` is :math:`R_z(a) R_y(b) R_x(c)`.

:func:`euler_zyx_thesis` reproduces seed 004 eq. 4.19 literally,

.. math::
    \psi = \operatorname{atan2}(2q_1q_2 - 2q_0q_3,\ 2q_0^2 + 2q_1^2 - 1),\quad
    \theta = -\arcsin(2q_1q_3 + 2q_0q_2),\quad
    \phi = \operatorname{atan2}(2q_2q_3 - 2q_0q_1,\ 2q_0^2 + 2q_3^2 - 1),

which, because the thesis' quaternions followed Madgwick's "earth relative to sensor" convention,
equals the intrinsic ZYX angles of the *conjugate* quaternion.  It is kept only so that ChakaMo
can be compared with the thesis' numbers.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "angle_between",
    "as_quaternion",
    "conjugate",
    "exp",
    "from_axis_angle",
    "from_euler",
    "from_intrinsic",
    "from_matrix",
    "from_two_vectors",
    "identity",
    "log",
    "multiply",
    "normalize",
    "positive_scalar",
    "rotate",
    "slerp",
    "to_axis_angle",
    "to_euler",
    "euler_zyx_thesis",
    "to_matrix",
]

_SMALL_ANGLE_RAD = 1e-8


def as_quaternion(q: ArrayLike) -> FloatArray:
    """Return ``q`` as a float64 array of shape ``(..., 4)``; raise ``ValueError`` otherwise."""
    arr = np.asarray(q, dtype=np.float64)
    if arr.ndim == 0 or arr.shape[-1] != 4:
        raise ValueError(f"a quaternion array must have shape (..., 4), got {arr.shape}")
    return arr


def _as_vector(v: ArrayLike) -> FloatArray:
    arr = np.asarray(v, dtype=np.float64)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"a vector array must have shape (..., 3), got {arr.shape}")
    return arr


def identity(n: int | None = None) -> FloatArray:
    """The identity rotation ``(1, 0, 0, 0)``; ``n`` copies stacked as ``(n, 4)`` when given."""
    q = np.array([1.0, 0.0, 0.0, 0.0])
    return q if n is None else np.tile(q, (n, 1))


def multiply(p: ArrayLike, q: ArrayLike) -> FloatArray:
    r"""Hamilton product :math:`p \otimes q` (broadcasting)."""
    p = as_quaternion(p)
    q = as_quaternion(q)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def conjugate(q: ArrayLike) -> FloatArray:
    """Conjugate ``(w, -x, -y, -z)``: the inverse rotation of a unit quaternion."""
    q = as_quaternion(q)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def normalize(q: ArrayLike) -> FloatArray:
    """Scale to unit norm; a zero quaternion raises ``ValueError``."""
    q = as_quaternion(q)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm == 0.0) or not np.all(np.isfinite(norm)):
        raise ValueError("cannot normalise a zero or non-finite quaternion")
    return q / norm


def positive_scalar(q: ArrayLike) -> FloatArray:
    """Choose the sign of each quaternion so that ``w >= 0`` (``q`` and ``-q`` are one rotation)."""
    q = as_quaternion(q)
    return np.where(q[..., :1] < 0.0, -q, q)


def rotate(q: ArrayLike, v: ArrayLike) -> FloatArray:
    r"""Rotate vectors: :math:`q \otimes (0, v) \otimes q^*` for unit ``q`` (broadcasting).

    Evaluated as :math:`v + 2w(u\times v) + 2u\times(u\times v)` with ``u`` the vector part.
    """
    q = as_quaternion(q)
    v = _as_vector(v)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def to_matrix(q: ArrayLike) -> FloatArray:
    """Rotation matrix ``(..., 3, 3)`` of a unit quaternion, so that ``R @ v == rotate(q, v)``."""
    q = as_quaternion(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    rows = [
        [1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
        [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)],
        [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def from_matrix(matrix: ArrayLike) -> FloatArray:
    """Unit quaternion (``w >= 0``) of a rotation matrix ``(..., 3, 3)`` (Shepperd's method).

    The branch on the largest of ``w², x², y², z²`` keeps the division well conditioned.
    """
    m = np.asarray(matrix, dtype=np.float64)
    if m.ndim < 2 or m.shape[-2:] != (3, 3):
        raise ValueError(f"a rotation matrix array must have shape (..., 3, 3), got {m.shape}")
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    candidates = np.stack([trace, m00, m11, m22], axis=-1)
    choice = np.argmax(candidates, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):  # the unchosen branches may divide by ~0
        # w largest
        s = np.sqrt(np.maximum(1.0 + trace, 0.0)) * 2.0
        qw = np.stack([0.25 * s, (m[..., 2, 1] - m[..., 1, 2]) / s, (m[..., 0, 2] - m[..., 2, 0]) / s,
                       (m[..., 1, 0] - m[..., 0, 1]) / s], axis=-1)
        s = np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 0.0)) * 2.0
        qx = np.stack([(m[..., 2, 1] - m[..., 1, 2]) / s, 0.25 * s, (m[..., 0, 1] + m[..., 1, 0]) / s,
                       (m[..., 0, 2] + m[..., 2, 0]) / s], axis=-1)
        s = np.sqrt(np.maximum(1.0 - m00 + m11 - m22, 0.0)) * 2.0
        qy = np.stack([(m[..., 0, 2] - m[..., 2, 0]) / s, (m[..., 0, 1] + m[..., 1, 0]) / s, 0.25 * s,
                       (m[..., 1, 2] + m[..., 2, 1]) / s], axis=-1)
        s = np.sqrt(np.maximum(1.0 - m00 - m11 + m22, 0.0)) * 2.0
        qz = np.stack([(m[..., 1, 0] - m[..., 0, 1]) / s, (m[..., 0, 2] + m[..., 2, 0]) / s,
                       (m[..., 1, 2] + m[..., 2, 1]) / s, 0.25 * s], axis=-1)
    q = np.select([(choice == k)[..., None] for k in range(4)], [qw, qx, qy, qz])
    return positive_scalar(normalize(q))


def from_axis_angle(axis: ArrayLike, angle_rad: ArrayLike) -> FloatArray:
    """Quaternion of a rotation by ``angle_rad`` about ``axis`` (normalised here; must be non-zero)."""
    axis = _as_vector(axis)
    norm = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(norm == 0.0):
        raise ValueError("the rotation axis must be a non-zero vector")
    half = 0.5 * np.asarray(angle_rad, dtype=np.float64)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * axis / norm], axis=-1)


def to_axis_angle(q: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Axis ``(..., 3)`` and angle in ``[0, π]`` rad; the axis is ``(1, 0, 0)`` for the identity."""
    rotvec = log(q)
    angle = np.linalg.norm(rotvec, axis=-1)
    safe = np.where(angle[..., None] > _SMALL_ANGLE_RAD, angle[..., None], 1.0)
    axis = np.where(angle[..., None] > _SMALL_ANGLE_RAD, rotvec / safe, np.array([1.0, 0.0, 0.0]))
    return axis, angle


def exp(rotvec: ArrayLike) -> FloatArray:
    r"""Unit quaternion of a rotation vector ``(..., 3)`` (rad): :math:`(\cos\frac\theta2, \hat r\sin\frac\theta2)`."""
    r = _as_vector(rotvec)
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(θ/2)/θ with its Taylor series near zero: 1/2 − θ²/48
    small = angle < 1e-4
    safe = np.where(small, 1.0, angle)
    k = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / safe)
    return np.concatenate([np.cos(half), k * r], axis=-1)


def log(q: ArrayLike) -> FloatArray:
    """Rotation vector ``(..., 3)`` (rad, angle in ``[0, π]``) of a unit quaternion."""
    q = positive_scalar(as_quaternion(q))
    w = q[..., :1]
    u = q[..., 1:]
    s = np.linalg.norm(u, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-12
    k = np.where(small, 2.0 / np.where(w == 0.0, 1.0, w), angle / np.where(small, 1.0, s))
    return k * u


def angle_between(q1: ArrayLike, q2: ArrayLike) -> FloatArray:
    r"""Smallest rotation angle (rad, in ``[0, π]``) from ``q1`` to ``q2``: :math:`|\log(q_1^* \otimes q_2)|`."""
    d = multiply(conjugate(q1), q2)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))


def slerp(q0: ArrayLike, q1: ArrayLike, t: ArrayLike) -> FloatArray:
    r"""Spherical linear interpolation along the shorter arc, :math:`q_0 \otimes \exp(t \log(q_0^* q_1))`.

    ``t`` broadcasts against the leading axes (``t = 0`` gives ``q0``, ``t = 1`` gives ``±q1``).
    """
    q0 = as_quaternion(q0)
    delta = log(multiply(conjugate(q0), q1))
    t = np.asarray(t, dtype=np.float64)[..., None]
    return multiply(q0, exp(t * delta))


def from_two_vectors(a: ArrayLike, b: ArrayLike) -> FloatArray:
    r"""Shortest-arc rotation ``q`` with ``rotate(q, â) == b̂`` (antiparallel: a half turn about a perpendicular).

    The angle is :math:`\operatorname{atan2}(|a \times b|, a \cdot b)` and the axis :math:`a \times b`, both
    accurate near 0 and π, where the textbook :math:`(1 + a\cdot b, a \times b)` loses its digits.
    """
    a = _as_vector(a)
    b = _as_vector(b)
    na = np.linalg.norm(a, axis=-1, keepdims=True)
    nb = np.linalg.norm(b, axis=-1, keepdims=True)
    if np.any(na == 0.0) or np.any(nb == 0.0):
        raise ValueError("cannot rotate a zero vector")
    a = a / na
    b = b / nb
    cross = np.cross(a, b)
    sin = np.linalg.norm(cross, axis=-1, keepdims=True)
    angle = np.arctan2(sin, np.sum(a * b, axis=-1, keepdims=True))
    # exactly (anti)parallel: any axis perpendicular to a (irrelevant when the angle is 0)
    helper = np.where(np.abs(a[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    perp = np.cross(a, helper)
    perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
    axis = np.where(sin > 0.0, cross / np.where(sin > 0.0, sin, 1.0), perp)
    return np.concatenate([np.cos(0.5 * angle), np.sin(0.5 * angle) * axis], axis=-1)


def _check_sequence(seq: str) -> str:
    if len(seq) != 3 or not (set(seq) <= set("XYZ") or set(seq) <= set("xyz")) or seq[0] == seq[1] or seq[1] == seq[2]:
        raise ValueError(
            f"Euler sequence {seq!r} is not valid: use three axes from 'XYZ' (intrinsic) or 'xyz' (extrinsic) "
            "with no axis repeated back to back, e.g. 'ZYX'"
        )
    return seq


_GIMBAL_LOCK_RAD = 1e-7


def to_euler(q: ArrayLike, seq: str = "ZYX") -> FloatArray:
    r"""Euler angles ``(..., 3)`` in rad, first rotation first (see module docstring for the convention).

    Direct method of Bernardes & Viollet (PLoS ONE 17(11), 2022), valid for all 12 sequences.  Written for an
    extrinsic sequence of axes :math:`(i, j, k)` (an intrinsic ``"ABC"`` is the extrinsic ``"cba"`` with the
    angles reversed).  For a proper sequence (:math:`i = k`) *k* is replaced by the third axis; with
    :math:`\epsilon = (i-j)(j-k)(k-i)/2` the sign of the permutation :math:`(i, j, k)`,

    .. math::
        (a, b, c, d) = egin{cases} (q_w,\ q_i,\ q_j,\ \epsilon q_k) & 	ext{proper} \
                       (q_w - q_j,\ q_i + \epsilon q_k,\ q_j + q_w,\ \epsilon q_k - q_i) & 	ext{Tait–Bryan}
                       \end{cases}

    (the Tait–Bryan case rotates the quaternion by 90° about *j* so that it becomes a proper one).  Then
    :math:`	heta_2 = 2\,\mathrm{atan2}(\sqrt{c^2+d^2}, \sqrt{a^2+b^2})` (minus :math:`\pi/2` for Tait–Bryan),
    and with :math:`	heta_\pm = \mathrm{atan2}(b, a) \pm \mathrm{atan2}(d, c)` the outer angles are
    :math:`	heta_1 = 	heta_-`, :math:`	heta_3 = 	heta_+` (times :math:`\epsilon` for Tait–Bryan).

    In gimbal lock (:math:`	heta_2` within 1e-7 rad of 0 or π before the shift) only the sum or the difference
    of the outer angles is defined: the first angle of ``seq`` takes it all and the third is 0, as
    ``scipy.spatial.transform.Rotation.as_euler`` does (the numbers are scipy's to ~1e-15, without its import).
    Angles are wrapped to :math:`[-\pi, \pi)`.
    """
    q = as_quaternion(q)
    seq = _check_sequence(seq)
    extrinsic = seq.islower()
    i, j, k = ("xyz".index(c) for c in (seq if extrinsic else seq.lower()[::-1]))
    proper = i == k
    if proper:
        k = 3 - i - j
    eps = (i - j) * (j - k) * (k - i) // 2
    w, qi, qj, qk = q[..., 0], q[..., 1 + i], q[..., 1 + j], eps * q[..., 1 + k]
    if proper:
        a, b, c, d = w, qi, qj, qk
    else:
        a, b, c, d = w - qj, qi + qk, qj + w, qk - qi
    middle = 2.0 * np.arctan2(np.hypot(c, d), np.hypot(a, b))
    half_sum, half_diff = np.arctan2(b, a), np.arctan2(d, c)
    outer_sign = 1 if proper else eps
    at_zero = np.abs(middle) <= _GIMBAL_LOCK_RAD
    at_pi = np.abs(middle - np.pi) <= _GIMBAL_LOCK_RAD
    if extrinsic:  # axes in time order i, j, k
        first, third = half_sum - half_diff, outer_sign * (half_sum + half_diff)
        locked = np.where(at_zero, 2.0 * half_sum, -2.0 * half_diff)
    else:  # the intrinsic sequence's first axis is the extrinsic k
        first, third = outer_sign * (half_sum + half_diff), half_sum - half_diff
        locked = outer_sign * np.where(at_zero, 2.0 * half_sum, 2.0 * half_diff)
    lock = at_zero | at_pi
    first = np.where(lock, locked, first)
    third = np.where(lock, 0.0, third)
    if not proper:
        middle = middle - 0.5 * np.pi
    angles = np.stack([first, middle, third], axis=-1)
    return (angles + np.pi) % (2.0 * np.pi) - np.pi


def from_intrinsic(angles_rad: ArrayLike, axes: str) -> FloatArray:
    r"""Product of turns about the moving axes, ``(..., 4)``: ``"ZXY"`` gives :math:`R_z(a)\,R_x(b)\,R_y(c)`.

    ``angles_rad`` has shape ``(..., len(axes))``, any number of axes from ``"XYZ"``.  The closed form
    (one product of axis quaternions, no sign flip) keeps a time series of angles a continuous series of
    quaternions, which the simulator differentiates; :func:`from_euler` adds ``w >= 0``.
    """
    a = np.asarray(angles_rad, dtype=np.float64)
    if not axes or not set(axes) <= set("XYZ") or a.ndim == 0 or a.shape[-1] != len(axes):
        raise ValueError(f"angles_rad must have shape (..., {len(axes)}) and axes letters from 'XYZ', "
                         f"got {a.shape}, {axes!r}")
    q = None
    for i, ax in enumerate(axes):
        qi = np.zeros(a.shape[:-1] + (4,))
        qi[..., 0] = np.cos(0.5 * a[..., i])
        qi[..., 1 + "XYZ".index(ax)] = np.sin(0.5 * a[..., i])
        q = qi if q is None else multiply(q, qi)
    return q


def from_euler(angles_rad: ArrayLike, seq: str = "ZYX") -> FloatArray:
    """Unit quaternion(s) ``(..., 4)`` from Euler angles ``(..., 3)`` in rad (``w >= 0``).

    Extrinsic ``"abc"`` is intrinsic ``"CBA"`` with the angles reversed (:func:`from_intrinsic`).
    """
    a = _as_vector(angles_rad)
    seq = _check_sequence(seq)
    q = from_intrinsic(a, seq) if seq.isupper() else from_intrinsic(a[..., ::-1], seq[::-1].upper())
    return positive_scalar(q)


def euler_zyx_thesis(q: ArrayLike) -> FloatArray:
    """Seed 004 eq. 4.19 literally: ``(ψ, θ, φ)`` in rad as the source thesis extracted them."""
    q = as_quaternion(q)
    q0, q1, q2, q3 = np.moveaxis(q, -1, 0)
    psi = np.arctan2(2 * q1 * q2 - 2 * q0 * q3, 2 * q0**2 + 2 * q1**2 - 1)
    theta = -np.arcsin(np.clip(2 * q1 * q3 + 2 * q0 * q2, -1.0, 1.0))
    phi = np.arctan2(2 * q2 * q3 - 2 * q0 * q1, 2 * q0**2 + 2 * q3**2 - 1)
    return np.stack([psi, theta, phi], axis=-1)
