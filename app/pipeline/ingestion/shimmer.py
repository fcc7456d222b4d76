"""Shimmer Consensys CSV export (Shimmer3 IMU): one file per sensor × recording.

Layout (Consensys "Export", calibrated data)::

    "sep=\t"                                        optional: Excel's separator hint (tab or comma)
    Shimmer_8A21_Timestamp_Unix_CAL<TAB>Shimmer_8A21_Accel_LN_X_CAL<TAB>...<TAB>Shimmer_8A21_Mag_Z_CAL
    CAL<TAB>CAL<TAB>...                              optional: the format row (CAL / RAW)
    ms<TAB>m/(s^2)<TAB>...<TAB>deg/s<TAB>local_flux   the units row
    1678700000000.00<TAB>0.12<TAB>...

* Columns ``<device>_<signal>_<axis>_CAL``: time ``Timestamp_Unix`` (ms since 1970, preferred) or
  ``Timestamp`` (ms on the device's clock); accelerometer ``Accel_LN`` (low noise) or ``Accel_WR`` (wide
  range) in m/(s^2); gyroscope ``Gyro`` in deg/s; magnetometer ``Mag`` in ``local_flux``, the Shimmer
  calibration's unit, scaled like gauss (the earth ≈ 0.25–0.65): read as gauss (×100 → µT) and checked for
  plausibility like every field.  Units come from the units row; ``RAW`` columns are ignored.
* The sensor id is the ``Shimmer_XXXX`` prefix of the column names.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from app.pipeline.ingestion.model import IngestionError, Stream
from app.pipeline.ingestion.tables import check_stamps, numeric_columns, parse_table, read_text
from app.pipeline.ingestion.units import check_magnitude, unit_factor

_COLUMN = re.compile(r"^(?P<device>.+?)_(?P<signal>Timestamp_Unix|Timestamp|Accel_LN|Accel_WR|Gyro|Mag)"
                     r"(?:_(?P<axis>[XYZ]))?_CAL$", re.IGNORECASE)
_UNITS = {"m/(s^2)": "m/s2", "m/s^2": "m/s2", "local_flux": "gauss", "local_flux*": "gauss", "deg/s": "deg/s",
          "ms": "ms", "mgauss": "mgauss", "ut": "ut", "gauss": "gauss"}


def looks_like_shimmer(text_head: str) -> bool:
    """The first kilobytes are a Consensys export (``sep=`` hint, or ``_CAL`` columns with a Shimmer time)."""
    lines = [ln.strip().strip('"') for ln in text_head.splitlines() if ln.strip()]
    if not lines:
        return False
    header = lines[1] if lines[0].lower().startswith("sep=") and len(lines) > 1 else lines[0]
    return "_CAL" in header and "Timestamp" in header and ("Accel" in header or "Gyro" in header)


def read_shimmer(path: str | os.PathLike) -> tuple[Stream, Stream, Stream, str | None]:
    """Read a Consensys CSV → ``(acc, gyr, mag, device)`` in project units (see module docstring)."""
    path = Path(path)
    text = read_text(path)
    lines = text.splitlines(keepends=True)
    delimiter = None
    start = 0
    if lines and lines[0].strip().strip('"').lower().startswith("sep="):
        sep = lines[0].strip().strip('"')[4:]
        delimiter = {"\\t": "\t", "": "\t"}.get(sep, sep[:1])
        start = 1
    notes: list = []
    header, rows = parse_table(path, "".join(lines[start:]), notes, delimiter=delimiter)
    meta = 0
    while meta < len(rows) and rows[meta] and not _number(rows[meta][0]):
        meta += 1                                    # the CAL row and the units row
    if meta == 0 or meta >= len(rows):
        raise IngestionError("shimmer.no_units_row", file=path)
    units_row = rows[meta - 1]
    data = rows[meta:]
    first_row = start + meta + 2
    found: dict[tuple[str, str], int] = {}
    device = None
    for i, h in enumerate(header):
        m = _COLUMN.match(h.strip())
        if m:
            found[(m.group("signal").lower(), (m.group("axis") or "").lower())] = i
            device = device or m.group("device")
    t_key = "timestamp_unix" if ("timestamp_unix", "") in found else "timestamp"
    acc_sig = "accel_ln" if ("accel_ln", "x") in found else "accel_wr"
    want = {"acc": acc_sig, "gyr": "gyro", "mag": "mag"}
    missing = [f"{sig}_{a}" for sig in want.values() for a in "xyz" if (sig, a) not in found]
    if (t_key, "") not in found or missing:
        raise IngestionError("shimmer.columns_missing", file=path,
                             columns=", ".join(missing or ["Timestamp_Unix_CAL"]))
    t_i = found[(t_key, "")]
    t_unit = _UNITS.get(units_row[t_i].strip().lower(), units_row[t_i].strip())
    t_factor = unit_factor("time", t_unit)
    if t_factor is None:
        raise IngestionError("shimmer.unit_unknown", file=path, unit=units_row[t_i], column=header[t_i])
    t_s = numeric_columns(path, header, data, [t_i], first_row=first_row)[:, 0] * t_factor
    check_stamps(path, t_s, header[t_i], first_row=first_row)
    streams = []
    for kind, sig in want.items():
        cols = [found[(sig, a)] for a in "xyz"]
        declared = {units_row[c].strip() for c in cols}
        unit = _UNITS.get(next(iter(declared)).lower(), next(iter(declared)))
        factor = unit_factor(kind, unit) if len(declared) == 1 else None
        if factor is None:
            raise IngestionError("shimmer.unit_unknown", file=path, unit=", ".join(sorted(declared)),
                                 column=header[cols[0]])
        values = numeric_columns(path, header, data, cols, first_row=first_row) * factor
        check_magnitude(kind, values, unit, path)
        streams.append(Stream(kind=kind, t_s=t_s, values=values, declared_unit=next(iter(declared)), file=path,
                              time_base="epoch" if t_key == "timestamp_unix" else "elapsed",
                              notes=tuple(notes) if kind == "acc" else ()))
    if t_key != "timestamp_unix":
        streams = [Stream(s.kind, s.t_s - s.t_s[0], s.values, s.declared_unit, s.file, None, "elapsed", s.notes)
                   for s in streams]
    return streams[0], streams[1], streams[2], device


def _number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def write_shimmer(path: str | os.PathLike, epoch_ms, acc, gyr, mag_ut, *, device: str = "Shimmer_8A21",
                  delimiter: str = "\t", sep_line: bool = True, low_noise: bool = True) -> Path:
    """Write a Consensys-style CSV (tests, demo): acc m/s², gyr rad/s (written deg/s), mag µT (written
    local_flux = gauss); one row per ``epoch_ms``."""
    path = Path(path)
    acc_sig = "Accel_LN" if low_noise else "Accel_WR"
    names = [f"{device}_Timestamp_Unix_CAL"] + [f"{device}_{s}_{a}_CAL" for s in (acc_sig, "Gyro", "Mag")
                                                for a in "XYZ"]
    units = ["ms"] + ["m/(s^2)"] * 3 + ["deg/s"] * 3 + ["local_flux"] * 3
    out = ([f'"sep={chr(92)}t"' if delimiter == "\t" else f'"sep={delimiter}"'] if sep_line else [])
    out += [delimiter.join(names), delimiter.join(["CAL"] * len(names)), delimiter.join(units)]
    g = np.rad2deg(np.asarray(gyr))
    m = np.asarray(mag_ut) / 100.0
    for k, ms in enumerate(np.asarray(epoch_ms, dtype=np.float64)):
        out.append(delimiter.join([f"{ms:.3f}"] + [f"{x:.6f}" for x in (*acc[k], *g[k], *m[k])]))
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path
