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


_NS = ('xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main" '
       'xmlns:r="http://schemas.openxmlformats.org/officeDocument/2006/relationships"')
_RELS = "http://schemas.openxmlformats.org/officeDocument/2006/relationships"


def _workbook(path, sheet: bytes, names: int = 1, strings: bytes | None = None,
              strings_at: str = "xl/sharedStrings.xml"):
    """A workbook written by openpyxl, its sheet replaced by ``sheet``, listed ``names`` times in workbook.xml (every
    name on the one part, as no spreadsheet program writes it), with shared strings ``strings`` at ``strings_at``
    (declared by the workbook's relationship, wherever that part lies)."""
    import openpyxl

    buf = io.BytesIO()
    openpyxl.Workbook().save(buf)
    src = zipfile.ZipFile(io.BytesIO(buf.getvalue()))
    listing = "".join(f'<sheet name="s{i}" sheetId="{i + 1}" r:id="rId1"/>' for i in range(names))
    parts = {SHEET: sheet, "xl/workbook.xml": f"<workbook {_NS}><sheets>{listing}</sheets></workbook>".encode()}
    rels = src.read("xl/_rels/workbook.xml.rels")
    if strings is not None:
        parts[strings_at] = strings
        rels = rels.replace(b"</Relationships>", f'<Relationship Type="{_RELS}/sharedStrings" '
                            f'Target="/{strings_at}" Id="rId9"/></Relationships>'.encode())
    parts["xl/_rels/workbook.xml.rels"] = rels
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as out:
        for info in src.infolist():
            out.writestr(info.filename, parts.pop(info.filename, None) or src.read(info))
        for name, data in parts.items():
            out.writestr(name, data)
    return path


def test_a_sheet_listed_under_many_names_is_counted_and_kept_once(tmp_path, monkeypatch):
    """Review finding: 12 names on one 40 MB sheet in a 45 kB upload were counted and kept once per name (27 s,
    +520 MB).  The caps count parts: one count, one kept body, whatever the names; the names still each read."""
    from app.pipeline.ingestion.xlsx_cells import Workbook

    p = _workbook(tmp_path / "names.xlsx", _sheet(['<row r="2"><c r="A2"><v>1</v></c></row>']), names=12)
    counted, kept = [], []
    count, keep = excel.count_rows_cells, Workbook.keep
    monkeypatch.setattr(excel, "count_rows_cells", lambda *a, **k: counted.append(1) or count(*a, **k))
    monkeypatch.setattr(Workbook, "keep", lambda self, part, xml: kept.append(part) or keep(self, part, xml))
    with excel.open_workbook(p) as wb:
        assert len(wb.sheetnames) == 12 and wb.parts == [SHEET]
        assert [wb.header(n, 2) for n in wb.sheetnames] == [("elapsed (s)", "x-axis (g)")] * 12
    assert counted == [1] and kept == [SHEET]
    assert _refusal(p).code == "xlsx.several_layout_sheets"


def test_more_sheet_names_than_parts_allowed_are_refused(tmp_path):
    p = _workbook(tmp_path / "names.xlsx", _sheet([]), names=excel.MAX_PARTS + 1)
    err = _refusal(p)
    assert err.code == "xlsx.too_many_parts" and err.params["count"] == excel.MAX_PARTS + 1


def test_shared_strings_are_capped_by_their_role_not_their_path(tmp_path):
    """Review finding: shared strings placed under xl/worksheets/ got the 64 MB sheet cap (and openpyxl parsed
    them whole: 8 MB of ``<si/>`` took 17.6 s and 158 MB).  The relationship says what the part is."""
    strings = b"<sst " + _NS.encode() + b">" + b"<si/>" * (excel.MAX_PART_MB * 2**20 // 5 + 1) + b"</sst>"
    p = _workbook(tmp_path / "ss.xlsx", _sheet([]), strings=strings, strings_at="xl/worksheets/ss.xml")
    assert p.stat().st_size < 100_000
    err = _refusal(p)
    assert err.code == "xlsx.too_big" and err.params["member"] == "xl/worksheets/ss.xml"
    assert err.params["limit_mb"] == excel.MAX_PART_MB


def test_more_shared_strings_than_cells_are_refused_before_they_are_parsed(tmp_path):
    """An 11 kB workbook with 4 MB of ``<si/>`` (within the size cap) took openpyxl 6.8 s to parse: a text no cell
    can show is refused by the count of ``<si``, before any is parsed."""
    strings = b"<sst " + _NS.encode() + b">" + b"<si/>" * 800_000 + b"</sst>"
    sheet = _sheet(['<row r="2"><c r="A2" t="s"><v>799999</v></c></row>'])
    p = _workbook(tmp_path / "ss.xlsx", sheet, strings=strings)
    err = _refusal(p)
    assert err.code == "xlsx.too_many_strings" and err.params["count"] == 800_000
    assert err.params["limit"] < 2000   # the sheet's 14 cells and the slack


def test_shared_strings_within_the_cells_are_read(tmp_path):
    """The common Excel case: the header's texts in the shared strings, read by openpyxl's reader from the XML the
    caps counted; a string table that failed to parse is not taken for an empty one the next time."""
    from xml.etree.ElementTree import ParseError

    texts = "".join(f"<si><t>{h}</t></si>" for h in HEADER)
    head = "".join(f'<c r="{chr(65 + i)}1" t="s"><v>{i}</v></c>' for i in range(len(HEADER)))
    sheet = f'<worksheet {_NS}><sheetData><row r="1">{head}</row></sheetData></worksheet>'.encode()
    good = _workbook(tmp_path / "good.xlsx", sheet, strings=f"<sst {_NS}>{texts}</sst>".encode())
    with excel.open_workbook(good) as wb:
        assert wb.header(wb.sheetnames[0], len(HEADER)) == tuple(HEADER)
    bad = _workbook(tmp_path / "bad.xlsx", sheet, strings=f"<sst {_NS}>{texts}".encode())
    with excel.open_workbook(bad) as wb:
        for _ in range(2):
            with pytest.raises(ParseError):
                wb.rows(wb.sheetnames[0], 1, len(HEADER))


def test_the_sheet_xml_is_held_once(tmp_path):
    """The caps' count reads a sheet into one buffer, and the body kept is that buffer cut in place: no list of
    pieces, joined copy and body slice held at once (review finding)."""
    from app.pipeline.ingestion.xlsx_cells import Workbook

    p = _workbook(tmp_path / "one.xlsx", _sheet(['<row r="2"><c r="A2"><v>1</v></c></row>'] * 100))
    with zipfile.ZipFile(p) as z, z.open(SHEET) as fh:
        xml = excel.count_rows_cells(fh, chunk_bytes=64)[2]
    with Workbook(p) as wb:
        wb.keep(SHEET, xml)
        assert wb._bodies[SHEET] is xml and xml.startswith(b'<row r="1">') and xml.endswith(b"</row>")
