"""MetaBase CSV (MbientLab MetaWear / MetaMotion): reader and writer, one file per stream.

File name: ``{label}_MetaWear_{YYYY-MM-DDTHH.MM.SS.mmm}_{MAC}_{Stream}_{rate}Hz_{firmware}.csv`` (the
extension in any case: a copy through a FAT-formatted stick may end in ``.CSV``).
Header, two dialects (both read, both written)::

    epoch (ms),time (-13:00),elapsed (s),x-axis (g),y-axis (g),z-axis (g)
    epoc (ms),timestamp (+0200),elapsed (s),x-axis (g),y-axis (g),z-axis (g)

Units: Accelerometer g, Gyroscope deg/s, Magnetometer T (tesla: the real export's numbers are
~5e-5, i.e. 50 µT; checked).  The time base is ``epoch (ms)`` (the phone's clock, shared by every
sensor of a session); the time string (``:`` or ``.`` between hour, minute, second) and its time zone
label are unreliable and ignored on reading.  Without an epoch column the elapsed seconds are used.
"""

from __future__ import annotations

import datetime as dt
import os
import re
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from app.pipeline.files import write_text_atomic
from app.pipeline.ingestion.model import IngestionError, Stream
from app.pipeline.ingestion.tables import check_stamps, numeric_columns, read_csv_rows
from app.pipeline.ingestion.units import check_magnitude, unit_factor

FILE_NAME = re.compile(
    r"^(?P<label>.*)_MetaWear_(?P<datetime>\d{4}-\d{2}-\d{2}T\d{2}[.:]\d{2}[.:]\d{2}(?:[.:]\d{1,6})?)_"
    r"(?P<mac>[0-9A-Fa-f]{12})_(?P<stream>[A-Za-z ]+?)_(?P<rate>\d+(?:\.\d+)?)Hz(?:_(?P<firmware>[^_]*))?\.[cC][sS][vV]$")
STREAMS = {"Accelerometer": "acc", "Gyroscope": "gyr", "Magnetometer": "mag"}
STREAM_NAMES = {v: k for k, v in STREAMS.items()}
FILE_UNITS = {"acc": "g", "gyr": "deg/s", "mag": "T"}
DECIMALS = {"acc": 3, "gyr": 3, "mag": 9}
_KNOWN = {"acc": "g, mg or m/s²", "gyr": "deg/s or rad/s", "mag": "T, mT, µT or nT"}
_COL = re.compile(r"^\s*(?P<name>[^()]*?)\s*(?:\((?P<unit>[^()]*)\))?\s*$")


def parse_file_name(path: Path) -> dict[str, str] | None:
    """``label, datetime, mac, stream, rate, firmware`` of a MetaBase file name, or ``None``."""
    m = FILE_NAME.match(Path(path).name)
    return None if m is None else m.groupdict()


def _split(col: str) -> tuple[str, str]:
    m = _COL.match(col)
    return (m.group("name").lower(), (m.group("unit") or "").strip()) if m else (col.lower(), "")


def read_metabase_csv(path: str | os.PathLike, kind: str | None = None) -> Stream:
    """Read one MetaBase stream file → :class:`Stream` in project units (epoch seconds, m/s²/rad/s/µT).

    ``kind`` (acc/gyr/mag) defaults to the stream named in the file name, else to the unit in the header.
    """
    path = Path(path)
    name = parse_file_name(path)
    header, rows = read_csv_rows(path)
    cols = [_split(c) for c in header]
    names = [c[0] for c in cols]
    i_epoch = next((i for i, n in enumerate(names) if n in ("epoch", "epoc")), None)
    i_elapsed = next((i for i, n in enumerate(names) if n == "elapsed"), None)
    axes = [next((i for i, n in enumerate(names) if n == f"{a}-axis"), None) for a in "xyz"]
    if None in axes or (i_epoch is None and i_elapsed is None):
        raise IngestionError(
            f"{path}: not a MetaBase stream file: the header {','.join(header)!r} lacks "
            f"'epoch (ms)' or 'elapsed (s)' and 'x-axis/y-axis/z-axis (unit)' columns; export the stream again "
            f"from MetaBase (or rename the file if it is not a stream export).")
    units = {cols[i][1] for i in axes}
    if len(units) != 1:
        raise IngestionError(f"{path}: the three axes declare different units {sorted(units)}; fix the header.")
    unit = units.pop()
    if kind is None and name is not None:
        kind = STREAMS.get(name["stream"].strip())
    if kind is None:
        kind = next((k for k in ("acc", "gyr", "mag") if unit_factor(k, unit) is not None
                     and not (k == "mag" and unit.lower() in ("g", "mg"))), None)
    factor = None if kind is None else unit_factor(kind, unit)
    if factor is None:
        stream = STREAM_NAMES.get(kind, "this stream") if kind else "this stream"
        raise IngestionError(
            f"{path}: unit ({unit}) is not one ChakaMo knows for {stream}; expected "
            f"{_KNOWN.get(kind, 'g, deg/s or T')}; correct the unit in the column header.")
    time_col = i_epoch if i_epoch is not None else i_elapsed
    data = numeric_columns(path, header, rows, [time_col, *axes])
    t_s = data[:, 0] * (1e-3 if time_col == i_epoch else 1.0)
    check_stamps(path, t_s, f"'{header[time_col]}' stamp")
    values = data[:, 1:] * factor
    if np.isnan(values).all():
        raise IngestionError(f"{path}: every sample is empty; export the recording again.")
    check_magnitude(kind, values, unit, path)
    return Stream(kind=kind, t_s=t_s, values=values, declared_unit=unit, file=path,
                  nominal_fs_hz=float(name["rate"]) if name else None,
                  time_base="epoch" if time_col == i_epoch else "elapsed")


# ----------------------------------------------------------------------------------------------- writer

def file_name(label: str, start_epoch_ms: int, mac: str, kind: str, rate_hz: float, firmware: str = "1.5.1",
              utc_offset_h: float = 0.0) -> str:
    """The MetaBase file name of one stream (the date part is local time at ``utc_offset_h``)."""
    when = dt.datetime.fromtimestamp(start_epoch_ms / 1e3 + 3600 * utc_offset_h, tz=dt.timezone.utc)
    stamp = when.strftime("%Y-%m-%dT%H.%M.%S.") + f"{when.microsecond // 1000:03d}"
    mac = mac.replace(":", "").upper()
    return f"{label}_MetaWear_{stamp}_{mac}_{STREAM_NAMES[kind]}_{rate_hz:.3f}Hz_{firmware}.csv"


def _tz_label(utc_offset_h: float, dialect: str) -> str:
    sign = "-" if utc_offset_h < 0 else "+"
    h, m = divmod(round(abs(utc_offset_h) * 60), 60)
    return f"{sign}{h:02d}:{m:02d}" if dialect == "epoch" else f"{sign}{h:02d}{m:02d}"


def write_metabase_csv(path: str | os.PathLike, kind: str, epoch_ms: ArrayLike, values: ArrayLike, *,
                       dialect: str = "epoch", time_sep: str = ":", utc_offset_h: float = 0.0) -> Path:
    """Write one stream exactly as MetaBase does; values in project units (m/s², rad/s, µT).

    epoch_ms : (n,) integer Unix milliseconds.   values : (n, 3); NaN rows are written as empty cells.
    dialect : ``"epoch"`` (``epoch (ms),time (-13:00),...``) or ``"epoc"`` (``epoc (ms),timestamp (+0200),...``).
    time_sep : ``":"`` or ``"."`` between hour, minute and second in the time string.
    Units written: g (3 decimals), deg/s (3 decimals), T (9 decimals), elapsed s (3 decimals).
    The file appears complete or not at all (written to ``.part``, then renamed).
    """
    if dialect not in ("epoch", "epoc"):
        raise ValueError(f"dialect must be 'epoch' or 'epoc', got {dialect!r}")
    if time_sep not in (":", "."):
        raise ValueError(f"time_sep must be ':' or '.', got {time_sep!r}")
    if kind not in FILE_UNITS:
        raise ValueError(f"kind must be one of {sorted(FILE_UNITS)}, got {kind!r}")
    path = Path(path)
    ms = np.asarray(epoch_ms, dtype=np.int64)
    v = np.asarray(values, dtype=np.float64)
    if v.shape != (len(ms), 3):
        raise ValueError(f"values must be ({len(ms)}, 3) to match epoch_ms, got {v.shape}")
    unit = FILE_UNITS[kind]
    v = v / unit_factor(kind, unit)
    dec = DECIMALS[kind]
    tz = _tz_label(utc_offset_h, dialect)
    head = (f"epoch (ms),time ({tz})" if dialect == "epoch" else f"epoc (ms),timestamp ({tz})") + \
        f",elapsed (s),x-axis ({unit}),y-axis ({unit}),z-axis ({unit})"
    local = ms + int(round(utc_offset_h * 3600e3))
    tstr = np.datetime_as_string(local.astype("datetime64[ms]"), unit="ms")
    if time_sep == ".":
        tstr = np.char.replace(tstr, ":", ".")
    lines = [head]
    for k in range(len(ms)):
        cells = ",".join(f"{x:.{dec}f}" for x in v[k]) if np.all(np.isfinite(v[k])) else ",,"
        lines.append(f"{ms[k]},{tstr[k]},{(ms[k] - ms[0]) / 1e3:.3f},{cells}")
    return write_text_atomic(path, "\n".join(lines) + "\n")


def write_recording_metabase(folder: str | os.PathLike, label: str, mac: str,
                             streams: Mapping[str, tuple[ArrayLike, ArrayLike]], *, rates_hz: Mapping[str, float]
                             | None = None, dialect: str = "epoch", time_sep: str = ":", utc_offset_h: float = 0.0,
                             firmware: str = "1.5.1") -> list[Path]:
    """Write the three stream files of one recording.

    streams : ``{"acc": (t_s, values), "gyr": ..., "mag": ...}`` with ``t_s`` Unix seconds (phone clock)
        and values in project units.   rates_hz : the nominal rates for the file names (default 100/100/20).
    The file names share the label, MAC and the recording's first stamp.
    """
    rates = {"acc": 100.0, "gyr": 100.0, "mag": 20.0, **(rates_hz or {})}
    ms = {k: np.round(np.asarray(t, dtype=np.float64) * 1e3).astype(np.int64) for k, (t, _) in streams.items()}
    start = int(min(m[0] for m in ms.values()))
    out = []
    for kind, (_, values) in streams.items():
        p = Path(folder) / file_name(label, start, mac, kind, rates[kind], firmware, utc_offset_h)
        out.append(write_metabase_csv(p, kind, ms[kind], values, dialect=dialect, time_sep=time_sep,
                                      utc_offset_h=utc_offset_h))
    return out


def group_metabase_files(paths: Sequence[Path]) -> dict[tuple[str, str], dict[str, Path]]:
    """Group MetaBase files by (label, MAC) → {kind: path}; other streams (temperature...) are ignored."""
    groups: dict[tuple[str, str], dict[str, Path]] = {}
    for p in paths:
        n = parse_file_name(p)
        if n is None:
            continue
        kind = STREAMS.get(n["stream"].strip())
        if kind is None:
            continue
        g = groups.setdefault((n["label"], n["mac"].upper()), {})
        if kind in g:
            raise IngestionError(f"{p} and {g[kind]} are both the {n['stream']} of recording {n['label']!r} on "
                                 f"sensor {n['mac']}; keep only one of them (or rename the label).")
        g[kind] = p
    return groups
