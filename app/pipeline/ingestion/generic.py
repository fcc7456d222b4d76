"""Generic CSV: one file per sensor × recording whose header declares every column and its unit.

Format (comma-separated, one header row, ``.`` decimal point)::

    time (s),acc_x (g),acc_y (g),acc_z (g),gyr_x (deg/s),gyr_y (deg/s),gyr_z (deg/s),mag_x (uT),mag_y (uT),mag_z (uT)
    0.000,0.012,-0.998,0.051,0.61,-0.12,0.30,12.5,-20.1,-38.0
    0.010,0.011,-0.997,0.050,0.55,-0.10,0.28,,,

* Column names: ``time`` (or ``t``), ``acc_x/y/z``, ``gyr_x/y/z``, ``mag_x/y/z``; a stream may have its own
  time column ``acc_time``, ``gyr_time``, ``mag_time`` (else it uses ``time``).  Other columns are ignored.
* Units in parentheses, or as a suffix after the last ``_`` of the name's unit part
  (``t_s``, ``acc_x_m_s2``, ``gyr_x_rad_s``, ``mag_x_ut``): time s/ms/us, or Unix time as a column
  ``epoch (ms)`` / ``epoch_ms`` or a unit ``(epoch ms)`` (e.g. ``mag_time (epoch ms)``); acc g, mg, m/s²;
  gyr deg/s, rad/s; mag T, mT, µT (uT), nT, G, or ``normalised`` (norm ≈ 1, e.g. ``mag_x (normalised)``),
  optionally with the local field strength: ``mag_x (normalised 48.5 uT)``; a normalised magnetometer stays
  normalised (``Stream.mag_unit == "normalised"``, ``Stream.field_ut`` the declared strength or ``None``).
* A stream sampled slower (magnetometer at 20 Hz) leaves its cells empty in the other rows; an empty
  cell is a missing sample, text is an error.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from app.pipeline.files import write_text_atomic
from app.pipeline.ingestion.model import IngestionError, Stream, rows_all
from app.pipeline.ingestion.tables import check_stamps, numeric_columns, read_csv_rows
from app.pipeline.ingestion.units import check_magnitude, normalise_unit, normalised_field, unit_factor

_PAREN = re.compile(r"^\s*(?P<name>[^()]*?)\s*\((?P<unit>[^()]*)\)\s*$")
_SUFFIX = re.compile(r"^(?P<name>(?:acc|gyr|mag)_[xyz]|(?:acc_|gyr_|mag_)?(?:time|t)|epoch)_(?P<unit>.+)$")


def _column(col: str) -> tuple[str, str | None]:
    """(name, unit) of a header cell, both folded; unit ``None`` when not declared."""
    m = _PAREN.match(col)
    if m:
        return m.group("name").strip().lower().replace(" ", "_"), m.group("unit")
    m = _SUFFIX.match(col.strip().lower())
    if m:
        return m.group("name"), m.group("unit")
    return col.strip().lower(), None


def read_generic_csv(path: str | os.PathLike) -> tuple[Stream, Stream, Stream]:
    """Read a generic CSV → ``(acc, gyr, mag)`` streams in project units (see the module docstring)."""
    path = Path(path)
    notes: list = []
    header, rows = read_csv_rows(path, notes)
    cols = [_column(c) for c in header]
    index = {n: i for i, (n, _) in enumerate(cols)}
    if "t" in index and "time" not in index:
        index["time"] = index["t"]
    if "epoch" in index:
        index.setdefault("time", index["epoch"])
    streams = []
    for kind in ("acc", "gyr", "mag"):
        axes = [index.get(f"{kind}_{a}") for a in "xyz"]
        if None in axes:
            missing = [f"{kind}_{a}" for a, i in zip("xyz", axes) if i is None]
            raise IngestionError("generic.column_missing", file=path, columns=", ".join(missing))
        t_i = index.get(f"{kind}_time", index.get(f"{kind}_t", index.get("time")))
        if t_i is None:
            raise IngestionError("generic.no_time", file=path)
        units = {cols[i][1] for i in axes}
        if len(units) != 1 or None in units:
            raise IngestionError("generic.units_differ", file=path, columns=", ".join(header[i] for i in axes),
                                 example=f"{kind}_x ({ {'acc': 'g', 'gyr': 'deg/s', 'mag': 'uT'}[kind]})")
        unit = units.pop()
        t_name, t_unit = cols[t_i]
        is_epoch = t_name == "epoch" or normalise_unit(t_unit or "") in ("epochms", "epoch_ms", "unixms")
        factor, t_factor = unit_factor(kind, unit), (1e-3 if is_epoch else unit_factor("time", t_unit or "s"))
        if factor is None or t_factor is None:
            bad = unit if factor is None else t_unit
            raise IngestionError("generic.unit_unknown", file=path, unit=bad)
        data = numeric_columns(path, header, rows, [t_i, *axes])
        keep = ~rows_all(np.isnan(data[:, 1:]))     # rows where this stream was not sampled
        rows_used = np.nonzero(keep)[0]
        t_s = data[keep, 0] * t_factor
        if rows_used.size == 0:
            raise IngestionError("generic.stream_empty", file=path, stream=kind)
        check_stamps(path, t_s, header[t_i], first_row=2 + int(rows_used[0]))
        values = data[keep, 1:] * factor
        check_magnitude(kind, values, unit, path)
        normalised, field_ut = normalised_field(unit) if kind == "mag" else (False, None)
        streams.append(Stream(kind=kind, t_s=t_s, values=values, declared_unit=unit, file=path,
                              time_base="epoch" if is_epoch else "elapsed", notes=tuple(notes) if kind == "acc"
                              else (), mag_unit="normalised" if normalised else "µT", field_ut=field_ut))
    return streams[0], streams[1], streams[2]


def write_generic_csv(path: str | os.PathLike, acc: tuple, gyr: tuple, mag: tuple) -> Path:
    """Write ``(t_s, values)`` streams (project units) as a generic CSV with per-stream time columns.

    Columns ``acc_time (s),acc_x (m/s2),...,gyr_time (s),gyr_x (rad/s),...,mag_time (s),mag_x (uT),...``;
    6 decimals for time and values; shorter streams leave empty cells.
    """
    path = Path(path)
    head = []
    for kind, unit in (("acc", "m/s2"), ("gyr", "rad/s"), ("mag", "uT")):
        head += [f"{kind}_time (s)"] + [f"{kind}_{a} ({unit})" for a in "xyz"]
    n = max(len(s[0]) for s in (acc, gyr, mag))
    lines = [",".join(head)]
    for k in range(n):
        cells = []
        for t, v in (acc, gyr, mag):
            cells += ([f"{t[k]:.6f}"] + [f"{x:.6f}" for x in v[k]]) if k < len(t) else ["", "", "", ""]
        lines.append(",".join(cells))
    return write_text_atomic(path, "\n".join(lines) + "\n")
