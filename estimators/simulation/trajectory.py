r"""Rigid-body trajectories: dense samples, spline derivatives, truth at arbitrary times.

A :class:`Trajectory` holds a body's orientation ``q_earth_body`` and position ``pos_m`` (ENU, m)
sampled densely (1 kHz by default) from a smooth definition.  Everything the IMU model needs is
derived from two cubic splines through those samples:

* position :math:`\mathbf p(t)`: a ``CubicSpline`` per axis gives velocity :math:`\dot{\mathbf p}`
  and the kinematic acceleration :math:`\ddot{\mathbf p}` (earth frame);
* orientation: a ``CubicSpline`` through the four quaternion components (signs made continuous
  first), :math:`\tilde q(t)`, is normalised for the truth, :math:`q = \tilde q/|\tilde q|`, and
  differentiated for the body angular velocity

  .. math:: \boldsymbol\omega_{body} = 2\,\operatorname{vec}(q^* \otimes \dot q)
            = \frac{2\,\operatorname{vec}(\tilde q^* \otimes \dot{\tilde q})}{|\tilde q|^2},

  (the second form holds because :math:`\operatorname{vec}(\tilde q^*\tilde q) = 0`).

Truth (``q``) and rate (``ω``) come from the *same* spline, so integrating the simulated
gyroscope reproduces the simulated truth to the integrator's own accuracy.  With data sampled at
1 kHz from a C²-smooth motion the spline's error against the underlying definition is of order
:math:`h^3` for rates (below 1e-7 rad/s for motions of a few hundred deg/s).

Smooth building blocks used by the built-in motions live here too: :func:`min_jerk`
(:math:`10\tau^3 - 15\tau^4 + 6\tau^5`, zero velocity and acceleration at both ends) and
:func:`bump` (:math:`64\tau^3(1-\tau)^3`, zero value, slope and curvature at both ends, 1 at
:math:`\tau = 1/2`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat

if TYPE_CHECKING:  # scipy.interpolate costs ~0.9 s to import: loaded when a trajectory is first evaluated
    from scipy.interpolate import CubicSpline

FloatArray = NDArray[np.float64]

DEFAULT_FS_HZ = 1000.0

__all__ = ["DEFAULT_FS_HZ", "KinematicState", "Trajectory", "bump", "intrinsic_rotation", "min_jerk",
           "time_grid"]


def min_jerk(tau: ArrayLike) -> FloatArray:
    r"""Minimum-jerk ramp :math:`s(\tau) = 10\tau^3 - 15\tau^4 + 6\tau^5`, clipped to ``[0, 1]`` outside."""
    x = np.clip(np.asarray(tau, dtype=np.float64), 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def bump(tau: ArrayLike) -> FloatArray:
    r"""C²-smooth bump :math:`64\tau^3(1-\tau)^3` on ``[0, 1]`` (peak 1 at the middle), zero outside."""
    x = np.clip(np.asarray(tau, dtype=np.float64), 0.0, 1.0)
    return 64.0 * x**3 * (1.0 - x) ** 3


def intrinsic_rotation(angles_rad: ArrayLike, axes: str) -> FloatArray:
    r"""Quaternions (n, 4) of intrinsic rotations, e.g. ``"ZXY"``: :math:`R_z(a)\,R_x(b)\,R_y(c)`.

    :func:`estimators.quaternion.from_intrinsic` on ``angles_rad`` of shape (n, len(axes)): no sign flip,
    so smooth angles give a smooth quaternion series (``from_euler`` would force ``w >= 0``).
    """
    a = np.asarray(angles_rad, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"angles_rad must have shape (n, {len(axes)}), got {a.shape}")
    return quat.from_intrinsic(a, axes)


def time_grid(duration_s: float, fs_hz: float = DEFAULT_FS_HZ, t_start_s: float = 0.0) -> FloatArray:
    """Dense grid ``t_start_s + k/fs_hz`` covering ``[t_start_s, t_start_s + duration_s]`` (both ends)."""
    if not (np.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f"duration_s must be a positive finite number of seconds, got {duration_s!r}")
    if not (np.isfinite(fs_hz) and fs_hz > 0.0):
        raise ValueError(f"fs_hz must be a positive finite rate in Hz, got {fs_hz!r}")
    n = int(np.floor(duration_s * fs_hz + 1e-9)) + 1
    return t_start_s + np.arange(n) / fs_hz


def _continuous_signs(q: FloatArray) -> FloatArray:
    """Flip quaternion signs so that consecutive samples lie in the same hemisphere (q and −q are one rotation)."""
    if len(q) < 2:
        return q
    dots = np.sum(q[1:] * q[:-1], axis=1)
    flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0.0, -1.0, 1.0))])
    return q * flips[:, None]


@dataclass(frozen=True, eq=False)
class KinematicState:
    """The true kinematics of a body at given times (all arrays have the times along axis 0).

    Attributes
    ----------
    t_s : (n,) trajectory (true) time, s.
    q_earth_body : (n, 4) orientation, maps body to ENU earth coordinates.
    pos_m : (n, 3) position of the body origin, ENU, m.
    vel_m_s : (n, 3) velocity, ENU, m/s.
    acc_m_s2 : (n, 3) kinematic acceleration :math:`\\ddot p`, ENU, m/s² (no gravity).
    gyr_rad_s : (n, 3) angular velocity in *body* coordinates, rad/s.
    ang_acc_rad_s2 : (n, 3) angular acceleration in body coordinates, rad/s².
    """

    t_s: FloatArray
    q_earth_body: FloatArray
    pos_m: FloatArray
    vel_m_s: FloatArray
    acc_m_s2: FloatArray
    gyr_rad_s: FloatArray
    ang_acc_rad_s2: FloatArray


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Dense, smooth rigid-body trajectory (see module docstring for the derivative maths).

    Parameters
    ----------
    t_s : (M,) strictly increasing times, s (dense: ~1 kHz; at least 4 samples).
    q_earth_body : (M, 4) unit quaternions (normalised and made sign-continuous here).
    pos_m : (M, 3) ENU positions of the body origin, m.

    The arrays are copied and made read-only.  Use :meth:`at` for the truth at arbitrary times
    inside ``[t_start_s, t_end_s]``; :meth:`mounted` gives the trajectory of a sensor fixed to the body.
    """

    t_s: FloatArray
    q_earth_body: FloatArray
    pos_m: FloatArray

    def __post_init__(self) -> None:
        t = np.array(self.t_s, dtype=np.float64).reshape(-1)
        q = np.array(self.q_earth_body, dtype=np.float64)
        p = np.array(self.pos_m, dtype=np.float64)
        if len(t) < 4:
            raise ValueError(f"a Trajectory needs at least 4 samples, got {len(t)}")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            raise ValueError("Trajectory.t_s must be finite and strictly increasing")
        if q.shape != (len(t), 4):
            raise ValueError(f"q_earth_body must have shape ({len(t)}, 4), got {q.shape}")
        if p.shape != (len(t), 3):
            raise ValueError(f"pos_m must have shape ({len(t)}, 3), got {p.shape}")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(p))):
            raise ValueError("q_earth_body and pos_m must be finite")
        q = _continuous_signs(quat.normalize(q))
        for name, arr in (("t_s", t), ("q_earth_body", q), ("pos_m", p)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_functions(
        cls,
        q_fn: Callable[[FloatArray], ArrayLike],
        pos_fn: Callable[[FloatArray], ArrayLike] | None,
        duration_s: float,
        *,
        fs_hz: float = DEFAULT_FS_HZ,
        t_start_s: float = 0.0,
    ) -> Trajectory:
        """Sample vectorised functions ``q_fn(t) -> (M, 4)`` and ``pos_fn(t) -> (M, 3)`` (``None``: at the origin)."""
        t = time_grid(duration_s, fs_hz, t_start_s)
        q = np.asarray(q_fn(t), dtype=np.float64)
        p = np.zeros((len(t), 3)) if pos_fn is None else np.asarray(pos_fn(t), dtype=np.float64)
        return cls(t, q, p)

    @classmethod
    def static(
        cls, duration_s: float, q_earth_body: ArrayLike = (1.0, 0.0, 0.0, 0.0), pos_m: ArrayLike = (0.0, 0.0, 0.0),
        *, fs_hz: float = DEFAULT_FS_HZ,
    ) -> Trajectory:
        """A body at rest for ``duration_s`` seconds."""
        t = time_grid(duration_s, fs_hz)
        q = np.broadcast_to(quat.normalize(np.asarray(q_earth_body, dtype=np.float64)), (len(t), 4))
        p = np.broadcast_to(np.asarray(pos_m, dtype=np.float64), (len(t), 3))
        return cls(t, q, p)

    def mounted(self, q_body_sensor: ArrayLike | None = None, lever_arm_m: ArrayLike | None = None) -> Trajectory:
        r"""Trajectory of a sensor rigidly fixed to this body.

        :math:`q_{earth,sensor} = q_{earth,body} \otimes q_{body,sensor}` and
        :math:`p_{sensor} = p + R_{earth,body}\, r` with ``lever_arm_m`` :math:`r` in body coordinates (m).
        """
        q = self.q_earth_body
        p = self.pos_m
        if q_body_sensor is not None:
            q = quat.multiply(q, quat.normalize(np.asarray(q_body_sensor, dtype=np.float64)))
        if lever_arm_m is not None:
            r = np.asarray(lever_arm_m, dtype=np.float64)
            if r.shape != (3,):
                raise ValueError(f"lever_arm_m must have shape (3,), got {r.shape}")
            p = p + quat.rotate(self.q_earth_body, r)
        return Trajectory(self.t_s, q, p)

    # ------------------------------------------------------------------ properties
    @property
    def t_start_s(self) -> float:
        return float(self.t_s[0])

    @property
    def t_end_s(self) -> float:
        return float(self.t_s[-1])

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    @cached_property
    def _q_spline(self) -> CubicSpline:
        from scipy.interpolate import CubicSpline

        return CubicSpline(self.t_s, self.q_earth_body, axis=0)

    @cached_property
    def _p_spline(self) -> CubicSpline:
        from scipy.interpolate import CubicSpline

        return CubicSpline(self.t_s, self.pos_m, axis=0)


    # ------------------------------------------------------------------ evaluation
    def _check_times(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=np.float64)
        tol = 1e-9 * max(1.0, abs(self.t_end_s))
        if t.size and (np.min(t) < self.t_start_s - tol or np.max(t) > self.t_end_s + tol):
            raise ValueError(
                f"times must lie inside the trajectory [{self.t_start_s}, {self.t_end_s}] s, "
                f"got [{np.min(t)}, {np.max(t)}] s"
            )
        return np.clip(t, self.t_start_s, self.t_end_s)

    def _omega(self, t: FloatArray) -> FloatArray:
        qt = self._q_spline(t)
        dq = self._q_spline(t, 1)
        n2 = np.sum(qt * qt, axis=-1, keepdims=True)
        return 2.0 * quat.multiply(quat.conjugate(qt), dq)[..., 1:] / n2

    def _angular_acceleration(self, t: FloatArray, omega: FloatArray) -> FloatArray:
        # d/dt of 2 vec(q̃* q̇̃)/|q̃|²: vec(q̇̃* q̇̃) = 0, d|q̃|²/dt = 2 q̃·q̇̃
        qt = self._q_spline(t)
        dq = self._q_spline(t, 1)
        ddq = self._q_spline(t, 2)
        n2 = np.sum(qt * qt, axis=-1, keepdims=True)
        dn2 = 2.0 * np.sum(qt * dq, axis=-1, keepdims=True)
        return (2.0 * quat.multiply(quat.conjugate(qt), ddq)[..., 1:] - omega * dn2) / n2

    def orientation(self, t_s: ArrayLike) -> FloatArray:
        """``q_earth_body`` (n, 4) at arbitrary times (the normalised quaternion spline)."""
        t = self._check_times(t_s)
        return quat.normalize(self._q_spline(t))

    def position(self, t_s: ArrayLike) -> FloatArray:
        """Position (n, 3), ENU m, at arbitrary times."""
        return self._p_spline(self._check_times(t_s))

    def velocity(self, t_s: ArrayLike) -> FloatArray:
        """Velocity (n, 3), ENU m/s, at arbitrary times."""
        return self._p_spline(self._check_times(t_s), 1)

    def acceleration(self, t_s: ArrayLike) -> FloatArray:
        """Kinematic acceleration :math:`\\ddot p` (n, 3), ENU m/s² (no gravity), at arbitrary times."""
        return self._p_spline(self._check_times(t_s), 2)

    def angular_velocity(self, t_s: ArrayLike) -> FloatArray:
        r"""Body angular velocity :math:`\omega = 2\,\mathrm{vec}(q^*\otimes\dot q)` (n, 3), rad/s, body frame."""
        return self._omega(self._check_times(t_s))

    def at(self, t_s: ArrayLike) -> KinematicState:
        """All true kinematics at arbitrary times inside the trajectory."""
        t = self._check_times(t_s)
        omega = self._omega(t)
        return KinematicState(
            t_s=np.array(t),
            q_earth_body=quat.normalize(self._q_spline(t)),
            pos_m=self._p_spline(t),
            vel_m_s=self._p_spline(t, 1),
            acc_m_s2=self._p_spline(t, 2),
            gyr_rad_s=omega,
            ang_acc_rad_s2=self._angular_acceleration(t, omega),
        )
