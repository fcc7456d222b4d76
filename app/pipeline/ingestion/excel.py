"""The thesis' Excel layout (seed 004 §8.6, Fig. 8.6): one .xlsx per sensor × recording.

Row 1 is the header, data from row 2; each column's unit is read from its header::

    A elapsed (s) | B–D x/y/z-axis (g)       accelerometer (100 Hz)
                  | E–G x/y/z-axis (deg/s)   gyroscope, on A's time
    H elapsed (s) | I–K x/y/z-axis (T)       magnetometer (20 Hz: shorter columns, blank below)
    L elapsed (s) | M temperature (C)        ignored

File names ``{calibracion-sensor|standing|laydown|step}-{muslo|pierna}-{ID}-{ddmmyyyy}-{n}[-H].xlsx``.
The time base is elapsed seconds (no epoch): the two sensors' recordings are assumed to start together.
A workbook with several sheets: the one sheet whose header has this layout is used (and the choice is
noted); none or several such sheets is refused.  The cells are read by :mod:`.xlsx_cells` (the sheet XML
matched by regular expressions, the data rows by numpy over the bytes: :mod:`.xlsx_scan`; openpyxl's values); ``openpyxl`` reads the shared strings and writes the test workbooks.

Size caps (issue 16, finding 4: a 70 kB crafted workbook unpacked to 18 MB of identical rows and cost
10–30 s of CPU; the cost of reading grows with rows and cells, about 0.1 ms a row measured here).  An .xlsx
is a zip archive: before any part is parsed, the archive's directory is read (:func:`check_archive`) and a
part that would unpack beyond :data:`MAX_SHEET_MB` (a worksheet) or :data:`MAX_PART_MB` (anything else:
the shared strings are parsed whole when a cell needs them: their cap goes by the relationship that names them,
wherever they lie), more than :data:`MAX_PARTS` parts (or sheet names) or more than :data:`MAX_UNPACKED_MB` in all
is refused.  ``ZipInfo.file_size`` is a declaration, but Python's
reader never returns more bytes than it (and checks the CRC at the end), so a lying archive is bounded too.
Then each sheet's XML is streamed once through a tag count (:func:`open_workbook`, ~0.03 s a MB:
decompression and :func:`.xlsx_cells.count_tags`, no XML tree, stopped at the caps), and more than :data:`MAX_ROWS`
rows or :data:`MAX_CELLS` cells is refused before the sheets are parsed; the XML so read is the one parsed (one
decompression per sheet, and one open workbook for the phyphox sniff, the phyphox reader and this one); the parse itself is bounded by the
same numbers (``max_row``, and the 13 columns of the layout), so a row number far away (``r="1048576"``, filled
with empty rows up to ``max_row``) or a cell in column XFD cannot blow it up either.  The worst accepted workbook
cost ~6 s of CPU with openpyxl; the checks of the web application run in a helper process with a time limit.
"""

from __future__ import annotations

import os
import re
import zipfile
from pathlib import Path
from typing import BinaryIO

import numpy as np

from app.pipeline.ingestion.model import IngestionError, Note, Stream, rows_all
from app.pipeline.ingestion.tables import check_stamps, first_huge_cell
from app.pipeline.ingestion.units import check_magnitude, unit_factor
from app.pipeline.ingestion.xlsx_cells import Workbook, count_tags

HEADER = ["elapsed (s)", "x-axis (g)", "y-axis (g)", "z-axis (g)", "x-axis (deg/s)", "y-axis (deg/s)",
          "z-axis (deg/s)", "elapsed (s)", "x-axis (T)", "y-axis (T)", "z-axis (T)", "elapsed (s)",
          "temperature (C)"]
_GROUPS = {"acc": (0, (1, 2, 3)), "gyr": (0, (4, 5, 6)), "mag": (7, (8, 9, 10))}
_CELL = re.compile(r"(?P<name>[^()]*+)\((?P<unit>[^()]*+)\)")

#: most data rows of a sheet: 10 minutes at 100 Hz (the protocol's recordings last 0.5–1.5 min, seed 004 §8)
MAX_ROWS = 60_000
#: most cells of a sheet (the layout's 13 columns fill about 8 a row: acc/gyro every row, mag 1 row in 5)
MAX_CELLS = 16 * MAX_ROWS
#: largest unpacked worksheet (60 000 rows of 13 full-precision numbers take ~40 MB)
MAX_SHEET_MB = 64
#: largest other unpacked part (shared strings, styles, theme: a few kB in a real workbook)
MAX_PART_MB = 8
#: largest unpacked workbook, and most parts in its archive
MAX_UNPACKED_MB = 128
MAX_PARTS = 256
#: shared strings allowed beyond the sheets' cells (a writer may keep a few texts no cell shows any more)
_STRINGS_SLACK = 1000


def _name_unit(text: str) -> tuple[str, str] | None:
    """``(name, unit)`` of a header cell ``"name (unit)"`` (blanks around the name and the whole cell ignored), or
    ``None``.  Stripped in Python and matched possessively: linear in the cell's length (a lazy name before
    ``\\s*\\(`` rescanned a run of blanks from every position: quadratic in a crafted header cell)."""
    m = _CELL.fullmatch(text.strip())
    return (m.group("name").rstrip(), m.group("unit")) if m else None


def _openpyxl():
    try:
        import openpyxl
    except ImportError:  # pragma: no cover - dependency declared in pyproject
        raise IngestionError("xlsx.no_openpyxl") from None
    return openpyxl


def _layout_problem(header: list) -> str | None:
    """``None`` if ``header`` (row 1) has the Fig. 8.6 layout, else what is wrong."""
    cells = [("" if c is None else str(c)) for c in header[:11]] + [""] * max(0, 11 - len(header))
    for t, axes in _GROUPS.values():
        m = _name_unit(cells[t])
        if not m or m[0].lower() not in ("elapsed", "time", "tiempo"):
            return f"cell {chr(65 + t)}1 is {cells[t]!r}, expected 'elapsed (s)'"
        for a, i in zip("xyz", axes):
            m = _name_unit(cells[i])
            if not m or not m[0].lower().startswith(a):
                return f"cell {chr(65 + i)}1 is {cells[i]!r}, expected '{a}-axis (unit)'"
    return None


def check_archive(path: Path) -> None:
    """Refuse an archive whose parts would unpack beyond the caps (module docstring), from its directory alone."""
    try:
        with zipfile.ZipFile(path) as z:
            infos = z.infolist()
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise IngestionError("xlsx.cannot_open", file=path, reason=f"{type(exc).__name__}: {exc}"[:200]) from None
    if len(infos) > MAX_PARTS:
        raise IngestionError("xlsx.too_many_parts", file=path, count=len(infos), limit=MAX_PARTS)
    mb = 1024 * 1024
    for info in infos:
        limit = MAX_SHEET_MB if info.filename.startswith("xl/worksheets/") else MAX_PART_MB
        if info.file_size > limit * mb:
            raise IngestionError("xlsx.too_big", file=path, member=info.filename, size_mb=info.file_size // mb,
                                 limit_mb=limit)
    total = sum(i.file_size for i in infos)
    if total > MAX_UNPACKED_MB * mb:
        raise IngestionError("xlsx.too_big", file=path, member="(all)", size_mb=total // mb, limit_mb=MAX_UNPACKED_MB)


def count_rows_cells(fh: BinaryIO, stop_rows: int | None = None, stop_cells: int | None = None,
                     chunk_bytes: int = 1 << 20) -> tuple[int, int, bytearray | None]:
    """(row tags, cell tags, the XML read) of the stream ``fh`` (a worksheet), read in pieces of ``chunk_bytes``
    into one buffer (no list of pieces joined into a second copy); the count stops early once past ``stop_rows``
    rows or ``stop_cells`` cells, and the XML is then ``None``.  Each piece is counted up to the buffer's last
    ``>`` and the rest on the next: a start tag cannot hold a ``>`` before its end, so none is cut or counted
    twice."""
    rows = cells = done = 0
    buf = bytearray()
    while True:
        piece = fh.read(chunk_bytes)
        buf += piece
        cut = max(buf.rfind(b">", done) + 1, done) if piece else len(buf)
        rows += count_tags(buf, b"row", cut, done)
        cells += count_tags(buf, b"c", cut, done)
        done = cut
        if (stop_rows is not None and rows > stop_rows) or (stop_cells is not None and cells > stop_cells):
            return rows, cells, None
        if not piece:
            return rows, cells, buf


def open_workbook(path: str | os.PathLike) -> Workbook:
    """The workbook at ``path``, open, every sheet checked against the caps (module docstring) before any is parsed.

    The archive's directory first (:func:`check_archive`); then the listed sheets (at most :data:`MAX_PARTS`) and
    the shared strings' size by their role (the relationship's type, wherever the part lies: at most
    :data:`MAX_PART_MB`); then each part holding a sheet, once however many names list it, is streamed once
    through :func:`count_rows_cells` and, when within the caps, handed to the :class:`.xlsx_cells.Workbook`
    (:meth:`~.xlsx_cells.Workbook.keep`), which parses it from there: a sheet is decompressed once for the caps
    and the reading.  Kept are sheets up to :data:`MAX_SHEET_MB` in all (one full data sheet; a part beyond is read
    again if parsed), and all XML read at most :data:`MAX_UNPACKED_MB`.  Last the shared strings: more ``<si>``
    than the sheets hold cells (each text is some cell's; :data:`_STRINGS_SLACK` more, :data:`MAX_CELLS` at most)
    is refused before openpyxl parses them (~8 µs a string: 4 MB of ``<si/>`` took 6.8 s, review finding).  The caller closes the workbook (a ``with`` block).  A damaged archive or
    sheet (zip, XML, deflate stream, CRC) is refused as ``xlsx.cannot_open``."""
    path = Path(path)
    check_archive(path)
    try:
        wb = Workbook(path)
    except Exception as exc:  # noqa: BLE001 - zip/xml errors of a damaged file
        raise IngestionError("xlsx.cannot_open", file=path, reason=f"{type(exc).__name__}: {exc}"[:200]) from None
    mb = 1024 * 1024
    try:
        if wb.listed > MAX_PARTS:
            raise IngestionError("xlsx.too_many_parts", file=path, count=wb.listed, limit=MAX_PARTS)
        strings = wb.strings_part
        if strings is not None and wb.size(strings) > MAX_PART_MB * mb:
            raise IngestionError("xlsx.too_big", file=path, member=strings, size_mb=wb.size(strings) // mb,
                                 limit_mb=MAX_PART_MB)
        total = kept = all_cells = 0
        for part in wb.parts:
            with wb.open_member(part) as fh:
                rows, cells, xml = count_rows_cells(fh, stop_rows=MAX_ROWS + 1, stop_cells=MAX_CELLS)
            if rows > MAX_ROWS + 1:
                raise IngestionError("xlsx.too_many_rows", file=path, sheet=part, limit=MAX_ROWS,
                                     minutes=MAX_ROWS // 6000)
            if cells > MAX_CELLS:
                raise IngestionError("xlsx.too_many_cells", file=path, sheet=part, cells=cells, limit=MAX_CELLS)
            total += len(xml)
            all_cells += cells
            if total > MAX_UNPACKED_MB * mb:
                raise IngestionError("xlsx.too_big", file=path, member="(all)", size_mb=total // mb,
                                     limit_mb=MAX_UNPACKED_MB)
            if kept + len(xml) <= MAX_SHEET_MB * mb:
                kept += len(xml)
                wb.keep(part, xml)
            del xml
        if strings is not None:
            with wb.open_member(strings) as fh:
                xml = fh.read()
            n, limit = count_tags(xml, b"si"), min(all_cells + _STRINGS_SLACK, MAX_CELLS)
            if n > limit:
                raise IngestionError("xlsx.too_many_strings", file=path, member=strings, count=n, limit=limit)
            wb.keep_strings(xml)
    except IngestionError:
        wb.close()
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged sheet (missing part, deflate stream, CRC)
        wb.close()
        raise IngestionError("xlsx.cannot_open", file=path, reason=f"{type(exc).__name__}: {exc}"[:200]) from None
    return wb


class OneWorkbook:
    """The ``.xlsx`` files of one recording, opened (:func:`open_workbook`: the caps) one at a time: called with a
    path, the workbook of that path, open; opening another closes the one before (its sheets' XML, up to
    :data:`MAX_SHEET_MB`, is dropped with it), so a phyphox set of several workbooks holds one in memory.  A single
    workbook's sniff and reader share one opening; a set of ``N`` is opened ``2N`` times (the sniff walks them
    all, then the reader starts again from the first: memory bounded, not time).  ``None`` for a path that is not
    an ``.xlsx``.
    :meth:`close` (or a ``with`` block) closes the last one."""

    def __init__(self) -> None:
        self._path: Path | None = None
        self._wb: Workbook | None = None

    def __call__(self, path: Path) -> Workbook | None:
        path = Path(path)
        if path.suffix.lower() != ".xlsx":
            return None
        if path != self._path:
            self.close()
            self._wb, self._path = open_workbook(path), path
        return self._wb

    def close(self) -> None:
        if self._wb is not None:
            self._wb.close()
        self._wb = self._path = None

    def __enter__(self) -> OneWorkbook:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_thesis_xlsx(path: str | os.PathLike, sheet: str | None = None,
                     wb: Workbook | None = None) -> tuple[Stream, Stream, Stream, str]:
    """Read a thesis workbook → ``(acc, gyr, mag, note)`` in project units; ``note`` says which sheet was used.

    ``wb``: the workbook already open (:func:`open_workbook`, by the caller that sniffed it; the caller closes
    it), else it is opened here.  Refused before parsing when beyond the size caps (module docstring)."""
    path = Path(path)
    own = wb is None
    if own:
        wb = open_workbook(path)
    try:
        names = wb.sheetnames
        if sheet is not None:
            if sheet not in names:
                raise IngestionError("xlsx.no_such_sheet", file=path, sheet=sheet, sheets=", ".join(names))
            chosen = sheet
        else:
            good = [n for n in names if _layout_problem(list(wb.header(n, len(HEADER)))) is None]
            if len(good) != 1:
                detail = ""
                if not good:
                    problem = _layout_problem(list(wb.header(names[0], len(HEADER))))
                    detail = f" (sheet {names[0]!r}: {problem or 'empty'})"
                raise IngestionError("xlsx.no_layout_sheet" if not good else "xlsx.several_layout_sheets",
                                     file=path, sheets=", ".join(good), detail=detail)
            chosen = good[0]
        header_row = list(wb.header(chosen, len(HEADER)))
        numbers, others = wb.table(chosen, max_row=MAX_ROWS + 1, max_col=len(HEADER))
    except IngestionError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged sheet (a cell's bad number, a shared string missing)
        raise IngestionError("xlsx.cannot_open", file=path, reason=f"{type(exc).__name__}: {exc}"[:200]) from None
    finally:
        if own:
            wb.close()
    note = Note.of("sheet_chosen_of", sheet=chosen, sheets=str(names)) if len(names) > 1 else \
        Note.of("sheet_chosen", sheet=chosen)
    if len(numbers) < 2:
        raise IngestionError("xlsx.no_rows", file=path, sheet=chosen)
    problem = _layout_problem(header_row)
    if problem:
        raise IngestionError("xlsx.not_layout", file=path, sheet=chosen, problem=problem)
    header = [("" if c is None else str(c)) for c in header_row]
    width = 11
    table = numbers[1:, :width].copy()
    for (i, j), c in sorted(others.items()):   # text and booleans below the header: a number typed as text
        if i == 0 or j >= width or (isinstance(c, str) and not c.strip()):
            continue
        try:
            if isinstance(c, bool):         # Excel's TRUE/FALSE: float() would take them as 1/0
                raise TypeError
            table[i - 1, j] = float(c)
        except (TypeError, ValueError):
            raise IngestionError("xlsx.cell_not_number", file=path, sheet=chosen, cell=f"{chr(65 + j)}{i + 1}",
                                 value=repr(c)[:40]) from None
    huge = first_huge_cell(table)  # the CSV readers' check: inf, 1e300 (norms would overflow); nan is empty
    if huge is not None:
        i, j = huge
        raise IngestionError("xlsx.cell_infinite" if np.isinf(table[i, j]) else "xlsx.cell_huge", file=path,
                             sheet=chosen, cell=f"{chr(65 + j)}{i + 2}", value=f"{table[i, j]:.3g}")
    streams = []
    for kind, (t_col, axes) in _GROUPS.items():
        units = {_name_unit(header[i])[1].strip() for i in axes}
        t_unit = _name_unit(header[t_col])[1]
        if len(units) != 1:
            raise IngestionError("file.axes_units_differ", file=path, units=", ".join(sorted(units)))
        unit = units.pop()
        f, ft = unit_factor(kind, unit), unit_factor("time", t_unit)
        if f is None or ft is None:
            bad = unit if f is None else t_unit
            raise IngestionError("xlsx.unit_unknown", file=path, unit=bad)
        block = table[:, [t_col, *axes]]
        used = ~rows_all(np.isnan(block))
        last = int(np.nonzero(used)[0][-1]) + 1 if used.any() else 0
        block = block[:last]
        if last == 0:
            raise IngestionError("xlsx.stream_empty", file=path, sheet=chosen, stream=kind)
        t_s = block[:, 0] * ft
        check_stamps(path, t_s, f"{header[t_col]} ({chr(65 + t_col)})")
        values = block[:, 1:] * f
        check_magnitude(kind, values, unit, path)
        streams.append(Stream(kind=kind, t_s=t_s, values=values, declared_unit=unit, file=path,
                              time_base="elapsed"))
    return streams[0], streams[1], streams[2], note


def write_thesis_xlsx(path: str | os.PathLike, acc: tuple, gyr_values: np.ndarray, mag: tuple,
                      extra_sheets: tuple[str, ...] = ()) -> Path:
    """Write a workbook in the thesis layout (for tests and the demo).

    acc : ``(t_s, values m/s²)``; gyr_values : (n, 3) rad/s on acc's times; mag : ``(t_s, values µT)``.
    Written in g, deg/s, T like Fig. 8.6; temperature constant 25 °C once per second.
    """
    openpyxl = _openpyxl()
    path = Path(path)
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.title = "data"
    ws.append(HEADER)
    t_a, a = np.asarray(acc[0]), np.asarray(acc[1]) / unit_factor("acc", "g")
    g = np.asarray(gyr_values) / unit_factor("gyr", "deg/s")
    t_m, m = np.asarray(mag[0]), np.asarray(mag[1]) / unit_factor("mag", "T")
    t_temp = np.arange(0.0, t_a[-1] - t_a[0], 1.0)
    for k in range(max(len(t_a), len(t_m))):
        row: list = []
        row += [round(t_a[k] - t_a[0], 3), *np.round(a[k], 3), *np.round(g[k], 3)] if k < len(t_a) else [None] * 7
        row += [round(t_m[k] - t_m[0], 3), *(float(f"{x:.5g}") for x in m[k])] if k < len(t_m) else [None] * 4
        row += [float(t_temp[k]), 25.0] if k < len(t_temp) else []
        ws.append(row)
    for name in extra_sheets:
        wb.create_sheet(name).append(["notes"])
    tmp = path.with_name(path.name + ".part")
    wb.save(tmp)
    os.replace(tmp, path)
    return path
