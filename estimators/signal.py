r"""The few digital filters the estimators need, without ``scipy.signal`` (whose import costs ~1 s).

``scipy.signal`` parses thousands of docstrings and pulls in ``scipy.stats`` at import; ChakaMo uses five of its
functions.  This module gives them with the same numbers (the tests use scipy as the oracle, to ~1e-12) and an
import that costs only numpy.  The recursions are compiled with numba on first use (``cache=True``), so importing
this module does not import numba either.

Everything filters along ``axis`` (default 0, time along axis 0 as in DESIGN §3); other axes are channels.

Butterworth low-pass, 2nd order (:func:`butter_lowpass`, :func:`butter_lowpass_sos`)
------------------------------------------------------------------------------------
The analog prototype :math:`H(s) = \Omega^2 / (s^2 + \sqrt2\,\Omega s + \Omega^2)` is mapped to the z-plane by
the bilinear transform :math:`s = 2 f_s (1 - z^{-1}) / (1 + z^{-1})`, with the cut-off prewarped,
:math:`\Omega = 2 f_s \tan(\pi f_c / f_s)`, so that the digital filter is exactly −3 dB at :math:`f_c`.
With :math:`K = \tan(\pi f_c / f_s)` and :math:`D = 1 + \sqrt2 K + K^2`,

.. math::
    b = \frac{K^2}{D}\,(1, 2, 1), \qquad a = \Bigl(1,\ \frac{2(K^2 - 1)}{D},\ \frac{1 - \sqrt2 K + K^2}{D}\Bigr),

which is what ``scipy.signal.butter(2, fc_hz, fs=fs_hz)`` returns (its zeros at :math:`z=-1`, poles from the
prototype's :math:`\Omega e^{\pm j3\pi/4}`).  The second-order-sections form is the single row
``[b0, b1, b2, 1, a1, a2]``.

Linear recursion (:func:`lfilter`, :func:`sosfilt`)
-----------------------------------------------------
:math:`a_0 y[n] = \sum_{k=0}^{M} b_k x[n-k] - \sum_{k=1}^{M} a_k y[n-k]`, computed in the transposed direct
form II with the state :math:`z \in \mathbb R^{M}` (coefficients divided by :math:`a_0`):

.. math::
    y[n] = b_0 x[n] + z_0, \qquad z_{i} \leftarrow b_{i+1} x[n] - a_{i+1} y[n] + z_{i+1}\ (z_M = 0).

``sosfilt`` runs one such 2nd-order recursion per section, the output of one feeding the next.

Steady-state initial conditions (:func:`lfilter_zi`, :func:`sosfilt_zi`)
------------------------------------------------------------------------
The state :math:`z_\infty` left by a unit step held forever solves :math:`z = A^\top z + B` with the
companion matrix :math:`A` of :math:`a` (first row :math:`-a_{1..M}`, ones below the diagonal) and
:math:`B_i = b_{i+1} - a_{i+1} b_0`, i.e. :math:`(I - A^\top) z_\infty = B`.  Starting a recursion at
:math:`x_0 z_\infty` removes the start-up transient of a signal that begins at :math:`x_0`.  For sections,
section *s* sees the step scaled by the DC gains :math:`\prod_{r<s} \sum b_r / \sum a_r` of those before it.

Zero-phase filtering (:func:`filtfilt`, :func:`sosfiltfilt`)
------------------------------------------------------------
The signal is extended at both ends by its odd reflection about the end samples,
:math:`x[-k] = 2x[0] - x[k]` and :math:`x[N-1+k] = 2x[N-1] - x[N-1-k]` for :math:`k = 1..p` (``padlen`` *p*),
filtered forward from :math:`x_{ext}[0]\,z_\infty`, then backward (time reversed) from
:math:`y[\text{end}]\,z_\infty`, and the padding is cut off.  The result has zero phase and the squared
magnitude response.  Default ``padlen`` as scipy: :math:`3\max(\mathrm{len}(a), \mathrm{len}(b))` for ``ba``,
:math:`3(2S + 1 - \min(\#\{b_{s,2}=0\}, \#\{a_{s,2}=0\}))` for *S* sections.

Savitzky–Golay derivative (:func:`savgol_derivative`)
-----------------------------------------------------
Within a window of :math:`L = 2h + 1` samples at offsets :math:`u = -h..h`, the least-squares polynomial of
degree *p* has coefficients :math:`c = V^+ x` (Vandermonde :math:`V_{ki} = u_k^{\,i}`, pseudo-inverse
:math:`V^+`).  Its *d*-th derivative at offset *u* is a fixed linear combination of the window,
:math:`\sum_i c_i\, i!/(i-d)!\; u^{i-d} / \Delta^d`; the rows of :math:`E V^+` (one row per evaluation offset)
are those weights.  Interior samples use the centre row; the first and last *h* samples use the rows of their
own offsets applied to the first and last full window (scipy's ``mode="interp"``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "butter_lowpass",
    "butter_lowpass_sos",
    "filtfilt",
    "lfilter",
    "lfilter_zi",
    "savgol_derivative",
    "sosfilt",
    "sosfilt_zi",
    "sosfiltfilt",
]


# --------------------------------------------------------------------------- design

def butter_lowpass(cutoff_hz: float, fs_hz: float) -> tuple[FloatArray, FloatArray]:
    """2nd-order Butterworth low-pass ``(b (3,), a (3,))``, ``a[0] == 1``; as ``scipy.signal.butter(2, cutoff_hz, fs=fs_hz)``.

    ``cutoff_hz`` must lie strictly between 0 and the Nyquist frequency ``fs_hz / 2``.
    """
    if not (fs_hz > 0.0 and 0.0 < cutoff_hz < 0.5 * fs_hz):
        raise ValueError(f"cutoff_hz must lie strictly between 0 and fs_hz / 2 = {0.5 * fs_hz} Hz, got {cutoff_hz} Hz")
    k = math.tan(math.pi * cutoff_hz / fs_hz)
    k2 = k * k
    d = 1.0 + math.sqrt(2.0) * k + k2
    b0 = k2 / d
    b = np.array([b0, 2.0 * b0, b0])
    a = np.array([1.0, 2.0 * (k2 - 1.0) / d, (1.0 - math.sqrt(2.0) * k + k2) / d])
    return b, a


def butter_lowpass_sos(cutoff_hz: float, fs_hz: float) -> FloatArray:
    """The same filter as one second-order section ``(1, 6)``: ``[[b0, b1, b2, 1, a1, a2]]``."""
    b, a = butter_lowpass(cutoff_hz, fs_hz)
    return np.concatenate([b, a])[None, :]


# --------------------------------------------------------------------------- recursion kernels
# Plain Python on 2-D float64 arrays (time, channel); compiled with numba on first use.  The plain functions are
# the readable reference the tests compare the compiled ones with.

def _lfilter_kernel(b: FloatArray, a: FloatArray, x: FloatArray, zi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Transposed direct form II; ``b``, ``a`` of equal length ``M + 1`` with ``a[0] == 1``; ``zi`` ``(M, C)``."""
    n, c = x.shape
    m = b.shape[0] - 1
    y = np.empty((n, c))
    z = zi.copy()
    for j in range(c):
        for t in range(n):
            xt = x[t, j]
            yt = b[0] * xt + (z[0, j] if m > 0 else 0.0)
            for i in range(m - 1):
                z[i, j] = b[i + 1] * xt - a[i + 1] * yt + z[i + 1, j]
            if m > 0:
                z[m - 1, j] = b[m] * xt - a[m] * yt
            y[t, j] = yt
    return y, z


def _sosfilt_kernel(sos: FloatArray, x: FloatArray, zi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Cascade of transposed direct form II sections; ``sos`` ``(S, 6)`` with ``a0 == 1``; ``zi`` ``(S, 2, C)``."""
    n, c = x.shape
    s_count = sos.shape[0]
    y = np.empty((n, c))
    z = zi.copy()
    for j in range(c):
        for t in range(n):
            xc = x[t, j]
            for s in range(s_count):
                xn = sos[s, 0] * xc + z[s, 0, j]
                z[s, 0, j] = sos[s, 1] * xc - sos[s, 4] * xn + z[s, 1, j]
                z[s, 1, j] = sos[s, 2] * xc - sos[s, 5] * xn
                xc = xn
            y[t, j] = xc
    return y, z


_COMPILED: dict[str, Callable[..., Any]] = {}


def _compiled(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` compiled with numba (imported here, on the first filter call, not at import of this module)."""
    jit = _COMPILED.get(fn.__name__)
    if jit is None:
        import numba

        jit = _COMPILED[fn.__name__] = numba.njit(cache=True, nogil=True)(fn)
    return jit


# --------------------------------------------------------------------------- helpers

def _as_float(x: ArrayLike) -> FloatArray:
    return np.asarray(x, dtype=np.float64)


def _to_2d(x: FloatArray, axis: int) -> tuple[FloatArray, tuple[int, ...]]:
    """``x`` with ``axis`` moved first and the other axes flattened into channels, C-contiguous."""
    moved = np.moveaxis(x, axis, 0)
    return np.ascontiguousarray(moved.reshape(moved.shape[0], -1)), moved.shape


def _from_2d(y: FloatArray, moved_shape: tuple[int, ...], axis: int) -> FloatArray:
    return np.moveaxis(y.reshape(moved_shape), 0, axis)


def _normalised_ba(b: ArrayLike, a: ArrayLike) -> tuple[FloatArray, FloatArray]:
    b = np.atleast_1d(_as_float(b))
    a = np.atleast_1d(_as_float(a))
    if b.ndim != 1 or a.ndim != 1 or b.size == 0 or a.size == 0 or a[0] == 0.0:
        raise ValueError("b and a must be non-empty 1-D coefficient arrays with a[0] != 0")
    m = max(b.size, a.size)
    b = np.concatenate([b, np.zeros(m - b.size)]) / a[0]
    a = np.concatenate([a, np.zeros(m - a.size)]) / a[0]
    return b, a


def _checked_sos(sos: ArrayLike) -> FloatArray:
    sos = np.atleast_2d(_as_float(sos))
    if sos.ndim != 2 or sos.shape[1] != 6 or sos.shape[0] == 0:
        raise ValueError(f"sos must have shape (n_sections, 6), got {sos.shape}")
    if not np.all(sos[:, 3] == 1.0):
        sos = sos.copy()
        sos[:, :3] /= sos[:, 3:4]
        sos[:, 3:] /= sos[:, 3:4]
    return sos


# --------------------------------------------------------------------------- filters

def lfilter_zi(b: ArrayLike, a: ArrayLike) -> FloatArray:
    """Steady-state state ``(M,)`` of :func:`lfilter` for a unit step: solves :math:`(I - A^T) z = B` (module docs)."""
    b, a = _normalised_ba(b, a)
    m = b.size - 1
    if m == 0:
        return np.zeros(0)
    companion = np.zeros((m, m))
    companion[0, :] = -a[1:]
    companion[1:, :-1] += np.eye(m - 1)
    rhs = b[1:] - a[1:] * b[0]
    return np.linalg.solve(np.eye(m) - companion.T, rhs)


def lfilter(b: ArrayLike, a: ArrayLike, x: ArrayLike, axis: int = 0, zi: ArrayLike | None = None
            ) -> FloatArray | tuple[FloatArray, FloatArray]:
    """IIR/FIR filter ``y`` along ``axis`` (transposed direct form II), as ``scipy.signal.lfilter``.

    ``zi`` (optional) is the initial state, shape ``x.shape`` with ``axis`` of length ``max(len(a), len(b)) - 1``;
    with it the final state is returned too, ``(y, zf)``.
    """
    b, a = _normalised_ba(b, a)
    x = _as_float(x)
    axis = axis % x.ndim
    x2, moved_shape = _to_2d(x, axis)
    m = b.size - 1
    if zi is None:
        z0 = np.zeros((m, x2.shape[1]))
    else:
        zi = _as_float(zi)
        expected = x.shape[:axis] + (m,) + x.shape[axis + 1:]
        if zi.shape != expected:
            raise ValueError(f"zi must have shape {expected}, got {zi.shape}")
        z0, _ = _to_2d(zi, axis)
    y2, zf2 = _compiled(_lfilter_kernel)(b, a, x2, z0)
    y = _from_2d(y2, moved_shape, axis)
    if zi is None:
        return y
    return y, _from_2d(zf2, (m,) + moved_shape[1:], axis)


def sosfilt_zi(sos: ArrayLike) -> FloatArray:
    """Steady-state state ``(S, 2)`` of :func:`sosfilt` for a unit step (module docs)."""
    sos = _checked_sos(sos)
    zi = np.empty((sos.shape[0], 2))
    scale = 1.0
    for s in range(sos.shape[0]):
        b, a = sos[s, :3], sos[s, 3:]
        zi[s] = scale * lfilter_zi(b, a)
        scale *= b.sum() / a.sum()
    return zi


def sosfilt(sos: ArrayLike, x: ArrayLike, axis: int = 0, zi: ArrayLike | None = None
            ) -> FloatArray | tuple[FloatArray, FloatArray]:
    """Cascade of second-order sections along ``axis``, as ``scipy.signal.sosfilt``.

    ``zi`` (optional) shape ``(S,) + x.shape`` with ``axis`` (of ``x``) of length 2; with it ``(y, zf)``.
    """
    sos = _checked_sos(sos)
    x = _as_float(x)
    axis = axis % x.ndim
    x2, moved_shape = _to_2d(x, axis)
    s_count = sos.shape[0]
    if zi is None:
        z0 = np.zeros((s_count, 2, x2.shape[1]))
    else:
        zi = _as_float(zi)
        expected = (s_count,) + x.shape[:axis] + (2,) + x.shape[axis + 1:]
        if zi.shape != expected:
            raise ValueError(f"zi must have shape {expected}, got {zi.shape}")
        z0 = np.ascontiguousarray(np.moveaxis(zi, axis + 1, 1).reshape(s_count, 2, -1))
    y2, zf2 = _compiled(_sosfilt_kernel)(sos, x2, z0)
    y = _from_2d(y2, moved_shape, axis)
    if zi is None:
        return y
    zf = np.moveaxis(zf2.reshape((s_count, 2) + moved_shape[1:]), 1, axis + 1)
    return y, zf


def _extension(x2: FloatArray, padlen: int, padtype: str) -> FloatArray:
    """``x2`` ``(N, C)`` extended by ``padlen`` samples at each end: ``"odd"`` reflects about the end sample's value
    (:math:`2x_0 - x_k`: keeps the end's slope), ``"even"`` mirrors the samples (:math:`x_k`: keeps their level, so an
    end that falls in the middle of a motion is not extrapolated along it), as scipy's ``padtype``."""
    if padlen == 0:
        return x2
    head, tail = x2[padlen:0:-1], x2[-2:-padlen - 2:-1]
    if padtype == "odd":
        head, tail = 2.0 * x2[0] - head, 2.0 * x2[-1] - tail
    return np.concatenate([head, x2, tail])


def _check_padding(padtype: str, padlen: int, n: int) -> None:
    if padtype not in ("odd", "even"):
        raise ValueError(f"padtype {padtype!r} is not supported: 'odd' or 'even'")
    if not 0 <= padlen < n:
        raise ValueError(f"padlen must be between 0 and the signal length - 1 = {n - 1}, got {padlen}")


def filtfilt(b: ArrayLike, a: ArrayLike, x: ArrayLike, axis: int = 0, padtype: str = "odd",
             padlen: int | None = None) -> FloatArray:
    """Zero-phase forward-backward :func:`lfilter` with odd or even padding and steady-state start, as
    ``scipy.signal.filtfilt``."""
    b, a = _normalised_ba(b, a)
    x = _as_float(x)
    axis = axis % x.ndim
    x2, moved_shape = _to_2d(x, axis)
    padlen = 3 * b.size if padlen is None else int(padlen)
    _check_padding(padtype, padlen, x2.shape[0])
    kernel = _compiled(_lfilter_kernel)
    zi = lfilter_zi(b, a)[:, None]
    ext = _extension(x2, padlen, padtype)
    y, _ = kernel(b, a, ext, zi * ext[0])
    y_rev = np.ascontiguousarray(y[::-1])
    y, _ = kernel(b, a, y_rev, zi * y_rev[0])
    y = y[::-1]
    if padlen:
        y = y[padlen:-padlen]
    return _from_2d(np.ascontiguousarray(y), moved_shape, axis)


def sosfiltfilt(sos: ArrayLike, x: ArrayLike, axis: int = 0, padtype: str = "odd",
                padlen: int | None = None) -> FloatArray:
    """Zero-phase forward-backward :func:`sosfilt`, as ``scipy.signal.sosfiltfilt``."""
    sos = _checked_sos(sos)
    x = _as_float(x)
    axis = axis % x.ndim
    x2, moved_shape = _to_2d(x, axis)
    if padlen is None:
        trailing_zeros = min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
        padlen = 3 * (2 * sos.shape[0] + 1 - trailing_zeros)
    padlen = int(padlen)
    _check_padding(padtype, padlen, x2.shape[0])
    kernel = _compiled(_sosfilt_kernel)
    zi = sosfilt_zi(sos)[:, :, None]
    ext = _extension(x2, padlen, padtype)
    y, _ = kernel(sos, ext, zi * ext[0])
    y_rev = np.ascontiguousarray(y[::-1])
    y, _ = kernel(sos, y_rev, zi * y_rev[0])
    y = y[::-1]
    if padlen:
        y = y[padlen:-padlen]
    return _from_2d(np.ascontiguousarray(y), moved_shape, axis)


def _savgol_weights(window_length: int, polyorder: int, deriv: int, delta: float) -> FloatArray:
    """Weights ``(L, L)``: row *r* gives the ``deriv``-th derivative at window position *r* (module docs)."""
    half = window_length // 2
    u = np.arange(window_length, dtype=np.float64) - half
    powers = np.arange(polyorder + 1)
    vander = u[:, None] ** powers  # (L, p + 1)
    fit = np.linalg.pinv(vander)  # (p + 1, L): polynomial coefficients from the window
    # d-th derivative of u**i at each offset: i!/(i-d)! u**(i-d) for i >= d
    falling = np.array([math.perm(int(i), deriv) if i >= deriv else 0 for i in powers], dtype=np.float64)
    expo = np.clip(powers - deriv, 0, None)
    evaluate = falling * u[:, None] ** expo  # (L, p + 1)
    return (evaluate @ fit) / delta**deriv


def savgol_derivative(x: ArrayLike, window_length: int, polyorder: int, delta: float = 1.0, axis: int = 0,
                      deriv: int = 1) -> FloatArray:
    """Savitzky–Golay derivative along ``axis``, as ``scipy.signal.savgol_filter(x, window_length, polyorder,
    deriv=deriv, delta=delta, axis=axis)`` (its default ``mode="interp"``).

    ``window_length`` odd and at most the signal length; ``polyorder < window_length``; ``delta`` the sample
    spacing (e.g. ``1 / fs_hz`` s, so that the result is per second).
    """
    x = _as_float(x)
    axis = axis % x.ndim
    x2, moved_shape = _to_2d(x, axis)
    n = x2.shape[0]
    window_length, polyorder, deriv = int(window_length), int(polyorder), int(deriv)
    if window_length % 2 == 0 or window_length < 1:
        raise ValueError(f"window_length must be a positive odd number, got {window_length}")
    if not 0 <= polyorder < window_length:
        raise ValueError(f"polyorder must be between 0 and window_length - 1, got {polyorder}")
    if window_length > n:
        raise ValueError(f"window_length ({window_length}) must not exceed the signal length ({n})")
    if deriv < 0:
        raise ValueError(f"deriv must be >= 0, got {deriv}")
    weights = _savgol_weights(window_length, polyorder, deriv, float(delta))
    half = window_length // 2
    windows = np.lib.stride_tricks.sliding_window_view(x2, window_length, axis=0)  # (N - L + 1, C, L)
    y = np.empty_like(x2)
    y[half:n - half] = windows @ weights[half]
    y[:half] = weights[:half] @ x2[:window_length]
    y[n - half:] = weights[window_length - half:] @ x2[n - window_length:]
    return _from_2d(y, moved_shape, axis)
