"""The quote-free fast path of :func:`app.pipeline.ingestion.tables.numeric_columns` (``numpy.loadtxt``, empty cells
written ``nan`` first) against its cell-by-cell path, the reference: same numbers, same NaN, same refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.pipeline.ingestion.model import IngestionError
from app.pipeline.ingestion.tables import Rows, numeric_columns, parse_table

LINES = [
    "t,a,b,c",
    "0.0,1.5,,3",
    "0.01,,,",          # a run of empty cells, and one at the end
    ",2.5,7e-3,-1",     # one at the start
    "0.03,nan,4, ",     # a literal nan, and a cell of only blanks
    "0.04,1e3,-0.0,+2",
]


@pytest.mark.parametrize("delimiter", [",", ";", "\t"])
def test_empty_cells_read_as_the_cell_by_cell_path_reads_them(delimiter):
    lines = [ln.replace(",", delimiter) for ln in LINES]
    header, rows = parse_table(Path("x.csv"), "\n".join(lines) + "\n", delimiter=delimiter)
    assert isinstance(rows, Rows)
    reference = numeric_columns(Path("x.csv"), header, [r for r in rows], [0, 1, 2, 3])   # lists: cell by cell
    fast = numeric_columns(Path("x.csv"), header, rows, [0, 1, 2, 3])
    np.testing.assert_array_equal(fast, reference)
    assert np.isnan(fast[1, 1:]).all() and np.isnan(fast[2, 0]) and np.isnan(fast[3, 3])
    for cols in ([1, 2], [3], [0, 3]):   # any columns, several times on one Rows (a generic CSV's three streams)
        np.testing.assert_array_equal(numeric_columns(Path("x.csv"), header, rows, cols), reference[:, cols])


def test_a_text_cell_beside_empty_ones_is_still_named():
    header, rows = parse_table(Path("x.csv"), "t,a,b\n0,1,\n0.01,oops,\n0.02,3,4\n")
    with pytest.raises(IngestionError) as err:
        numeric_columns(Path("x.csv"), header, rows, [0, 1, 2])
    assert err.value.code == "cell.not_number" and err.value.params["row"] == 3 and err.value.params["column"] == "a"
