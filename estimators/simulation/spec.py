r"""Sensor specifications: error models of the three streams, the device clock, mounting draws.

Units are in the field names; every field is documented once with its default.  The equations
that use them (S4–S8) are in :mod:`estimators.simulation.imu`.  Defaults describe a MetaMotionR
(Bosch BMI160 accelerometer/gyroscope, BMM150 magnetometer) after its factory trim; use
``.perfect()`` for noise-free tests, ``.noise_only()`` for white noise alone, and
:func:`dataclasses.replace` to vary single fields.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.physics import GRAVITY_M_S2

FloatArray = NDArray[np.float64]

__all__ = ["AccErrors", "ClockSpec", "GRAVITY_M_S2", "GyrErrors", "ImuSpec", "MAG_EARTH_UT", "MagErrors",
           "random_rotation"]

MAG_EARTH_UT = (0.0, 20.0, -40.0)


def _vec3(value: Any, name: str) -> FloatArray:
    arr = np.array(value, dtype=np.float64)
    if arr.shape == ():
        arr = np.full(3, float(arr))
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite scalar or a (3,) vector, got {value!r}")
    arr.setflags(write=False)
    return arr


def _mat3(value: Any, name: str) -> FloatArray:
    arr = np.array(value, dtype=np.float64)
    if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite (3, 3) matrix, got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


def _set(obj: Any, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


def _nonneg(value: float, name: str) -> float:
    if not (np.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


def _range(value: float | None, name: str) -> float | None:
    if value is None:
        return None
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be None (no saturation) or a positive number, got {value!r}")
    return float(value)


@dataclass(frozen=True, eq=False)
class GyrErrors:
    """Gyroscope errors (S4–S6).  Defaults: a BMI160 as in a MetaMotionR (after its factory trim).

    noise_density_rad_s_rthz : white noise density, rad/s/√Hz (7e-4: 0.007 rad/s rms at 100 Hz).
    bias_rad_s : constant bias (3,), rad/s (default ≈ 0.6–1.1 °/s per axis).
    bias_walk_rad_s_rts : bias random-walk density, rad/s/√s (1e-4: ≈ 0.05 °/s drift over 100 s, 1σ).
    scale_error : per-axis scale error (3,), dimensionless (0.005 = +0.5 %).
    cross_axis : (3, 3) cross-axis / axis-misalignment matrix C (zero diagonal), dimensionless.
    range_rad_s : saturation ±range, rad/s (2000 °/s); None = no saturation.
    """

    noise_density_rad_s_rthz: float = 7e-4
    bias_rad_s: ArrayLike = (0.012, -0.019, 0.010)
    bias_walk_rad_s_rts: float = 1e-4
    scale_error: ArrayLike = (0.004, -0.003, 0.002)
    cross_axis: ArrayLike = ((0.0, 0.003, -0.002), (-0.002, 0.0, 0.004), (0.003, -0.001, 0.0))
    range_rad_s: float | None = float(np.deg2rad(2000.0))

    def __post_init__(self) -> None:
        _set(self, "noise_density_rad_s_rthz", _nonneg(self.noise_density_rad_s_rthz, "noise_density_rad_s_rthz"))
        _set(self, "bias_rad_s", _vec3(self.bias_rad_s, "bias_rad_s"))
        _set(self, "bias_walk_rad_s_rts", _nonneg(self.bias_walk_rad_s_rts, "bias_walk_rad_s_rts"))
        _set(self, "scale_error", _vec3(self.scale_error, "scale_error"))
        _set(self, "cross_axis", _mat3(self.cross_axis, "cross_axis"))
        _set(self, "range_rad_s", _range(self.range_rad_s, "range_rad_s"))

    @classmethod
    def perfect(cls) -> GyrErrors:
        """No noise, bias, scale or axis errors, no saturation."""
        return cls(0.0, 0.0, 0.0, 0.0, np.zeros((3, 3)), None)

    @classmethod
    def noise_only(cls) -> GyrErrors:
        """Default white noise only (no bias, scale, axis errors or saturation)."""
        return replace(cls.perfect(), noise_density_rad_s_rthz=cls.noise_density_rad_s_rthz)


@dataclass(frozen=True, eq=False)
class AccErrors:
    """Accelerometer errors (S4–S6).  Defaults: a BMI160 (±16 g range).

    noise_density_m_s2_rthz : white noise density, m/s²/√Hz (2e-3 ≈ 200 µg/√Hz: 0.02 m/s² rms at 100 Hz).
    bias_m_s2 : constant bias (3,), m/s² (default 5–12 mg, within the BMI160's ±40 mg zero-g offset).
    bias_walk_m_s2_rts : bias random-walk density, m/s²/√s.
    scale_error : per-axis scale error (3,), dimensionless.
    cross_axis : (3, 3) cross-axis matrix C (zero diagonal), dimensionless.
    range_m_s2 : saturation ±range, m/s² (16 g); None = no saturation.
    """

    noise_density_m_s2_rthz: float = 2e-3
    bias_m_s2: ArrayLike = (0.05, -0.08, 0.12)
    bias_walk_m_s2_rts: float = 2e-4
    scale_error: ArrayLike = (0.003, 0.005, -0.004)
    cross_axis: ArrayLike = ((0.0, -0.002, 0.003), (0.001, 0.0, -0.002), (-0.003, 0.002, 0.0))
    range_m_s2: float | None = 16.0 * GRAVITY_M_S2

    def __post_init__(self) -> None:
        _set(self, "noise_density_m_s2_rthz", _nonneg(self.noise_density_m_s2_rthz, "noise_density_m_s2_rthz"))
        _set(self, "bias_m_s2", _vec3(self.bias_m_s2, "bias_m_s2"))
        _set(self, "bias_walk_m_s2_rts", _nonneg(self.bias_walk_m_s2_rts, "bias_walk_m_s2_rts"))
        _set(self, "scale_error", _vec3(self.scale_error, "scale_error"))
        _set(self, "cross_axis", _mat3(self.cross_axis, "cross_axis"))
        _set(self, "range_m_s2", _range(self.range_m_s2, "range_m_s2"))

    @classmethod
    def perfect(cls) -> AccErrors:
        return cls(0.0, 0.0, 0.0, 0.0, np.zeros((3, 3)), None)

    @classmethod
    def noise_only(cls) -> AccErrors:
        return replace(cls.perfect(), noise_density_m_s2_rthz=cls.noise_density_m_s2_rthz)


@dataclass(frozen=True, eq=False)
class MagErrors:
    """Magnetometer errors (S6–S7).  Defaults: a BMM150 near a small battery and PCB.

    noise_density_ut_rthz : white noise density, µT/√Hz (0.1: ≈ 0.45 µT rms at 20 Hz).
    hard_iron_ut : constant offset b (3,), µT.
    soft_iron : (3, 3) matrix A (identity = none); symmetric positive definite in practice.
    range_ut : saturation ±range, µT (1300); None = no saturation.
    """

    noise_density_ut_rthz: float = 0.1
    hard_iron_ut: ArrayLike = (12.0, -7.0, 21.0)
    soft_iron: ArrayLike = ((1.04, 0.02, -0.01), (0.02, 0.97, 0.015), (-0.01, 0.015, 1.01))
    range_ut: float | None = 1300.0

    def __post_init__(self) -> None:
        _set(self, "noise_density_ut_rthz", _nonneg(self.noise_density_ut_rthz, "noise_density_ut_rthz"))
        _set(self, "hard_iron_ut", _vec3(self.hard_iron_ut, "hard_iron_ut"))
        soft = _mat3(self.soft_iron, "soft_iron")
        if abs(np.linalg.det(soft)) < 1e-6:
            raise ValueError("soft_iron must be an invertible (3, 3) matrix")
        _set(self, "soft_iron", soft)
        _set(self, "range_ut", _range(self.range_ut, "range_ut"))

    @classmethod
    def perfect(cls) -> MagErrors:
        return cls(0.0, 0.0, np.eye(3), None)

    @classmethod
    def noise_only(cls) -> MagErrors:
        return replace(cls.perfect(), noise_density_ut_rthz=cls.noise_density_ut_rthz)


@dataclass(frozen=True)
class ClockSpec:
    """Sampling rates and the device clock (S8).  Defaults: ideal clock, 100/100/20 Hz, common start.

    acc_fs_hz, gyr_fs_hz, mag_fs_hz : nominal output data rates, Hz (device clock).
    acc_start_s, gyr_start_s, mag_start_s : device-clock delay of each stream's first sample, s (>= 0).
    clock_drift_ppm : device clock rate error, parts per million (5000 = 0.5 % fast; negative = slow).
    clock_offset_s : what the device clock reads at the trajectory start, s.
    jitter_s : standard deviation of the reported time stamps around the true device times, s.
    """

    acc_fs_hz: float = 100.0
    gyr_fs_hz: float = 100.0
    mag_fs_hz: float = 20.0
    acc_start_s: float = 0.0
    gyr_start_s: float = 0.0
    mag_start_s: float = 0.0
    clock_drift_ppm: float = 0.0
    clock_offset_s: float = 0.0
    jitter_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("acc_fs_hz", "gyr_fs_hz", "mag_fs_hz"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be a positive rate in Hz, got {v!r}")
        for name in ("acc_start_s", "gyr_start_s", "mag_start_s", "jitter_s"):
            _nonneg(getattr(self, name), name)
        if not (np.isfinite(self.clock_drift_ppm) and abs(self.clock_drift_ppm) < 1e5):
            raise ValueError(f"clock_drift_ppm must be finite with |value| < 1e5, got {self.clock_drift_ppm!r}")
        if not np.isfinite(self.clock_offset_s):
            raise ValueError(f"clock_offset_s must be finite, got {self.clock_offset_s!r}")

    @classmethod
    def metamotion(cls) -> ClockSpec:
        """A realistic MetaMotionR-like clock: streams start a few ms apart, 40 ppm drift, 0.5 ms jitter."""
        return cls(acc_start_s=0.003, gyr_start_s=0.0, mag_start_s=0.017, clock_drift_ppm=40.0, jitter_s=0.0005)

    @property
    def rate_factor(self) -> float:
        """Device seconds per true second, :math:`1 + \\delta`."""
        return 1.0 + 1e-6 * self.clock_drift_ppm


@dataclass(frozen=True)
class ImuSpec:
    """Everything about one simulated sensor except its motion: errors of each stream and the clock.

    ``ImuSpec()`` is a representative MetaMotionR (noise, biases, scale/axis errors, iron, ideal clock);
    ``ImuSpec.perfect()`` a noise-free ideal sensor; ``ImuSpec.noise_only()`` white noise only.
    Vary single fields with :func:`dataclasses.replace`.
    """

    acc: AccErrors = field(default_factory=AccErrors)
    gyr: GyrErrors = field(default_factory=GyrErrors)
    mag: MagErrors = field(default_factory=MagErrors)
    clock: ClockSpec = field(default_factory=ClockSpec)

    @classmethod
    def perfect(cls, clock: ClockSpec | None = None) -> ImuSpec:
        return cls(AccErrors.perfect(), GyrErrors.perfect(), MagErrors.perfect(), clock or ClockSpec())

    @classmethod
    def noise_only(cls, clock: ClockSpec | None = None) -> ImuSpec:
        return cls(AccErrors.noise_only(), GyrErrors.noise_only(), MagErrors.noise_only(), clock or ClockSpec())

    @classmethod
    def random(cls, seed: int | np.random.Generator | None = None, clock: ClockSpec | None = None) -> ImuSpec:
        """Default noise with biases, scale/axis errors and iron drawn from typical ranges (one sensor unit)."""
        rng = np.random.default_rng(seed)

        def cross(sd: float) -> FloatArray:
            c = rng.normal(0.0, sd, (3, 3))
            np.fill_diagonal(c, 0.0)
            return c

        sym = rng.normal(0.0, 0.03, (3, 3))
        soft = np.eye(3) + 0.5 * (sym + sym.T)
        return cls(
            AccErrors(bias_m_s2=rng.normal(0.0, 0.1, 3), scale_error=rng.normal(0.0, 0.005, 3),
                      cross_axis=cross(0.003)),
            GyrErrors(bias_rad_s=rng.normal(0.0, 0.02, 3), scale_error=rng.normal(0.0, 0.005, 3),
                      cross_axis=cross(0.003)),
            MagErrors(hard_iron_ut=rng.normal(0.0, 20.0, 3), soft_iron=soft),
            clock or ClockSpec(),
        )


def random_rotation(max_angle_rad: float, seed: int | np.random.Generator | None = None) -> FloatArray:
    """A rotation (4,) about a uniformly random axis by an angle uniform in ``[0, max_angle_rad]``.

    Use it for a random mounting misalignment ``q_segment_sensor``.
    """
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    return quat.from_axis_angle(axis, rng.uniform(0.0, float(max_angle_rad)))
