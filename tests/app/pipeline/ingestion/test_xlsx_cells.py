"""The streaming cell reader (:mod:`app.pipeline.ingestion.xlsx_cells`) against openpyxl as the oracle."""

from __future__ import annotations

import numpy as np
import openpyxl
import pytest

from app.pipeline.ingestion.excel import HEADER, MAX_ROWS, write_thesis_xlsx
from app.pipeline.ingestion.phyphox import MAX_COLUMNS, write_phyphox
from app.pipeline.ingestion.xlsx_cells import Workbook


def _oracle(path, name, max_row, max_col):
    wb = openpyxl.load_workbook(path, read_only=True, data_only=True)
    try:
        return [tuple(r) for r in wb[name].iter_rows(max_row=max_row, max_col=max_col, values_only=True)]
    finally:
        wb.close()


def _same(path, max_row, max_col):
    with Workbook(path) as wb:
        names = wb.sheetnames
        assert names == openpyxl.load_workbook(path, read_only=True).sheetnames
        for name in names:
            mine, theirs = wb.rows(name, max_row, max_col), _oracle(path, name, max_row, max_col)
            assert len(mine) == len(theirs), name
            for a, b in zip(mine, theirs):
                assert [(type(x), x) for x in a] == [(type(x), x) for x in b], name
            numbers, others = wb.table(name, max_row, max_col)   # the fast reader: the same values
            for i, r in enumerate(theirs):
                for j, v in enumerate(r):
                    if isinstance(v, (int, float)) and not isinstance(v, bool):
                        assert numbers[i, j] == float(v) and (i, j) not in others, (name, i, j)
                    elif v is None:
                        assert (i >= len(numbers) or np.isnan(numbers[i, j])) and (i, j) not in others
                    else:
                        assert type(others[(i, j)]) is type(v) and others[(i, j)] == v, (name, i, j)
                        assert np.isnan(numbers[i, j])


def test_thesis_workbook_values_are_openpyxls(tmp_path):
    rng = np.random.default_rng(7)
    t = np.arange(0, 3, 0.01)
    acc = rng.normal(0, 9.81, (t.size, 3))
    gyr = rng.normal(0, 2, (t.size, 3))
    tm = np.arange(0, 3, 0.05)
    mag = rng.normal(0, 40, (tm.size, 3))
    path = write_thesis_xlsx(tmp_path / "step-muslo-P01-01012024-1.xlsx", (t, acc), gyr, (tm, mag),
                             extra_sheets=("notas", "notas año"))
    _same(path, MAX_ROWS + 1, len(HEADER))
    _same(path, 1, len(HEADER))


def test_phyphox_workbook_values_are_openpyxls(tmp_path):
    rng = np.random.default_rng(8)
    t = np.arange(0, 2, 0.01)
    streams = {k: (t, rng.normal(0, 5, (t.size, 3))) for k in ("acc", "gyr", "mag")}
    path = write_phyphox(tmp_path / "phyphox.xlsx", streams, layout="xlsx")
    _same(path, MAX_ROWS + 1, MAX_COLUMNS)


def test_odd_cells_spanish_and_portuguese_conventions(tmp_path):
    """Spanish/Portuguese headers ('tiempo', 'año', 'ção'), decimal-comma numbers typed as text ('0,5'), ints,
    booleans, formulas with cached values, XML-escaped text, blank cells and rows, rows far away and columns
    beyond the ones read: every value as openpyxl gives it."""
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.title = "Hoja1"
    ws.append(["tiempo (s)", "eje x (g)", "rotação (deg/s)", "<a & b> \"c\" 'd'", None, "año"])
    ws.append([0, 0.5, "0,5", True, False, -1.25e-7])
    ws.append([1, None, "", 3, "  ", 1e300])
    ws["C6"] = "=A2+A3"
    ws["P7"] = 99.0
    ws["A9"] = "1.234,56"
    ws.cell(row=12, column=2, value=2**40)
    second = wb.create_sheet("Folha de cálculo")
    second.append(["Tempo (s)", "Aceleração x (m/s^2)"])
    second.append([0.001, 9.81])
    path = tmp_path / "odd.xlsx"
    wb.save(path)
    for max_row in (1, 5, 20):
        for max_col in (3, 13, 20):
            _same(path, max_row, max_col)


@pytest.mark.parametrize("max_row", [3, 50])
def test_rows_far_away_pad_like_openpyxl(tmp_path, max_row):
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.append(["elapsed (s)", "x"])
    ws.append([0.0, 1.0])
    ws.cell(row=10_000, column=1, value=5.0)
    path = tmp_path / "far.xlsx"
    wb.save(path)
    _same(path, max_row, 4)


def _with_sheet(path, xml: bytes):
    """A one-sheet workbook written by openpyxl whose sheet XML is replaced by ``xml``."""
    import io
    import zipfile

    wb = openpyxl.Workbook()
    buf = io.BytesIO()
    wb.save(buf)
    src = zipfile.ZipFile(io.BytesIO(buf.getvalue()))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as out:
        for info in src.infolist():
            out.writestr(info.filename, xml if info.filename == "xl/worksheets/sheet1.xml" else src.read(info))
    return path


@pytest.mark.parametrize("cells", [
    # no references (the slow path), a rich inline string, an error, a str formula result, escapes
    '<row><c t="inlineStr"><is><r><t>tiem</t></r><r><t>po (s)</t></r></is></c><c t="e"><v>#N/A</v></c>'
    '<c t="str"><f>A1</f><v>a &amp; b</v></c></row><row><c><v>1.5</v></c><c><v>2</v></c><c t="b"><v>1</v></c></row>',
    # a namespace prefix, attributes in another order and single quotes (the slow path)
    '<x:row r="1"><x:c t="n" r="B1"><x:v>3</x:v></x:c></x:row><x:row r="3"><x:c r=\'A3\' s="0"><x:v>-2E-3</x:v>'
    '</x:c><x:c r="C3" t="inlineStr"><x:is><x:t>ação</x:t></x:is></x:c></x:row>',
    # plain numbers below the header as Excel writes them (a style, no type), then a text cell among them: the
    # header's pattern reads the whole sheet
    '<row r="1"><c r="A1" t="inlineStr"><is><t>elapsed (s)</t></is></c></row><row r="2"><c r="A2" s="1"><v>0.25</v>'
    '</c><c r="B2" s="1" t="n"><v>-3E-3</v></c></row><row r="3"><c r="A3" t="str"><v>0,5</v></c><c r="B3"><v>4</v>'
    '</c></row>',
    # a prefixed cell among plain ones (both are SpreadsheetML cells): it was dropped when the plain ones were all
    # the patterns counted
    '<row r="1"><c r="A1" t="inlineStr"><is><t>elapsed (s)</t></is></c></row><row r="2"><c r="A2"><v>0.25</v></c>'
    '<x:c r="B2"><x:v>7</x:v></x:c></row>',
    # the fast path with a gap in the rows and an empty value
    '<row r="1"><c r="A1" t="inlineStr"><is><t>elapsed (s)</t></is></c></row><row r="4"><c r="A4" s="1" t="n">'
    '<v>0.25</v></c><c r="B4" t="n"></c><c r="D4"><v>7</v></c></row>',
])
def test_hand_written_sheets_read_like_openpyxl(tmp_path, cells):
    path = _with_sheet(tmp_path / "hand.xlsx", _sheet_xml(cells))
    for max_row in (1, 4, 10):
        _same(path, max_row, 5)


def _sheet_xml(cells: str) -> bytes:
    prefix = ' xmlns:x="http://schemas.openxmlformats.org/spreadsheetml/2006/main"' if "<x:" in cells else ""
    tag = "x:" if prefix else ""
    return ('<?xml version="1.0" encoding="UTF-8"?><worksheet xmlns="http://schemas.openxmlformats.org/'
            f'spreadsheetml/2006/main"{prefix}><{tag}sheetData>{cells}</{tag}sheetData></worksheet>').encode()


_HEAD = '<row r="1"><c r="A1" t="inlineStr"><is><t>elapsed (s)</t></is></c><c r="B1"><v>9</v></c></row>'


@pytest.mark.parametrize("cells", [
    # a row going back (openpyxl skips it), in the plain part and right after the header
    _HEAD + '<row r="3"><c r="A3"><v>3</v></c></row><row r="2"><c r="A2"><v>2</v></c><c r="B2"><v>4</v></c></row>'
    '<row r="4"><c r="A4"><v>5</v></c></row>',
    '<row r="2"><c r="A2"><v>2</v></c></row>' + _HEAD + '<row r="3"><c r="A3"><v>3</v></c></row>',
    # a repeated row (openpyxl keeps the first)
    _HEAD + '<row r="2"><c r="A2"><v>2</v></c></row><row r="2"><c r="A2"><v>7</v></c><c r="B2"><v>8</v></c></row>',
    # a cell whose reference names another row (openpyxl places it by its column in the row it lies in)
    _HEAD + '<row r="2"><c r="A2"><v>2</v></c><c r="B5"><v>6</v></c></row><row r="3"><c r="A3"><v>3</v></c></row>',
    _HEAD + '<row r="2"><c r="A2"><v>2</v></c></row><row r="3"><c r="A7"><v>3</v></c></row>',
    # a column repeated in a row (openpyxl keeps the last), a number then a text
    _HEAD + '<row r="2"><c r="A2"><v>2</v></c><c r="A2" t="str"><v>x</v></c></row>',
    # a row without r among rows with r (it follows the previous one)
    _HEAD + '<row><c r="A2"><v>2</v></c></row><row r="3"><c r="A3"><v>3</v></c></row>',
    # a value too large for binary64 is inf for openpyxl as for float()
    _HEAD + '<row r="2"><c r="A2"><v>1e999</v></c><c r="B2"><v>-1E999</v></c></row>',
])
def test_the_fast_table_keeps_openpyxls_row_order(tmp_path, cells):
    """Review finding: the fast path placed each cell by its reference, so rows out of order, a repeated row and a
    cell naming another row came out otherwise than openpyxl reads them (a row dropped or overwritten)."""
    path = _with_sheet(tmp_path / "order.xlsx", _sheet_xml(cells))
    for max_row in (1, 3, 10):
        _same(path, max_row, 3)


@pytest.mark.parametrize("text", ["inf", "-inf", "nan", "NaN", "Infinity"])
def test_a_number_cell_of_inf_or_nan_is_refused_like_openpyxl(tmp_path, text):
    """openpyxl refuses ``<v>inf</v>`` in a number cell (``int('inf')``); the fast path took it as ±inf/NaN (a NaN
    silently empty).  Both readers now raise."""
    path = _with_sheet(tmp_path / "inf.xlsx", _sheet_xml(_HEAD + f'<row r="2"><c r="A2"><v>1.5</v></c>'
                                                         f'<c r="B2"><v>{text}</v></c></row>'))
    with pytest.raises(ValueError):
        _oracle(path, "Sheet", 10, 3)
    with Workbook(path) as wb:
        with pytest.raises(ValueError):
            wb.table("Sheet", 10, 3)
        with pytest.raises(ValueError):
            wb.rows("Sheet", 10, 3)


def test_unclosed_cells_and_rows_are_read_in_linear_time():
    """A crafted sheet (within the size caps) of thousands of cells and rows that never close, then filler: no
    element matches, and each pattern scans the text about once — the lazy ``.*?</c>`` of the first version scanned
    to the sheet's end from every unclosed start (4000 × 1 MB here: minutes of CPU, holding the interpreter lock in
    the job's thread; review finding).  No time is asserted: before the fix this test did not finish for minutes."""
    from app.pipeline.ingestion import xlsx_cells as x

    filler = b"x" * 1_000_000
    assert x._FAST.findall(b'<c r="A1"><v>1</v>' * 4000 + filler) == []
    assert x._CELL.findall(b'<c r="A1"><v>1</v>' * 4000 + filler) == []
    assert x._ROW.findall(b'<row r="1">' * 4000 + filler) == []
    assert x._V.findall(b"<v>1" * 4000 + filler) == []
    closed = b'<row r="1"><c r="A1"><v>1</v></c></row>'
    assert x._FAST.findall(b'<c r="A1"><v>1</v>' * 4000 + closed) == [(b"A1", b"", b"1")]
    # start tags that never reach their ">": the lazy attributes ([^>]*?) of _ROW/_CELL and the optional
    # (?:\s[^>]*)? of _V/_T scanned to the sheet's end from each (20 000 x 1 MB: many minutes before the fix)
    for pattern, tag in ((x._ROW, b"<row "), (x._CELL, b"<c "), (x._V, b"<v "), (x._T, b"<t "),
                         (x._FAST, b'<c r="A1"><f ')):
        assert pattern.findall(tag * 20_000 + filler) == [], tag
    # one attribute name 300 kB long: every position of it was a start scanning to its end (24 s for 40 kB)
    assert x._attrs(b"r" * 300_000) == {}
    assert x._attrs(b'a' * 300_000 + b' r="7" t="n"') == {b"r": b"7", b"t": b"n"}


def test_a_row_tag_with_a_long_attribute_name_is_refused_in_linear_time(tmp_path):
    """End to end (review finding): a 5 kB workbook whose sheet is one ``<row r="1" aaaa…/>`` kept
    ``read_recording`` busy 39 s with a 30 kB name (the header is read before any fast path); 1 MB here."""
    from app.pipeline.ingestion import IngestionError
    from app.pipeline.ingestion.session import read_recording

    xml = (b'<?xml version="1.0" encoding="UTF-8"?><worksheet xmlns="http://schemas.openxmlformats.org/'
           b'spreadsheetml/2006/main"><sheetData><row r="1" ' + b"a" * 1_000_000 + b'/></sheetData></worksheet>')
    path = _with_sheet(tmp_path / "standing-muslo-X-01012024-1.xlsx", xml)
    assert path.stat().st_size < 10_000
    with pytest.raises(IngestionError) as err:
        read_recording([path])
    assert err.value.code == "xlsx.no_layout_sheet"


def test_a_header_cell_of_blanks_is_matched_in_linear_time():
    """The header's ``name (unit)`` pattern: a lazy name before ``\\s*\\(`` rescanned a run of blanks from each
    position (0.09 s for 10 000 blanks, ~15 min for the 1 000 000 here)."""
    from app.pipeline.ingestion.excel import _layout_problem, _name_unit

    assert _name_unit("a" + " " * 1_000_000 + "b") is None
    assert _name_unit("  x-axis   (deg/s) ") == ("x-axis", "deg/s")
    assert "expected 'elapsed (s)'" in _layout_problem(["t" + " " * 1_000_000 + "(s"] + HEADER[1:])


# ------------------------------------------------------------------ the numpy scan of plain number cells


def _regex_cells(body: bytes):
    """The cells of ``body`` by the regular expression reader's own pattern (the reference of the scan): ``(col,
    row, value)`` of each, or ``None`` when a ``<c`` is not such a cell."""
    from app.pipeline.ingestion import xlsx_cells as x
    from app.pipeline.ingestion.xlsx_scan import references

    cells = x._FAST.findall(body)
    if len(cells) != body.count(b"<c"):
        return None
    refs = np.array([c[0] for c in cells], dtype=bytes)
    col, row = references(refs) if cells else (np.zeros(0), np.zeros(0))
    return [(int(c), int(r), float(v[2])) for c, r, v in zip(col, row, cells)]


_PLAIN = (b'<row r="2" spans="1:3"><c r="A2" s="1"><v>0.25</v></c><c r="B2" t="n"><v>-3E-3</v></c>'
          b'<c r="C2" s="2" t="n"><v>12</v></c></row><row r="3"/><row r="4"><c r="AB4"><v>1.5e2</v></c>'
          b'<c r="XFD4" t="n" s="7"><v>-0.000001</v></c></row>')


@pytest.mark.parametrize("body,plain", [
    (_PLAIN, True),
    (_PLAIN.replace(b"</row><row", b"</row>\n  <row"), True),   # blanks between rows: ignored, as openpyxl does
    (_PLAIN.replace(b'<c r="B2" t="n">', b'<c r="B2" t="s">'), False),     # a shared string
    (_PLAIN.replace(b"<v>12</v>", b"<v></v>"), False),                    # an empty value
    (_PLAIN.replace(b"<v>12</v>", b"<v> 12</v>"), False),                 # a blank in a value
    (_PLAIN.replace(b"<v>12</v>", b"<f>A2</f><v>12</v>"), False),         # a formula
    (_PLAIN.replace(b'<c r="A2" s="1">', b'<c s="1" r="A2">'), False),    # r not first
    (_PLAIN.replace(b'<c r="A2" s="1">', b"<c r='A2' s='1'>"), False),    # single quotes
    (_PLAIN.replace(b'r="AB4"', b'r="ab4"'), False),                       # lower-case column
    (_PLAIN.replace(b'r="AB4"', b'r="ABCD4"'), False),                     # four letters
    (_PLAIN.replace(b'r="AB4"', b'r="AB1234567890"'), False),              # ten digits
    (_PLAIN.replace(b'r="AB4"', b'r="4"'), False),                         # no column
    (_PLAIN.replace(b'<c r="A2" s="1">', b'<c r="A2" s="1" foo="2">'), False),   # another attribute
    (_PLAIN.replace(b"<v>0.25</v></c>", b"<v>0.25</v> </c>"), False),     # text inside the cell
    (_PLAIN.replace(b'<row r="3"/>', b"<!-- a > b --><row r=\"3\"/>"), False),   # a comment
    (_PLAIN.replace(b'<row r="3"/>', b'<row r="3"/>x > y'), False),        # '>' in text
    (_PLAIN.replace(b'<c r="C2"', b'<x:c r="C2"').replace(b"</c></row><row r=\"3\"/>",
                                                          b"</x:c></row><row r=\"3\"/>"), False),   # a prefix
    (_PLAIN.replace(b"</row><row r=\"3\"/>", b"<row r=\"3\"/>"), False),  # a row never closed
    (_PLAIN.replace(b'<c r="A2" s="1"><v>0.25</v></c>', b'<c r="A2" s="1"/>'), False),   # an empty cell
    (_PLAIN.replace(b"<v>12</v>", b"<v>1&#46;2</v>"), False),             # an entity in a number
    (_PLAIN.replace(b"<v>12</v>", b"<v>" + b"1" * 50 + b"</v>"), False),  # longer than the scan reads
    (b"", False),
])
def test_the_scan_reads_plain_cells_as_the_regular_expressions_do(body, plain):
    """The scan (:func:`.xlsx_scan.plain_cells`) reads a sheet of plain number cells as :data:`.xlsx_cells._FAST`
    reads it, and leaves anything else (``None``) to the regular expressions."""
    from app.pipeline.ingestion.xlsx_scan import plain_cells

    found = plain_cells(body)
    assert (found is not None) == plain
    if plain:
        col, row, values, cells_at, rows_at = found
        assert list(zip(col.tolist(), row.tolist(), values.tolist())) == _regex_cells(body)
        assert [body[i:i + 3] for i in cells_at] == [b'<c '] * len(col)
        assert [body[i:i + 5] for i in rows_at] == [b"<row "] * 3


def test_the_scan_agrees_with_the_regular_expressions_on_mutated_sheets():
    """Random edits of a sheet of plain cells (a byte replaced, inserted or deleted, around the tags): wherever
    the scan reads the result, it reads what the regular expressions read (differential test)."""
    from app.pipeline.ingestion.xlsx_scan import plain_cells

    rng = np.random.default_rng(14)
    alphabet = np.frombuffer(b'<>/"= rcvstn0123456789.-eEABZ\n', np.uint8)
    accepted = 0
    for _ in range(3000):
        body = bytearray(_PLAIN)
        for _ in range(int(rng.integers(1, 3))):
            i = int(rng.integers(0, len(body)))
            action = rng.integers(0, 3)
            if action == 0:
                body[i] = int(rng.choice(alphabet))
            elif action == 1:
                body.insert(i, int(rng.choice(alphabet)))
            else:
                del body[i]
        found = plain_cells(bytes(body))
        if found is not None:
            accepted += 1
            reference = _regex_cells(bytes(body))
            assert reference is not None, bytes(body)
            assert list(zip(found[0].tolist(), found[1].tolist(), found[2].tolist())) == reference, bytes(body)
    assert accepted > 100   # the edits inside values, references and numbers that keep the cells plain


def test_excel_style_sheets_take_the_scan_and_read_like_openpyxl(tmp_path, monkeypatch):
    """A sheet as Excel writes it (styles, no type, ``spans``, an empty row, two- and three-letter columns) is
    read by the scan, with openpyxl's values; so is the thesis writer's workbook."""
    from app.pipeline.ingestion import xlsx_cells

    taken = []

    def spy(body, start=0):
        found = scan(body, start)
        taken.append(found is not None)
        return found

    scan = xlsx_cells.plain_cells
    monkeypatch.setattr(xlsx_cells, "plain_cells", spy)
    head = '<row r="1"><c r="A1" t="inlineStr"><is><t>elapsed (s)</t></is></c></row>'
    path = _with_sheet(tmp_path / "excel.xlsx", _sheet_xml(head + _PLAIN.decode()))
    for max_row in (1, 3, 10):
        _same(path, max_row, 30)
    rng = np.random.default_rng(3)
    t = np.arange(0, 2, 0.01)
    thesis = write_thesis_xlsx(tmp_path / "step-muslo-P01-01012024-1.xlsx", (t, rng.normal(0, 9.81, (t.size, 3))),
                               rng.normal(0, 2, (t.size, 3)), (t[::5], rng.normal(0, 40, (t[::5].size, 3))))
    _same(thesis, MAX_ROWS + 1, len(HEADER))
    assert taken and all(taken)


def test_the_scan_is_linear_on_crafted_sheets():
    """Sheets within the caps that defeat the scan in every step (a million ``<``, a million distinct attribute
    texts, tags that never close): each is answered in a few numpy passes (no time asserted: a quadratic step
    would not finish)."""
    from app.pipeline.ingestion.xlsx_scan import MAX_FORMS, plain_cells

    assert plain_cells(b"<" * 1_000_000) is None
    assert plain_cells(b'<row r="1">' * 200_000) is None
    forms = b"".join(b'<c r="A%d" s="%d"><v>1</v></c>' % (i + 2, i) for i in range(MAX_FORMS + 1))
    assert plain_cells(b'<row r="2">' + forms + b"</row>") is None    # more distinct texts than read
    many = b"".join(b'<row r="%d"><c r="A%d" s="1"><v>%d</v></c></row>' % (i, i, i) for i in range(2, 100_000))
    assert plain_cells(many)[2][-1] == 99_999.0


def test_a_sheet_of_foreign_tags_is_refused_before_its_tags_are_counted_in_arrays():
    """A review's crafted sheet: 31 M ``<>`` pairs (66 kB zipped, within the 64 MB sheet cap) made the scan hold
    one int64 position per ``<`` and ``>`` and their differences, about 1 GB, before it found them foreign.  Now
    the byte counts refuse it first; a plain sheet's memory stays that of its cells."""
    import tracemalloc

    from app.pipeline.ingestion.xlsx_scan import plain_cells

    for padding in (b"<>", b"<c ><><><>", b'<c r="A1"><><><>'):   # the last two keep the tag counts' balance
        body = b'<row r="2"><c r="A2"><v>1</v></c>' + padding * (8_000_000 // len(padding)) + b"</row>"
        tracemalloc.start()
        try:
            assert plain_cells(body) is None
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < len(body) // 4, (padding, peak)        # was 8–16 × len(body)
    plain = b"".join(b'<row r="%d"><c r="A%d"><v>%d</v></c></row>' % (i, i, i) for i in range(2, 1002))
    assert plain_cells(plain)[2][-1] == 1001.0


def test_tag_counts_are_bytes_counts():
    """:func:`.xlsx_scan.occurrences` (numpy compares, a block at a time) counts what ``bytes.count`` counts, on
    random bytes of the tags' alphabet, any range and block size (matches across block edges and at the end), and
    refuses a text that could overlap itself (``bytes.count`` would count fewer)."""
    from app.pipeline.ingestion.xlsx_scan import occurrences

    rng = np.random.default_rng(14)
    alphabet = np.frombuffer(b'<:/crows >"', np.uint8)
    texts = [b"<", b"<c ", b"<row", b"</row", b"<c", b":c", b":row", b"<si"]
    for _ in range(2000):
        data = rng.choice(alphabet, size=int(rng.integers(0, 80))).tobytes()
        start, end = int(rng.integers(0, 12)), int(rng.integers(0, 90))
        block = int(rng.choice([1, 2, 3, 7, 64, 1 << 17]))
        for kind in (bytes, bytearray):
            assert occurrences(kind(data), texts, start, end, block) == [data.count(t, start, end) for t in texts]
    assert occurrences(b"<c " * 100_000, [b"<c "]) == [100_000]
    with pytest.raises(ValueError):
        occurrences(b"aaaa", [b"aa"])
