"""Scalar quaternion arithmetic for the compiled (numba) orientation kernels, defined once.

Quaternions are ``(w, x, y, z)`` passed as four floats (no arrays: the kernels keep their state in
scalars and numba inlines these small functions), with the conventions of :mod:`estimators.quaternion`:
Hamilton product, ``rotate(q, v) = q ⊗ (0, v) ⊗ q*``.  :func:`qrot` uses the same cross-product form
as :func:`estimators.quaternion.rotate`, so a kernel and its numpy reference round alike.
"""

from __future__ import annotations

from numba import njit

__all__ = ["qmat", "qmul", "qrot"]


@njit(cache=True)
def qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product ``a ⊗ b`` as four floats."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True)
def qrot(w, x, y, z, vx, vy, vz):
    """``v`` rotated by the unit quaternion ``q``: :math:`v + 2w(u×v) + 2u×(u×v)`, ``u = (x, y, z)``."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


@njit(cache=True)
def qmat(w, x, y, z):
    """Rotation matrix of a unit quaternion, row-major 9-tuple (``R v == qrot(q, v)``)."""
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))
