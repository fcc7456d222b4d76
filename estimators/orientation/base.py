r"""The orientation family: one contract, one input check, one initial alignment.

Every method estimates ``q_earth_sensor`` — the unit quaternion (w, x, y, z) mapping sensor
coordinates to the ENU earth frame (x east, y magnetic north, z up) — from accelerometer
(m/s², specific force: at rest the upward axis reads +9.81), gyroscope (rad/s) and, for 9D
methods, magnetometer (µT; any unit works, only directions are used) samples on one time grid.

Contract
--------
``Method(params).estimate(acc, gyr, mag=None, *, fs_hz) -> self`` fills

* ``orientation_``: ``(N, 4)`` ``q_earth_sensor`` per sample, the estimate *after* sample ``k``;
* ``flags_``: :class:`SampleFlags`, which samples were missing or saturated;
* ``state_``: the filter state after the last sample (see *Online form*).

Online form (state in, state out)
---------------------------------
``state = method.initial_state(acc, mag, fs_hz=...)`` aligns a new state on the first samples, and
``q, state = method.update(state, acc, gyr, mag, fs_hz=...)`` runs the *same* compiled kernel on
one sample ``(3,)`` or a block ``(n, 3)``.  Running two halves of a recording through
``update`` gives exactly the result of one batch.  The state is a 1-D float64 array whose first
four entries are the quaternion; the rest is documented by each method.

Missing and saturated samples (documented handling, not errors)
---------------------------------------------------------------
* A row with NaN in the accelerometer or magnetometer skips that correction (the filter predicts
  with the gyroscope only); a row with NaN in the gyroscope holds the orientation (zero rate).
* 6D (``mag=None``) is 9D with every field sample missing: ``ImuInput.mag`` is ``None`` (what
  :meth:`OrientationMethod._check_dimension` and the initial alignment look at), ``mag_ok`` is all
  False and :attr:`ImuInput.mag_array` is zeros, so every kernel takes one code path for both.
* Samples whose absolute value on any axis reaches ``acc_range_m_s2`` / ``gyr_range_rad_s``
  (when those ranges are given) are *saturated*: a saturated accelerometer row is treated as
  missing; a saturated gyroscope row is still integrated (nothing better is known) and flagged.
* An accelerometer or field row that is all zero, or so small that its squared norm underflows (norm below
  ≈ 1e-154), has no direction: it does not correct (like a missing row) but is not flagged.
* Every such sample is reported in ``flags_``.

Everything else a user can get wrong raises ``ValueError`` naming the problem: wrong shapes,
mismatched lengths, empty arrays, ``±inf`` values (corrupted data, not a missing sample),
``fs_hz`` not finite and positive, no valid accelerometer sample at all.

Initial alignment (orientation from the first sample)
-----------------------------------------------------
Unless ``q0`` is given, the state starts from the first ``init_window_s`` (2 s) of valid samples,
*motion-compensated*: the gyroscope is integrated over the window, :math:`q_{0k} = \prod_{j \le k}
\exp(\omega_j\,dt)` (the rotation from "before sample 0" to sample ``k``), and every accelerometer and
magnetometer sample is rotated back into the sensor frame before sample 0,
:math:`\bar m = \operatorname{mean}_k R(q_{0k})\,m_k`; gravity :math:`\bar a` is the slope of the integrated
rotated specific force :math:`\sum_{j\le k} R(q_{0j})\,a_j\,\Delta t` over time (:func:`velocity_regression`: the
least-squares velocity regression, equal to the mean at rest).  A recording that starts in motion (a swinging
shank) is then aligned on gravity, not on gravity plus the limb's acceleration: linear accelerations average
out over the window as in VQF's quasi-inertial frame (Laidig & Seel 2023, §3.2), and the regression also
removes what a plain mean keeps of a window that ends mid-swing (ours; ChakaMo's own filter keeps the plain
mean, ``align_by_regression``).  Every valid row counts, impacts included: heel strikes act mostly along
gravity, and leaving out the rows of large norm biases the mean (a swinging limb's centripetal and
tangential accelerations also reach ±40 % of g; measured on the gait scenarios of the tests).  A gyroscope bias
``b`` costs at most ``|b| * init_window_s`` (0.7°/s → < 1.5°).  Gravity fixes roll and pitch; with a
magnetometer, the horizontal part of the field fixes heading (TRIAD in ENU: east = m × up,
north = up × east; only directions are used, so the field may be in any unit); without one, heading
starts at zero (the smallest rotation taking the measured "up" to the earth's z axis).  The result is
the orientation *before* sample 0, the state the first filter step advances with ``gyr[0]``.
At rest (or online, :meth:`OrientationMethod.initial_state` without ``gyr``) this is the plain mean.

An aligned start is trusted: a method's measures for a *wrong* start (a large initial covariance, a
warm-up with fast gains) apply only to a start given as ``q0``.  From the alignment, Guo and Valenti's
Kalman filter start with the covariance of ``ALIGNED_STD_RAD`` (0.05 rad) and Madgwick and Valenti's
complementary filter skip their warm-up: on a clip that starts in motion those measures replaced the
aligned start by the first raw, acceleration-laden samples (gait scenarios, heading RMS: guo 15–150° →
4–7°, madgwick 0.4–14.5° → 2.5–5.8°).

Motion-compensated accelerometer (the published filters)
--------------------------------------------------------
A method with ``uses_acc_lowpass`` (Guo, Madgwick, both Valenti filters) does not feed its published update
the raw accelerometer but the specific force low-passed in a quasi-inertial frame
(:mod:`~estimators.orientation.acc_lowpass`; time constant ``acc_lowpass_s``, 0 = the published filter).  Its
state is the method's own state followed by that stage's block (``acc_lowpass.SIZE`` entries), so online
blocks still equal one batch; the block starts from the alignment window's gravity and start velocity, also
when ``q0`` is given (``q0`` is an attitude; the stage needs none): started empty from a ``q0``, the stage took
sample 0's body acceleration for gravity (gait seeds 6–7, ``q0`` = truth, a 4 g strike on sample 0: Madgwick,
Valenti CF and KF heading RMS 15–46° and tilt up to 50°; from the window 1.0–3.4° and ≤ 3.7°).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields, replace
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.orientation import acc_lowpass

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

INIT_WINDOW_S = 2.0
#: standard deviation (rad) of the motion-compensated alignment, for filters with an initial uncertainty
#: (measured on the gait scenarios of the tests, starting in motion: tilt ≤ 4°, heading ≤ 7°)
ALIGNED_STD_RAD = 0.05


@dataclass(frozen=True)
class SampleFlags:
    """Per-sample booleans ``(N,)`` describing what the filter could not use."""

    acc_missing: BoolArray
    gyr_missing: BoolArray
    mag_missing: BoolArray
    acc_saturated: BoolArray
    gyr_saturated: BoolArray

    @property
    def any(self) -> BoolArray:
        """True where any flag is set."""
        return self.acc_missing | self.gyr_missing | self.mag_missing | self.acc_saturated | self.gyr_saturated


@dataclass(frozen=True)
class ImuInput:
    """Validated inputs on one time grid: finite arrays (missing rows zeroed) and validity masks.

    ``acc_ok[k]`` / ``mag_ok[k]`` say whether that row may correct the estimate;
    ``mag`` is ``None`` for 6D estimation, and then ``mag_ok`` is all False (6D is 9D with every
    field sample missing) and :attr:`mag_array` is zeros.
    """

    acc: FloatArray
    gyr: FloatArray
    mag: FloatArray | None
    acc_ok: BoolArray
    mag_ok: BoolArray
    fs_hz: float
    flags: SampleFlags

    @property
    def n(self) -> int:
        return self.acc.shape[0]

    @property
    def dt_s(self) -> float:
        return 1.0 / self.fs_hz

    @property
    def mag_array(self) -> FloatArray:
        """The field rows for a kernel, ``(N, 3)``: ``mag``, or zeros in 6D (never read: no ``mag_ok``)."""
        return self.mag if self.mag is not None else np.zeros((self.n, 3))


def _as_stream(name: str, values: ArrayLike) -> FloatArray:
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array of shape (N, 3): {exc}") from None
    if arr.ndim == 1 and arr.shape[0] == 3:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3) with time along axis 0, got {arr.shape}")
    if arr.shape[0] == 0:
        raise ValueError(f"{name} is empty: at least one sample is needed")
    if np.isinf(arr).any():
        row = int(np.flatnonzero(np.isinf(arr).any(axis=1))[0])
        raise ValueError(
            f"{name} holds an infinite value at sample {row}: the recording is corrupted "
            "(mark missing samples with NaN instead)"
        )
    return arr


def check_fs(fs_hz: float) -> float:
    """Return ``fs_hz`` as a float; ``ValueError`` unless finite and > 0."""
    try:
        fs = float(fs_hz)
    except (TypeError, ValueError):
        raise ValueError(f"fs_hz must be a number in Hz, got {fs_hz!r}") from None
    if not np.isfinite(fs) or fs <= 0.0:
        raise ValueError(f"fs_hz must be finite and > 0 Hz, got {fs_hz!r}")
    return fs


def validate_imu(
    acc: ArrayLike,
    gyr: ArrayLike,
    mag: ArrayLike | None = None,
    *,
    fs_hz: float,
    acc_range_m_s2: float | None = None,
    gyr_range_rad_s: float | None = None,
    require_valid_acc: bool = True,
) -> ImuInput:
    """Check and prepare raw inputs for a filter (see the module docstring for the rules).

    ``require_valid_acc=False`` accepts a block without any usable accelerometer sample: an online
    ``update`` of an already aligned state can predict through a gap.
    """
    fs = check_fs(fs_hz)
    acc_arr = _as_stream("acc", acc)
    gyr_arr = _as_stream("gyr", gyr)
    n = acc_arr.shape[0]
    if gyr_arr.shape[0] != n:
        raise ValueError(f"acc and gyr must have the same number of samples, got {n} and {gyr_arr.shape[0]}")
    mag_arr = None if mag is None else _as_stream("mag", mag)
    if mag_arr is not None and mag_arr.shape[0] != n:
        raise ValueError(
            f"mag must be on the accelerometer's time grid ({n} samples), got {mag_arr.shape[0]}: "
            "resample it first (ingestion interpolates the 20 Hz magnetometer onto the 100 Hz grid)"
        )

    acc_missing = np.isnan(acc_arr).any(axis=1)
    gyr_missing = np.isnan(gyr_arr).any(axis=1)
    mag_missing = np.isnan(mag_arr).any(axis=1) if mag_arr is not None else np.zeros(n, dtype=bool)
    acc_saturated = _saturated(acc_arr, acc_range_m_s2, "acc_range_m_s2")
    gyr_saturated = _saturated(gyr_arr, gyr_range_rad_s, "gyr_range_rad_s")
    # free fall, a zero-filled gap or a row whose squared norm underflows (‖·‖ < 1e-154): no direction
    acc_zero = _no_direction(acc_arr)
    acc_ok = ~(acc_missing | acc_saturated | acc_zero)
    if require_valid_acc and not acc_ok.any():
        raise ValueError("acc has no valid sample (all missing, saturated or zero): orientation cannot be aligned")
    # 6D: no field sample may correct (9D with every field sample missing); flags.mag_missing stays False
    mag_ok = ~(mag_missing | _no_direction(mag_arr)) if mag_arr is not None else np.zeros(n, dtype=bool)

    def finite(arr: FloatArray, bad: BoolArray) -> FloatArray:
        if bad.any():
            arr = arr.copy()
            arr[bad] = 0.0
        return np.ascontiguousarray(arr)

    return ImuInput(
        acc=finite(acc_arr, acc_missing),
        gyr=finite(gyr_arr, gyr_missing),
        mag=None if mag_arr is None else finite(mag_arr, mag_missing),
        acc_ok=acc_ok,
        mag_ok=mag_ok,
        fs_hz=fs,
        flags=SampleFlags(acc_missing, gyr_missing, mag_missing, acc_saturated, gyr_saturated),
    )


def _no_direction(arr: FloatArray) -> BoolArray:
    """Rows without a direction: zero, or so small that a kernel's 1/‖·‖ overflows (NaN rows: False)."""
    with np.errstate(under="ignore"):
        return np.einsum("ij,ij->i", arr, arr) < np.finfo(np.float64).tiny


def _saturated(arr: FloatArray, range_: float | None, name: str) -> BoolArray:
    if range_ is None:
        return np.zeros(arr.shape[0], dtype=bool)
    if not np.isfinite(range_) or range_ <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {range_!r}")
    with np.errstate(invalid="ignore"):
        return (np.abs(arr) >= range_ * (1.0 - 1e-9)).any(axis=1)


def alignment_samples(fs_hz: float, window_s: float = INIT_WINDOW_S) -> int:
    """How many samples the initial alignment of ``estimate`` reads at ``fs_hz`` (from the first valid one)."""
    return max(1, int(round(window_s * check_fs(fs_hz))))


def align(acc: ArrayLike, mag: ArrayLike | None = None) -> FloatArray:
    """``q_earth_sensor`` from one specific-force direction and (optionally) one field direction.

    TRIAD in ENU: up = â; east = m̂ × up; north = up × east.  Without ``mag`` (or with a field
    parallel to gravity) heading is zero: the smallest rotation taking ``up`` to ``(0, 0, 1)``.
    """
    up = np.asarray(acc, dtype=np.float64)
    up = up / np.linalg.norm(up)
    if mag is not None:
        east = np.cross(np.asarray(mag, dtype=np.float64), up)
        norm = np.linalg.norm(east)
        if norm > 1e-9 * max(np.linalg.norm(mag), 1e-300):
            east /= norm
            north = np.cross(up, east)
            # rows of R_earth_sensor are the earth axes written in sensor coordinates
            return quat.from_matrix(np.stack([east, north, up]))
    return quat.from_two_vectors(up, np.array([0.0, 0.0, 1.0]))


@dataclass(frozen=True)
class Alignment:
    """What the initial alignment learnt from its window (module docstring, *Initial alignment*).

    q: ``q_earth_sensor`` before sample 0.   acc_mean, mag_mean: the motion-compensated mean specific force
    (m/s²) and field (input unit; ``None`` without one) in the sensor frame before sample 0.
    n_acc, n_mag: how many rows each mean holds.   mag_norm_mean: mean norm of those field rows (input unit).
    velocity_start: the sensor's velocity at sample 0 relative to its window mean (m/s, same frame;
    :func:`velocity_regression`).
    """

    q: FloatArray
    acc_mean: FloatArray
    mag_mean: FloatArray | None
    n_acc: int
    n_mag: int
    mag_norm_mean: float
    velocity_start: FloatArray | None = None


def initial_alignment(data: ImuInput, use_mag: bool = True, window_s: float = INIT_WINDOW_S,
                      regression: bool = True) -> Alignment:
    """Align on the first ``window_s`` of data, motion-compensated (module docstring).

    ``regression=False`` takes gravity as the plain motion-compensated mean (ChakaMo's own filter, whose
    quasi-inertial low-pass follows the alignment and whose numbers were measured with it); the start velocity
    is then zero.

    The window starts at the first valid accelerometer row and holds at least that row.  The heading comes
    from the field samples marked ``mag_ok`` in the window (none in 6D; if none there, the first valid one)
    unless ``use_mag`` is False.
    """
    n_window = alignment_samples(data.fs_hz, window_s)
    first = int(np.flatnonzero(data.acc_ok)[0])
    stop = min(data.n, first + n_window)
    q_rel = _window_strapdown(data.gyr[:stop], data.dt_s)  # missing gyroscope rows are zeros: held
    sel = np.flatnonzero(data.acc_ok[first:stop]) + first
    acc_rot = quat.rotate(q_rel[sel], data.acc[sel])
    if regression:
        acc_mean, velocity_start = velocity_regression(acc_rot, data.dt_s)
    else:
        acc_mean, velocity_start = acc_rot.mean(axis=0), np.zeros(3)
    mag_mean, n_mag, mag_norm = None, 0, 0.0
    if use_mag:  # 6D: no mag_ok, so no field and heading zero
        sel_m = np.flatnonzero(data.mag_ok[first:stop]) + first
        if sel_m.size:
            mag_mean = quat.rotate(q_rel[sel_m], data.mag[sel_m]).mean(axis=0)
            n_mag, mag_norm = int(sel_m.size), float(np.linalg.norm(data.mag[sel_m], axis=1).mean())
        elif data.mag_ok.any():  # no field sample in the window: the first one, rotated back
            k = int(np.flatnonzero(data.mag_ok)[0])
            q_k = _window_strapdown(data.gyr[:k + 1], data.dt_s)[k]
            mag_mean = quat.rotate(q_k, data.mag[k])
            n_mag, mag_norm = 1, float(np.linalg.norm(data.mag[k]))
    return Alignment(align(acc_mean, mag_mean), acc_mean, mag_mean, int(sel.size), n_mag, mag_norm, velocity_start)


def velocity_regression(acc_rot: FloatArray, dt_s: float) -> tuple[FloatArray, FloatArray]:
    r"""Gravity (specific force, m/s²) from motion-compensated rows ``(n, 3)``, and the start velocity (m/s).

    With :math:`V_k = \Delta t\sum_{j\le k} a_j` (the integrated specific force, in the frame before sample 0)
    and the model :math:`V_k = v_0 + g\,t_k + u_k` (the limb's velocity :math:`u` about its mean), ``g`` is the
    least-squares slope :math:`\sum (t_k-\bar t)(V_k-\bar V) / \sum (t_k-\bar t)^2`, :math:`t_k = (k+1)\Delta t`.
    The plain mean is :math:`(V_n - V_0)/t_n`: it reads the velocity change between the window's two *ends*,
    so a window that holds 1.8 gait cycles keeps a residual of the swing (on the gait scenarios of the tests:
    tilt 1.2–3.6°, heading 2–7°); the slope reads the whole velocity curve (tilt 0.5–2.1°, heading 0–3.7°).
    At rest (and for fewer than 3 rows) both are the mean.

    The second result is the residual of the first row, :math:`u_0 = V_0 - v_0 - g\,t_0`: the limb's velocity
    at sample 0 relative to its mean over the window (zero at rest), which the accelerometer stage of the
    published filters uses to start its low-pass without a transient (:func:`acc_lowpass.initial_block`).
    """
    n = acc_rot.shape[0]
    if n < 3:
        return acc_rot.mean(axis=0), np.zeros(3)
    v = np.cumsum(acc_rot, axis=0) * dt_s
    t = (np.arange(n) + 1.0) * dt_s
    tc = t - t.mean()
    v_mean = v.mean(axis=0)
    gravity = (tc @ (v - v_mean)) / (tc @ tc)
    return gravity, v[0] - (v_mean - gravity * t.mean()) - gravity * t[0]


def initial_orientation(data: ImuInput, use_mag: bool = True, window_s: float = INIT_WINDOW_S) -> FloatArray:
    """``q_earth_sensor`` before sample 0 (:func:`initial_alignment`'s ``q``)."""
    return initial_alignment(data, use_mag, window_s).q


def _window_strapdown(gyr: FloatArray, dt_s: float) -> FloatArray:
    """``q_0k`` (k, 4): the rotation from before sample 0 to sample ``k``, ``∏_{j≤k} exp(ω_j dt)``.

    The prefix products by a Hillis–Steele scan (``log2 k`` vectorised steps; the product is associative):
    step ``j`` sets ``x_k ← x_{k−2^j} ⊗ x_k``, so ``x_k`` ends as the ordered product of steps ``0..k``.
    """
    out = quat.exp(gyr * dt_s)
    shift = 1
    while shift < out.shape[0]:
        out[shift:] = quat.multiply(out[:-shift], out[shift:])  # the right side is evaluated first
        shift *= 2
    return quat.normalize(out)


def check_parameter(
    name: str,
    value: Any,
    *,
    unit: str = "",
    low: float = 0.0,
    low_open: bool = False,
    high: float = np.inf,
    allow_inf: bool = False,
    hint: str = "",
) -> None:
    """Refuse a parameter outside ``[low, high]`` (``(low, high]`` with ``low_open``) with a message naming it.

    ``allow_inf`` admits ``+inf`` (a tolerance switched off); NaN and non-numbers are always refused.
    """
    where = f" ({hint})" if hint else ""
    units = f" {unit}" if unit else ""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a number{units}, got {value!r}")
    if np.isnan(value) or (np.isinf(value) and not (allow_inf and value > 0)):
        raise ValueError(f"{name} must be a finite number{units}{where}, got {value!r}")
    if (value <= low if low_open else value < low) or value > high:
        bounds = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        raise ValueError(f"{name} must be in {bounds}{units}{where}, got {value!r}")


def check_flag(name: str, value: Any) -> None:
    """Refuse a switch that is not ``True`` or ``False`` with a message naming it."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")


def params_from_kwargs(params_type: type, values: dict[str, Any]) -> Any:
    """Build a parameter dataclass from keyword values; unknown names raise ``ValueError`` listing the valid ones."""
    names = {f.name for f in fields(params_type)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ValueError(
            f"unknown parameter(s) {', '.join(unknown)} for {params_type.__name__}; "
            f"valid: {', '.join(sorted(names))}"
        )
    return params_type(**values)


class OrientationMethod(ABC):
    """Base of every orientation filter.

    Subclasses set ``name``, ``params_type`` (a frozen dataclass whose ``__post_init__`` validates),
    ``state_size`` (length of the state vector), ``supports_6d`` / ``supports_9d`` (both True unless
    set), and implement :meth:`_run` (the compiled kernel) and :meth:`_run_reference` (readable
    numpy, same numbers); :meth:`_state_from_quaternion` when the rest of a fresh state is not zero.
    """

    name: ClassVar[str]
    params_type: ClassVar[type]
    state_size: ClassVar[int]
    supports_6d: ClassVar[bool] = True
    supports_9d: ClassVar[bool] = True
    #: the published update reads the motion-compensated accelerometer (module docstring); the params then
    #: have ``acc_lowpass_s`` and the last ``acc_lowpass.SIZE`` state entries are that stage's block
    uses_acc_lowpass: ClassVar[bool] = False
    #: the method's own kernel runs that stage per sample (Guo: its strapdown subtracts the bias estimate)
    lowpass_in_kernel: ClassVar[bool] = False
    #: gravity of the initial alignment by the velocity regression (else the plain window mean)
    align_by_regression: ClassVar[bool] = True
    #: the state has parts seeded from the alignment window besides the stage (:meth:`_seed_from_window`), so
    #: a start from ``q0`` reads the window too
    seeds_from_window: ClassVar[bool] = False

    def __init__(self, params: Any | None = None) -> None:
        if params is None:
            params = self.params_type()
        elif not isinstance(params, self.params_type):
            raise TypeError(f"{type(self).__name__} takes {self.params_type.__name__}, got {type(params).__name__}")
        self.params = params

    # ------------------------------------------------------------------ batch
    def estimate(
        self,
        acc: ArrayLike,
        gyr: ArrayLike,
        mag: ArrayLike | None = None,
        *,
        fs_hz: float,
        q0: ArrayLike | None = None,
        acc_range_m_s2: float | None = None,
        gyr_range_rad_s: float | None = None,
    ) -> Self:
        """Run the filter over a recording; results in ``orientation_``, ``flags_``, ``state_``."""
        data = validate_imu(acc, gyr, mag, fs_hz=fs_hz, acc_range_m_s2=acc_range_m_s2,
                            gyr_range_rad_s=gyr_range_rad_s)
        self._check_dimension(data.mag is not None)
        state0 = self._initial_state_for(data, q0)
        self.orientation_, self.state_ = self._filter(data, state0, reference=False)
        self.flags_ = data.flags
        return self

    def reference(
        self, acc: ArrayLike, gyr: ArrayLike, mag: ArrayLike | None = None, *, fs_hz: float,
        q0: ArrayLike | None = None,
    ) -> FloatArray:
        """The readable numpy implementation on the same inputs (slow; for tests and study)."""
        data = validate_imu(acc, gyr, mag, fs_hz=fs_hz)
        self._check_dimension(data.mag is not None)
        q, _ = self._filter(data, self._initial_state_for(data, q0), reference=True)
        return q

    # ----------------------------------------------------------------- online
    def initial_state(
        self, acc: ArrayLike, mag: ArrayLike | None = None, *, gyr: ArrayLike | None = None,
        fs_hz: float | None = None, q0: ArrayLike | None = None,
    ) -> FloatArray:
        """A fresh state aligned on ``acc`` (and ``mag``): one sample ``(3,)`` or the first samples ``(n, 3)``.

        ``fs_hz`` is the rate ``update`` will run at.  Without ``gyr`` the samples are averaged as they are (a
        sensor at rest); with ``gyr`` (rad/s, same rows) they are motion-compensated as ``estimate`` does (module
        docstring), so ``initial_state(acc[:w], mag[:w], gyr=gyr[:w], fs_hz=fs)`` with ``w = alignment_samples(fs)``
        is the state ``estimate`` starts from (and without ``gyr`` too when the window's rates are zero).  A start
        with rate-dependent parts (the accelerometer stage's filter, a method's window-seeded parts: every default
        method) needs ``fs_hz`` also without ``gyr``, with or without ``q0``, and refuses to guess it
        (``ValueError``): the state used to be built at 1 Hz there, and ``update`` at 100 Hz then read the stage's
        1 Hz steady state (Madgwick online vs batch 2.2°, Guo online 88–111° off the truth).
        """
        acc_arr = np.atleast_2d(np.asarray(acc, dtype=np.float64))
        if fs_hz is None:
            if gyr is not None:
                raise ValueError("initial_state with gyr needs fs_hz (the sample rate, Hz) to integrate it")
            if self._start_needs_rate:
                raise ValueError(f"initial_state of {self.name!r} needs fs_hz (the sample rate, Hz, that update "
                                 "will run at): its start state holds rate-dependent parts")
            fs = 1.0  # nothing in this start depends on the rate
        else:
            fs = check_fs(fs_hz)
        gyr_arr = np.zeros_like(acc_arr) if gyr is None else np.atleast_2d(np.asarray(gyr, dtype=np.float64))
        data = validate_imu(acc_arr, gyr_arr, mag if mag is None else np.atleast_2d(mag), fs_hz=fs)
        self._check_dimension(data.mag is not None)
        return self._initial_state_for(data, q0, window_s=data.n / fs)

    def update(
        self, state: ArrayLike, acc: ArrayLike, gyr: ArrayLike, mag: ArrayLike | None = None, *, fs_hz: float,
    ) -> tuple[FloatArray, FloatArray]:
        """Advance ``state`` over one sample or a block; returns ``(q_earth_sensor, new_state)``.

        A block may lie wholly inside a gap of the accelerometer (all NaN): the state then predicts
        with the gyroscope only.
        """
        data = validate_imu(acc, gyr, mag, fs_hz=fs_hz, require_valid_acc=False)
        self._check_dimension(data.mag is not None)
        state_arr = np.array(state, dtype=np.float64)  # a copy: the caller's state is never mutated
        if state_arr.shape != (self.state_size,):
            raise ValueError(f"{self.name} state must have shape ({self.state_size},) (layout in the class "
                             f"docstring; make one with initial_state), got {state_arr.shape}")
        q, new_state = self._run_online(data, state_arr)
        return (q[0] if np.ndim(acc) == 1 else q), new_state

    # ---------------------------------------------------------------- helpers
    def _check_dimension(self, has_mag: bool) -> None:
        if has_mag and not self.supports_9d:
            raise ValueError(f"method {self.name!r} has no magnetometer (9D) variant; call it with mag=None")
        if not has_mag and not self.supports_6d:
            raise ValueError(f"method {self.name!r} needs a magnetometer: it has no 6D variant")

    def _initial_state_for(self, data: ImuInput, q0: ArrayLike | None, window_s: float = INIT_WINDOW_S) -> FloatArray:
        """The start state: aligned on the first ``window_s`` of data, or at ``q0`` when it is given.

        ``q0`` gives only the attitude.  What needs none, the accelerometer stage's gravity and start
        velocity and the method's own window-seeded parts (:meth:`_seed_from_window`: Guo's field references,
        ChakaMo's running mean and field reference), is still read from the window's motion-compensated data
        (read once), for every method: seeded from sample 0 alone, a heel strike there or the raw sample's body
        acceleration misled them (gait seeds 6–7, ``q0`` = truth, a 4 g strike on sample 0: Madgwick and both
        Valenti filters, heading RMS up to 46°; causal ChakaMo tilt up to 55°; test
        ``test_a_heel_strike_on_sample_0_with_q0_given``).
        """
        if q0 is None:
            alignment = initial_alignment(data, window_s=window_s, regression=self.align_by_regression)
            state = self._state_from_alignment(alignment, data)
        else:
            q = quat.normalize(quat.as_quaternion(q0))
            if q.shape != (4,):
                raise ValueError(f"q0 must be one quaternion of shape (4,), got {q.shape}")
            state = self._state_from_quaternion(q, data)
            alignment = (initial_alignment(data, window_s=window_s, regression=self.align_by_regression)
                         if self._lowpass_on or self.seeds_from_window else None)
        if alignment is not None:
            self._seed_from_window(state, alignment, data)
        if self._lowpass_on:  # the stage starts where the alignment window left it
            state[-acc_lowpass.SIZE:] = acc_lowpass.initial_block(
                alignment.acc_mean, self._lowpass_coefficients(data.fs_hz), alignment.velocity_start, data.dt_s)
        return state

    def _seed_from_window(self, state: FloatArray, alignment: Alignment, data: ImuInput) -> None:
        """Seed, in place, the parts of ``state`` that come from the alignment window and need no attitude,
        whether the start is aligned or given as ``q0``; here none (a method that has some sets
        ``seeds_from_window``)."""
        return None

    @property
    def _start_needs_rate(self) -> bool:
        """Whether the start state depends on ``fs_hz`` (the stage's coefficients, window-seeded parts)."""
        return self._lowpass_on or self.seeds_from_window

    @property
    def _lowpass_on(self) -> bool:
        return self.uses_acc_lowpass and self.params.acc_lowpass_s > 0.0

    def _lowpass_coefficients(self, fs_hz: float) -> FloatArray:
        return acc_lowpass.coefficients(float(self.params.acc_lowpass_s), fs_hz)

    def _filter(self, data: ImuInput, state0: FloatArray, *, reference: bool) -> tuple[FloatArray, FloatArray]:
        """The method's kernel (or its numpy reference) on the motion-compensated accelerometer when it uses one."""
        run = self._run_reference if reference else self._run
        if not self._lowpass_on or self.lowpass_in_kernel:
            return run(data, state0)
        state0 = np.asarray(state0, dtype=np.float64)
        lowpass = acc_lowpass.lowpass_reference if reference else acc_lowpass.lowpass_batch
        acc_f, block = lowpass(data.acc, data.gyr, data.acc_ok, data.dt_s, self._lowpass_coefficients(data.fs_hz),
                               np.ascontiguousarray(state0[-acc_lowpass.SIZE:]))
        q, state = run(replace(data, acc=acc_f), state0)
        state = np.array(state, dtype=np.float64)
        state[-acc_lowpass.SIZE:] = block
        return q, state

    def _state_from_alignment(self, alignment: Alignment, data: ImuInput) -> FloatArray:
        """A fresh state from the initial alignment; here :meth:`_state_from_quaternion` of its ``q``.

        A method whose state holds running means (ChakaMo) seeds them with the window's means.
        """
        return self._state_from_quaternion(alignment.q, data)

    def _state_from_quaternion(self, q: FloatArray, data: ImuInput) -> FloatArray:
        """A fresh state vector whose first four entries are ``q``; here the rest is zero."""
        state = np.zeros(self.state_size)
        state[:4] = q
        return state

    @abstractmethod
    def _run(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Compiled kernel: ``(q (N, 4), final state)``; must not modify ``state0``."""

    def _run_online(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        """What :meth:`update` runs: the causal kernel.  A method whose batch is non-causal overrides this."""
        return self._filter(data, state0, reference=False)

    @abstractmethod
    def _run_reference(self, data: ImuInput, state0: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Readable numpy implementation with the same results as :meth:`_run` (≤ 1e-9)."""
