"""Shared checks for tabular files: rows, numeric cells, time stamps.  Every failure names file, row, column."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Sequence

import numpy as np

from app.pipeline.ingestion.model import FloatArray, IngestionError

#: Fewest samples / shortest span a stream may have.
MIN_SAMPLES = 10
MIN_DURATION_S = 1.0
#: Largest magnitude a cell may hold: beyond any epoch in ms (year 33658) and any sensor reading in any unit
#: ChakaMo reads, and small enough that squaring it (vector norms) cannot overflow float64.
MAX_ABS_CELL = 1e15


def read_csv_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    """Header and data rows of a comma-separated file; refuses empty, header-only and ragged (truncated) files.

    NUL bytes are refused before decoding: they are what a UTF-16/UTF-32 export (Excel's "Unicode text") or a
    damaged copy looks like, and read as UTF-8 they would give a header that merely "lacks columns"."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise IngestionError(f"{path}: cannot be read ({exc.strerror}); check that the file exists and is "
                             f"readable, or copy it again.") from None
    if b"\x00" in raw:
        raise IngestionError(f"{path}: the file contains NUL bytes (saved as UTF-16/UTF-32 'Unicode text', or "
                             f"damaged); save it again as a UTF-8 (or plain) CSV, or export the recording again.")
    try:
        text = raw.decode("utf-8-sig")
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except UnicodeDecodeError as exc:
        raise IngestionError(f"{path}: not a text CSV file ({exc.reason}); export it again as CSV.") from None
    except csv.Error as exc:  # a cell beyond csv's field limit, a quote left open at the end...
        raise IngestionError(f"{path}: not a readable CSV file ({exc}); the file is damaged — export the "
                             f"recording again.") from None
    while rows and not any(c.strip() for c in rows[-1]):
        rows.pop()
    if not rows:
        raise IngestionError(f"{path}: the file is empty; export the recording again.")
    header = [h.strip() for h in rows[0]]
    if len(header) == 1 and ";" in header[0]:
        raise IngestionError(f"{path}: the columns are separated by ';'; save the file as comma-separated CSV "
                             f"with '.' as the decimal point.")
    data = rows[1:]
    if not data:
        raise IngestionError(f"{path}: the file has a header but no data rows; export the recording again.")
    k = len(header)
    for i, r in enumerate(data):
        if len(r) != k:
            where = "the last row" if i == len(data) - 1 else f"row {i + 2}"
            raise IngestionError(
                f"{path}: {where} has {len(r)} cells but the header has {k}"
                + ("; the file looks truncated (copy or export it again)." if i == len(data) - 1
                   else "; the file is damaged or has a stray separator — export it again."))
    return header, data


def numeric_columns(path: Path, header: Sequence[str], rows: list[list[str]], columns: Sequence[int],
                    first_row: int = 2) -> FloatArray:
    """Columns ``columns`` of ``rows`` as float64 (n, len(columns)); empty cells → NaN, text → error.

    ``first_row`` is the 1-based file row of ``rows[0]`` (for messages).
    """
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
                    raise IngestionError(
                        f"{path}: row {i + first_row}, column '{header[c]}' holds {cell!r}, which is not a number; "
                        f"fix or delete that row (decimal point '.', no thousands separator).") from None
    huge = first_huge_cell(out)
    if huge is not None:
        i, j = huge
        raise IngestionError(f"{path}: row {i + first_row}, column '{header[columns[j]]}' {huge_text(out[i, j])}; "
                             f"fix or delete that row.")
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


def check_stamps(path: Path, t_s: FloatArray, what: str = "time stamps", first_row: int = 2) -> None:
    """Time stamps present, strictly increasing, enough of them.

    Order matters for the message: stamps that go back (a clock reset at midnight) are named as such before
    the span is judged, which such stamps make negative."""
    if np.isnan(t_s).any():
        i = int(np.argmax(np.isnan(t_s)))
        raise IngestionError(f"{path}: row {i + first_row} has no {what}; fix or delete that row.")
    _check_increasing(path, t_s, what, first_row)
    if len(t_s) < MIN_SAMPLES or t_s[-1] - t_s[0] < MIN_DURATION_S:
        raise IngestionError(f"{path}: only {len(t_s)} samples ({t_s[-1] - t_s[0]:.2f} s); the recording is too "
                             f"short (at least {MIN_DURATION_S:g} s) — record again.")


def _check_increasing(path: Path, t_s: FloatArray, what: str, first_row: int) -> None:
    d = np.diff(t_s)
    if (d <= 0).any():
        i = int(np.argmax(d <= 0))
        kind = "repeats" if d[i] == 0 else "goes back in time at"
        raise IngestionError(
            f"{path}: rows {i + first_row} and {i + first_row + 1}: the {what} {kind} {float(t_s[i + 1]):.6g} s "
            f"(duplicated or out-of-order rows). Export the recording again, or remove the "
            f"{'duplicated' if d[i] == 0 else 'out-of-order'} rows.")
