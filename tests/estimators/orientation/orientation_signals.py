"""Small synthetic signals and error measures shared by the per-method orientation tests.

A rotating body: a known angular velocity integrated with quaternion exp; acc and mag are the earth
vectors seen from the sensor (``../shared/DESIGN.md`` §3: ENU, at rest the up axis reads +9.81).
"""

from __future__ import annotations

import numpy as np

from estimators import quaternion as quat

FS_HZ = 100.0
GRAVITY_ENU = np.array([0.0, 0.0, 9.81])
FIELD_ENU_UT = np.array([0.0, 20.0, -40.0])
Q_Z90 = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])  # q_ENU_NWU: the ahrs oracles work in NWU
GYR_BIAS = np.array([0.01, -0.02, 0.015])


def rotating_body(n: int, *, seed: int = 0, noise: bool = True, still: bool = False, gyr_noise: float = 0.01):
    """Truth q_earth_sensor after each sample, (acc, gyr, mag) and the orientation before sample 0."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_HZ
    if still:
        omega = np.zeros((n, 3))
    else:
        omega = np.stack([1.5 * np.sin(2 * np.pi * 0.5 * t), 1.0 * np.cos(2 * np.pi * 0.3 * t),
                          0.8 * np.sin(2 * np.pi * 0.2 * t + 1.0)], axis=1)
    q_all = np.empty((n + 1, 4))
    q_all[0] = quat.from_euler([0.4, 0.2, -0.3], "ZYX")  # before the first sample
    for k in range(n):  # gyro sample k is the rate over the interval that ends at sample k
        q_all[k + 1] = quat.multiply(q_all[k], quat.exp(omega[k] / FS_HZ))
    q = q_all[1:]
    acc = quat.rotate(quat.conjugate(q), GRAVITY_ENU)
    mag = quat.rotate(quat.conjugate(q), FIELD_ENU_UT)
    gyr = omega.copy()
    if noise:
        acc += rng.normal(0.0, 0.1, acc.shape)
        mag += rng.normal(0.0, 0.5, mag.shape)
        gyr += rng.normal(0.0, gyr_noise, gyr.shape) + GYR_BIAS
    return q, acc, gyr, mag, q_all[0]


def angle_deg(q1, q2):
    """Total rotation angle between two orientations, degrees."""
    return np.degrees(quat.angle_between(q1, q2))


def tilt_deg(q1, q2):
    """Angle between the two estimated "up" directions seen from the sensor (heading-free), degrees."""
    up1 = quat.rotate(quat.conjugate(q1), [0.0, 0.0, 1.0])
    up2 = quat.rotate(quat.conjugate(q2), [0.0, 0.0, 1.0])
    return np.degrees(np.arccos(np.clip(np.sum(up1 * up2, axis=-1), -1.0, 1.0)))
