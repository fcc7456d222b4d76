"""estimators.signal against scipy.signal (the oracle, imported here only) on the call sites' own settings."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal as sp

from estimators import signal as sig

FS_HZ = 100.0


def _signal(n: int, channels: int = 3, seed: int = 0) -> np.ndarray:
    """A drifting, noisy multi-channel recording (steps and a ramp, so the ends are not at zero)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_HZ
    base = np.stack([np.sin(2 * np.pi * (0.3 + 0.4 * j) * t) * (1 + j) + 0.5 * t + 3.0 * j for j in range(channels)],
                    axis=1)
    base[n // 3:] += 2.0
    return base + rng.normal(0.0, 0.3, base.shape)


def _close(actual, expected, rtol=1e-12):
    expected = np.asarray(expected)
    scale = max(1.0, float(np.max(np.abs(expected))))
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rtol * scale)


@pytest.mark.parametrize("fc_hz, fs_hz", [(0.3, 100.0), (6.0, 100.0), (22.5, 50.0), (44.9, 100.0), (1.0, 20.0)])
def test_butter_lowpass_matches_scipy_ba_and_sos(fc_hz, fs_hz):
    b, a = sig.butter_lowpass(fc_hz, fs_hz)
    b_ref, a_ref = sp.butter(2, fc_hz, btype="low", fs=fs_hz)
    _close(b, b_ref / a_ref[0], 1e-14)
    _close(a, a_ref / a_ref[0], 1e-14)
    sos_ref = sp.butter(2, fc_hz / (0.5 * fs_hz), output="sos")
    _close(sig.butter_lowpass_sos(fc_hz, fs_hz), sos_ref, 1e-14)


def test_butter_lowpass_is_minus_3_db_at_the_cutoff():
    b, a = sig.butter_lowpass(5.0, FS_HZ)
    z = np.exp(1j * 2 * np.pi * 5.0 / FS_HZ)
    gain = abs(np.polyval(b[::-1], 1 / z) / np.polyval(a[::-1], 1 / z))
    assert gain == pytest.approx(1 / math.sqrt(2), rel=1e-12)
    assert b.sum() / a.sum() == pytest.approx(1.0, rel=1e-12)  # unit DC gain


@pytest.mark.parametrize("fc_hz", [6.0, 0.5])
def test_butter_lowpass_refuses_a_cutoff_outside_0_to_nyquist(fc_hz):
    with pytest.raises(ValueError, match="cutoff_hz"):
        sig.butter_lowpass(fc_hz * 10, 10.0)
    with pytest.raises(ValueError, match="cutoff_hz"):
        sig.butter_lowpass(0.0, FS_HZ)


@pytest.mark.parametrize("b, a", [
    ([1.0], [1.0, -0.97]),  # the offline heading's first-order recursion
    (*sp.butter(2, 3.0, fs=FS_HZ),),
    ([0.2, 0.3, -0.1, 0.05], [2.0, -0.4, 0.1]),  # unnormalised, unequal lengths
])
def test_lfilter_and_lfilter_zi_match_scipy(b, a):
    x = _signal(700)
    _close(sig.lfilter(b, a, x, axis=0), sp.lfilter(b, a, x, axis=0))
    _close(sig.lfilter(b, a, x[:, 1]), sp.lfilter(b, a, x[:, 1]))
    _close(sig.lfilter(b, a, x.T, axis=1), sp.lfilter(b, a, x.T, axis=1))
    zi_ref = sp.lfilter_zi(b, a)
    _close(sig.lfilter_zi(b, a), zi_ref)
    zi = np.outer(zi_ref, x[0])
    y, zf = sig.lfilter(b, a, x, axis=0, zi=zi)
    y_ref, zf_ref = sp.lfilter(b, a, x, axis=0, zi=zi)
    _close(y, y_ref)
    _close(zf, zf_ref)


def test_lfilter_two_halves_equal_one_pass():
    b, a = sp.butter(2, 4.0, fs=FS_HZ)
    x = _signal(600)
    zi = np.zeros((2, 3))
    y1, z1 = sig.lfilter(b, a, x[:250], zi=zi)
    y2, _ = sig.lfilter(b, a, x[250:], zi=z1)
    _close(np.concatenate([y1, y2]), sig.lfilter(b, a, x), 1e-14)


@pytest.mark.parametrize("padtype", ["odd", "even"])
@pytest.mark.parametrize("fc_hz, padlen", [(2.25, 7), (0.6, 120), (10.0, None), (10.0, 0)])
def test_filtfilt_matches_scipy(fc_hz, padlen, padtype):
    b, a = sp.butter(2, fc_hz, btype="low", fs=FS_HZ)
    x = _signal(900, seed=1)
    ref = sp.filtfilt(b, a, x, axis=0, padtype=padtype, padlen=padlen)
    _close(sig.filtfilt(b, a, x, axis=0, padtype=padtype, padlen=padlen), ref)
    _close(sig.filtfilt(b, a, x[:, 2], padlen=padlen), sp.filtfilt(b, a, x[:, 2], padlen=padlen))


def test_filtfilt_with_the_call_site_padding_on_a_short_signal():
    """chakamo_offline pads by min(n - 1, ceil(3 τ fs)): on a short recording the pad is the whole signal."""
    b, a = sig.butter_lowpass(math.sqrt(2) / (2 * math.pi * 0.5), FS_HZ)
    x = _signal(12, seed=2)
    ref = sp.filtfilt(b, a, x, axis=0, padtype="odd", padlen=11)
    _close(sig.filtfilt(b, a, x, axis=0, padtype="odd", padlen=11), ref)


@pytest.mark.parametrize("fc_hz, padlen", [(6.0, 50), (1.5, 200), (6.0, None)])
def test_sosfiltfilt_and_sosfilt_match_scipy(fc_hz, padlen):
    sos = sp.butter(2, fc_hz / (0.5 * FS_HZ), output="sos")
    x = _signal(1500, seed=3)
    _close(sig.sosfiltfilt(sos, x, axis=0, padlen=padlen), sp.sosfiltfilt(sos, x, axis=0, padlen=padlen))
    _close(sig.sosfilt(sos, x), sp.sosfilt(sos, x, axis=0))
    _close(sig.sosfilt_zi(sos), sp.sosfilt_zi(sos))


def test_sosfiltfilt_with_several_sections_matches_scipy():
    sos = sp.butter(5, 0.1, output="sos")  # three sections, the last first-order (trailing zeros)
    x = _signal(800, seed=4)
    _close(sig.sosfiltfilt(sos, x, axis=0), sp.sosfiltfilt(sos, x, axis=0))
    zi = sp.sosfilt_zi(sos)[:, :, None] * x[0]
    zi = np.moveaxis(zi, 2, 1).swapaxes(1, 2)  # (S, 2, C)
    y, zf = sig.sosfilt(sos, x, zi=zi)
    y_ref, zf_ref = sp.sosfilt(sos, x, axis=0, zi=zi)
    _close(y, y_ref)
    _close(zf, zf_ref)


def test_zero_phase_filter_delays_nothing():
    """A slow sine low-passed forward and backward keeps its peak where it was (a causal filter would lag)."""
    t = np.arange(2000) / FS_HZ
    x = np.sin(2 * np.pi * 0.5 * t)
    y = sig.sosfiltfilt(sig.butter_lowpass_sos(5.0, FS_HZ), x, padlen=100)
    assert np.argmax(y[:200]) == np.argmax(x[:200])
    np.testing.assert_allclose(y[100:-100], x[100:-100], atol=1e-3)


# scipy fits the edge windows with np.polyfit on positions 0..L-1 (not centred); at degree 4 that alone differs
# from a centred fit by a few 1e-12 of the signal, so the tolerance there is 1e-11.
@pytest.mark.parametrize("window, polyorder, rtol", [(7, 2, 1e-12), (5, 2, 1e-12), (21, 3, 1e-12), (9, 4, 1e-11)])
def test_savgol_derivative_matches_scipy(window, polyorder, rtol):
    x = _signal(400, seed=5)
    dt_s = 1.0 / FS_HZ
    ref = sp.savgol_filter(x, window, polyorder, deriv=1, delta=dt_s, axis=0)
    _close(sig.savgol_derivative(x, window, polyorder, delta=dt_s, axis=0), ref, rtol)
    ref_1d = sp.savgol_filter(x[:, 0], window, polyorder, deriv=1, delta=dt_s)
    _close(sig.savgol_derivative(x[:, 0], window, polyorder, delta=dt_s), ref_1d, rtol)


def test_savgol_derivative_of_a_quadratic_is_exact_and_smoothing_matches_scipy():
    t = np.arange(50) / FS_HZ
    x = 3.0 * t**2 - 2.0 * t + 1.0
    np.testing.assert_allclose(sig.savgol_derivative(x, 7, 2, delta=1 / FS_HZ), 6.0 * t - 2.0, atol=1e-9)
    y = _signal(60, seed=6)
    _close(sig.savgol_derivative(y, 11, 3, deriv=0), sp.savgol_filter(y, 11, 3, axis=0))


def test_savgol_derivative_refuses_bad_windows():
    x = np.zeros(10)
    for window, order in [(6, 2), (7, 7), (11, 2)]:
        with pytest.raises(ValueError, match="window_length|polyorder"):
            sig.savgol_derivative(x, window, order)


def test_compiled_kernels_equal_their_plain_python_reference():
    b, a = sp.butter(2, 3.0, fs=FS_HZ)
    x = _signal(300, seed=7)
    zi = np.outer(sp.lfilter_zi(b, a), x[0])
    y_jit, z_jit = sig._compiled(sig._lfilter_kernel)(b, a, x, zi)
    y_py, z_py = sig._lfilter_kernel(b, a, x, zi)
    np.testing.assert_array_equal(y_jit, y_py)
    np.testing.assert_array_equal(z_jit, z_py)
    sos = sp.butter(4, 0.1, output="sos")
    zs = np.zeros((2, 2, 3))
    np.testing.assert_array_equal(sig._compiled(sig._sosfilt_kernel)(sos, x, zs)[0], sig._sosfilt_kernel(sos, x, zs)[0])


def test_import_costs_neither_scipy_nor_numba():
    code = "import sys, estimators.signal; print(sorted(m for m in ('scipy', 'numba') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


# quaternion.to_euler replaced scipy.spatial's Rotation.as_euler for the same reason (its import cost ~0.4 s);
# scipy stays its oracle here, beside the other replaced functions (tests/estimators/test_quaternion.py keeps
# the round-trip and meaning tests).
_SEQUENCES = [a + b + c for a in "XYZ" for b in "XYZ" for c in "XYZ" if a != b and b != c]


@pytest.mark.parametrize("seq", _SEQUENCES + [s.lower() for s in _SEQUENCES])
def test_to_euler_matches_scipy_including_gimbal_lock(seq):
    import warnings

    from scipy.spatial.transform import Rotation

    from estimators import quaternion as quat

    rng = np.random.default_rng(8)
    q = quat.normalize(rng.normal(size=(500, 4)))
    ref = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_euler(seq)
    np.testing.assert_allclose(quat.to_euler(q, seq), ref, rtol=0, atol=1e-12)
    proper = seq[0] == seq[2]
    for middle_rad in ((0.0, np.pi) if proper else (0.5 * np.pi, -0.5 * np.pi)):
        ang = np.column_stack([rng.uniform(-3, 3, 20), np.full(20, middle_rad), rng.uniform(-3, 3, 20)])
        rot = Rotation.from_euler(seq, ang)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # scipy warns of the gimbal lock
            ref = rot.as_euler(seq)
        got = quat.to_euler(rot.as_quat()[:, [3, 0, 1, 2]], seq)
        wrapped = np.angle(np.exp(1j * (got - ref)))  # ±π are the same angle
        np.testing.assert_allclose(wrapped, 0.0, atol=1e-9)


def test_quaternion_import_costs_no_scipy():
    code = "import sys, estimators.quaternion; print('scipy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
