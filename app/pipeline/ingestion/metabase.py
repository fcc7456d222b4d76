"""MetaBase CSV (MbientLab MetaWear / MetaMotion): reader and writer, one file per stream.

File name: ``[{label}_]{device}_{YYYY-MM-DDTHH.MM.SS.mmm}_{MAC}_{Stream}_{rate}Hz[_{firmware}].csv``.
``device`` is the sensor's name as its user set it in the app (``MetaWear`` by default; real exports carry
``Werable1``, ``MetaWearA0``... : any name without ``_``); ``label`` is what the user typed for the recording
(may hold ``_``, may be absent); the MAC may be written with ``:`` or ``-``; the milliseconds are optional;
the extension in any case (a copy through a FAT-formatted stick may end in ``.CSV``).  The date-time is the
phone's local time at the recording's start.
Header, two dialects (both read, both written)::

    epoch (ms),time (-13:00),elapsed (s),x-axis (g),y-axis (g),z-axis (g)
    epoc (ms),timestamp (+0200),elapsed (s),x-axis (g),y-axis (g),z-axis (g)

Units: Accelerometer g, Gyroscope deg/s, Magnetometer T (tesla: the real export's numbers are
~5e-5, i.e. 50 µT; checked).  The time base is ``epoch (ms)`` (the phone's clock, shared by every
sensor of a session); the time string (``:`` or ``.`` between hour, minute, second) and its time zone
label are unreliable and ignored on reading.  Without an epoch column the elapsed seconds are used.

A file saved again by a spreadsheet (Excel) keeps ``elapsed (s)`` but prints ``epoch (ms)`` with six
significant digits (``1.63552E+12``: every stamp of 2.8 hours the same).  Such stamps are recognised (an
exponent in the column and repeated values) and the time base is rebuilt: the file name's start time plus
``elapsed (s)``, with a note.  The name's time is local; :func:`rebuild_offset_s` finds the phone's UTC
offset from another stream of the session whose epoch survived (``session.py`` applies it), otherwise the
rebuilt stamps stay on local time (consistent between the sensors of one phone).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import replace
import os
import re
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from app.pipeline.files import write_text_atomic
from app.pipeline.ingestion.model import IngestionError, Note, Stream
from app.pipeline.ingestion.tables import check_stamps, numeric_columns, read_csv_rows
from app.pipeline.ingestion.units import check_magnitude, unit_factor

FILE_NAME = re.compile(
    r"^(?:(?P<label>.*)_)?(?P<device>[^_]+)_"
    r"(?P<datetime>\d{4}-\d{2}-\d{2}[T ]\d{2}[.:\-]\d{2}[.:\-]\d{2}(?:[.:]\d{1,6})?)_"
    r"(?P<mac>[0-9A-Fa-f]{2}(?:[:\-]?[0-9A-Fa-f]{2}){5})_(?P<stream>[A-Za-z ]+?)_(?P<rate>\d+(?:[.,]\d+)?)Hz"
    r"(?:_(?P<firmware>[^_]*))?\.[cC][sS][vV]$")
STREAMS = {"Accelerometer": "acc", "Gyroscope": "gyr", "Magnetometer": "mag"}
STREAM_NAMES = {v: k for k, v in STREAMS.items()}
FILE_UNITS = {"acc": "g", "gyr": "deg/s", "mag": "T"}
DECIMALS = {"acc": 3, "gyr": 3, "mag": 9}
_KNOWN = {"acc": "g, mg or m/s²", "gyr": "deg/s or rad/s", "mag": "T, mT, µT or nT"}
_COL = re.compile(r"^\s*(?P<name>[^()]*?)\s*(?:\((?P<unit>[^()]*)\))?\s*$")


def parse_file_name(path: Path) -> dict[str, str] | None:
    """``label, device, datetime, mac, stream, rate, firmware`` of a MetaBase file name, or ``None``.

    ``label`` is ``""`` when the name starts with the device; ``mac`` is upper case without separators;
    ``rate`` uses ``.``.  A name whose stream is not a MetaBase sensor word (Accelerometer, Gyroscope,
    Magnetometer, Pressure, Temperature, ...) still parses; :data:`STREAMS` says which ones a knee session uses."""
    m = FILE_NAME.match(Path(path).name)
    if m is None:
        return None
    d = m.groupdict()
    d["label"] = d["label"] or ""
    d["mac"] = re.sub(r"[:\-]", "", d["mac"]).upper()
    d["rate"] = d["rate"].replace(",", ".")
    return d


def start_time(name: dict[str, str]) -> dt.datetime:
    """The recording's start in the file name (phone's local time, naive)."""
    date, clock = re.split(r"[T ]", name["datetime"], maxsplit=1)
    parts = re.split(r"[.:\-]", clock)
    ms = (parts[3] + "000")[:6] if len(parts) > 3 else "0"
    return dt.datetime(*map(int, date.split("-")), int(parts[0]), int(parts[1]), int(parts[2]), int(ms))


def rebuild_offset_s(stream: Stream, name: dict[str, str]) -> float:
    """The phone's UTC offset, s, from a stream whose epoch is real: name's local start − first stamp, rounded
    to 15 minutes (the name's time precedes the first sample by a fraction of a second)."""
    local = start_time(name).replace(tzinfo=dt.timezone.utc).timestamp()
    return 900.0 * round((local - float(stream.t_s[0])) / 900.0)


def _excel_epoch(rows: list[list[str]], i_epoch: int, epoch: np.ndarray) -> bool:
    """``epoch (ms)`` printed by a spreadsheet: an exponent in the cells and stamps repeated."""
    sample = [r[i_epoch] for r in rows[:50]]
    return any(("e" in c or "E" in c) for c in sample) and len(np.unique(epoch[np.isfinite(epoch)])) < 0.5 * len(epoch)


def _split(col: str) -> tuple[str, str]:
    m = _COL.match(col)
    return (m.group("name").lower(), (m.group("unit") or "").strip()) if m else (col.lower(), "")


def read_metabase_csv(path: str | os.PathLike, kind: str | None = None) -> Stream:
    """Read one MetaBase stream file → :class:`Stream` in project units (epoch seconds, m/s²/rad/s/µT).

    ``kind`` (acc/gyr/mag) defaults to the stream named in the file name, else to the unit in the header.
    Epoch stamps mangled by a spreadsheet are rebuilt from the name's start and ``elapsed (s)`` (module
    docstring); the stream's ``notes`` say so, and what :func:`.tables.read_csv_rows` repaired.
    """
    path = Path(path)
    name = parse_file_name(path)
    notes: list = []
    header, rows = read_csv_rows(path, notes)
    cols = [_split(c) for c in header]
    names = [c[0] for c in cols]
    i_epoch = next((i for i, n in enumerate(names) if n in ("epoch", "epoc")), None)
    i_elapsed = next((i for i, n in enumerate(names) if n == "elapsed"), None)
    axes = [next((i for i, n in enumerate(names) if n == f"{a}-axis"), None) for a in "xyz"]
    if None in axes or (i_epoch is None and i_elapsed is None):
        raise IngestionError("metabase.not_a_stream", file=path, header=",".join(header)[:200])
    units = {cols[i][1] for i in axes}
    if len(units) != 1:
        raise IngestionError("file.axes_units_differ", file=path, units=", ".join(sorted(units)))
    unit = units.pop()
    if kind is None and name is not None:
        kind = STREAMS.get(name["stream"].strip())
    if kind is None:
        kind = next((k for k in ("acc", "gyr", "mag") if unit_factor(k, unit) is not None
                     and not (k == "mag" and unit.lower() in ("g", "mg"))), None)
    factor = None if kind is None else unit_factor(kind, unit)
    if factor is None:
        raise IngestionError("unit.unknown_for_stream", file=path, unit=unit, stream=kind or "?",
                             expected=_KNOWN.get(kind, "g, deg/s, T"))
    time_col = i_epoch if i_epoch is not None else i_elapsed
    cols_read = [time_col, *axes] + ([i_elapsed] if i_epoch is not None and i_elapsed is not None else [])
    data = numeric_columns(path, header, rows, cols_read)
    t_s = data[:, 0] * (1e-3 if time_col == i_epoch else 1.0)
    time_base = "epoch" if time_col == i_epoch else "elapsed"
    if i_epoch is not None and len(cols_read) == 5 and _excel_epoch(rows, i_epoch, data[:, 0]):
        if name is None:
            raise IngestionError("metabase.excel_epoch_no_name", file=path, column=header[i_epoch])
        start = start_time(name).replace(tzinfo=dt.timezone.utc).timestamp()
        t_s = start + data[:, 4]
        time_col = i_elapsed
        notes.append(Note.of("excel_epoch_rebuilt", file=path.name, column=header[i_epoch],
                             start=start_time(name).isoformat(sep=" ", timespec="milliseconds")))
        time_base = "epoch-local"
    check_stamps(path, t_s, header[time_col])
    values = data[:, 1:4] * factor
    if np.isnan(values).all():
        raise IngestionError("stream.all_empty", file=path)
    check_magnitude(kind, values, unit, path)
    return Stream(kind=kind, t_s=t_s, values=values, declared_unit=unit, file=path,
                  nominal_fs_hz=float(name["rate"]) if name else None,
                  time_base=time_base, notes=tuple(notes))


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


def group_metabase_files(paths: Sequence[Path]) -> dict[tuple[str, str, str], dict[str, Path]]:
    """Group MetaBase files by (label, MAC, start date-time) → {kind: path}; other streams (pressure,
    temperature...) are ignored.  The start is part of the key: one sensor's two recordings typed with the
    same label (``1``, as real exports show) are two recordings, not one with doubled streams."""
    groups: dict[tuple[str, str, str], dict[str, Path]] = {}
    for p in paths:
        n = parse_file_name(p)
        if n is None:
            continue
        kind = STREAMS.get(n["stream"].strip())
        if kind is None:
            continue
        g = groups.setdefault((n["label"] or n["device"], n["mac"], n["datetime"]), {})
        if kind in g:
            raise IngestionError("metabase.stream_twice", file=p.name, other=g[kind].name, stream=n["stream"],
                                 label=n["label"] or n["device"], sensor=n["mac"])
        g[kind] = p
    return groups


def settle_local_time(streams: Sequence[Stream], final: bool = True) -> list[Stream]:
    """Put streams whose epoch was rebuilt on local time (``time_base="epoch-local"``) on the others' UTC epoch.

    The phone's UTC offset comes from any MetaBase stream among ``streams`` whose epoch survived
    (:func:`rebuild_offset_s`); each rebuilt stream is shifted by it and noted.  Without such a stream the
    rebuilt ones are left alone, or, with ``final``, declared ``"epoch"`` as they are (local time read as
    UTC: consistent between the sensors of one phone, whose files all lost their epoch) with a note.
    """
    offsets = [rebuild_offset_s(s, n) for s in streams if s.time_base == "epoch"
               for n in [parse_file_name(s.file)] if n is not None]
    out = []
    for s in streams:
        if s.time_base != "epoch-local":
            out.append(s)
        elif offsets:
            off = offsets[0]
            out.append(replace(s, t_s=s.t_s - off, time_base="epoch",
                               notes=s.notes + (Note.of("excel_epoch_offset", file=s.file.name,
                                                        offset_h=off / 3600.0),)))
        elif final:
            out.append(replace(s, time_base="epoch",
                               notes=s.notes + (Note.of("excel_epoch_local", file=s.file.name),)))
        else:
            out.append(s)
    return out
