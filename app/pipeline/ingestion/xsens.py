"""Xsens MT Manager text/CSV export (MTi, MTw Awinda): one file per sensor × recording.

Layout (MT Manager "Export → ASCII", tab-, comma- or semicolon-separated)::

    // General information:
    //  MT Manager version: 2022.2.0
    // Device information:
    //  DeviceId: 00B42D4F
    // Device settings:
    //  Update Rate: 100.0Hz          (older exports; newer ones give no rate: it comes from the stamps)
    PacketCounter<TAB>SampleTimeFine<TAB>Acc_X<TAB>Acc_Y<TAB>Acc_Z<TAB>Gyr_X<TAB>...<TAB>Mag_X<TAB>Mag_Y<TAB>Mag_Z
    51400<TAB>3265020123<TAB>0.069663<TAB>...

* Units (fixed by the format, not written in the file): ``Acc_*`` m/s² (specific force), ``Gyr_*`` rad/s,
  ``Mag_*`` **normalised** (a.u.: the field after Xsens' factory calibration divided by the field strength
  at calibration, norm ≈ 1).  The magnetometer is therefore marked ``mag_unit="normalised"`` (no µT scale,
  :class:`.model.Stream`); a field strength in ``session.json`` (``mag_field_ut``) is carried, never applied.
  ``Acc`` may be absent when ``FreeAcc`` (gravity removed) was exported instead: refused, since the
  calibration needs gravity.  Missing samples are ``NaN`` or empty cells.
* Time: ``UTC_Year .. UTC_Nano`` columns when exported and valid → Unix epoch (``time_base="epoch"``);
  else ``SampleTimeFine`` (10 kHz ticks, 32-bit, unwrapped) → seconds from the file's first sample; else
  ``PacketCounter`` (16-bit, unwrapped) / the header's update rate.
* The sensor id is the ``DeviceId`` of the header (else the 8 hex digits of an ``MT_<id>_`` file name).
"""

from __future__ import annotations

import datetime as dt
import os
import re
from pathlib import Path

import numpy as np

from app.pipeline.ingestion.model import IngestionError, Stream, rows_all
from app.pipeline.ingestion.tables import check_stamps, numeric_columns, parse_table, read_text
from app.pipeline.ingestion.units import check_magnitude, unit_factor

TICKS_PER_S = 10_000.0
_RATE = re.compile(r"(?:update|output|sample)\s*rate\s*:\s*(\d+(?:\.\d+)?)\s*hz", re.IGNORECASE)
_DEVICE = re.compile(r"device\s*id\s*:\s*([0-9A-Fa-f]{8})", re.IGNORECASE)
_NAME_ID = re.compile(r"(?:^|[_-])MT_([0-9A-Fa-f]{8})(?:[_-]|$)|[_-]([0-9A-Fa-f]{8})$")


def looks_like_xsens(text_head: str) -> bool:
    """The first kilobytes of a file are an MT Manager export (``//`` preamble or its column names)."""
    lines = [ln.strip() for ln in text_head.splitlines() if ln.strip()]
    if not lines:
        return False
    if lines[0].startswith("//") and any("mt manager" in ln.lower() or "xsens" in ln.lower() or "deviceid" in
                                         ln.lower().replace(" ", "") for ln in lines[:30]):
        return True
    header = next((ln for ln in lines if not ln.startswith("//")), "")
    return "PacketCounter" in header or ("Acc_X" in header and "Gyr_X" in header)


def _unwrap(x: np.ndarray, modulus: float) -> np.ndarray:
    d = np.diff(x)
    wraps = np.concatenate([[0.0], np.cumsum(np.where(d < -modulus / 2, modulus, 0.0))])
    return x + wraps


def read_xsens(path: str | os.PathLike) -> tuple[Stream, Stream, Stream, str | None]:
    """Read an MT Manager export → ``(acc, gyr, mag, device_id)`` in project units (see module docstring).

    ``mag`` is normalised (``mag_unit="normalised"``, norm ≈ 1)."""
    path = Path(path)
    text = read_text(path)
    lines = text.splitlines(keepends=True)
    k = 0
    while k < len(lines) and (lines[k].lstrip().startswith("//") or not lines[k].strip()):
        k += 1
    preamble = "".join(lines[:k])
    notes: list = []
    header, rows = parse_table(path, "".join(lines[k:]), notes)
    index = {h.strip(): i for i, h in enumerate(header)}
    missing = [c for c in ("Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z", "Mag_X", "Mag_Y", "Mag_Z")
               if c not in index]
    if missing:
        raise IngestionError("xsens.columns_missing", file=path, columns=", ".join(missing))
    utc = ["UTC_Year", "UTC_Month", "UTC_Day", "UTC_Hour", "UTC_Minute", "UTC_Second", "UTC_Nano"]
    t_s, time_base, column = None, "elapsed", "SampleTimeFine"
    if all(c in index for c in utc):
        u = numeric_columns(path, header, rows, [index[c] for c in utc], first_row=k + 2)
        if np.isfinite(u).all() and (u[:, 0] > 1990).all():
            base = np.array([dt.datetime(int(y), int(mo), int(d), int(h), int(mi), int(s),
                                         tzinfo=dt.timezone.utc).timestamp() for y, mo, d, h, mi, s in u[:, :6]])
            t_s, time_base, column = base + u[:, 6] * 1e-9, "epoch", "UTC_*"
    if t_s is None and "SampleTimeFine" in index:
        fine = numeric_columns(path, header, rows, [index["SampleTimeFine"]], first_row=k + 2)[:, 0]
        if np.isfinite(fine).all():
            t_s = _unwrap(fine, 2.0 ** 32) / TICKS_PER_S
    if t_s is None and "PacketCounter" in index:
        rate = _RATE.search(preamble)
        if rate is None:
            raise IngestionError("xsens.no_time", file=path)
        pc = numeric_columns(path, header, rows, [index["PacketCounter"]], first_row=k + 2)[:, 0]
        t_s, column = _unwrap(pc, 65536.0) / float(rate.group(1)), "PacketCounter"
    if t_s is None:
        raise IngestionError("xsens.no_time", file=path)
    if time_base == "elapsed":
        t_s = t_s - t_s[0]
    check_stamps(path, t_s, column, first_row=k + 2)
    streams = []
    for kind, prefix, unit in (("acc", "Acc", "m/s2"), ("gyr", "Gyr", "rad/s"), ("mag", "Mag", "normalised")):
        values = numeric_columns(path, header, rows, [index[f"{prefix}_{a}"] for a in "XYZ"], first_row=k + 2)
        keep = ~rows_all(np.isnan(values))
        if not keep.any():
            raise IngestionError("stream.all_empty", file=path)
        values = values[keep] * (unit_factor(kind, unit) if kind != "mag" else 1.0)
        check_magnitude(kind, values, unit, path)
        rate = _RATE.search(preamble)
        streams.append(Stream(kind=kind, t_s=t_s[keep], values=values, declared_unit=unit, file=path,
                              nominal_fs_hz=float(rate.group(1)) if rate else None, time_base=time_base,
                              notes=tuple(notes) if kind == "acc" else (),
                              mag_unit="normalised" if kind == "mag" else "µT"))
    m = _DEVICE.search(preamble)
    n = _NAME_ID.search(path.stem)
    device = m.group(1).upper() if m else (next(g for g in n.groups() if g).upper() if n else None)
    return streams[0], streams[1], streams[2], device


def write_xsens(path: str | os.PathLike, t_s, acc, gyr, mag_normalised, *, device_id: str = "00B42D4F",
                delimiter: str = "\t", update_rate_hz: float | None = None, t0_ticks: int = 3_265_000_000) -> Path:
    """Write an MT Manager-style export (tests, demo): one row per ``t_s`` (s from 0), acc m/s², gyr rad/s,
    mag normalised (norm ≈ 1); NaN rows give ``NaN`` cells (the magnetometer's slower rows).
    ``t0_ticks`` near 2³² makes ``SampleTimeFine`` wrap inside the recording, as real MTw files do."""
    path = Path(path)
    t = np.asarray(t_s, dtype=np.float64)
    pre = ["// General information:", "//  MT Manager version: 2022.2.0", "// Device information:",
           f"//  DeviceId: {device_id}", "// Device settings:"]
    if update_rate_hz:
        pre.append(f"//  Update Rate: {update_rate_hz:.1f}Hz")
    pre.append("// Coordinate system: ENU")
    head = ["PacketCounter", "SampleTimeFine", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z",
            "Mag_X", "Mag_Y", "Mag_Z"]
    out = pre + [delimiter.join(head)]
    fine = (np.round(t * TICKS_PER_S).astype(np.int64) + t0_ticks) % 2 ** 32
    for k in range(len(t)):
        cells = [str((51400 + k) % 65536), str(int(fine[k]))]
        for v in (acc[k], gyr[k], mag_normalised[k]):
            cells += ["NaN"] * 3 if not np.all(np.isfinite(v)) else [f"{x:.6f}" for x in v]
        out.append(delimiter.join(cells))
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path
