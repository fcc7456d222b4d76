"""Crafted workbooks are refused before they cost the server (issue 16, finding 4; ``excel.py``'s size caps).

The files are built the way an attacker would: a real openpyxl workbook whose worksheet XML is then replaced by
one of identical rows (deflate packs them ~240:1), or whose archive declares a huge part.  Each is refused by
its cap, with the cap's code, before a cell is parsed; a real workbook of the thesis layout still reads.
"""

from __future__ import annotations

import io
import re
import zipfile

import numpy as np
import pytest

from app.pipeline.ingestion import IngestionError, read_thesis_xlsx
from app.pipeline.ingestion import excel
from app.pipeline.ingestion.excel import HEADER, MAX_CELLS, MAX_ROWS, write_thesis_xlsx
from app.pipeline.ingestion.messages import LANGUAGES

SHEET = "xl/worksheets/sheet1.xml"


def _rewrite_sheet(path, xml: bytes) -> None:
    """Replace the worksheet of the one-sheet workbook at ``path`` by ``xml`` (deflated)."""
    import openpyxl

    wb = openpyxl.Workbook()
    wb.active.title = "data"
    wb.active.append(HEADER)
    buf = io.BytesIO()
    wb.save(buf)
    src = zipfile.ZipFile(io.BytesIO(buf.getvalue()))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as out:
        for info in src.infolist():
            out.writestr(info.filename, xml if info.filename == SHEET else src.read(info))


def _sheet(rows: list[str]) -> bytes:
    head = "".join(f'<c r="{chr(65 + i)}1" t="inlineStr"><is><t>{h}</t></is></c>' for i, h in enumerate(HEADER))
    return ('<?xml version="1.0" encoding="UTF-8" standalone="yes"?><worksheet '
            'xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main"><sheetData>'
            f'<row r="1">{head}</row>' + "".join(rows) + "</sheetData></worksheet>").encode()


def crafted_rows_xlsx(path, n_rows: int = 100_000):
    """The penetration test's kind of file: ~70 kB on disk, 17.6 MB of identical numeric rows unpacked
    (read in full before the caps: 11 s of CPU here, ~30 s on the tester's machine)."""
    _rewrite_sheet(path, _sheet(["<row>" + "<c><v>1</v></c>" * 11 + "</row>"] * n_rows))
    return path


def _refusal(path) -> IngestionError:
    with pytest.raises(IngestionError) as exc:
        read_thesis_xlsx(path)
    for lang in LANGUAGES:  # every refusal says what to do in each language
        assert exc.value.message(lang) and "{" not in exc.value.message(lang)
    return exc.value


def test_the_crafted_70_kb_workbook_is_refused_by_its_row_count(tmp_path):
    p = crafted_rows_xlsx(tmp_path / "step-muslo-X-01012024-1.xlsx")
    info = zipfile.ZipFile(p).getinfo(SHEET)
    assert p.stat().st_size < 100_000 and info.file_size > 17_000_000  # what made it costly
    err = _refusal(p)
    assert err.code == "xlsx.too_many_rows" and err.params["limit"] == MAX_ROWS


def test_a_zip_bomb_is_refused_from_the_archive_directory(tmp_path):
    p = tmp_path / "bomb.xlsx"
    _rewrite_sheet(p, _sheet([]) + b" " * (excel.MAX_SHEET_MB * 2**20 + 1))  # 64 MB of blanks: ~65 kB packed
    assert p.stat().st_size < 200_000
    err = _refusal(p)
    assert err.code == "xlsx.too_big" and err.params["member"] == SHEET


def test_too_many_cells_in_few_rows_are_refused(tmp_path):
    p = tmp_path / "wide.xlsx"
    per_row = 400  # cells far beyond the layout's 13 columns
    rows = ["<row>" + "<c><v>1</v></c>" * per_row + "</row>"] * (MAX_CELLS // per_row + 2)
    _rewrite_sheet(p, _sheet(rows))
    err = _refusal(p)
    assert err.code == "xlsx.too_many_cells"


def test_a_real_workbook_reads_and_the_row_cap_is_exact(tmp_path, monkeypatch):
    n = 3000
    t = np.arange(n) / 100.0
    rng = np.random.default_rng(0)
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + 0.01 * rng.standard_normal((n, 3))
    tm = np.arange(n // 5) / 20.0
    mag = np.tile([0.0, 20.0, -40.0], (n // 5, 1)) + rng.standard_normal((n // 5, 3))
    p = write_thesis_xlsx(tmp_path / "standing-muslo-X-01012024-1.xlsx", (t, acc), 0.01 * rng.standard_normal((n, 3)),
                          (tm, mag))
    a, _, m, _ = read_thesis_xlsx(p)
    assert len(a.t_s) == n and len(m.t_s) == n // 5
    monkeypatch.setattr(excel, "MAX_ROWS", n)  # the cap at exactly this workbook's rows: still read
    assert len(read_thesis_xlsx(p)[0].t_s) == n
    monkeypatch.setattr(excel, "MAX_ROWS", n - 1)  # one row fewer: refused
    assert _refusal(p).code == "xlsx.too_many_rows"


def test_tags_cut_by_a_piece_boundary_are_counted_once(tmp_path):
    """The streamed count equals a count of the whole XML whatever the piece size, and the XML it hands on (the one
    the reader then parses) is the sheet's, whole."""
    p = tmp_path / "count.xlsx"
    _rewrite_sheet(p, _sheet(['<row r="%d"><c r="A%d"><v>%d</v></c><c/></row>' % (i, i, i) for i in range(2, 500)]))
    xml = zipfile.ZipFile(p).read(SHEET)
    truth = (len(re.findall(rb"<(?:[A-Za-z_][\w.-]*:)?row[\s/>]", xml)),   # the tags by a regular expression
             len(re.findall(rb"<(?:[A-Za-z_][\w.-]*:)?c[\s/>]", xml)))
    assert truth == (499, 13 + 2 * 498)
    for piece in (7, 64, 1000, 1 << 20):
        with zipfile.ZipFile(p) as z, z.open(SHEET) as fh:
            assert excel.count_rows_cells(fh, chunk_bytes=piece) == (*truth, xml)


def test_a_workbook_is_opened_and_each_sheet_counted_once_per_read(tmp_path, monkeypatch):
    """``read_recording`` opens an .xlsx once for the phyphox sniff and the thesis reader, and the XML the caps
    counted is the XML parsed (issue 14's read goal: each sheet was opened and counted twice, once per reader)."""
    from app.pipeline.ingestion import xlsx_cells
    from app.pipeline.ingestion.session import read_recording

    n = 300
    t = np.arange(n) / 100.0
    p = write_thesis_xlsx(tmp_path / "standing-muslo-X-01012024-1.xlsx", (t, np.tile([0.0, 0.0, 9.81], (n, 1))),
                          np.zeros((n, 3)), (t[::5], np.tile([0.0, 20.0, -40.0], (n // 5, 1))),
                          extra_sheets=("notas",))
    opened, counted, read = [], [], []
    init, count, zread = xlsx_cells.Workbook.__init__, excel.count_rows_cells, zipfile.ZipFile.read
    monkeypatch.setattr(xlsx_cells.Workbook, "__init__", lambda self, path: opened.append(path) or init(self, path))
    monkeypatch.setattr(excel, "count_rows_cells", lambda *a, **k: counted.append(1) or count(*a, **k))
    monkeypatch.setattr(zipfile.ZipFile, "read", lambda self, name, *a: read.append(name) or zread(self, name, *a))
    rec = read_recording([p])
    assert rec.fmt == "thesis-xlsx" and len(rec.acc.t_s) == n
    assert opened == [p] and len(counted) == 2   # two sheets, each counted once
    assert not [m for m in read if m.startswith("xl/worksheets/")]   # and never decompressed again
