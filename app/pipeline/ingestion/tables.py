"""Shared checks for tabular files: rows, numeric cells, time stamps.  Every failure names file, row, column."""

from __future__ import annotations

import csv
import io
import re
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

import datetime as dt

from app.pipeline.ingestion.model import FloatArray, IngestionError, Note

#: Fewest samples / shortest span a stream may have.
MIN_SAMPLES = 10
MIN_DURATION_S = 1.0
#: Largest magnitude a cell may hold: beyond any epoch in ms (year 33658) and any sensor reading in any unit
#: ChakaMo reads, and small enough that squaring it (vector norms) cannot overflow float64.
MAX_ABS_CELL = 1e15


def read_csv_rows(path: Path, notes: list | None = None) -> tuple[list[str], list[list[str]]]:
    """Header and data rows of a comma- (or ``;``-) separated file; refuses empty, header-only and ragged files.

    Repaired, each with a :class:`Note` appended to ``notes`` (when given):

    * ``;`` between the header's fields (Excel in Spanish or Portuguese): read with ``;`` as separator and
      ``,`` as the decimal point (``9,81`` → ``9.81``);
    * a last row cut short (fewer cells than the header, or, when the file does not end with a line break, a
      last cell that is not a number): dropped — a copy or an export interrupted;
    * rows repeated exactly (every cell equal to an earlier row's): dropped, the first kept.

    NUL bytes are refused before decoding: they are what a UTF-16/UTF-32 export (Excel's "Unicode text") or a
    damaged copy looks like, and read as UTF-8 they would give a header that merely "lacks columns"."""
    return parse_table(path, read_text(path), notes)


def read_text(path: Path) -> str:
    """The file as text (UTF-8, BOM dropped); NUL bytes, undecodable bytes and unreadable files refused."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise IngestionError("file.unreadable", file=path, reason=exc.strerror or str(exc)) from None
    if b"\x00" in raw:
        raise IngestionError("file.nul_bytes", file=path)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise IngestionError("file.not_text", file=path, reason=exc.reason) from None


def parse_table(path: Path, text: str, notes: list | None = None,
                delimiter: str | None = None) -> tuple[list[str], list[list[str]]]:
    """:func:`read_csv_rows` on ``text`` (the table part of a file, its first line the header).

    ``delimiter`` ``None``: ``;`` when the header has at least as many ``;`` as ``,`` (then ``,`` is the
    decimal point), else ``,``; a tab-separated header (Xsens, Shimmer) gives ``"\t"``."""
    notes = [] if notes is None else notes
    first = text.split("\n", 1)[0]
    if delimiter is None:
        delimiter = "\t" if first.count("\t") > max(first.count(","), first.count(";")) else \
            ";" if first.count(";") > 0 and first.count(";") >= first.count(",") else ","
    semicolon = delimiter == ";"
    lines = text.splitlines() if '"' not in text and not _ODD_BREAKS.search(text) else None
    if lines is not None and max(map(len, lines), default=0) < _CSV_FIELD_LIMIT:
        rows = [ln.split(delimiter) for ln in lines]     # no quoting: the rows csv gives, 3× faster
    else:
        lines = None
        try:
            rows = list(csv.reader(io.StringIO(text, newline=""), delimiter=delimiter))
        except csv.Error as exc:  # a cell beyond csv's field limit, a quote left open at the end...
            raise IngestionError("file.damaged_csv", file=path, reason=str(exc)) from None
    while rows and not any(c.strip() for c in rows[-1]):
        rows.pop()
    if not rows:
        raise IngestionError("file.empty", file=path)
    header = [h.strip() for h in rows[0]]
    data = rows[1:]
    if semicolon:
        data = [[c.replace(",", ".") for c in r] for r in data]
        notes.append(Note.of("csv_semicolon", file=path.name))
    if not data:
        raise IngestionError("file.header_only", file=path)
    k = len(header)
    last = data[-1]
    cut = len(last) < k or (not text.rstrip(" \t").endswith(("\n", "\r")) and len(last) == k
                            and not _number_or_empty(last[-1]))
    if cut and len(data) > 1:
        data.pop()
        notes.append(Note.of("truncated_last_row", file=path.name, row=len(data) + 2))
    if set(map(len, data)) != {k}:
        i = next(i for i, r in enumerate(data) if len(r) != k)
        raise IngestionError("file.ragged_row", file=path, row=i + 2, cells=len(data[i]), header_cells=k)
    body = lines[1:1 + len(data)] if lines is not None else [delimiter.join(r) for r in data]
    dropped = _copies(data, keep_last=False) if len(set(body)) != len(body) else []
    if dropped:
        if not _in_time_order(header, data, dropped) and _in_time_order(header, data, _copies(data, keep_last=True)):
            dropped = _copies(data, keep_last=True)     # the block pasted before its original: keep the original
        gone = set(dropped)
        data = [r for i, r in enumerate(data) if i not in gone]
        body = [ln for i, ln in enumerate(body) if i not in gone]
        notes.append(Note.of("duplicate_rows", file=path.name, rows=len(dropped), first_row=min(dropped) + 2))
    if lines is None:
        return header, data
    rows = Rows(data)
    rows.lines, rows.delimiter = (body if not semicolon else [ln.replace(",", ".") for ln in body]), delimiter
    return header, rows


class Rows(list):
    """Data rows (lists of cells) that also keep their text lines (``lines``, ``delimiter``) when the file
    had no quoting: :func:`numeric_columns` then parses the numbers in C (``numpy.loadtxt``)."""

    lines: list[str]
    delimiter: str


#: line breaks str.splitlines() knows and csv does not (\v, \f, \x1c-\x1e, NEL, LS, PS): such a file takes csv
_ODD_BREAKS = re.compile("[\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029]")
#: beyond csv's per-field limit a damaged file must still fail as csv fails it (one huge "cell")
_CSV_FIELD_LIMIT = csv.field_size_limit()


def _copies(data: list[list[str]], keep_last: bool) -> list[int]:
    """Indices of rows equal to another row, all but the first (or the last) of each group."""
    seen: set[tuple[str, ...]] = set()
    order = range(len(data) - 1, -1, -1) if keep_last else range(len(data))
    out = []
    for i in order:
        key = tuple(data[i])
        if key in seen:
            out.append(i)
        else:
            seen.add(key)
    return sorted(out)


_TIME_WORDS = ("epoc", "time", "elapsed", "stamp", "packetcounter")


def _in_time_order(header: list[str], data: list[list[str]], dropped: list[int]) -> bool:
    """Whether the first time-like column (by name) still increases once ``dropped`` rows are gone."""
    j = next((i for i, h in enumerate(header) if any(w in h.lower() for w in _TIME_WORDS)), None)
    if j is None:
        return True
    gone = set(dropped)
    values = []
    for i, r in enumerate(data):
        if i not in gone:
            try:
                values.append(float(r[j]))
            except ValueError:
                continue
    return bool(np.all(np.diff(values) > 0)) if len(values) > 1 else True


def _number_or_empty(cell: str) -> bool:
    cell = cell.strip().strip('"')
    if not cell:
        return True
    try:
        float(cell)
    except ValueError:
        return False
    return True


def numeric_columns(path: Path, header: Sequence[str], rows: list[list[str]], columns: Sequence[int],
                    first_row: int = 2) -> FloatArray:
    """Columns ``columns`` of ``rows`` as float64 (n, len(columns)); empty cells → NaN, text → error.

    ``first_row`` is the 1-based file row of ``rows[0]`` (for messages).  Rows from :func:`parse_table` of a
    quote-free file are parsed by ``numpy.loadtxt``; any cell it refuses (empty, text) falls back to the
    cell-by-cell path below, whose message names the row and column.
    """
    lines = getattr(rows, "lines", None)
    if lines is not None and len(lines) == len(rows) and rows:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = np.loadtxt(lines, delimiter=rows.delimiter, usecols=tuple(columns), dtype=np.float64,
                                 comments=None, ndmin=2)
        except ValueError:
            out = None
        if out is not None and out.shape == (len(rows), len(columns)) and first_huge_cell(out) is None:
            return out
    out = np.empty((len(rows), len(columns)))
    for j, c in enumerate(columns):
        col = [r[c] for r in rows]
        try:
            out[:, j] = np.array(col, dtype=np.float64)
        except ValueError:
            for i, cell in enumerate(col):
                cell = cell.strip()
                if cell == "":
                    out[i, j] = np.nan
                    continue
                try:
                    out[i, j] = float(cell)
                except ValueError:
                    raise IngestionError("cell.not_number", file=path, row=i + first_row, column=header[c],
                                         cell=cell[:40]) from None
    huge = first_huge_cell(out)
    if huge is not None:
        i, j = huge
        raise IngestionError("cell.infinite" if np.isinf(out[i, j]) else "cell.huge", file=path, row=i + first_row,
                             column=header[columns[j]], value=f"{out[i, j]:.3g}")
    return out


def first_huge_cell(table: np.ndarray) -> tuple[int, int] | None:
    """``(row, column)`` of the first cell of ``table`` beyond :data:`MAX_ABS_CELL` (inf included; NaN, an
    empty cell, is not), or None."""
    with np.errstate(invalid="ignore"):
        huge = np.abs(table) > MAX_ABS_CELL
    return tuple(int(k) for k in np.argwhere(huge)[0]) if huge.any() else None


def huge_text(value: float) -> str:
    """What is wrong with a cell :func:`first_huge_cell` found, for the message."""
    return "is infinite" if np.isinf(value) else f"holds {value:.3g}, beyond any time stamp or reading"


def when(t_s: float, t0_s: float) -> str:
    """An instant for a message: seconds from the recording's start, plus the UTC wall-clock time when the
    stamps are Unix epoch seconds (``"12.340 s (2021-10-29 14:18:52.356 UTC)"``), never ``1.63552e+09 s``."""
    text = f"{t_s - t0_s:.3f} s"
    if t0_s > 1e8:  # epoch seconds (after 1973): a real date
        clock = dt.datetime.fromtimestamp(t_s, tz=dt.timezone.utc)
        text += f" ({clock:%Y-%m-%d %H:%M:%S}.{clock.microsecond // 1000:03d} UTC)"
    return text


def check_stamps(path: Path, t_s: FloatArray, column: str = "time", first_row: int = 2) -> None:
    """Time stamps present, strictly increasing, enough of them; ``column`` is the stamp column's header.

    Order matters for the message: stamps that go back (a clock reset at midnight) are named as such before
    the span is judged, which such stamps make negative."""
    if np.isnan(t_s).any():
        i = int(np.argmax(np.isnan(t_s)))
        raise IngestionError("stamp.missing", file=path, row=i + first_row, column=column)
    _check_increasing(path, t_s, column, first_row)
    if len(t_s) < MIN_SAMPLES or t_s[-1] - t_s[0] < MIN_DURATION_S:
        raise IngestionError("stream.too_short", file=path, samples=len(t_s), seconds=float(t_s[-1] - t_s[0]),
                             min_s=MIN_DURATION_S)


def _check_increasing(path: Path, t_s: FloatArray, column: str, first_row: int) -> None:
    d = np.diff(t_s)
    if (d <= 0).any():
        i = int(np.argmax(d <= 0))
        raise IngestionError("stamp.repeats" if d[i] == 0 else "stamp.goes_back", file=path, row=i + first_row,
                             row2=i + first_row + 1, column=column, at=when(float(t_s[i + 1]), float(t_s[0])))
