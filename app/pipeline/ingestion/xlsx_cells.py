"""The cell values of an .xlsx workbook's sheets, read straight from the sheet XML (ECMA-376 Part 1, §18.3.1).

openpyxl builds a Python object for every XML element of a sheet (a row, a cell, its ``<v>``): ~1.6 s of CPU
for the eight workbooks of a 10-cycle thesis session (issue 14, ``python -m benchmarks.read_formats``).  Here
each ``<row>`` and each ``<c r=.. t=..>…</c>`` of ``<sheetData>`` is matched by a regular expression over the
decompressed bytes and only the value is converted, with openpyxl's rules so that the values are the same as
``openpyxl.load_workbook(path, read_only=True, data_only=True)[name].iter_rows(max_row=…, max_col=…,
values_only=True)`` (tested with openpyxl as the oracle).  The rows below a header that hold plain numbers only
(a recording's data) are found faster still, by numpy over the bytes (:mod:`.xlsx_scan`).  The rules:

- ``t`` absent or ``n``: the ``<v>`` text as ``int`` when it has no ``.``/``e``/``E``, else ``float``;
  ``s``: the shared string of that index (``xl/sharedStrings.xml``, read by openpyxl's own string-table reader);
  ``str`` and ``e``: the text; ``b``: ``bool``; ``inlineStr``: the ``<t>`` texts of its ``<is>`` joined;
  an empty or missing ``<v>`` is ``None``; a formula's cached ``<v>`` is its value (``data_only``).
- A row without ``r`` follows the previous one; a cell without ``r`` the previous cell of its row.  Missing rows
  are rows of ``None``, every row has ``max_col`` values, and a row beyond ``max_row`` stops the read and pads
  the rows up to ``max_row`` with ``None`` rows (as openpyxl does).
- Not interpreted: number formats (a date-styled number is its serial number, openpyxl makes it a ``datetime``;
  neither reader of this package accepts a date), ``t="d"`` ISO dates (kept as text), and a ``>`` inside an
  attribute value of ``<c>``/``<row>`` (no spreadsheet program writes one).

The workbook's size caps must have run before a sheet is parsed: :func:`app.pipeline.ingestion.excel.open_workbook`
checks the archive, streams each sheet's part once through its tag count and hands the XML it read to the
:class:`Workbook` (:meth:`Workbook.keep`), so a sheet is decompressed once for the caps and every read after.
Every pattern here runs in linear time on any input: possessive quantifiers, no ``<`` inside a tag's attributes
(XML forbids it in a value), attribute names started only at their first character (tested on the unclosed and
overlong tags that were quadratic).
"""

from __future__ import annotations

import io
import posixpath
import re
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from app.pipeline.ingestion.xlsx_scan import in_order, occurrences, plain_cells, references, tag_positions

_MAIN = "{http://schemas.openxmlformats.org/spreadsheetml/2006/main}"
_REL = "{http://schemas.openxmlformats.org/officeDocument/2006/relationships}"
_PKG_REL = "{http://schemas.openxmlformats.org/package/2006/relationships}"
_P = rb"(?:[A-Za-z_][\w.-]*+:)?"  # an optional namespace prefix (``:`` is not in the class: possessive is exact)
_SHEET_DATA_START = re.compile(rb"<" + _P + rb"sheetData\s*+/?>")
#: the attributes of a start tag up to its ``/>`` or ``>``: no ``<`` (XML forbids it in a value) and possessive, so
#: from an unclosed ``<row `` the scan stops at the next ``<`` and never backtracks (a lazy ``[^>]*?`` scanned to the
#: next ``>`` from every unclosed start, and ``(?:\s[^>]*)?`` backtracked through it: quadratic, review finding)
_ATTRS = rb"((?:[^<>/]++|/(?!>))*+)"


def _inside(tag: bytes) -> bytes:
    """The content of an element ``tag`` up to its end tag, never crossing another start or end tag of the same
    name, with possessive quantifiers: linear time.  (A lazy ``.*?</c>`` scanned to the end of the sheet from every
    unclosed ``<c>``: quadratic in a crafted sheet the size caps allow — review finding.)"""
    return rb"[^<]*+(?:<(?!/?" + _P + tag + rb"[\s/>])[^<]*+)*+"


#: a cell as every writer known writes it (no namespace prefix, ``r`` first, ``s`` and ``t`` only, double quotes):
#: ``r`` (column letters, row), ``t``, and the ``<v>`` text after an optional ``<f>``
_FAST = re.compile(rb'<c r="([A-Z]{1,3}\d{1,9})"(?: s="\d+")?(?: t="(\w+)")?(?: s="\d+")?'
                   rb'(?:/>|>(?:<f' + _ATTRS[1:-1] + rb'(?:/>|>[^<]*+</f>))?(?:<v>([^<]*+)</v>)?' + _inside(rb"c")
                   + rb'</c>)', re.S)
#: a cell tag with a namespace prefix (``<x:c r=…>``): :data:`_FAST` does not see it
_PREFIXED_CELL = re.compile(rb"<[A-Za-z_][\w.-]*+:c[\s/>]")
_ROW = re.compile(rb"<" + _P + rb"row(?=[\s/>])" + _ATTRS + rb"(?:/>|>(" + _inside(rb"row") + rb")</" + _P
                  + rb"row\s*+>)", re.S)
_CELL = re.compile(rb"<" + _P + rb"c(?=[\s/>])" + _ATTRS + rb"(?:/>|>(" + _inside(rb"c") + rb")</" + _P + rb"c\s*+>)",
                   re.S)
#: one attribute; the look-behind starts a name only at its first character (else every position of one long name
#: would be a start, each scanning to the name's end: 24 s for 40 kB, review finding)
_ATTR = re.compile(rb"""(?<![\w:.-])([\w:.-]++)\s*+=\s*+(?:"([^"]*+)"|'([^']*+)')""")
_V = re.compile(rb"<" + _P + rb"v(?=[\s>])" + _ATTRS + rb">(" + _inside(rb"v") + rb")</" + _P + rb"v\s*+>", re.S)
_T = re.compile(rb"<(" + _P + rb")(rPh|t)(?=[\s/>])" + _ATTRS + rb"(?:/>|>(" + _inside(rb"(?:rPh|t)") + rb")</\1\2\s*+>)",
                re.S)
_ENTITY = re.compile(r"&(#x[0-9A-Fa-f]++|#[0-9]++|lt|gt|amp|quot|apos);")
_NAMED = {"lt": "<", "gt": ">", "amp": "&", "quot": '"', "apos": "'"}


def _unescape(raw: bytes) -> str:
    text = raw.decode("utf-8")
    if "&" not in text:
        return text

    def one(m: re.Match) -> str:
        e = m.group(1)
        if e[0] == "#":
            return chr(int(e[2:], 16) if e[1] in "xX" else int(e[1:]))
        return _NAMED[e]
    return _ENTITY.sub(one, text)


def _attrs(raw: bytes) -> dict[bytes, bytes]:
    """An element's attributes by local name (``x:r`` → ``r``)."""
    return {m.group(1).rsplit(b":", 1)[-1]: m.group(2) if m.group(2) is not None else m.group(3)
            for m in _ATTR.finditer(raw)}


def count_tags(data: bytes | bytearray, name: bytes, end: int | None = None, start: int = 0) -> int:
    """Start tags ``<name …>`` (with or without a namespace prefix: ``<x:name/>``) in ``data[start:end]``, or a few
    more.

    One count of ``<name`` (:func:`.xlsx_scan.occurrences`: numpy compares, 3-4x less CPU than ``bytes.count``,
    which is ~10× faster than a regular expression): it also counts the
    other tags whose name begins so (``<cols>``, ``<col>``, ``<cfRule>``, ``<rowBreaks>``: a few a sheet, none
    inside ``<sheetData>``), so as a cap it is stricter by those few, never looser.  A regular expression
    (exact) only when a ``:name`` occurs (a prefixed tag, or that text in a value); it is looked for (in the same
    compares as ``<name``) only where a ``:`` occurs at all (a one-byte search)."""
    end = len(data) if end is None else end
    if data.find(b":", start, end) >= 0:
        tags, prefixed = occurrences(data, [b"<" + name, b":" + name], start, end)
        if prefixed:
            return len(re.compile(rb"<" + _P + re.escape(name) + rb"[\s/>]").findall(data, start, end))
        return tags
    return occurrences(data, [b"<" + name], start, end)[0]


def _content(body: bytes, ref: bytes) -> bytes:
    """The content of the cell ``ref`` (its first occurrence in ``body``)."""
    start = body.find(b'<c r="' + ref + b'"')
    start = body.find(b">", start) + 1
    return body[start:body.find(b"</c>", start)]


def _column(ref: bytes) -> int:
    """1-based column of a cell reference (``b"AB12"`` → 28)."""
    n = 0
    for ch in ref:
        if 65 <= ch <= 90:
            n = n * 26 + ch - 64
        elif 97 <= ch <= 122:
            n = n * 26 + ch - 96
        else:
            break
    return n


def _body(data: bytes | bytearray) -> bytes | bytearray:
    """The bytes between ``<sheetData>`` and ``</sheetData>`` of a sheet's XML (empty when it has none).  A
    ``bytearray`` is cut in place and returned (no second copy of the sheet held beside it: review finding)."""
    start = _SHEET_DATA_START.search(data)
    if start is None or data[start.end() - 2:start.end()] == b"/>":
        return b""
    end = data.rfind(b"sheetData", start.end())
    end = len(data) if end < 0 else data.rfind(b"<", start.end(), end)
    if isinstance(data, bytearray):
        del data[end:]
        del data[:start.end()]
        return data
    return data[start.end():end]


def _inline(body: bytes) -> str:
    """openpyxl's ``Text.content``: the ``<t>`` texts of an ``<is>``, plain and rich runs, phonetic runs left out."""
    out, skip_to = [], -1
    for m in _T.finditer(body):
        if m.start() < skip_to:
            continue
        if m.group(2) == b"rPh":
            skip_to = m.end()
            continue
        out.append(_unescape(m.group(4) or b""))
    return "".join(out)


class Workbook:
    """An open .xlsx: :attr:`sheetnames` in workbook order, :meth:`rows` and :meth:`table` of one sheet.

    Sheets are held by part (the archive member), not by name: several names listing one part share it.  A part's
    XML is the one handed over by :meth:`keep` (read once, under the caps), else read from the archive when parsed
    whole and kept until :meth:`close`; each part's first row is kept (:meth:`header`).  The shared strings are
    parsed on first use (a workbook written by openpyxl has none: its texts are inline)."""

    def __init__(self, path: str | Path) -> None:
        self._zip = zipfile.ZipFile(path)
        try:
            names = set(self._zip.namelist())
            wb = ElementTree.fromstring(self._zip.read("xl/workbook.xml"))
            rels = ElementTree.fromstring(self._zip.read("xl/_rels/workbook.xml.rels"))
            targets, strings_part = {}, None
            for rel in rels.iter(_PKG_REL + "Relationship"):
                target = rel.get("Target", "")
                target = target.lstrip("/") if target.startswith("/") else posixpath.normpath("xl/" + target)
                targets[rel.get("Id")] = target
                if rel.get("Type", "").endswith("/sharedStrings"):
                    strings_part = target
            self._parts = {}
            #: ``<sheet>`` entries of workbook.xml: the caps refuse too many before any is read
            self.listed = 0
            for sheet in wb.iter(_MAIN + "sheet"):
                self.listed += 1
                self._parts[sheet.get("name")] = targets[sheet.get(_REL + "id")]
            self.sheetnames = list(self._parts)
            #: the archive members holding the sheets, each once (several names may list one part)
            self.parts = list(dict.fromkeys(self._parts.values()))
            if strings_part is None and "xl/sharedStrings.xml" in names:
                strings_part = "xl/sharedStrings.xml"
            #: the shared strings' member, by its relationship (its cap goes by this role, not by its path)
            self.strings_part = strings_part if strings_part in names else None
            self._strings_xml: bytes | None = None
            self._string_table: list[str] | None = None
            self._bodies: dict[str, bytes | bytearray] = {}   # by part
            self._headers: dict[tuple[str, int], tuple] = {}  # by (part, max_col)
        except BaseException:
            self._zip.close()
            raise

    def close(self) -> None:
        self._zip.close()
        self._bodies.clear()

    def __enter__(self) -> Workbook:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def part(self, name: str) -> str:
        """The archive member holding sheet ``name``'s XML."""
        return self._parts[name]

    def size(self, member: str) -> int:
        """The unpacked size the archive declares for ``member`` (the reader never returns more)."""
        return self._zip.getinfo(member).file_size

    def open_member(self, member: str):
        """An archive member (a sheet's XML, the shared strings) as a stream of bytes (the caps read it in pieces)."""
        return self._zip.open(member)

    def keep(self, part: str, xml: bytes | bytearray) -> None:
        """Use ``xml`` (the sheet ``part``'s XML, as read for the caps) instead of reading it again (a ``bytearray``
        is cut to its ``<sheetData>`` in place)."""
        self._bodies[part] = _body(xml)

    def keep_strings(self, xml: bytes) -> None:
        """Use ``xml`` (the shared strings, as read for the caps) instead of reading them again."""
        self._strings_xml = xml

    @property
    def _strings(self) -> list[str]:
        if self._string_table is None:
            from openpyxl.reader.strings import read_string_table

            if self._strings_xml is None and self.strings_part is not None:
                self._strings_xml = self._zip.read(self.strings_part)
            xml = self._strings_xml
            table = read_string_table(io.BytesIO(xml)) if xml is not None else []
            self._string_table, self._strings_xml = table, None   # set once read whole: a failed read stays unread
        return self._string_table

    def _sheet_data(self, name: str) -> bytes | bytearray:
        """The bytes between ``<sheetData>`` and ``</sheetData>`` of sheet ``name`` (empty when it has none), kept
        for the next read of the same part."""
        part = self._parts[name]
        if part not in self._bodies:
            self._bodies[part] = _body(self._zip.read(part))
        return self._bodies[part]

    def header(self, name: str, max_col: int) -> tuple:
        """Row 1 of sheet ``name`` (``max_col`` values; ``()`` for an empty sheet), read once per part.  A part
        not kept (:meth:`keep`) is read for it and not kept either: only the sheet parsed whole stays."""
        key = (self._parts[name], max_col)
        if key not in self._headers:
            body = self._bodies.get(key[0])
            if body is None:
                body = _body(self._zip.read(key[0]))
            self._headers[key] = next(iter(self._rows(body, max_row=1, max_col=max_col)), ())
        return self._headers[key]

    def table(self, name: str, max_row: int, max_col: int) -> tuple[np.ndarray, dict[tuple[int, int], object]]:
        """The same cells as :meth:`rows`, as ``(numbers, others)``: ``numbers[i, j]`` the float of row ``i + 1``,
        column ``j + 1`` when that cell is a number (``t`` absent or ``n``), NaN otherwise; ``others[(i, j)]`` every
        other non-empty value (text, bool) as :meth:`rows` gives it.  Rows end at the last one holding a cell.

        Below row 1, when every cell is a plain number as spreadsheet programs write them, the cells are found by
        numpy over the sheet's bytes (:func:`.xlsx_scan.plain_cells`: no regular expression and no Python object a
        cell: about half the CPU of :data:`_FAST`'s ``findall`` with the conversion after it, 1.1–1.4× faster than
        the ``findall`` alone; ``python -m benchmarks.xlsx_scan``, the demo's 47 309-cell sheet, load 9: 0.038–0.040
        s vs 0.044–0.052 s and 0.075–0.077 s CPU), and row 1 (the header) by :data:`_FAST` (reference, type,
        value); otherwise every cell by :data:`_FAST`, whose numbers are converted by numpy in one call (the same
        correctly rounded decimal → binary64 as ``float``).  A sheet whose cells do not all carry their reference
        (``r``), or whose cell tags have a namespace prefix, is read through :meth:`rows` instead."""
        body = self._sheet_data(name)
        cut = body.find(b"</row>") + len(b"</row>")   # the end of row 1 (or of the first row element)
        cut = cut if cut >= len(b"</row>") else len(body)   # (positions, not slices: no copy of the sheet)
        plain = plain_cells(body, cut) if cut < len(body) else None
        if plain is not None:
            cells = _FAST.findall(body, 0, cut)
            n_cells = body.count(b"<c", 0, cut)
            head_cells_at, head_rows_at = tag_positions(body, cut)
            plain_col, plain_row, plain_value, cells_at, rows_at = plain
            cells_at, rows_at = np.concatenate([head_cells_at, cells_at]), np.concatenate([head_rows_at, rows_at])
        else:
            plain_col = plain_row = np.zeros(0, dtype=np.int64)
            plain_value = np.zeros(0)
            cells, n_cells = _FAST.findall(body), body.count(b"<c")
            cells_at, rows_at = tag_positions(body)
        if not (cells or len(plain_col)) or len(cells) != n_cells \
                or (body.find(b":") >= 0 and b":c" in body and _PREFIXED_CELL.search(body)):   # memchr first
            return self._table_of_rows(name, max_row, max_col)
        head = np.array(cells, dtype=bytes).reshape(-1, 3)   # bytes arrays: no object per cell
        ref, kind, value = head[:, 0], head[:, 1], head[:, 2]
        head_col, head_row = references(ref)
        col, row = np.concatenate([head_col, plain_col]), np.concatenate([head_row, plain_row])
        if not in_order(body, row, col, cells_at, rows_at):
            return self._table_of_rows(name, max_row, max_col)
        beyond = np.nonzero(row > max_row)[0]
        n = int(beyond[0]) if beyond.size else len(row)   # openpyxl stops at the first row beyond max_row
        keep = (col >= 1) & (col <= max_col) & (row >= 1) & (np.arange(len(row)) < n)
        head_number = keep[:len(head)] & ((kind == b"") | (kind == b"n")) & (value != b"")
        floats = np.concatenate([value[head_number].astype(np.float64), plain_value[keep[len(head):]]])
        number = keep & np.concatenate([head_number, np.ones(len(plain_col), dtype=bool)])
        if not np.isfinite(floats).all():   # 'inf'/'nan' (openpyxl's int() refuses them) or '1e999' (inf)
            return self._table_of_rows(name, max_row, max_col)
        n_rows = int(row[keep].max()) if keep.any() else 0
        numbers = np.full((n_rows, max_col), np.nan)
        numbers[row[number] - 1, col[number] - 1] = floats
        others = {}
        for k in np.nonzero(keep[:len(head)] & ~head_number)[0]:
            v = self._value(kind[k], value[k], _content(body, ref[k]) if kind[k] == b"inlineStr" else b"")
            if v is not None:
                others[(int(row[k]) - 1, int(col[k]) - 1)] = v
        return numbers, others

    def _table_of_rows(self, name: str, max_row: int, max_col: int
                       ) -> tuple[np.ndarray, dict[tuple[int, int], object]]:
        """:meth:`table` from :meth:`rows`: one Python value a cell, openpyxl's rules for any sheet."""
        rows = self.rows(name, max_row, max_col)
        numbers = np.full((len(rows), max_col), np.nan)
        others: dict[tuple[int, int], object] = {}
        for i, r in enumerate(rows):
            for j, v in enumerate(r):
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    numbers[i, j] = v
                elif v is not None:
                    others[(i, j)] = v
        last = max([i for i in range(len(rows)) if any(x is not None for x in rows[i])], default=-1) + 1
        return numbers[:last], others

    def _value(self, kind: bytes, raw: bytes, inner: bytes):
        """One cell's value by openpyxl's rules (module docstring); ``inner`` the cell's content after its ``<v>``."""
        if kind == b"inlineStr":
            start = re.search(rb"<" + _P + rb"is[\s>/]", inner)
            return _inline(inner[start.start():]) if start else None
        if not raw:
            return None
        if kind in (b"n", b""):
            return float(raw) if b"." in raw or b"e" in raw or b"E" in raw else int(raw)
        if kind == b"s":
            return self._strings[int(raw)]
        if kind == b"b":
            return bool(int(raw))
        return _unescape(raw)  # str, e, d

    def rows(self, name: str, max_row: int, max_col: int, min_row: int = 1) -> list[tuple]:
        """Rows ``min_row``–``max_row`` of sheet ``name``, each ``max_col`` values (module docstring)."""
        return self._rows(self._sheet_data(name), max_row, max_col, min_row)

    def _rows(self, body: bytes | bytearray, max_row: int, max_col: int, min_row: int = 1) -> list[tuple]:
        empty = (None,) * max_col
        out: list[tuple] = []
        counter = min_row
        index = 0
        for row in _ROW.finditer(body):
            r = _attrs(row.group(1)).get(b"r")
            index = int(r) if r is not None and r.isdigit() else (int(float(r)) if r is not None else index + 1)
            if index > max_row:
                break
            while counter < index:
                out.append(empty)
                counter += 1
            if counter > index:
                continue
            counter += 1
            values = [None] * max_col
            col = 0
            for cell in _CELL.finditer(row.group(2) or b""):
                a = _attrs(cell.group(1))
                ref = a.get(b"r")
                col = _column(ref) if ref else col + 1
                if not 1 <= col <= max_col:
                    continue
                inner = cell.group(2) or b""
                v = _V.search(inner)
                values[col - 1] = self._value(a.get(b"t", b"n"), v.group(2) if v else b"", inner)
            out.append(tuple(values))
        if max_row < index:
            out.extend([empty] * (max_row + 1 - counter))
        return out


__all__ = ["Workbook"]
