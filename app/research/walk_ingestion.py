r"""Ingestion of foot-mounted walks for pedestrian dead reckoning (``chakamo walk``).

The IEZ format (the source thesis' raw recordings, ``../shared/data/iez/README.md``)
------------------------------------------------------------------------------------
Comma-separated integers, no header, one row per sample, blank lines between rows::

    t_ms, ax1, ay1, az1, gx1, gy1, gz1, ax2, ay2, az2, gx2, gy2, gz2

``t_ms`` is the microcontroller clock (ms, nominal 10 ms, gaps of up to ~24 ms); the rest are raw
MPU-6050 int16 counts of sensor 1 then sensor 2.  The file name carries the ranges,
``conf-ABCD-...``: A/B the accelerometer/gyroscope range codes of sensor 1, C/D those of sensor 2:

========  =====================  ==========================
code      accelerometer          gyroscope
========  =====================  ==========================
0         ±2 g, 16384 counts/g   ±250 °/s, 131 counts/(°/s)
1         ±4 g, 8192             ±500 °/s, 65.5
2         ±8 g, 4096             ±1000 °/s, 32.8
3         ±16 g, 2048            ±2000 °/s, 16.4
========  =====================  ==========================

Conversion (once, here): ``acc = counts / (counts per g) * 9.81`` m/s², ``gyr = counts / (counts per
°/s) * π/180`` rad/s; ``t_s = (t_ms - t_ms[0]) / 1000``.  A sample whose count on any axis reached the
int16 rails (≥ 32767 or ≤ −32768, minus ``SATURATION_MARGIN_COUNTS``) is flagged saturated in
``acc_saturated`` / ``gyr_saturated``; the value is kept (it is the range limit, not the truth).
The clock's gaps are kept: the estimators integrate with the per-sample ``dt_s = diff(t_s)``.

Other formats
-------------
``fmt="npz"``: a NumPy archive with ``t_s`` (N,), ``acc`` (N, 3) m/s², ``gyr`` (N, 3) rad/s (the
project units already; optional ``acc_saturated``/``gyr_saturated``).  Simulated walks and other
loggers convert to it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.physics import GRAVITY_M_S2  # the thesis converted counts with 9.81

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

ACC_COUNTS_PER_G = (16384.0, 8192.0, 4096.0, 2048.0)
GYR_COUNTS_PER_DEG_S = (131.0, 65.5, 32.8, 16.4)
ACC_RANGE_G = (2, 4, 8, 16)
GYR_RANGE_DEG_S = (250, 500, 1000, 2000)
INT16_MAX = 32767
INT16_MIN = -32768
SATURATION_MARGIN_COUNTS = 0
FORMATS = ("iez", "npz")
_CONF_RE = re.compile(r"conf-([0-3])([0-3])([0-3])([0-3])", re.IGNORECASE)
_N_COLUMNS = 13

__all__ = ["FORMATS", "WalkRecording", "range_codes_from_name", "read_iez", "read_walk"]


@dataclass(frozen=True, eq=False)
class WalkRecording:
    """One foot-mounted sensor's walk in project units (shared/DESIGN.md §3).

    t_s : (N,) sample times from the first sample, s (strictly increasing; gaps kept).
    acc : (N, 3) specific force, m/s².   gyr : (N, 3) angular rate, rad/s.
    acc_saturated, gyr_saturated : (N,) a component reached the sensor's range.
    acc_range_m_s2, gyr_range_rad_s : the configured full-scale ranges (NaN when unknown).
    sensor : 1 or 2 (which foot's sensor of the file).   source : file name.
    """

    t_s: FloatArray
    acc: FloatArray
    gyr: FloatArray
    acc_saturated: BoolArray
    gyr_saturated: BoolArray
    acc_range_m_s2: float
    gyr_range_rad_s: float
    sensor: int
    source: str

    @property
    def dt_s(self) -> FloatArray:
        """(N,) integration step of each sample: ``t[k] - t[k-1]``, the nominal step for sample 0."""
        d = np.diff(self.t_s)
        return np.concatenate([[np.median(d)], d])

    @property
    def fs_hz(self) -> float:
        """Nominal rate from the median step, Hz."""
        return float(1.0 / np.median(np.diff(self.t_s)))

    def __len__(self) -> int:
        return len(self.t_s)


def range_codes_from_name(name: str) -> tuple[int, int, int, int]:
    """The four range codes ``(acc1, gyr1, acc2, gyr2)`` of a file name ``conf-ABCD-...``."""
    m = _CONF_RE.search(Path(name).name)
    if m is None:
        raise ValueError(
            f"cannot read the sensor ranges from the file name {Path(name).name!r}: IEZ files are named "
            "'conf-ABCD-...' (A, B = accelerometer and gyroscope range codes 0-3 of sensor 1, C, D of sensor 2); "
            "rename the file to its original name")
    return tuple(int(c) for c in m.groups())  # type: ignore[return-value]


def _parse_iez_rows(text: str, name: str) -> NDArray[np.int64]:
    rows = []
    for line_no, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        parts = line.split(",")
        if len(parts) != _N_COLUMNS:
            raise ValueError(f"{name}, line {line_no}: expected {_N_COLUMNS} comma-separated integers "
                             f"(t_ms and 6 counts per sensor), found {len(parts)}")
        try:
            rows.append([int(p) for p in parts])
        except ValueError:
            raise ValueError(f"{name}, line {line_no}: not an integer in {line[:60]!r}; IEZ rows are raw counts") from None
    if len(rows) < 10:
        raise ValueError(f"{name}: only {len(rows)} samples; an IEZ walk has thousands (is this the right file?)")
    data = np.asarray(rows, dtype=np.int64)
    counts = data[:, 1:]
    if counts.min() < INT16_MIN or counts.max() > INT16_MAX:
        raise ValueError(f"{name}: counts outside the int16 range [{INT16_MIN}, {INT16_MAX}]; not raw MPU-6050 data")
    return data


def read_iez(path: str | Path, sensor: int = 1) -> WalkRecording:
    """Read one sensor (1 or 2) of an IEZ CSV walk into project units (see the module docstring)."""
    path = Path(path)
    if sensor not in (1, 2):
        raise ValueError(f"sensor must be 1 or 2 (the two feet of an IEZ file), got {sensor!r}")
    codes = range_codes_from_name(path.name)
    text = path.read_text(encoding="ascii", errors="replace")
    data = _parse_iez_rows(text, path.name)
    t_ms = data[:, 0].astype(np.float64)
    d = np.diff(t_ms)
    if np.any(d <= 0):
        k = int(np.argmax(d <= 0)) + 1
        raise ValueError(f"{path.name}: the millisecond clock does not increase at sample {k} "
                         f"({int(t_ms[k - 1])} -> {int(t_ms[k])} ms); the file is corrupt or concatenated")
    a_code, g_code = codes[2 * (sensor - 1)], codes[2 * (sensor - 1) + 1]
    cols = slice(1, 7) if sensor == 1 else slice(7, 13)
    raw = data[:, cols]
    lim_hi, lim_lo = INT16_MAX - SATURATION_MARGIN_COUNTS, INT16_MIN + SATURATION_MARGIN_COUNTS
    sat = (raw >= lim_hi) | (raw <= lim_lo)
    acc = raw[:, :3] / ACC_COUNTS_PER_G[a_code] * GRAVITY_M_S2
    gyr = np.deg2rad(raw[:, 3:] / GYR_COUNTS_PER_DEG_S[g_code])
    return WalkRecording(
        t_s=(t_ms - t_ms[0]) / 1000.0, acc=acc, gyr=gyr,
        acc_saturated=sat[:, :3].any(axis=1), gyr_saturated=sat[:, 3:].any(axis=1),
        acc_range_m_s2=ACC_RANGE_G[a_code] * GRAVITY_M_S2, gyr_range_rad_s=float(np.deg2rad(GYR_RANGE_DEG_S[g_code])),
        sensor=sensor, source=path.name)


def read_npz(path: str | Path, sensor: int = 1) -> WalkRecording:
    """Read a walk already in project units from ``.npz`` (``t_s``, ``acc``, ``gyr``; see module docstring)."""
    path = Path(path)
    with np.load(path) as z:
        missing = [k for k in ("t_s", "acc", "gyr") if k not in z]
        if missing:
            raise ValueError(f"{path.name}: missing array(s) {', '.join(missing)}; need t_s (N,), acc (N,3), gyr (N,3)")
        t = np.asarray(z["t_s"], dtype=np.float64)
        acc = np.asarray(z["acc"], dtype=np.float64)
        gyr = np.asarray(z["gyr"], dtype=np.float64)
        n = len(t)
        sat_a = np.asarray(z["acc_saturated"], bool) if "acc_saturated" in z else np.zeros(n, bool)
        sat_g = np.asarray(z["gyr_saturated"], bool) if "gyr_saturated" in z else np.zeros(n, bool)
    if acc.shape != (n, 3) or gyr.shape != (n, 3):
        raise ValueError(f"{path.name}: acc and gyr must have shape ({n}, 3) like t_s, got {acc.shape} and {gyr.shape}")
    if n < 10 or np.any(np.diff(t) <= 0) or not (np.all(np.isfinite(acc)) and np.all(np.isfinite(gyr))):
        raise ValueError(f"{path.name}: need ≥ 10 finite samples with strictly increasing t_s")
    return WalkRecording(t - t[0], acc, gyr, sat_a, sat_g, float("nan"), float("nan"), sensor, path.name)


def read_walk(path: str | Path, *, fmt: str = "iez", sensor: int = 1) -> WalkRecording:
    """Read a walk file of format ``fmt`` (one of ``FORMATS``)."""
    if not Path(path).is_file():
        raise ValueError(f"{path}: no such file")
    if fmt == "iez":
        return read_iez(path, sensor)
    if fmt == "npz":
        return read_npz(path, sensor)
    raise ValueError(f"unknown walk format {fmt!r}; choose one of {', '.join(FORMATS)}")
