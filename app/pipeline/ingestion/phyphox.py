"""phyphox (RWTH Aachen phone app) exports: CSV, the zip of CSVs, and Excel.

Layout, from the app's public export code and experiment definitions (``DataExport``; the "Raw Sensors"
experiments' ``<export>`` sets):

* **CSV** ("Comma, decimal point", "Tabulator, decimal point", "Semicolon, decimal comma", "Tabulator, decimal
  comma"): a header of quoted column names, then one row per sample, numbers as ``0.000000000E0`` (``9.806650000E0``,
  ``-1.2E-3``) with the chosen decimal mark; a column shorter than the others is padded with ``NaN``.  The full
  export is a ``.zip`` with one ``<set name>.csv`` per export set (``Raw Data.csv``) and ``meta/device.csv``,
  ``meta/time.csv`` (``"event","experiment time","system time","system time text"``: the ``START`` row maps the
  experiment's time 0 to Unix seconds); the "minimal" export is the single ``.csv``.  ``meta/device.csv`` names the
  phone's model; a serial only when it has a unique-id row (:func:`_device_id`).
* **Excel** (``.xlsx``): one sheet per export set, the header in row 1, numbers below.

Columns, by name (case-insensitive; each set restarts with its own ``Time (s)``)::

    Time (s)                                     seconds from the experiment's start
    Acceleration x/y/z (m/s^2)                   "Acceleration with g": specific force, m/s²
    Gyroscope x/y/z (rad/s)                      rad/s
    Magnetic field x/y/z (µT)                    µT ("Magnetic Field x" in older versions)
    Absolute ... / anything else                 ignored

A recording is one file holding the three sensors (a custom experiment with all three, in one set or three), or
the exports of the three experiments listed together (``session.json`` ``files``).  ``Linear Acceleration``
("Acceleration without g") lacks gravity, which the calibration needs: refused, saying to export "Acceleration
with g".  Time base: Unix seconds when every file is a zip with ``meta/time.csv`` (one phone's clock), else
seconds from each export's start (``elapsed``: the sensors taken to start together).  Units are converted once,
here (:mod:`.units`); Android's and iOS's phyphox both give the specific force with +9.81 on the up axis.

Size caps (the thesis workbook's, issue 16 finding 4, and a zip bomb's).  An ``.xlsx`` is opened by
:func:`.excel.open_workbook` (the same caps, one definition) before its sheets are parsed (:mod:`.xlsx_cells`,
the thesis reader's cell reader), in the sniff too: a refusal there is the refusal the thesis reader would give,
raised once.  :func:`.session.read_recording` opens the workbooks one at a time (:class:`.excel.OneWorkbook`) and hands each to
the sniff and to the reader (phyphox's or the thesis'): a single workbook's sheets are checked and decompressed
once, and a set of several holds one in memory at a time (each opened twice: by the sniff, then by the reader).  Rows are
read up to :data:`.excel.MAX_ROWS` and :data:`MAX_COLUMNS` columns.  A zip member is refused when its declared
size passes :data:`MAX_MEMBER_MB`, the members read when they pass :data:`MAX_ZIP_MB` in all, the archive when
it lists more than :data:`MAX_MEMBERS` entries; a member is read in pieces that stop at its cap, so a declared
size that lies cannot take more memory either.  The numbers: phyphox writes a number in ~16 characters
(``-1.234567890E-3,``), so a set of 4 columns takes ~64 B a row: 10 minutes at 100 Hz is ~4 MB, the one-set
export of three sensors (15 columns) ~15 MB, a 400 Hz gyroscope's 10 minutes ~15 MB.  32 MB per member is twice
the largest of these; 96 MB in all holds three such members (one per sensor) and ``meta/``.
"""

from __future__ import annotations

import io
import os
import re
import zipfile
from pathlib import Path
from typing import Sequence

import numpy as np

from app.pipeline.ingestion import excel
from app.pipeline.ingestion.model import IngestionError, Note, Stream
from app.pipeline.ingestion.tables import check_stamps, numeric_columns, parse_table
from app.pipeline.ingestion.units import check_magnitude, unit_factor
from app.pipeline.ingestion.xlsx_cells import Workbook

_COLUMN = re.compile(r"^\s*(?P<name>.*?)\s*\((?P<unit>[^()]*)\)\s*$")
_AXIS = {"acc": re.compile(r"^acceleration ([xyz])$"), "gyr": re.compile(r"^gyroscope ([xyz])$"),
         "mag": re.compile(r"^magnetic field ([xyz])$")}
_LINEAR = re.compile(r"^linear acceleration [xyz]$")
_NAMES = {"acc": "Acceleration with g", "gyr": "Gyroscope", "mag": "Magnetometer"}
#: largest unpacked zip member, all members read, most entries of the archive (module docstring)
MAX_MEMBER_MB = 32
MAX_ZIP_MB = 96
MAX_MEMBERS = 64
#: most columns of an .xlsx sheet read (a set is time + 3-4 per sensor; all raw sensors in one set ~25)
MAX_COLUMNS = 64
_MB = 1024 * 1024

__all__ = ["looks_like_phyphox", "read_phyphox", "workbook_is_phyphox", "write_phyphox"]


def _header_kinds(header: Sequence) -> bool:
    names = [_name(h) for h in header]
    return "time" in names and any(p.match(n) for n in names for p in (*_AXIS.values(), _LINEAR))


def _name(cell) -> str:
    m = _COLUMN.match("" if cell is None else str(cell).strip().strip('"'))
    return "" if m is None else " ".join(m.group("name").lower().split())


def _first_line(text: str) -> list[str]:
    first = text.split("\n", 1)[0]
    sep = "\t" if "\t" in first else ";" if first.count(";") > first.count(",") else ","
    return [c.strip().strip('"') for c in first.split(sep)]


def _tables_zip(z: zipfile.ZipFile) -> list[str]:
    return [n for n in z.namelist() if n.lower().endswith(".csv") and not n.startswith("meta/")
            and not n.endswith("/")]


def workbook_is_phyphox(wb: Workbook) -> bool:
    """Some sheet of the open workbook ``wb`` has a phyphox header (row 1)."""
    return any(_header_kinds(wb.header(n, MAX_COLUMNS)) for n in wb.sheetnames)


def looks_like_phyphox(path: Path, wb: Workbook | None = None) -> bool:
    """A phyphox export by content: a CSV (or a zip's CSV, or an .xlsx sheet) whose header has ``Time (s)`` and
    phyphox's sensor column names.  ``wb``: an ``.xlsx`` already open (:func:`.excel.open_workbook`)."""
    suffix = path.suffix.lower()
    try:
        if suffix in (".csv", ".txt"):
            with open(path, encoding="utf-8-sig", errors="replace") as fh:
                return _header_kinds(_first_line(fh.read(4096)))
        if suffix == ".zip":
            with zipfile.ZipFile(path) as z:
                def head(member: str) -> str:  # the first 4 kB only, not the whole member decompressed
                    with z.open(member) as fh:
                        return fh.read(4096).decode("utf-8-sig", "replace")
                return any(_header_kinds(_first_line(head(n))) for n in _tables_zip(z)[:8])
        if suffix == ".xlsx":
            if wb is not None:
                return workbook_is_phyphox(wb)
            try:
                with excel.open_workbook(path) as book:  # the caps before any sheet is parsed (module docstring)
                    return workbook_is_phyphox(book)
            except IngestionError as exc:
                if exc.code == "xlsx.cannot_open":
                    return False
                raise
    except IngestionError:
        raise
    except Exception:  # noqa: BLE001 - sniffing: anything unreadable is simply not phyphox
        return False
    return False


def _csv_table(path: Path, text: str, where: str, notes: list) -> tuple[list[str], np.ndarray]:
    """Header and float table of one phyphox CSV (any of its separators and decimal marks)."""
    lines = text.split("\n", 2)
    if "\t" in lines[0] and len(lines) > 1 and "," in lines[1]:  # "Tabulator, decimal comma"
        text = text.replace(",", ".")
        notes.append(Note.of("csv_decimal_comma", file=where))
    head, sep, body = text.partition("\n")
    if '"' in head and '"' not in body:  # phyphox quotes the header's names only: unquoted, the fast parser reads it
        text = head.replace('"', "") + sep + body
    header, rows = parse_table(path, text, notes)
    header = [h.strip().strip('"') for h in header]
    names = [_name(h) for h in header]  # only the columns read: time and the sensor axes (NaN elsewhere)
    used = [j for j, n in enumerate(names) if n == "time" or any(p.match(n) for p in (*_AXIS.values(), _LINEAR))]
    table = np.full((len(rows), len(header)), np.nan)
    table[:, used] = numeric_columns(path, header, rows, used)
    return header, table


def _xlsx_tables(path: Path, wb: Workbook) -> list[tuple[str, list[str], np.ndarray]]:
    """``[(sheet, header, table)]`` of the open workbook's sheets with a phyphox header."""
    out = []
    for name in wb.sheetnames:
        try:
            first = wb.header(name, MAX_COLUMNS)
            if not _header_kinds(first):
                continue
            numbers, others = wb.table(name, max_row=excel.MAX_ROWS + 1, max_col=MAX_COLUMNS)
        except Exception as exc:  # noqa: BLE001 - a damaged sheet (a bad number, a shared string missing)
            raise IngestionError("file.unreadable", file=path, reason=str(exc)[:120]) from None
        header = ["" if c is None else str(c) for c in first]
        table = numbers[1:, :len(header)]
        for (i, j), v in sorted(others.items()):
            if i > 0 and j < len(header) and v not in ("", "NaN"):
                raise IngestionError("cell.not_number", file=path, row=i + 1, column=header[j], cell=str(v)[:40])
        out.append((name, header, table))
    return out


def check_zip(path: Path, z: zipfile.ZipFile, members: Sequence[str]) -> None:
    """Refuse an archive of more than :data:`MAX_MEMBERS` entries, or whose ``members`` declare more than
    :data:`MAX_MEMBER_MB` each or :data:`MAX_ZIP_MB` in all (module docstring), from its directory alone."""
    infos = z.infolist()
    if len(infos) > MAX_MEMBERS:
        raise IngestionError("zip.too_many_members", file=path, count=len(infos), limit=MAX_MEMBERS)
    sizes = {i.filename: i.file_size for i in infos}
    for m in members:
        if sizes.get(m, 0) > MAX_MEMBER_MB * _MB:
            raise IngestionError("zip.too_big", file=path, member=m, size_mb=sizes[m] // _MB, limit_mb=MAX_MEMBER_MB)
    total = sum(sizes.get(m, 0) for m in members)
    if total > MAX_ZIP_MB * _MB:
        raise IngestionError("zip.too_big", file=path, member="(all)", size_mb=total // _MB, limit_mb=MAX_ZIP_MB)


def read_member(path: Path, z: zipfile.ZipFile, member: str, limit_mb: int = MAX_MEMBER_MB,
                chunk_bytes: int = 1 << 20) -> bytes:
    """``member``'s bytes, read in pieces that stop once past ``limit_mb`` (then refused): the declared size
    checked by :func:`check_zip` may lie."""
    limit = limit_mb * _MB
    pieces, size = [], 0
    with z.open(member) as fh:
        while True:
            piece = fh.read(min(chunk_bytes, limit + 1 - size))
            if not piece:
                return b"".join(pieces)
            pieces.append(piece)
            size += len(piece)
            if size > limit:
                raise IngestionError("zip.too_big", file=path, member=member, size_mb=size // _MB, limit_mb=limit_mb)


def _epoch_offset(path: Path, z: zipfile.ZipFile) -> float | None:
    """Unix seconds of experiment time 0 from ``meta/time.csv``'s first ``START`` row, or None."""
    try:
        text = read_member(path, z, "meta/time.csv").decode("utf-8-sig", "replace")
    except (KeyError, zipfile.BadZipFile, OSError):
        return None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if len(lines) < 2:
        return None
    sep = "\t" if "\t" in lines[0] else ";" if ";" in lines[0] else ","
    for ln in lines[1:]:
        cells = [c.strip().strip('"') for c in ln.split(sep)]
        if len(cells) >= 3 and cells[0].upper() == "START":
            try:
                exp_t, sys_t = (float(c.replace(",", ".")) for c in cells[1:3])
            except ValueError:
                return None
            return sys_t - exp_t if np.isfinite(sys_t - exp_t) and sys_t > 1e8 else None
    return None


#: ``meta/device.csv`` properties that name one device (not a model), lower case without spaces
_DEVICE_ID_KEYS = ("uniqueid", "deviceid", "serial", "serialnumber")


def _device_id(path: Path, z: zipfile.ZipFile) -> str | None:
    """The phone's own identifier from the open zip's ``meta/device.csv`` (``"property","value"`` rows), or None.

    Only a property naming one device counts (:data:`_DEVICE_ID_KEYS`): the ``deviceModel`` / ``deviceBrand`` rows
    every export carries name a model, which two phones of a clinic may share, so they are never taken for a
    serial (the same-sensor check would then call two phones one)."""
    try:
        text = read_member(path, z, "meta/device.csv").decode("utf-8-sig", "replace")
    except (KeyError, zipfile.BadZipFile, OSError):
        return None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    sep = "\t" if lines and "\t" in lines[0] else ";" if lines and ";" in lines[0] else ","
    for ln in lines[1:]:
        cells = [c.strip().strip('"') for c in ln.split(sep)]
        if len(cells) >= 2 and cells[0].lower().replace(" ", "").replace("_", "") in _DEVICE_ID_KEYS and cells[1]:
            return cells[1][:64]
    return None


def _tables(path: Path, notes: list, wb: Workbook | None = None
            ) -> tuple[list[tuple[str, list[str], np.ndarray]], float | None, str | None]:
    """``([(where, header, table)], epoch offset or None, the phone's id or None)`` of one export file; ``wb`` the
    file's workbook when it is an ``.xlsx`` opened by the caller."""
    suffix = path.suffix.lower()
    if suffix == ".xlsx":
        if wb is not None:
            return _xlsx_tables(path, wb), None, None
        with excel.open_workbook(path) as book:
            return _xlsx_tables(path, book), None, None
    if suffix == ".zip":
        try:
            z = zipfile.ZipFile(path)
        except (zipfile.BadZipFile, OSError) as exc:
            raise IngestionError("phone.not_a_zip", file=path, reason=str(exc)[:120]) from None
        with z:
            out = []
            members = _tables_zip(z)
            check_zip(path, z, members + [n for n in z.namelist() if n == "meta/time.csv"])
            for member in members:
                try:
                    text = read_member(path, z, member).decode("utf-8-sig")
                except (UnicodeDecodeError, zipfile.BadZipFile, OSError) as exc:
                    raise IngestionError("phone.member_unreadable", file=path, member=member,
                                         reason=str(exc)[:120]) from None
                if _header_kinds(_first_line(text)):
                    out.append((f"{path.name}/{member}", *_csv_table(path, text, f"{path.name}/{member}", notes)))
            return out, _epoch_offset(path, z), _device_id(path, z)
    from app.pipeline.ingestion.tables import read_text
    return [(path.name, *_csv_table(path, read_text(path), path.name, notes))], None, None


def _streams_of(path: Path, where: str, header: list[str], table: np.ndarray) -> dict[str, tuple]:
    """``{kind: (t_s, values (n, 3) in SI, unit)}`` of one table; each ``Time (s)`` column starts a group."""
    out: dict[str, tuple] = {}
    names = [_name(h) for h in header]
    t_col = None
    found: dict[str, dict[str, int]] = {}
    groups: list[tuple[int, dict[str, dict[str, int]]]] = []
    for j, n in enumerate(names):
        if n == "time":
            if t_col is not None:
                groups.append((t_col, found))
            t_col, found = j, {}
            continue
        if _LINEAR.match(n):
            raise IngestionError("phyphox.linear_acceleration", file=path, member=where, column=header[j])
        for kind, pat in _AXIS.items():
            m = pat.match(n)
            if m and t_col is not None:
                found.setdefault(kind, {})[m.group(1)] = j
    if t_col is not None:
        groups.append((t_col, found))
    for t_col, kinds in groups:
        unit_t = _COLUMN.match(header[t_col]).group("unit")
        f_t = unit_factor("time", unit_t)
        for kind, axes in kinds.items():
            if set(axes) != {"x", "y", "z"}:
                raise IngestionError("phyphox.axes_missing", file=path, member=where, sensor=_NAMES[kind],
                                     axes=", ".join(a for a in "xyz" if a not in axes))
            unit = _COLUMN.match(header[axes["x"]]).group("unit")
            factor = unit_factor(kind, unit)
            if factor is None or f_t is None:
                raise IngestionError("phyphox.unit_unknown", file=path, member=where,
                                     column=header[axes["x"]] if factor is None else header[t_col],
                                     unit=unit if factor is None else unit_t)
            if kind in out:
                raise IngestionError("phyphox.sensor_twice", file=path, sensor=_NAMES[kind])
            t = table[:, t_col] * f_t
            v = table[:, [axes[a] for a in "xyz"]] * factor
            keep = np.isfinite(t)  # a shorter column is padded with NaN rows (time NaN too)
            out[kind] = (t[keep], v[keep], unit)
    return out


def read_phyphox(paths: Sequence[str | os.PathLike], workbooks: excel.OneWorkbook | None = None
                 ) -> tuple[Stream, Stream, Stream, str | None]:
    """Read one recording from phyphox exports (one file with the three sensors, or one file per sensor)
    → ``(acc m/s², gyr rad/s, mag µT, the phone's id or None)`` (module docstring).

    ``workbooks``: the opener of the ``.xlsx`` files among ``paths`` (:class:`.excel.OneWorkbook`: one open at a
    time, the one the sniff left open read without opening it again: for a set, the sniff's last, so the others are
    opened again), else each is opened and closed here.
    The phone's id is the ``meta/device.csv`` unique-id row of the zips (:func:`_device_id`), when every file is
    a zip and all give the same one."""
    paths = [Path(p) for p in paths]
    notes: list = []
    found: dict[str, tuple] = {}
    offsets = []
    ids = []
    for p in paths:
        tables, offset, device = _tables(p, notes, workbooks(p) if workbooks is not None else None)
        offsets.append(offset)
        ids.append(device)
        for where, header, table in tables:
            for kind, s in _streams_of(p, where, header, table).items():
                if kind in found:
                    raise IngestionError("phyphox.sensor_twice", file=p, sensor=_NAMES[kind])
                found[kind] = (p, offset, *s)
    missing = [_NAMES[k] for k in ("acc", "gyr", "mag") if k not in found]
    if missing:
        raise IngestionError("phyphox.sensors_missing", file=paths[0], sensors=", ".join(missing))
    epoch = all(o is not None for o in offsets)
    streams = []
    for kind in ("acc", "gyr", "mag"):
        p, offset, t, v, unit = found[kind]
        check_stamps(p, t, f"{kind}: Time (s)")
        if epoch:
            t = t + offset
        check_magnitude(kind, v, unit, p)
        streams.append(Stream(kind=kind, t_s=t, values=v, declared_unit=unit, file=p,
                              time_base="epoch" if epoch else "elapsed",
                              notes=tuple(dict.fromkeys(notes)) if kind == "acc" else ()))
    device = ids[0] if ids and ids[0] is not None and len(set(ids)) == 1 else None
    return streams[0], streams[1], streams[2], device


def _java_sci(x: float, decimal: str) -> str:
    """A number as phyphox's CSV writes it (Java ``DecimalFormat("0.000000000E0")``): ``-1.234000000E-3``."""
    if not np.isfinite(x):
        return "NaN"
    mant, exp = f"{x:.9E}".split("E")
    return f"{mant}E{int(exp)}".replace(".", decimal)


def write_phyphox(path: str | os.PathLike, streams: dict, *, layout: str = "zip", separator: str = ",",
                  decimal: str = ".", epoch0_s: float | None = None, old_names: bool = False,
                  unique_id: str | None = None) -> Path:
    """Write a phyphox-style export (tests, fuzzing) of ``{"acc": (t_s, m/s²), "gyr": (t_s, rad/s), "mag": (t_s,
    µT)}`` with ``t_s`` from the experiment's start.

    layout : ``"zip"`` (three sets ``Accelerometer.csv``, ``Gyroscope.csv``, ``Magnetometer.csv`` + ``meta/``),
        ``"zip-one-set"`` (one ``Raw Data.csv`` with three time columns, NaN-padded), ``"csv"`` (that one set as
        the minimal export), ``"xlsx"`` (one sheet per set).   separator / decimal : the CSV flavour.
    epoch0_s : Unix seconds of experiment time 0, written to ``meta/time.csv`` (zip layouts).
    old_names : ``Magnetic Field x`` as older app versions spell it.
    unique_id : a ``uniqueID`` row in ``meta/device.csv`` (:func:`_device_id`); None: the model only.
    """
    path = Path(path)
    mag = "Magnetic Field" if old_names else "Magnetic field"
    cols = {"acc": ("Acceleration {} (m/s^2)", "Absolute acceleration (m/s^2)"),
            "gyr": ("Gyroscope {} (rad/s)", "Absolute (rad/s)"),
            "mag": (mag + " {} (µT)", "Absolute field (µT)")}
    sets = {}
    for kind, title in (("acc", "Accelerometer"), ("gyr", "Gyroscope"), ("mag", "Magnetometer")):
        t, v = (np.asarray(a, dtype=np.float64) for a in streams[kind])
        header = ["Time (s)"] + [cols[kind][0].format(a) for a in "xyz"] + [cols[kind][1]]
        sets[title] = (header, np.column_stack([t, v, np.linalg.norm(v, axis=1)]))
    if layout in ("zip-one-set", "csv"):
        n = max(len(tab) for _, tab in sets.values())
        header = [h for hh, _ in sets.values() for h in hh]
        table = np.column_stack([np.vstack([tab, np.full((n - len(tab), tab.shape[1]), np.nan)])
                                 for _, tab in sets.values()])
        sets = {"Raw Data": (header, table)}
    if layout == "xlsx":
        import openpyxl
        wb = openpyxl.Workbook()
        wb.remove(wb.active)
        for title, (header, table) in sets.items():
            ws = wb.create_sheet(title)
            ws.append(header)
            for row in table:
                ws.append([None if not np.isfinite(x) else float(x) for x in row])
        wb.save(path)
        return path

    def csv_text(header, table) -> str:
        lines = [separator.join(f'"{h}"' for h in header)]
        lines += [separator.join(_java_sci(x, decimal) for x in row) for row in table]
        return "\n".join(lines) + "\n"

    if layout == "csv":
        (header, table), = sets.values()
        path.write_text(csv_text(header, table), encoding="utf-8")
        return path
    if layout not in ("zip", "zip-one-set"):
        raise ValueError(f"layout must be zip, zip-one-set, csv or xlsx, got {layout!r}")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for title, (header, table) in sets.items():
            z.writestr(f"{title}.csv", csv_text(header, table))
        q = '"'
        z.writestr("meta/device.csv", separator.join([q + "property" + q, q + "value" + q]) + "\n"
                   + separator.join([q + "deviceModel" + q, q + "Pixel 7" + q]) + "\n"
                   + (separator.join([q + "uniqueID" + q, q + unique_id + q]) + "\n" if unique_id else ""))
        if epoch0_s is not None:
            buf = io.StringIO()
            buf.write(separator.join(f'"{h}"' for h in ("event", "experiment time", "system time",
                                                       "system time text")) + "\n")
            buf.write(separator.join(['"START"', _java_sci(0.0, decimal), f"{epoch0_s:.3f}".replace(".", decimal),
                                      '"2023-03-13 10:00:00.000 UTC+00:00"']) + "\n")
            z.writestr("meta/time.csv", buf.getvalue())
    return path
