"""A sheet's cells found by numpy over the bytes of its XML: no regular expression a cell, no Python object a cell.

Used by :meth:`.xlsx_cells.Workbook.table` on a sheet's ``<sheetData>`` (the caps of :func:`.excel.open_workbook`
have run).  :func:`plain_cells` answers ``None`` for anything it does not recognise exactly, and the caller then
reads the sheet with :mod:`.xlsx_cells`' regular expressions (openpyxl's rules, tested with openpyxl as the oracle);
each step is a fixed number of numpy passes over the bytes or the tags: linear time on any input.

:func:`plain_cells` reads the rows below the header when they hold plain numbers only, as spreadsheet programs
write them: each row ``<row …>…</row>`` (or ``<row …/>``) holds cells ``<c r="B12"[ s="3"][ t="n"][ s="3"]>
<v>-0.123</v></c>`` (the plain number cells :data:`.xlsx_cells._FAST` reads), and nothing else is a tag:

0. the counts of ``<``, ``<c ``, ``<row`` and ``</row`` (:func:`occurrences`) must balance, at least 5 bytes a
   tag, before any array one entry per tag;
1. every ``<`` and every ``>`` of the bytes, found in one pass; they must alternate, ``<`` first (so no ``<`` or
   ``>`` lies in a value, an attribute, a text or a comment: those sheets are left to the regular expressions);
2. each tag's kind from the byte after its ``<`` and its length, then the rest of its name on the tags of that
   kind: rows one after another (``<row `` … ``</row>``, or ``<row …/>``), each holding whole cells of four
   adjacent tags (``<c r="``, ``<v>``, ``</v>``, ``</c>``); text between rows and cells is ignored, as openpyxl
   ignores it;
3. each cell's reference (``[A-Z]{1,3}[0-9]{1,9}`` then ``"``, in a window of 13 bytes), read by columns in
   groups of one shape (numbers of letters and digits), and the rest of its attributes, matched by
   :data:`NUMBER_ATTRS` once per distinct text (at most :data:`MAX_FORMS`: a sheet has one to a few, the style
   of each column);
4. the values (non-empty, no blank, at most :data:`MAX_VALUE_BYTES`) converted by numpy in one call (the same
   correctly rounded decimal → binary64 as ``float``).

On the demo session's eight workbooks in the thesis' layout (``python -m benchmarks.read_formats --formats
xlsx``, CPU, load 3–4.6) reading takes 0.38–0.40 s with this scan against 0.57–0.59 s before it (80cff72: the
regular expressions' ``findall`` made three objects a cell, and the array of them a fourth), about 1.5× less;
the scan alone against that ``findall``: ``python -m benchmarks.xlsx_scan``.  Step 0 by numpy compares instead of
four ``bytes.count`` (and the caps' ``<row``/``<c`` counts of :func:`.xlsx_cells.count_tags` likewise), step 1 in
one pass: ``python -m benchmarks.read_formats --formats xlsx --repeats 7``, nine pairs alternated with main at
2d78824 (load 3.0–6.9, CPU): median 0.244 s (0.228–0.307) against 0.308 s (0.266–0.358), eight pairs of nine
faster, by 0.043 s in the median pair.
"""

from __future__ import annotations

import re

import numpy as np

from app.pipeline.ingestion.model import rows_all

#: the attributes of a plain number cell after its reference (style and the number type, as spreadsheet programs
#: write them)
NUMBER_ATTRS = rb'(?: s="\d+")?(?: t="n")?(?: s="\d+")?'
_NUMBER_ATTRS = re.compile(NUMBER_ATTRS)
#: most distinct attribute texts of the plain cells (more: read by the regular expressions)
MAX_FORMS = 16
#: longest attribute text after the reference, and longest value (``-1.2345678901234567E-123`` has 24 bytes)
MAX_ATTRS_BYTES = 32
MAX_VALUE_BYTES = 40

_LT, _GT, _SLASH, _QUOTE = 60, 62, 47, 34


def references(refs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1-based (columns, rows) of an array of cell references (``b"AB12"`` → 28, 12), vectorised over the bytes
    (``[A-Z]{1,3}[0-9]{1,9}``, as :data:`.xlsx_cells._FAST` matches them)."""
    width = int(np.char.str_len(refs).max(initial=1))   # the longest reference present (≤ 12 by the pattern)
    codes = refs.astype(f"S{width}").view(np.uint8).reshape(-1, width).astype(np.int64)
    col = np.zeros(len(codes), dtype=np.int64)
    row = np.zeros(len(codes), dtype=np.int64)
    for k in range(width):
        c = codes[:, k]
        letter, digit = (c >= 65) & (c <= 90), (c >= 48) & (c <= 57)
        col = np.where(letter, col * 26 + c - 64, col)
        row = np.where(digit, row * 10 + c - 48, row)
    return col, row


def occurrences(data: bytes | bytearray, texts: list[bytes], start: int = 0, end: int | None = None,
                block: int = 1 << 17) -> list[int]:
    """``[data.count(text, start, end) for text in texts]`` (``start``, ``end`` not negative) for texts that cannot
    overlap themselves (no proper prefix of a text is also its suffix, as ``<row``, ``<c ``, ``:c``: then every
    match is counted, as ``bytes.count`` counts them), by numpy compares of one block of positions at a time.

    Each text's bytes are compared with the bytes at each position plus their offset, and the matches counted:
    3-4x less CPU than one ``bytes.count`` a text (whose two-way search runs at ~1.5 GB/s; a compare runs at
    ~13 GB/s), with three block-sized masks at most (``block`` bytes each, reused: the memory does not grow with
    ``data``, so a crafted sheet is refused by counts before any array one entry per tag).  The last positions,
    where a text would run past ``end``, are counted by ``bytes.count`` on those few bytes."""
    for text in texts:
        if not text or any(text[:k] == text[-k:] for k in range(1, len(text))):
            raise ValueError(f"{text!r} is empty or can overlap itself")
    end = len(data) if end is None else min(end, len(data))
    counts = [0] * len(texts)
    if end <= start:
        return counts
    v = np.frombuffer(data, dtype=np.uint8)
    stop = max(end - max(map(len, texts)) + 1, start)   # positions whose longest text ends within data[:end]
    size = min(block, stop - start)
    first, match, other = (np.empty(size, dtype=bool) for _ in range(3))
    for at in range(start, stop, block):
        n = min(block, stop - at)
        lead = None
        for i, text in enumerate(texts):
            if text[0] != lead:
                lead = text[0]
                np.equal(v[at:at + n], lead, out=first[:n])
            if len(text) == 1:
                counts[i] += int(np.count_nonzero(first[:n]))
                continue
            np.equal(v[at + 1:at + 1 + n], text[1], out=match[:n])
            np.logical_and(match[:n], first[:n], out=match[:n])
            for k in range(2, len(text)):
                np.equal(v[at + k:at + k + n], text[k], out=other[:n])
                np.logical_and(match[:n], other[:n], out=match[:n])
            counts[i] += int(np.count_nonzero(match[:n]))
    tail = bytes(data[stop:end])
    return [c + tail.count(text) for c, text in zip(counts, texts)]


def _windows(data: np.ndarray, start: np.ndarray, width: int) -> np.ndarray:
    """``(n, width)`` bytes of ``data`` (contiguous) from each ``start`` (``data`` padded with ``width`` bytes at its
    end), a copy of their own.  Gathered as one ``width``-byte item each, from a view whose items overlap (stride
    1): 2.3-2.7x faster than a ``sliding_window_view``'s rows (0.26 vs 0.61 ms for 12 000 windows of 13 bytes),
    which numpy copies byte run by byte run."""
    items = np.ndarray(buffer=data, dtype=f"V{width}", shape=(max(len(data) - width + 1, 0),), strides=(1,))
    return items[start].view(np.uint8).reshape(-1, width)


def _cut(window: np.ndarray, length: np.ndarray) -> np.ndarray:
    """``window`` (a copy of its own: :func:`_windows`) with the bytes from each row's ``length`` on set to zero,
    in place."""
    return np.multiply(window, np.arange(window.shape[1]) < length[:, None], out=window)


def _as_words(window: np.ndarray) -> np.ndarray:
    """The rows of a bytes ``window`` as rows of 8-byte words (padded with zeros): fast row comparison."""
    pad = -window.shape[1] % 8
    if pad:
        window = np.concatenate([window, np.zeros((len(window), pad), np.uint8)], axis=1)
    return np.ascontiguousarray(window).view(np.uint64)


def _are(data: np.ndarray, at: np.ndarray, text: bytes) -> bool:
    """Whether ``text`` is written at each position ``at`` of ``data``."""
    return all(bool(np.all(data[at + k] == c)) for k, c in enumerate(text))


def _cells_in_rows(data: np.ndarray, lt: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The indices (into ``lt``) of the cells' ``<c`` and of the rows' ``<row`` when the tags are rows one after
    another, each of whole four-tag cells (module docstring, steps 2 and 3), else ``None``.

    A tag is known by the byte after its ``<`` and its length; each kind's other bytes are then checked on the
    tags of that kind alone.  The row tags (``<row `` opening a row, or empty when it ends in ``/>``; ``</row>``)
    must pair up, the first tag opening a row and the last ending one, each row holding a multiple of four tags;
    then the other tags, taken in order, are ``<c r="…``, ``<v>``, ``</v>``, ``</c>`` over again (so a row holds
    whole cells and nothing else)."""
    second = data[lt + 1]
    size = gt - lt
    opening = second == ord("r")
    ending = (second == _SLASH) & (size == 5)
    opens = np.flatnonzero(opening)
    empty = data[gt[opens] - 1] == _SLASH
    closes = np.flatnonzero(ending)
    if len(opens) == 0 or len(opens) != len(closes) + np.count_nonzero(empty):
        return None
    if not (_are(data, lt[opens] + 2, b"ow ") and _are(data, lt[closes] + 2, b"row")):
        return None
    if np.any(empty):
        closes = np.flatnonzero(ending | np.isin(np.arange(len(lt)), opens[empty]))
    if opens[0] != 0 or closes[-1] != len(lt) - 1:
        return None
    if not (np.array_equal(opens[1:], closes[:-1] + 1) and np.all(closes >= opens)):
        return None
    if not np.all((closes - opens - 1)[closes > opens] % 4 == 0):
        return None
    quads = np.flatnonzero(~(opening | ending)).reshape(-1, 4)   # whole rows of cells: quads of adjacent tags
    cell, v, v_end, c_end = quads.T
    if not (np.all(second[cell] == ord("c")) and _are(data, lt[cell] + 2, b' r="')
            and np.all((second[v] == ord("v")) & (size[v] == 2))
            and np.all((second[v_end] == _SLASH) & (size[v_end] == 3)) and _are(data, lt[v_end] + 2, b"v")
            and np.all((second[c_end] == _SLASH) & (size[c_end] == 3)) and _are(data, lt[c_end] + 2, b"c")):
        return None
    return cell, opens


def _cell_references(ref: np.ndarray, room: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """1-based (columns, rows) of the references at the start of each row of ``ref`` (bytes, ``(n, 13)``), and the
    length of each with its closing quote, which lies within the ``room`` bytes left in its tag:
    ``[A-Z]{1,3}[0-9]{1,9}`` then ``"``, else ``None``.  Grouped by the numbers of letters and digits (a few groups
    a sheet), each group's letters and digits read column by column."""
    upper = [(ref[:, k] >= 65) & (ref[:, k] <= 90) for k in range(4)]
    letters = upper[0].astype(np.int64) + (upper[0] & upper[1]) + (upper[0] & upper[1] & upper[2])
    quote = np.argmax(ref == _QUOTE, axis=1)
    digits = quote - letters
    if not (np.all(upper[0]) and not np.any(upper[0] & upper[1] & upper[2] & upper[3])
            and np.all(ref[np.arange(len(ref)), quote] == _QUOTE) and np.all(quote < room)
            and np.all((digits >= 1) & (digits <= 9))):
        return None
    col = np.zeros(len(ref), dtype=np.int64)
    row = np.zeros(len(ref), dtype=np.int64)
    shape = letters * 16 + digits
    keys = np.flatnonzero(np.bincount(shape))
    for key in keys:                                      # at most 3 × 9 groups
        where = slice(None) if len(keys) == 1 else np.flatnonzero(shape == key)
        n_letters, n_digits = int(key) // 16, int(key) % 16
        part = ref[where]
        c = np.zeros(len(part), dtype=np.int64)
        for k in range(n_letters):
            c = c * 26 + part[:, k] - 64
        r = np.zeros(len(part), dtype=np.int64)
        for k in range(n_letters, n_letters + n_digits):
            d = part[:, k].astype(np.int64) - 48
            if np.any((d < 0) | (d > 9)):
                return None
            r = r * 10 + d
        col[where], row[where] = c, r
    return col, row, quote + 1


def plain_cells(body: bytes | bytearray, start: int = 0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """``(columns, rows, values, cell tags, row tags)`` of the cells of ``body[start:]`` in order (1-based columns
    and rows; float64 values; the positions in ``body`` of each ``<c`` and each ``<row``, for :func:`in_order`)
    when that part holds rows of plain number cells only (module docstring), else ``None``."""
    # Before any array one entry per tag: a part of plain rows holds only ``<row``/``</row>`` and four tags per
    # ``<c ``, so any other tag means "not plain", told by counts (:func:`occurrences`: one 128 kB block of masks
    # at a time, however long the sheet) before any array one entry per tag (a crafted sheet of
    # 31 M ``<>`` pairs, 66 kB zipped, cost about 1 GB of positions before this check).
    # A plain part also holds at least 5.5 bytes a tag (the least cell, ``<c r="A1"><v>1</v></c>``, is 22 bytes for
    # four tags; ``<row >``, ``</row>`` 6 bytes, ``<row />`` 7); the check asks for 5, a bound safely under that
    # least 5.5 (no plain part is refused by it), so a dense padding that keeps the counts (``<c ><><><>``, 2.5
    # bytes a tag) is refused before any array too.
    tags, cells, rows, ends = occurrences(body, [b"<", b"<c ", b"<row", b"</row"], start)
    if tags != 4 * cells + rows + ends or 5 * tags > len(body) - start:
        return None
    raw = np.frombuffer(body, dtype=np.uint8)[start:]
    # every '<' and '>' in one pass: they alternate, '<' first, when the even ones are all '<' and the odd all '>'
    marks = np.flatnonzero((raw == _LT) | (raw == _GT))
    lt, gt = marks[0::2], marks[1::2]
    if len(marks) == 0 or len(marks) % 2 or not (np.all(raw[lt] == _LT) and np.all(raw[gt] == _GT)):
        return None
    data = np.concatenate([raw, np.zeros(64, dtype=np.uint8)])   # every window below fits
    found = _cells_in_rows(data, lt, gt)
    if found is None:
        return None
    cell, rows = found
    # nothing between <c …> and <v>, nor between </v> and </c>
    if not (np.array_equal(gt[cell] + 1, lt[cell + 1]) and np.array_equal(gt[cell + 2] + 1, lt[cell + 3])):
        return None
    ref_at = lt[cell] + 6
    found = _cell_references(_windows(data, ref_at, 13), gt[cell] - ref_at)
    if found is None:
        return None
    col, row, ref_len = found
    # the attributes after the reference: NUMBER_ATTRS, checked once per distinct text
    rest_at = ref_at + ref_len
    rest_len = gt[cell] - rest_at
    width = int(rest_len.max(initial=0))
    if width > MAX_ATTRS_BYTES:
        return None
    if width:
        rest = _cut(_windows(data, rest_at, width), rest_len)
        words = _as_words(rest)
        undecided = np.ones(len(rest), dtype=bool)
        for _ in range(MAX_FORMS):
            first = int(np.argmax(undecided))
            if not undecided[first]:
                break
            if not _NUMBER_ATTRS.fullmatch(rest[first, :rest_len[first]].tobytes()):
                return None
            undecided &= ~(rows_all(words == words[first]) & (rest_len == rest_len[first]))
        if undecided.any():
            return None
    # the values: non-empty, no blank, converted at once
    v_at = gt[cell + 1] + 1
    v_len = lt[cell + 2] - v_at
    width = int(v_len.max(initial=1))
    if len(cell) and (v_len.min() < 1 or width > MAX_VALUE_BYTES):
        return None
    text = _cut(_windows(data, v_at, width), v_len)
    if np.any(((text >= 9) & (text <= 13)) | (text == 32)):
        return None
    try:
        values = text.view(f"S{width}").ravel().astype(np.float64)
    except ValueError:    # not a number numpy reads: left to the regular expressions (and their refusal)
        return None
    return col, row, values, lt[cell] + start, lt[rows] + start


def tag_positions(body: bytes | bytearray, end: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Positions of the cell tags (``<c`` then a blank, ``/`` or ``>``) and the row tags (``<row``) of
    ``body[:end]`` (a tag within 12 bytes of the end holds no cell of a row and is not counted)."""
    data = np.frombuffer(body, dtype=np.uint8)
    stop = max(min(len(data) if end is None else end, len(data) - 12), 0)
    second = data[1:stop + 1]
    lt = np.flatnonzero((data[:stop] == 60) & ((second == 99) | (second == 114)))   # '<c', '<r'
    third = data[lt + 2]
    is_cell = (data[lt + 1] == 99) & ((third == 32) | (third == 47) | (third == 62))
    is_row = (third == 111) & (data[lt + 3] == 119) & (data[lt + 1] == 114)
    return lt[is_cell], lt[is_row]


def in_order(body: bytes | bytearray, row: np.ndarray, col: np.ndarray, cells_at: np.ndarray,
             rows_at: np.ndarray) -> bool:
    """Whether the cells of ``body`` (their references' 1-based ``row`` and ``col``, in the sheet's order, one per
    cell tag at ``cells_at``; the row tags at ``rows_at``: :func:`tag_positions`) lie as openpyxl reads them when
    placed by reference: every row tag carries ``r``, the rows strictly increase, each cell names the row it lies
    in, and the cells strictly increase (row, then column).  openpyxl skips a row whose number goes back, keeps the
    first of a repeated row and the last of a repeated column, and places a cell by its column in the row it lies
    in, whatever row its reference names (review finding: the fast path placed them otherwise).  Each cell's row
    tag is found by a binary search of its position."""
    key = row * 32768 + col                     # 3 column letters: at most 18 278
    if len(key) > 1 and not bool(np.all(key[1:] > key[:-1])):
        return False
    if len(cells_at) != len(row) or not len(rows_at):
        return False
    data = np.frombuffer(body, dtype=np.uint8)
    # each row tag's number, from the bytes after '<row r="' (1-9 digits then '"'; else read by rows())
    at = rows_at + 8
    window = data[np.minimum(at[:, None] + np.arange(10), len(data) - 1)].astype(np.int64)
    digit = (window >= 48) & (window <= 57)
    width = np.argmin(digit, axis=1)
    prefix = data[np.minimum(at[:, None] - 4 + np.arange(4), len(data) - 1)]
    if not (np.all(prefix == np.frombuffer(b' r="', np.uint8)) and np.all(width >= 1)
            and np.all(window[np.arange(len(at)), width] == 34)):
        return False
    r = np.zeros(len(at), dtype=np.int64)
    for k in range(9):
        r = np.where(k < width, r * 10 + window[:, k] - 48, r)
    which = np.searchsorted(rows_at, cells_at) - 1   # each cell's row tag: the last one before it
    return bool(np.all(r[1:] > r[:-1])) and int(which.min(initial=0)) >= 0 and np.array_equal(r[which], row)


__all__ = ["MAX_FORMS", "NUMBER_ATTRS", "in_order", "occurrences", "plain_cells", "references", "tag_positions"]
