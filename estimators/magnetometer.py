r"""Magnetometer calibration: ellipsoid fit, quality figures a clinician can read, norm gating.

Model (eq. 1)
-------------
.. math::  \mathbf m_{raw} = A\,\mathbf m_{true} + \mathbf b + \boldsymbol\varepsilon,
           \qquad \lVert\mathbf m_{true}\rVert = F

* ``b`` (µT): *hard iron* — fields of magnetised parts that turn with the sensor plus the sensor's
  zero offset (the thesis' :math:`B_{offset}`, seed 004 eq. 7.1);
* ``A`` (3×3): *soft iron* — induced fields, axis scale factors and cross-axis terms;
* ``F`` (µT): the local Earth field, constant while the sensor is turned (22.6 µT in Montevideo).

Turning the sensor sweeps :math:`\mathbf m_{true}` over a sphere, so the raw samples lie on the ellipsoid
:math:`(\mathbf m - \mathbf b)^\top (A A^\top)^{-1} (\mathbf m - \mathbf b) = F^2` (eq. 2).

Only :math:`AA^\top` is observable.  Write :math:`A = VU` (polar decomposition: :math:`V=(AA^\top)^{1/2}`
symmetric positive definite, :math:`U` a rotation): :math:`U\mathbf m_{true}` lies on the same sphere,
so :math:`U` cannot be told from a turn of the body and we take :math:`U = I` — the calibrated axes
are the sensor axes rotated by the smallest rotation the data allow (exactly the sensor axes when
``A`` is symmetric, the usual case).  Likewise only :math:`F\,V` is observable; we fix the scale by
:math:`\det V = 1` (soft iron neither creates nor removes volume, as in NXP AN4246), so ``field_ut``
is the field strength in the sensor's own scale.  The calibration (eq. 3) is

.. math::  \mathbf m_{cal} = W(\mathbf m_{raw} - \mathbf b),\qquad
           W = \texttt{soft\_iron} = \det(V)^{1/3}\,V^{-1}\ \text{(symmetric, } \det W = 1),

and :math:`\lVert\mathbf m_{cal}\rVert = ` ``field_ut`` for every sample of an undisturbed recording.
Orientation filters use only directions, so the scale convention does not affect them.

Fit
---
1. *Algebraic fit* (eq. 4).  With :math:`\mathbf u = (\mathbf m - \boldsymbol\mu)/s` (centred on the
   sample mean, which lies inside the ellipsoid, so the constant term can be fixed to −1), solve the
   9 coefficients of :math:`\mathbf u^\top M\mathbf u + 2\mathbf p^\top\mathbf u = 1` (``M``
   symmetric) by linear least squares.  The quadric is an ellipsoid iff ``M`` is positive definite;
   otherwise ``ValueError``.  Centre :math:`\mathbf c = -M^{-1}\mathbf p`,
   :math:`k = 1 + \mathbf p^\top M^{-1}\mathbf p`, so :math:`\mathbf b = \boldsymbol\mu + s\mathbf c`
   and :math:`Q = M/(k s^2)` in :math:`(\mathbf m-\mathbf b)^\top Q(\mathbf m-\mathbf b) = 1`.
2. *Shape* (eq. 5): :math:`T = Q^{1/2} = V^{-1}/F` by eigen-decomposition,
   ``field_ut`` :math:`= \det(T)^{-1/3}`, :math:`W = ` ``field_ut`` :math:`\cdot T`.
3. *Geometric refinement* (eq. 6): Levenberg–Marquardt (:func:`_levenberg_marquardt`, analytic
   Jacobian, scaled by its column norms as MINPACK's ``lmder``) on the relative norm error :math:`r_i = \lVert T(\mathbf m_i - \mathbf b)\rVert - 1`
   over ``b`` and the 6 entries of ``T``.  One pass then drops samples with
   :math:`|r_i| F > \max(5\sigma_{MAD}, 0.01F)` (a magnet or a steel table near the figure-eight)
   and refits.  ``model="sphere"`` fits ``b`` and :math:`T = I/F` only (hard iron, as the thesis
   did, §7.3): better conditioned on a poor recording, blind to soft iron.
4. *Offset standard error* (eq. 7): :math:`\operatorname{diag}(\hat\sigma^2 (J^\top J)^{-1})^{1/2}`
   at the solution (Gauss–Newton covariance, white noise assumed).

Quality and warnings
--------------------
:class:`MagQuality` holds field strength, RMS of the calibrated-norm residual (µT and % of the
field), *coverage* — the fraction of 20 equal cells of the sphere (the faces of an icosahedron)
holding ≥ 3 calibrated directions — and *direction spread* (3 × the smallest eigenvalue of the
covariance of the calibrated unit vectors: 1 for a uniform sphere, 0.25 for a hemisphere, 0 when
all directions lie on one cone or plane).  The thesis' subject calibration read 18.4 µT instead of
22.6 µT, by the thesis' own diagnosis because the figure-eight left whole regions empty (seed 004
§8.7.1): ``MAG_COVERAGE_LOW`` catches that.  Other codes: ``MAG_RESIDUAL_HIGH``, ``MAG_FIELD_IMPLAUSIBLE`` (outside 20–70 µT),
``MAG_FIELD_MISMATCH`` (vs ``expected_field_ut``), ``MAG_OFFSET_UNCERTAIN``, ``MAG_SOFT_IRON_LARGE``,
``MAG_DISTURBED`` (many rejected samples), ``MAG_FEW_SAMPLES``.  ``quality.reliable`` is False
whenever any warning fired.

Bad and degenerate recordings (``ValueError``, never a silent answer)
--------------------------------------------------------------------
Wrong shapes, ±inf values, fewer than ``min_samples`` (50) finite rows; a sensor that hardly moved
(largest principal spread of the samples < 2 µT); a *planar* recording (turned about one axis only:
thinnest principal spread < 5 % of the largest — a circle fits infinitely many ellipsoids); a fit
that is not an ellipsoid; a fit whose calibrated directions fill less than a ~40° cap (direction
spread < 0.01 — the 9-parameter fit then collapses to a huge flat ellipsoid; the sphere model still
works on caps of ~45°).  Rows holding NaN are dropped and counted (``quality.n_dropped_nan``).
Recordings between these and a good figure-eight (little rotation, one hemisphere) give a fit that
carries warnings and ``reliable == False``.

Norm gating (seed 004 §7.3)
---------------------------
The thesis accepted a calibrated sample only if its norm stayed within ±0.5 µT of the mean norm,
otherwise the previous accepted sample was repeated; :func:`gate_norm` does exactly that, separately
from the fit.  With MEMS noise of ~0.3 µT per axis a ±0.5 µT band replaces a noticeable share of
good samples: check ``replaced.mean()``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.quality import QualityWarning

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

MIN_SAMPLES = 50  # fewer finite rows than this: ValueError
FEW_SAMPLES = 200  # fewer used samples than this: MAG_FEW_SAMPLES (60 s at 20 Hz gives 1200)
EARTH_FIELD_UT = (20.0, 70.0)  # plausible range of the Earth's field strength, µT
RESIDUAL_WARN_PCT = 3.0  # calibrated-norm RMS residual above this % of the field: MAG_RESIDUAL_HIGH
COVERAGE_WARN = 0.75  # fewer than 15 of the 20 direction cells reached: MAG_COVERAGE_LOW
SPREAD_WARN = 0.3  # direction spread below this (hemisphere: 0.25): MAG_COVERAGE_LOW
OFFSET_SD_WARN_UT = 0.5  # offset standard error above this: MAG_OFFSET_UNCERTAIN
SOFT_IRON_WARN = 0.25  # largest/smallest soft-iron axis − 1 above this: MAG_SOFT_IRON_LARGE
DISTURBED_WARN = 0.05  # share of rejected samples above this: MAG_DISTURBED
FIELD_MISMATCH_WARN = 0.10  # relative difference to expected_field_ut above this: MAG_FIELD_MISMATCH
MIN_CELL_SAMPLES = 3  # a direction cell counts as reached with at least this many samples
STATIC_SPREAD_UT = 2.0  # largest principal spread below this: the sensor did not turn (ValueError)
PLANAR_RATIO = 0.05  # thinnest / largest principal spread below this: planar recording (ValueError)
HOPELESS_SPREAD = 0.01  # fitted direction spread below this (a cap of < ~40°): ValueError

_PHI = (1.0 + 5.0**0.5) / 2.0
# Cell centres: the 20 vertices of a dodecahedron = face centres of an icosahedron (equal-area cells).
_CELLS = np.array(
    [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    + [v for a in (-1 / _PHI, 1 / _PHI) for c in (-_PHI, _PHI) for v in ((0, a, c), (a, c, 0), (c, 0, a))],
    dtype=float,
) / np.sqrt(3.0)
_SYM_I, _SYM_J = np.array([0, 1, 2, 1, 0, 0]), np.array([0, 1, 2, 2, 2, 1])  # 6 entries of a symmetric 3×3
_SHAPE_MAP = {"ellipsoid": np.eye(6), "sphere": np.array([[1.0], [1.0], [1.0], [0.0], [0.0], [0.0]])}


@dataclass(frozen=True)
class MagQuality:
    """Quality figures of one calibration recording (units in the names; fractions in 0..1)."""

    field_ut: float  # fitted local field strength, µT (sensor scale, det(soft_iron) = 1)
    residual_rms_ut: float  # RMS of |m_cal| − field_ut over the samples used, µT
    residual_pct: float  # the same in % of field_ut
    coverage_fraction: float  # share of the 20 equal sphere cells reached by calibrated directions
    coverage_cells: int  # number of those cells reached (≥ MIN_CELL_SAMPLES samples)
    direction_spread: float  # 3 × smallest eigenvalue of the direction covariance: 1 sphere, 0 plane
    offset_sd_ut: float  # largest standard error of the three offset components, µT
    n_samples: int  # samples used by the final fit
    n_dropped_nan: int  # rows dropped because they held NaN
    n_outliers: int  # samples rejected as magnetic disturbances
    warnings: tuple[QualityWarning, ...] = ()

    @property
    def reliable(self) -> bool:
        """True when no warning fired."""
        return not self.warnings

    @property
    def codes(self) -> tuple[str, ...]:
        return tuple(w.code for w in self.warnings)


@dataclass(frozen=True)
class MagCalibration:
    """Result of :func:`fit_ellipsoid`: ``m_cal = soft_iron @ (m_raw − offset_ut)`` (eq. 3)."""

    offset_ut: FloatArray  # (3,) hard iron b, µT
    soft_iron: FloatArray  # (3, 3) symmetric W, det 1
    field_ut: float  # |m_cal| of an undisturbed sample, µT
    model: str  # "ellipsoid" or "sphere"
    quality: MagQuality

    def __post_init__(self) -> None:
        for name in ("offset_ut", "soft_iron"):
            arr = np.array(getattr(self, name), dtype=np.float64)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def residual_rms_ut(self) -> float:
        return self.quality.residual_rms_ut

    @property
    def coverage_fraction(self) -> float:
        return self.quality.coverage_fraction

    def apply(self, mag: ArrayLike) -> FloatArray:
        """Calibrate raw samples ``(N, 3)`` or ``(3,)`` in µT (eq. 3); NaN rows stay NaN."""
        arr = _as_mag(mag, allow_vector=True)
        return (arr - self.offset_ut) @ self.soft_iron.T

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values (``results.json`` → calibration → magnetometer)."""
        quality = asdict(self.quality)
        quality["reliable"] = self.quality.reliable
        return {"model": self.model, "offset_ut": self.offset_ut.tolist(),
                "soft_iron": self.soft_iron.tolist(), "field_ut": self.field_ut, "quality": quality}


def fit_ellipsoid(mag: ArrayLike, *, model: str = "ellipsoid", expected_field_ut: float | None = None,
                  min_samples: int = MIN_SAMPLES) -> MagCalibration:
    """Fit hard and soft iron to a figure-eight recording (module docstring, eqs. 1–7).

    Args:
        mag: ``(N, 3)`` raw magnetometer samples, µT; rows holding NaN are dropped and counted.
        model: ``"ellipsoid"`` (hard + symmetric soft iron, 9 parameters) or ``"sphere"`` (hard iron
            and field strength only, 4 parameters).
        expected_field_ut: the local field strength (e.g. from a geomagnetic model), µT; when given,
            a fitted field differing by more than 10 % raises the ``MAG_FIELD_MISMATCH`` warning.
        min_samples: fewest finite rows accepted (≥ 10).

    Raises:
        ValueError: bad shape, ±inf, too few samples, a static or planar recording, no ellipsoid.
    """
    if model not in _SHAPE_MAP:
        raise ValueError(f"model must be one of {sorted(_SHAPE_MAP)}, got {model!r}")
    if expected_field_ut is not None and not (np.isfinite(expected_field_ut) and expected_field_ut > 0):
        raise ValueError(f"expected_field_ut must be finite and > 0 µT (or None), got {expected_field_ut!r}")
    if int(min_samples) < 10:
        raise ValueError(f"min_samples must be ≥ 10, got {min_samples!r}")
    raw = _as_mag(mag)
    nan_rows = np.isnan(raw).any(axis=1)
    x = raw[~nan_rows]
    if x.shape[0] < min_samples:
        raise ValueError(
            f"mag has {x.shape[0]} finite samples ({int(nan_rows.sum())} NaN rows dropped); at least "
            f"{min_samples} are needed: record the figure-eight for ~60 s"
        )
    _check_not_degenerate(x)
    shape_map = _SHAPE_MAP[model]
    params = _refine(_algebraic_fit(x, model), x, shape_map)
    keep = np.ones(x.shape[0], dtype=bool)  # one rejection pass of disturbed samples (Fit, step 3)
    field = float(np.linalg.det(_positive_shape(params, shape_map)) ** (-1.0 / 3.0))
    r_ut = _residual(params, x, shape_map) * field
    sigma = 1.4826 * np.median(np.abs(r_ut - np.median(r_ut)))
    outlier = np.abs(r_ut) > max(5.0 * sigma, 0.01 * field)
    if outlier.any() and (~outlier).sum() >= min_samples:
        keep = ~outlier
        params = _refine(params, x[keep], shape_map)
    return _calibration(params, x[keep], shape_map, model, int(nan_rows.sum()), int((~keep).sum()),
                        expected_field_ut)


def gate_norm(mag_cal: ArrayLike, tolerance_ut: float = 0.5, *,
              reference_ut: float | None = None) -> tuple[FloatArray, BoolArray]:
    """Seed 004 §7.3: replace calibrated samples whose norm leaves ``reference ± tolerance``.

    A replaced sample takes the value of the last accepted sample before it; samples before the
    first accepted one become NaN (missing: the filters skip their correction).  NaN rows stay NaN
    and are not counted as replaced.

    Args:
        mag_cal: ``(N, 3)`` calibrated samples, µT (the output of :meth:`MagCalibration.apply`).
        tolerance_ut: half-width of the accepted band, µT (thesis: 0.5).
        reference_ut: centre of the band, µT; default the mean norm of the finite samples (thesis);
            ``calibration.field_ut`` is the robust choice when many samples are disturbed.

    Returns:
        ``(gated (N, 3), replaced (N,) bool)``.
    """
    x = _as_mag(mag_cal)
    if not (np.isfinite(tolerance_ut) and tolerance_ut > 0):
        raise ValueError(f"tolerance_ut must be finite and > 0 µT, got {tolerance_ut!r}")
    norms = np.linalg.norm(x, axis=1)
    finite = np.isfinite(norms)
    if reference_ut is None:
        if not finite.any():
            raise ValueError("mag_cal has no finite sample: nothing to gate")
        reference_ut = float(norms[finite].mean())
    elif not (np.isfinite(reference_ut) and reference_ut > 0):
        raise ValueError(f"reference_ut must be finite and > 0 µT (or None), got {reference_ut!r}")
    replaced = finite & (np.abs(norms - reference_ut) > tolerance_ut)
    good = finite & ~replaced
    last_good = np.maximum.accumulate(np.where(good, np.arange(x.shape[0]), -1))
    gated = x.copy()
    has_prev = replaced & (last_good >= 0)
    gated[has_prev] = x[last_good[has_prev]]
    gated[replaced & (last_good < 0)] = np.nan
    return gated, replaced


# --- internals -------------------------------------------------------------------------------------


def _as_mag(mag: ArrayLike, *, allow_vector: bool = False) -> FloatArray:
    try:
        arr = np.asarray(mag, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"mag must be a numeric array of shape (N, 3) in µT: {exc}") from None
    if not (arr.ndim == 2 and arr.shape[1] == 3) and not (allow_vector and arr.shape == (3,)):
        raise ValueError(f"mag must have shape (N, 3) (x, y, z in µT, time along axis 0), got {arr.shape}")
    if np.isinf(arr).any():
        row = int(np.flatnonzero(np.isinf(arr.reshape(-1, 3)).any(axis=1))[0])
        raise ValueError(f"mag holds an infinite value at sample {row}: corrupted data (mark gaps with NaN)")
    return arr


def _check_not_degenerate(x: FloatArray) -> None:
    centred = x - x.mean(axis=0)
    spread = np.sqrt(np.maximum(np.linalg.eigvalsh(centred.T @ centred / x.shape[0]), 0.0))
    if spread[2] < STATIC_SPREAD_UT:
        raise ValueError(
            f"the sensor hardly turned: the samples spread only {spread[2]:.2f} µT; the figure-eight must "
            "turn the sensor through all orientations (also upside down)"
        )
    if spread[0] < PLANAR_RATIO * spread[2]:
        raise ValueError(
            f"the samples lie in a plane ({spread[0]:.2f} µT thick, {spread[2]:.1f} µT wide): the sensor was "
            "turned about one axis only, which fits infinitely many ellipsoids; repeat the figure-eight "
            "tilting the sensor in every direction"
        )


def _algebraic_fit(x: FloatArray, model: str) -> FloatArray:
    """Eqs. 4–5: parameters ``[b, T]`` (T = Q^½ as 6 entries, or 1/F for a sphere) from a linear quadric."""
    mu = x.mean(axis=0)
    s = float(np.sqrt(np.mean(np.sum((x - mu) ** 2, axis=1))))
    u = (x - mu) / s
    if model == "sphere":  # |u|² = 2 cᵀu + (r² − |c|²)
        design = np.column_stack([2.0 * u, np.ones(u.shape[0])])
        sol = np.linalg.lstsq(design, np.sum(u**2, axis=1), rcond=None)[0]
        centre = sol[:3]
        radius = np.sqrt(max(sol[3] + centre @ centre, np.finfo(float).tiny))
        return np.concatenate([mu + s * centre, [1.0 / (s * radius)]])
    design = np.hstack([u[:, _SYM_I] * u[:, _SYM_J] * [1, 1, 1, 2, 2, 2], 2.0 * u])
    th = np.linalg.lstsq(design, np.ones(u.shape[0]), rcond=None)[0]
    m_mat = _vec_to_sym(th[:6])
    evals, evecs = np.linalg.eigh(m_mat)
    if evals[0] <= 1e-9 * abs(evals[-1]):
        raise ValueError(
            "the magnetometer samples do not lie on an ellipsoid (the least-squares quadric is not closed): "
            "poor coverage of directions or a magnetic disturbance during the figure-eight; record it again "
            "away from metal, turning the sensor through all orientations"
        )
    centre = -np.linalg.solve(m_mat, th[6:])
    k = 1.0 + th[6:] @ (-centre)
    t_mat = (evecs * np.sqrt(evals / (k * s * s))) @ evecs.T
    return np.concatenate([mu + s * centre, t_mat[_SYM_I, _SYM_J]])


def _vec_to_sym(v: FloatArray) -> FloatArray:
    """(t00, t11, t22, t12, t02, t01) → symmetric 3×3."""
    return np.array([[v[0], v[5], v[4]], [v[5], v[1], v[3]], [v[4], v[3], v[2]]])


def _unpack(params: FloatArray, shape_map: FloatArray) -> tuple[FloatArray, FloatArray]:
    return params[:3], _vec_to_sym(shape_map @ params[3:])


def _residual(params: FloatArray, x: FloatArray, shape_map: FloatArray) -> FloatArray:
    """Eq. 6: r_i = |T (m_i − b)| − 1 (T symmetric)."""
    offset, t_mat = _unpack(params, shape_map)
    return np.linalg.norm((x - offset) @ t_mat, axis=1) - 1.0


def _jacobian(params: FloatArray, x: FloatArray, shape_map: FloatArray) -> FloatArray:
    offset, t_mat = _unpack(params, shape_map)
    d = x - offset
    y = d @ t_mat
    n = np.linalg.norm(y, axis=1)[:, None]
    d_offset = -(y @ t_mat) / n
    # d|y|/dT_jk = (y_j d_k + y_k d_j)/|y| for an off-diagonal pair, y_j d_j/|y| on the diagonal
    d_sym = (y[:, _SYM_I] * d[:, _SYM_J] + y[:, _SYM_J] * d[:, _SYM_I]) * [0.5, 0.5, 0.5, 1, 1, 1] / n
    return np.hstack([d_offset, d_sym @ shape_map])


def _refine(params: FloatArray, x: FloatArray, shape_map: FloatArray) -> FloatArray:
    return _levenberg_marquardt(lambda p: _residual(p, x, shape_map), lambda p: _jacobian(p, x, shape_map), params)


LM_MAX_ITERATIONS = 100
LM_TOLERANCE = 1e-12


def _levenberg_marquardt(residual: Any, jacobian: Any, x0: FloatArray, max_iterations: int = LM_MAX_ITERATIONS,
                         tol: float = LM_TOLERANCE) -> FloatArray:
    r"""Minimise :math:`\tfrac12\lVert r(x)\rVert^2` by Levenberg–Marquardt (Moré 1978; Nielsen's damping update).

    Each step solves the damped normal equations as the least-squares problem
    :math:`\min_\delta \lVert J\delta + r\rVert^2 + \lambda\lVert D\delta\rVert^2` (stacked, by ``lstsq``: no
    squaring of J's condition number), with :math:`D = \operatorname{diag}` of the largest column norms of *J* seen
    so far (scale invariance, MINPACK's ``mode=1``).  The gain ratio
    :math:`\rho = (\lVert r\rVert^2 - \lVert r(x+\delta)\rVert^2) / (\lVert r\rVert^2 - \lVert J\delta + r\rVert^2)`
    accepts the step when positive and scales :math:`\lambda` by :math:`\max(1/3, 1 - (2\rho - 1)^3)`, else
    multiplies it by :math:`\nu` (doubling each time).  Stops when the scaled step or the relative decrease of
    the cost falls below ``tol``, or the gradient :math:`J^\top r` vanishes.  Started from the algebraic fit the
    problem is nearly linear and converges in a handful of steps, to machine precision.
    """
    x = np.array(x0, dtype=np.float64)
    r = residual(x)
    cost = float(r @ r)
    jac = jacobian(x)
    scale = np.linalg.norm(jac, axis=0)
    scale[scale == 0.0] = 1.0
    lam = 1e-3  # relative to the scaled Gauss–Newton matrix: start close to a Gauss–Newton step
    nu = 2.0
    for _ in range(max_iterations):
        grad = jac.T @ r
        if np.max(np.abs(grad)) <= tol * max(cost, np.finfo(float).tiny) ** 0.5 * np.max(scale):
            break
        stacked = np.vstack([jac, np.sqrt(lam) * np.diag(scale)])
        step = np.linalg.lstsq(stacked, -np.concatenate([r, np.zeros(x.size)]), rcond=None)[0]
        predicted = cost - float(np.sum((jac @ step + r) ** 2))
        x_new = x + step
        r_new = residual(x_new)
        cost_new = float(r_new @ r_new)
        rho = (cost - cost_new) / predicted if predicted > 0.0 else -1.0
        small_step = np.linalg.norm(scale * step) <= tol * (np.linalg.norm(scale * x) + tol)
        if rho > 0.0:
            converged = small_step or (cost - cost_new) <= tol * cost
            x, r, cost = x_new, r_new, cost_new
            jac = jacobian(x)
            scale = np.maximum(scale, np.linalg.norm(jac, axis=0))
            lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            if converged:
                break
        else:
            if small_step:
                break
            lam *= nu
            nu *= 2.0
    return x


def _positive_shape(params: FloatArray, shape_map: FloatArray) -> FloatArray:
    """|T d| depends on T² only: return the positive-definite T (eigenvalues' absolute values)."""
    evals, evecs = np.linalg.eigh(_unpack(params, shape_map)[1])
    evals = np.abs(evals)
    if evals[0] <= 1e-9 * evals[-1]:
        raise ValueError("the refined fit collapsed (a flat ellipsoid): the recording does not constrain the field")
    return (evecs * evals) @ evecs.T


def _calibration(params: FloatArray, x: FloatArray, shape_map: FloatArray, model: str, n_nan: int,
                 n_outliers: int, expected_field_ut: float | None) -> MagCalibration:
    offset = params[:3].copy()
    t_mat = _positive_shape(params, shape_map)
    field = float(np.linalg.det(t_mat) ** (-1.0 / 3.0))
    soft_iron = field * t_mat if model == "ellipsoid" else np.eye(3)
    m_cal = (x - offset) @ soft_iron  # eq. 3 (soft_iron symmetric)
    norms = np.linalg.norm(m_cal, axis=1)
    rms = float(np.sqrt(np.mean((norms - field) ** 2)))
    unit = m_cal / norms[:, None]
    counts = np.bincount(np.argmax(unit @ _CELLS.T, axis=1), minlength=_CELLS.shape[0])
    cells = int(np.sum(counts >= MIN_CELL_SAMPLES))
    spread = float(3.0 * np.linalg.eigvalsh(np.cov(unit.T, bias=True))[0])
    if spread < HOPELESS_SPREAD:
        raise ValueError(
            f"the recording covers too few directions to calibrate (spread {spread:.3f}; 1 = all directions): "
            "the fit is meaningless. Repeat the figure-eight turning the sensor through all orientations"
            + ("; if it cannot be turned more, model='sphere' (hard iron only) needs less coverage"
               if model == "ellipsoid" else "")
        )
    jac = _jacobian(params, x, shape_map)  # eq. 7: Gauss–Newton covariance of the offset
    dof = max(x.shape[0] - params.size, 1)
    sigma2 = float(np.sum(_residual(params, x, shape_map) ** 2) / dof)
    try:
        offset_sd = float(np.sqrt(np.max(np.diag(np.linalg.inv(jac.T @ jac))[:3] * sigma2)))
    except np.linalg.LinAlgError:
        offset_sd = float("inf")
    axes = np.linalg.eigvalsh(soft_iron)
    quality = MagQuality(
        field_ut=field, residual_rms_ut=rms, residual_pct=100.0 * rms / field,
        coverage_fraction=cells / _CELLS.shape[0], coverage_cells=cells, direction_spread=spread,
        offset_sd_ut=offset_sd, n_samples=int(x.shape[0]), n_dropped_nan=n_nan, n_outliers=n_outliers,
    )
    warnings = _warnings(quality, float(axes[-1] / axes[0] - 1.0), expected_field_ut)
    return MagCalibration(offset_ut=offset, soft_iron=soft_iron, field_ut=field, model=model,
                          quality=replace(quality, warnings=warnings))


def _warnings(q: MagQuality, anisotropy: float, expected_field_ut: float | None) -> tuple[QualityWarning, ...]:
    """The fired checks as warnings; ``params`` carry the message's values unrounded, named as the fields
    of ``reports/translations_warnings.json``."""
    lo, hi = EARTH_FIELD_UT
    expected = 0.0 if expected_field_ut is None else float(expected_field_ut)
    checks = [
        (q.coverage_fraction < COVERAGE_WARN or q.direction_spread < SPREAD_WARN, "MAG_COVERAGE_LOW",
         f"The figure-eight reached {q.coverage_cells} of 20 regions of directions (spread {q.direction_spread:.2f}, "
         "1 = all directions): offset and field strength may be wrong. Repeat it turning the sensor through all "
         "orientations, also upside down.",
         {"cells": q.coverage_cells, "spread": q.direction_spread}),
        (q.residual_pct > RESIDUAL_WARN_PCT, "MAG_RESIDUAL_HIGH",
         f"After calibration the field strength still varies by {q.residual_rms_ut:.2f} µT RMS "
         f"({q.residual_pct:.1f} %): metal or a moving magnet nearby; repeat away from metal.",
         {"residual_ut": q.residual_rms_ut, "residual_pct": q.residual_pct}),
        (not lo <= q.field_ut <= hi, "MAG_FIELD_IMPLAUSIBLE",
         f"The fitted field strength is {q.field_ut:.1f} µT; the Earth's field is {lo:.0f}–{hi:.0f} µT. "
         "Check the units of the recording, its coverage and nearby metal.",
         {"field_ut": q.field_ut, "lo_ut": lo, "hi_ut": hi}),
        (expected_field_ut is not None and abs(q.field_ut / expected_field_ut - 1.0) > FIELD_MISMATCH_WARN,
         "MAG_FIELD_MISMATCH",
         f"The fitted field strength is {q.field_ut:.1f} µT, the local field {expected:.1f} µT.",
         {"field_ut": q.field_ut, "expected_ut": expected}),
        (q.offset_sd_ut > OFFSET_SD_WARN_UT, "MAG_OFFSET_UNCERTAIN",
         f"The offset is uncertain by ±{q.offset_sd_ut:.2f} µT: the recording constrains it poorly.",
         {"offset_sd_ut": q.offset_sd_ut}),
        (anisotropy > SOFT_IRON_WARN, "MAG_SOFT_IRON_LARGE",
         f"The axes' sensitivities differ by {100 * anisotropy:.0f} %, unusual for the sensor alone: "
         "metal fixed near it or poor coverage.",
         {"anisotropy_pct": 100.0 * anisotropy}),
        (q.n_outliers > DISTURBED_WARN * (q.n_samples + q.n_outliers), "MAG_DISTURBED",
         f"{q.n_outliers} samples were rejected as magnetic disturbances: keep metal away while recording.",
         {"n_outliers": q.n_outliers}),
        (q.n_samples < FEW_SAMPLES, "MAG_FEW_SAMPLES",
         f"Only {q.n_samples} samples were used: record the figure-eight for ~60 s.",
         {"n_samples": q.n_samples}),
    ]
    return tuple(QualityWarning(code, message, params) for fired, code, message, params in checks if fired)
