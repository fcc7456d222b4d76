"""Shared checks for tabular files: rows, numeric cells, time stamps.  Every failure names file, row, column."""

from __future__ import annotations

import csv
import io
import operator
import warnings
from pathlib import Path
from collections.abc import Sequence

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
    lines = text.splitlines() if '"' not in text and not any(c in text for c in _ODD_BREAKS) else None
    if lines is not None and max(map(len, lines), default=0) < _CSV_FIELD_LIMIT:
        while lines and not lines[-1].replace(delimiter, "").strip():
            lines.pop()
        if not lines:
            raise IngestionError("file.empty", file=path)
        header = [h.strip() for h in lines[0].split(delimiter)]
        body = lines[1:]
        if semicolon:
            body = [ln.replace(",", ".") for ln in body]
        data: Sequence = Rows(body, delimiter)          # no quoting: split lazily, numbers parsed in C
    else:
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
    if semicolon:
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
    widths = data.widths() if isinstance(data, Rows) else list(map(len, data))
    if set(widths) != {k}:
        i = next(i for i, w in enumerate(widths) if w != k)
        raise IngestionError("file.ragged_row", file=path, row=i + 2, cells=widths[i], header_cells=k)
    keys = data.lines if isinstance(data, Rows) else [tuple(r) for r in data]
    dropped = _copies(keys, keep_last=False) if len(set(keys)) != len(keys) else []
    if dropped:
        if not _in_time_order(header, data, dropped) and _in_time_order(header, data, _copies(keys, keep_last=True)):
            dropped = _copies(keys, keep_last=True)     # the block pasted before its original: keep the original
        gone = set(dropped)
        data = Rows([ln for i, ln in enumerate(data.lines) if i not in gone], delimiter) if isinstance(data, Rows) \
            else [r for i, r in enumerate(data) if i not in gone]
        notes.append(Note.of("duplicate_rows", file=path.name, rows=len(dropped), first_row=min(dropped) + 2))
    return header, data


class Rows(Sequence):
    """The data rows of a quote-free file, kept as text ``lines`` and split into cells (``rows[i]`` → list
    of str) only when asked; :func:`numeric_columns` parses their numbers in C (``numpy.loadtxt``)."""

    def __init__(self, lines: list[str], delimiter: str) -> None:
        self.lines, self.delimiter = lines, delimiter
        self._nan_lines: list[str] | None = None

    def __len__(self) -> int:
        return len(self.lines)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return Rows(self.lines[i], self.delimiter)
        return self.lines[i].split(self.delimiter)

    def __iter__(self):
        d = self.delimiter
        return (ln.split(d) for ln in self.lines)

    def pop(self) -> list[str]:
        self._nan_lines = None
        return self.lines.pop().split(self.delimiter)

    def empty_as_nan(self) -> list[str]:
        """The lines with every empty cell written ``nan`` (what :func:`numeric_columns`' cell-by-cell path makes
        of it), for ``numpy.loadtxt``; made once (a generic CSV reads three streams from one file).  A cell of
        only blanks stays as it is: loadtxt refuses it and the cell-by-cell path reads it."""
        if self._nan_lines is None:
            d = self.delimiter
            text = "\n".join(self.lines)
            for _ in range(2):   # ",,," : the first pass fills every other gap, the second the rest
                text = text.replace(d + d, f"{d}nan{d}")
            text = text.replace("\n" + d, f"\nnan{d}").replace(d + "\n", f"{d}nan\n")
            text = ("nan" if text.startswith(d) else "") + text + ("nan" if text.endswith(d) else "")
            self._nan_lines = text.split("\n")
        return self._nan_lines

    def widths(self) -> list[int]:
        """Cells per row (separators + 1), without splitting."""
        counts = list(map(operator.methodcaller("count", self.delimiter), self.lines))
        return [c + 1 for c in counts] if len(set(counts)) > 1 else [counts[0] + 1] * len(counts) if counts else []


#: line breaks str.splitlines() knows and csv does not (\v, \f, \x1c-\x1e, NEL, LS, PS): such a file takes csv.
#: Looked for one character at a time (``in``: a memchr each, ~0.2 ms a 1.6 MB file; a character class regular
#: expression took 8.5 ms, a quarter of reading a MetaBase session)
_ODD_BREAKS = "\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
#: beyond csv's per-field limit a damaged file must still fail as csv fails it (one huge "cell")
_CSV_FIELD_LIMIT = csv.field_size_limit()


def _copies(keys: Sequence, keep_last: bool) -> list[int]:
    """Indices of rows whose key (text line, or tuple of cells) repeats, all but the first (or last) of each."""
    seen: set = set()
    order = range(len(keys) - 1, -1, -1) if keep_last else range(len(keys))
    out = []
    for i in order:
        key = keys[i]
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
                    first_row: int = 2, max_abs: float | None = None) -> FloatArray:
    """Columns ``columns`` of ``rows`` as float64 (n, len(columns)); empty cells → NaN, text → error.

    ``first_row`` is the 1-based file row of ``rows[0]`` (for messages).  Rows from :func:`parse_table` of a
    quote-free file are parsed by ``numpy.loadtxt``; any cell it refuses (empty, text) falls back to the
    cell-by-cell path below, whose message names the row and column.
    """
    if isinstance(rows, Rows) and rows.lines:
        out = _loadtxt(rows.lines, rows.delimiter, columns)
        if out is None:   # empty cells (a stream sampled less often than the file's rows): NaN, as below
            out = _loadtxt(rows.empty_as_nan(), rows.delimiter, columns)
        if out is not None and out.shape == (len(rows), len(columns)) and first_huge_cell(out, max_abs) is None:
            return out
    out = np.empty((len(rows), len(columns)))
    cells = list(rows)   # each row split once (Rows splits on every access)
    for j, c in enumerate(columns):
        col = [r[c] for r in cells]
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
    huge = first_huge_cell(out, max_abs)
    if huge is not None:
        i, j = huge
        raise IngestionError("cell.infinite" if np.isinf(out[i, j]) else "cell.huge", file=path, row=i + first_row,
                             column=header[columns[j]], value=f"{out[i, j]:.3g}")
    return out


def _loadtxt(lines: list[str], delimiter: str, columns: Sequence[int]) -> FloatArray | None:
    """``numpy.loadtxt`` of ``columns`` of ``lines`` (float64, 2-D), None when it refuses a cell."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return np.loadtxt(lines, delimiter=delimiter, usecols=tuple(columns), dtype=np.float64, comments=None,
                              ndmin=2)
    except ValueError:
        return None


def first_huge_cell(table: np.ndarray, max_abs: float | None = None) -> tuple[int, int] | None:
    """``(row, column)`` of the first cell of ``table`` beyond :data:`MAX_ABS_CELL` (inf included; NaN, an
    empty cell, is not), or None."""
    with np.errstate(invalid="ignore"):
        huge = np.abs(table) > (MAX_ABS_CELL if max_abs is None else max_abs)
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
