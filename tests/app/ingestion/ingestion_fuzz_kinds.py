"""The kinds of malformed session files the ingestion fuzzer applies (``test_ingestion_fuzz.py``).

Each kind is one function ``mutate(folder, draw) -> files`` that damages (or harmlessly varies) exactly one
thing in a copy of a valid simulated session, using ``draw`` (a Hypothesis ``data.draw``) for everything
positional (which file, which row, which cell, what garbage), and returns the file(s) it touched: an error
must name one of them.  :data:`KINDS` is the table: name -> :class:`Kind` (format of the session it needs,
one-line description, the function, and ``must_load`` for variations a real export can have that ChakaMo
has to accept).

Sizes are bounded (at most a few hundred kB of garbage) so that no example can make a reader run long.
MetaBase files are ``epoc (ms),timestamp (+0000),elapsed (s),x-axis (g),y-axis (g),z-axis (g)`` (the demo's
dialect); the generic CSV has per-stream time columns; the thesis workbooks have one sheet ``data``.
"""

from __future__ import annotations

import datetime as dt
import io
import json
import re
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from hypothesis import strategies as st

Draw = Callable[[st.SearchStrategy], object]
STREAMS = ("Accelerometer", "Gyroscope", "Magnetometer")


def _not_number(s: str) -> bool:
    """True for text that is neither blank nor a number (``float`` refuses it)."""
    try:
        float(s)
    except ValueError:
        return bool(s.strip())
    return False


#: cell text that is not a number: no separators, quotes or line breaks (those are kinds of their own)
GARBAGE = st.text(st.characters(exclude_categories=("Cs",), exclude_characters=',;"\n\r\x00'),
                  min_size=1, max_size=12).filter(_not_number)
#: the same for a worksheet cell (openpyxl refuses control characters, which Excel cannot store either)
CELL_TEXT = st.text(st.characters(exclude_categories=("Cs", "Cc")), min_size=1, max_size=12).filter(_not_number)


@dataclass(frozen=True)
class Kind:
    fmt: str                      # "metabase", "generic" or "xlsx": the session it mutates
    what: str                     # one line for the table
    mutate: Callable[[Path, Draw], tuple[Path, ...]]
    must_load: bool = False       # a harmless variation: the session has to load, and sanely


# ------------------------------------------------------------------------------------------------ helpers

def _metabase_file(folder: Path, draw: Draw, streams: tuple[str, ...] = STREAMS) -> Path:
    files = sorted(p for p in folder.glob("*_MetaWear_*.csv") if any(f"_{s}_" in p.name for s in streams))
    return draw(st.sampled_from(files))


def _lines(path: Path) -> tuple[str, list[str]]:
    lines = path.read_text(encoding="utf-8").splitlines()
    return lines[0], lines[1:]


def _save(path: Path, header: str, rows: list[str], newline: str = "\n") -> None:
    path.write_bytes((newline.join([header, *rows]) + newline).encode("utf-8"))


def _row(draw: Draw, rows: list) -> int:
    return draw(st.integers(0, len(rows) - 1))


def _set_cell(path: Path, draw: Draw, text_strategy: st.SearchStrategy, columns=None) -> tuple[Path, ...]:
    header, rows = _lines(path)
    i = _row(draw, rows)
    cells = rows[i].split(",")
    j = draw(st.sampled_from(columns if columns is not None else range(len(cells))))
    cells[j] = draw(text_strategy)
    rows[i] = ",".join(cells)
    _save(path, header, rows)
    return (path,)


def _recording_files(folder: Path, draw: Draw) -> list[Path]:
    """The three stream files of one MetaBase recording (same label and MAC)."""
    acc = _metabase_file(folder, draw, ("Accelerometer",))
    stem = acc.name.split("_Accelerometer_")[0]
    return sorted(folder.glob(f"{stem}_*.csv"))


def _rename_label(files: list[Path], old: str, new: str) -> tuple[Path, ...]:
    out = []
    for p in files:
        q = p.with_name(p.name.replace(old, new, 1))
        p.rename(q)
        out.append(q)
    return tuple(out)


# ------------------------------------------------------------------------------------- MetaBase CSV kinds

def empty(folder, draw):
    p = _metabase_file(folder, draw)
    p.write_bytes(draw(st.sampled_from([b"", b"\n", b"\n\n  \n", b"\xef\xbb\xbf"])))
    return (p,)


def header_only(folder, draw):
    p = _metabase_file(folder, draw)
    header, _ = _lines(p)
    _save(p, header, [])
    return (p,)


def other_stream_header(folder, draw):
    files = _recording_files(folder, draw)
    target, source = draw(st.permutations(files))[:2]
    _, rows = _lines(target)
    _save(target, _lines(source)[0], rows)
    return (target,)


def truncated_mid_line(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows)
    cut = draw(st.integers(1, len(rows[i]) - 1))
    p.write_bytes(("\n".join([header, *rows[:i], rows[i][:cut]])).encode())
    return (p,)


def truncated_mid_number(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows)
    last = rows[i].rsplit(",", 1)
    if len(last[1]) > 1:
        last[1] = last[1][: draw(st.integers(1, len(last[1]) - 1))]
    p.write_bytes(("\n".join([header, *rows[:i], ",".join(last)])).encode())
    return (p,)


def random_bytes(folder, draw):
    p = _metabase_file(folder, draw)
    p.write_bytes(draw(st.binary(min_size=1, max_size=4000)))
    return (p,)


def spliced_garbage_bytes(folder, draw):
    p = _metabase_file(folder, draw)
    data = p.read_bytes()
    at = draw(st.integers(0, len(data)))
    p.write_bytes(data[:at] + draw(st.binary(min_size=1, max_size=64)) + data[at:])
    return (p,)


def utf16(folder, draw):
    p = _metabase_file(folder, draw)
    p.write_bytes(p.read_text().encode(draw(st.sampled_from(["utf-16", "utf-16-le", "utf-16-be", "utf-32"]))))
    return (p,)


def utf8_bom(folder, draw):
    p = _metabase_file(folder, draw)
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    return (p,)


def nul_bytes(folder, draw):
    p = _metabase_file(folder, draw)
    data = bytearray(p.read_bytes())
    for at in sorted(draw(st.lists(st.integers(0, len(data)), min_size=1, max_size=5)), reverse=True):
        data[at:at] = b"\x00"
    p.write_bytes(bytes(data))
    return (p,)


def line_endings(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    pattern = draw(st.lists(st.sampled_from(["\r\n", "\r", "\n"]), min_size=1, max_size=4))
    lines = [header, *rows]
    p.write_bytes("".join(ln + pattern[k % len(pattern)] for k, ln in enumerate(lines)).encode())
    return (p,)


def extra_columns(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    name = draw(st.sampled_from(["temperature (C)", "status", "", "pressure (Pa)", "x-axis status"]))
    value = draw(st.sampled_from(["", "1", "25.3", "ok"]))
    j = draw(st.integers(0, 6))
    def ins(line, cell):
        cells = line.split(",")
        cells.insert(j, cell)
        return ",".join(cells)
    _save(p, ins(header, name), [ins(r, value) for r in rows])
    return (p,)


def stray_separator(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows)
    at = draw(st.integers(0, len(rows[i])))
    rows[i] = rows[i][:at] + "," + rows[i][at:]
    _save(p, header, rows)
    return (p,)


def missing_column(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    j = draw(st.integers(0, 5))
    drop = lambda line: ",".join(c for k, c in enumerate(line.split(",")) if k != j)  # noqa: E731
    _save(p, drop(header), [drop(r) for r in rows])
    return (p,)


def swapped_columns(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    order = draw(st.permutations(range(6)))
    perm = lambda line: ",".join(line.split(",")[k] for k in order)  # noqa: E731
    _save(p, perm(header), [perm(r) for r in rows])
    return (p,)


def non_numeric_cell(folder, draw):
    return _set_cell(_metabase_file(folder, draw), draw, GARBAGE)


def nan_inf_cell(folder, draw):
    return _set_cell(_metabase_file(folder, draw), draw,
                     st.sampled_from(["NaN", "nan", "inf", "-inf", "Infinity", "+inf", "-nan"]), [0, 2, 3, 4, 5])


def huge_value(folder, draw):
    return _set_cell(_metabase_file(folder, draw), draw,
                     st.sampled_from(["1e300", "-1e300", "1.7e308", "1e309", "9" * 400, "1e-320", "99999999999999"]),
                     [0, 3, 4, 5])


_OTHER_UNITS = {"Accelerometer": ["mg", "m/s2", "m/s²", "deg/s", "T"], "Gyroscope": ["rad/s", "mdeg/s", "g"],
                "Magnetometer": ["mT", "µT", "uT", "nT", "G", "mG"]}
_FILE_UNIT = {"Accelerometer": "g", "Gyroscope": "deg/s", "Magnetometer": "T"}


def _stream_of(p: Path) -> str:
    return next(s for s in STREAMS if f"_{s}_" in p.name)


def declared_unit(folder, draw):
    """The header declares mg / mT / rad/s (and others) while the numbers stay in g, deg/s, T."""
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    s = _stream_of(p)
    _save(p, header.replace(f"({_FILE_UNIT[s]})", f"({draw(st.sampled_from(_OTHER_UNITS[s]))})"), rows)
    return (p,)


_CONVERT = {"Accelerometer": [("mg", 1e3), ("m/s2", 9.80665)], "Gyroscope": [("rad/s", 3.141592653589793 / 180)],
            "Magnetometer": [("mT", 1e3), ("uT", 1e6), ("nT", 1e9), ("G", 1e4)]}


def converted_unit(folder, draw):
    """A real export in another unit: header and numbers consistently in mg, rad/s, µT... (must load)."""
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    s = _stream_of(p)
    unit, factor = draw(st.sampled_from(_CONVERT[s]))
    out = []
    for r in rows:
        c = r.split(",")
        c[3:] = [f"{float(x) * factor:.9g}" if x else "" for x in c[3:]]
        out.append(",".join(c))
    _save(p, header.replace(f"({_FILE_UNIT[s]})", f"({unit})"), out)
    return (p,)


def duplicated_stamp(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows)
    rows.insert(i, rows[i] if draw(st.booleans()) else rows[i].split(",")[0] + "," + rows[i - 1].split(",", 1)[1])
    _save(p, header, rows)
    return (p,)


def non_monotonic_time(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows[1:]) + 1
    j = draw(st.integers(max(0, i - 20), i - 1))
    rows[i], rows[j] = rows[j], rows[i]
    _save(p, header, rows)
    return (p,)


def day_boundary(folder, draw):
    """From some row on, the epoch goes back one day (a clock that wrapped at midnight)."""
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows)
    back_ms = draw(st.sampled_from([86_400_000, 3_600_000, 1_000]))
    for k in range(i, len(rows)):
        c = rows[k].split(",", 1)
        rows[k] = f"{int(c[0]) - back_ms},{c[1]}"
    _save(p, header, rows)
    return (p,)


def rate_50hz(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    step = draw(st.sampled_from([2, 3, 4]))
    _save(p, header, rows[draw(st.integers(0, step - 1))::step])
    return (p,)


def single_row(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    n = draw(st.integers(1, 12))
    i = draw(st.integers(0, len(rows) - n))
    _save(p, header, rows[i:i + n])
    return (p,)


def gap_seconds(folder, draw):
    """A run of 0.1–4 s of rows missing (the radio dropped samples)."""
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    rate = 20 if "Magnetometer" in p.name else 100
    n = int(draw(st.floats(0.1, 4.0)) * rate)
    i = draw(st.integers(0, max(0, len(rows) - n)))
    _save(p, header, rows[:i] + rows[i + n:])
    return (p,)


def semicolon_decimal_comma(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    conv = lambda line: line.replace(",", ";").replace(".", ",")  # noqa: E731
    _save(p, header.replace(",", ";"), [conv(r) for r in rows])
    return (p,)


def decimal_comma(folder, draw):
    """Decimal comma with the comma still the separator (every row now has too many cells)."""
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows)
    rows[i:] = [r.split(",", 3)[0] + "," + ",".join(r.split(",", 3)[1:3]) + "," + r.split(",", 3)[3].replace(".", ",")
                for r in rows[i:]]
    _save(p, header, rows)
    return (p,)


def quoted_cells(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    quote_header = draw(st.booleans())
    q = lambda line: ",".join(f'"{c}"' for c in line.split(","))  # noqa: E731
    _save(p, q(header) if quote_header else header, [q(r) for r in rows])
    return (p,)


def whitespace_padding(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    pad = draw(st.sampled_from([" ", "  ", "\t"]))
    sp = lambda line: ",".join(f"{pad}{c}{pad}" for c in line.split(","))  # noqa: E731
    _save(p, sp(header), [sp(r) for r in rows])
    return (p,)


def very_long_line(folder, draw):
    p = _metabase_file(folder, draw)
    n = draw(st.sampled_from([2_000, 140_000, 400_000]))
    return _set_cell(p, draw, st.sampled_from(["1" * n, "x" * n, "1." + "0" * n, " " * n]))


def label_without_role(folder, draw):
    files = _recording_files(folder, draw)
    label = files[0].name.split("_MetaWear_")[0]
    role = label.split("-")[0]
    return _rename_label(files, label, label.replace(role, draw(st.sampled_from(["rec", "x", "prueba"])), 1))


def label_without_segment(folder, draw):
    files = _recording_files(folder, draw)
    label = files[0].name.split("_MetaWear_")[0]
    seg = next(w for w in ("muslo", "pierna") if w in label)
    return _rename_label(files, label, label.replace(seg, draw(st.sampled_from(["sensor", "rodilla", "a"]))))


def label_two_roles(folder, draw):
    files = _recording_files(folder, draw)
    label = files[0].name.split("_MetaWear_")[0]
    extra = draw(st.sampled_from(["standing", "step", "lying", "calibration"]))
    return _rename_label(files, label, f"{extra}-{label}")


def name_not_metabase(folder, draw):
    """One stream file renamed so it no longer follows the MetaBase pattern (rate, MAC or marker damaged).

    (Renaming it to another extension, ``.bak``, takes it out of the session by design: not fuzzed.)"""
    p = _metabase_file(folder, draw)
    how = draw(st.sampled_from([("_MetaWear_", "_"), ("Hz", ""), ("_1.5.1", " (1)")]))
    q = p.with_name(re.sub(r"_[0-9A-F]{12}_", "_XYZ_", p.name) if how == ("Hz", "") else p.name.replace(*how))
    p.rename(q)
    return (p, q)


def two_files_same_stream(folder, draw):
    p = _metabase_file(folder, draw)
    q = p.with_name(p.name.replace("_1.5.1.csv", draw(st.sampled_from(["_1.5.0.csv", "_1.6.0.csv", ".csv"]))))
    shutil.copy(p, q)
    return (p, q)


def upper_case_extension(folder, draw):
    """``.CSV`` / ``.Csv`` (copied through a FAT-formatted stick or Windows): the same file (must load)."""
    files = _recording_files(folder, draw)
    ext = draw(st.sampled_from([".CSV", ".Csv"]))
    out = []
    for p in files:
        q = p.with_name(p.stem + ext)
        p.rename(q)
        out.append(q)
    return tuple(out)


def nominal_rate_in_name(folder, draw):
    """The file name declares another nominal rate than the data has (only the stamps count: must load)."""
    p = _metabase_file(folder, draw)
    q = p.with_name(re.sub(r"_\d+\.\d+Hz_", f"_{draw(st.sampled_from(['50.000', '12.5', '800']))}Hz_", p.name))
    p.rename(q)
    return (q,)


# ----------------------------------------------------------------------------------------- session.json

def _manifest(folder: Path) -> Path:
    return folder / "session.json"


def manifest_invalid_json(folder, draw):
    p = _manifest(folder)
    text = p.read_text()
    at = draw(st.integers(0, len(text) - 1))
    edit = draw(st.sampled_from(["cut", "insert", "replace"]))
    junk = draw(st.sampled_from(["{", "}", ",", '"', "]", "x", "\\", "NaN,"]))
    text = {"cut": text[:at], "insert": text[:at] + junk + text[at:], "replace": text[:at] + junk + text[at + 1:]}[edit]
    p.write_text(text)
    return (p,)


JSON_VALUES = st.recursive(st.none() | st.booleans() | st.integers(-10**20, 10**20) | st.floats(allow_nan=True)
                           | st.text(max_size=8), lambda c: st.lists(c, max_size=3)
                           | st.dictionaries(st.text(max_size=5), c, max_size=3), max_leaves=6)


def manifest_wrong_types(folder, draw):
    p = _manifest(folder)
    data = json.loads(p.read_text())
    key = draw(st.sampled_from(["side", "step_height_m", "patient_id", "date", "sensors", "recordings", "name",
                                "weight_kg"]))
    data[key] = draw(JSON_VALUES)
    p.write_text(json.dumps(data))
    return (p,)


def manifest_not_an_object(folder, draw):
    p = _manifest(folder)
    p.write_text(json.dumps(draw(st.one_of(st.lists(JSON_VALUES, max_size=3), st.text(max_size=10), st.none(),
                                           st.integers(), st.floats()))))
    return (p,)


def _entries(folder: Path) -> list[dict]:
    stems = sorted({p.name.split("_Accelerometer_")[0] for p in folder.glob("*_Accelerometer_*.csv")})
    return [{"files": sorted(q.name for q in folder.glob(f"{s}_*.csv"))} for s in stems]


def manifest_unknown_words(folder, draw):
    p = _manifest(folder)
    entries = _entries(folder)
    i = draw(st.integers(0, len(entries) - 1))
    field = draw(st.sampled_from(["role", "segment"]))
    entries[i][field] = draw(st.sampled_from(["jumping", "elbow", "", "thighs", "TASK", "Muslo", "knee", "3"]))
    p.write_text(json.dumps({**json.loads(p.read_text()), "recordings": entries}))
    return (p,)


def manifest_paths_outside(folder, draw):
    p = _manifest(folder)
    entries = _entries(folder)
    i = draw(st.integers(0, len(entries) - 1))
    bad = draw(st.sampled_from(["../" + entries[i]["files"][0], "/etc/hostname", "sub/../../x.csv", "", ".",
                                "missing.csv", "session.json", str(folder / entries[i]["files"][0])]))
    entries[i]["files"][draw(st.integers(0, 2))] = bad
    p.write_text(json.dumps({**json.loads(p.read_text()), "recordings": entries}))
    return (p,)


def manifest_bad_entries(folder, draw):
    p = _manifest(folder)
    entries = _entries(folder)
    i = draw(st.integers(0, len(entries) - 1))
    how = draw(st.sampled_from(["no files", "files empty", "duplicate entry", "file twice", "sheet", "none"]))
    if how == "no files":
        del entries[i]["files"]
    elif how == "files empty":
        entries[i]["files"] = []
    elif how == "duplicate entry":
        entries.append(dict(entries[i]))
    elif how == "file twice":
        entries[i]["files"][1] = entries[i]["files"][0]
    elif how == "sheet":
        entries[i]["sheet"] = draw(st.sampled_from(["data", 3, None]))
    else:
        entries = []
    p.write_text(json.dumps({**json.loads(p.read_text()), "recordings": entries}))
    return (p,)


def manifest_not_utf8(folder, draw):
    p = _manifest(folder)
    text = p.read_text().replace("DEMO-001", "Pérez-Ñú")
    p.write_bytes(text.encode(draw(st.sampled_from(["latin-1", "utf-16", "cp1252"]))))
    return (p,)


# ------------------------------------------------------------------------------------------- thesis .xlsx

def _xlsx_file(folder: Path, draw: Draw) -> Path:
    return draw(st.sampled_from(sorted(folder.glob("*.xlsx"))))


def _edit_workbook(folder, draw, edit) -> tuple[Path, ...]:
    import openpyxl
    p = _xlsx_file(folder, draw)
    wb = openpyxl.load_workbook(p)
    edit(wb, wb.worksheets[0])
    wb.save(p)
    return (p,)


def xlsx_not_a_zip(folder, draw):
    p = _xlsx_file(folder, draw)
    p.write_bytes(draw(st.sampled_from([b"", b"PK\x03\x04", b"epoch (ms),x\n1,2\n"]) | st.binary(max_size=2000)))
    return (p,)


def xlsx_zip_not_workbook(folder, draw):
    p = _xlsx_file(folder, draw)
    buf = io.BytesIO()
    members = draw(st.lists(st.sampled_from(["[Content_Types].xml", "xl/workbook.xml", "word/document.xml",
                                             "mimetype", "data.csv"]), min_size=0, max_size=3, unique=True))
    with zipfile.ZipFile(buf, "w") as z:
        for m in members:
            z.writestr(m, draw(st.binary(max_size=200)))
    p.write_bytes(buf.getvalue())
    return (p,)


def xlsx_truncated(folder, draw):
    p = _xlsx_file(folder, draw)
    data = p.read_bytes()
    p.write_bytes(data[: draw(st.integers(0, len(data) - 1))])
    return (p,)


def xlsx_extra_sheets(folder, draw):
    def edit(wb, ws):
        what = draw(st.sampled_from(["empty", "notes", "copy"]))
        if what == "copy":
            extra = wb.copy_worksheet(ws)
        else:
            extra = wb.create_sheet(draw(st.sampled_from(["Hoja2", "notas", "Sheet 3"])))
            if what == "notes":
                extra.append(["fecha", "comentario"])
                extra.append(["13/03/2023", "ok"])
        wb.move_sheet(extra, offset=-draw(st.integers(0, len(wb.worksheets) - 1)))
    return _edit_workbook(folder, draw, edit)


def xlsx_empty_sheet(folder, draw):
    import openpyxl
    p = _xlsx_file(folder, draw)
    wb = openpyxl.Workbook()
    if draw(st.booleans()):
        wb.active.append([])
        wb.active.append([None, None])
    wb.save(p)
    return (p,)


def _data_cell(draw, ws):
    return draw(st.integers(2, ws.max_row)), draw(st.integers(1, 11))


def xlsx_text_cell(folder, draw):
    def edit(wb, ws):
        ws.cell(*_data_cell(draw, ws)).value = draw(CELL_TEXT)
    return _edit_workbook(folder, draw, edit)


def xlsx_odd_cell_types(folder, draw):
    """A bool, a date, a formula without a cached value or an error value in a numeric column."""
    def edit(wb, ws):
        ws.cell(*_data_cell(draw, ws)).value = draw(st.sampled_from(
            [True, False, dt.datetime(2023, 3, 13, 10, 0), dt.time(10, 0), "=1/0", "=A2+1", "#N/A", "#DIV/0!"]))
    return _edit_workbook(folder, draw, edit)


def xlsx_merged_cells(folder, draw):
    def edit(wb, ws):
        r, c = _data_cell(draw, ws)
        r0, c0 = draw(st.sampled_from([(1, 1), (r, c)]))
        ws.merge_cells(start_row=r0, start_column=c0, end_row=r0 + draw(st.integers(0, 50)),
                       end_column=min(13, c0 + draw(st.integers(0, 3))))
    return _edit_workbook(folder, draw, edit)


def xlsx_header_changed(folder, draw):
    def edit(wb, ws):
        ws.cell(1, draw(st.integers(1, 13))).value = draw(
            st.sampled_from(["", None, "x-axis", "x-axis (mg)", "elapsed (min)", "tiempo (s)", "y-axis (g)"]) | CELL_TEXT)
    return _edit_workbook(folder, draw, edit)


# --------------------------------------------------------------------------------------------- generic CSV

def _generic_file(folder: Path, draw: Draw) -> Path:
    return draw(st.sampled_from(sorted(folder.glob("*.csv"))))


def generic_header_unit(folder, draw):
    """One header cell loses its unit or declares an unknown/other one."""
    p = _generic_file(folder, draw)
    header, rows = _lines(p)
    cells = header.split(",")
    j = draw(st.integers(0, len(cells) - 1))
    name = cells[j].split(" (")[0]
    cells[j] = draw(st.sampled_from([name, f"{name} ()", f"{name} (furlong)", f"{name} (ms)", f"{name} (mg)",
                                     f"{name} (deg/s)", f"{name}_ms", f"{name} (epoch ms)"]))
    _save(p, ",".join(cells), rows)
    return (p,)


def generic_column_missing(folder, draw):
    p = _generic_file(folder, draw)
    header, rows = _lines(p)
    j = draw(st.integers(0, len(header.split(",")) - 1))
    drop = lambda line: ",".join(c for k, c in enumerate(line.split(",")) if k != j)  # noqa: E731
    _save(p, drop(header), [drop(r) for r in rows])
    return (p,)


def generic_stream_blank(folder, draw):
    """Every cell of one stream's columns (or of one axis) left empty from some row on."""
    p = _generic_file(folder, draw)
    header, rows = _lines(p)
    k = draw(st.integers(0, 2))
    cols = draw(st.sampled_from([range(4 * k, 4 * k + 4), range(4 * k + 1, 4 * k + 4), [4 * k + 2]]))
    i = draw(st.integers(0, len(rows) - 1))
    out = rows[:i]
    for r in rows[i:]:
        c = r.split(",")
        for j in cols:
            c[j] = ""
        out.append(",".join(c))
    _save(p, header, out)
    return (p,)


def generic_non_numeric(folder, draw):
    return _set_cell(_generic_file(folder, draw), draw, GARBAGE | st.sampled_from(["inf", "nan", "1e400"]))


# -------------------------------------------------------------------------------------------------- table

KINDS: dict[str, Kind] = {
    "empty": Kind("metabase", "an empty (0 byte / blank lines / BOM only) stream file", empty),
    "header_only": Kind("metabase", "the header line and no data rows", header_only),
    "other_stream_header": Kind("metabase", "the header of another stream of the same recording", other_stream_header),
    "truncated_mid_line": Kind("metabase", "the file cut at a random character of a random row", truncated_mid_line),
    "truncated_mid_number": Kind("metabase", "the file cut inside the last number of a random row",
                                 truncated_mid_number),
    "random_bytes": Kind("metabase", "the file replaced by random bytes", random_bytes),
    "spliced_garbage_bytes": Kind("metabase", "random bytes inserted at a random offset", spliced_garbage_bytes),
    "utf16": Kind("metabase", "the text re-encoded as UTF-16/UTF-32 (with or without BOM)", utf16),
    "utf8_bom": Kind("metabase", "a UTF-8 byte-order mark before the header", utf8_bom, must_load=True),
    "nul_bytes": Kind("metabase", "NUL bytes inserted at random offsets", nul_bytes),
    "line_endings": Kind("metabase", "CRLF, CR-only or mixed line endings", line_endings, must_load=True),
    "extra_columns": Kind("metabase", "an extra column (any name) inserted at a random position", extra_columns,
                          must_load=True),
    "stray_separator": Kind("metabase", "one extra ',' in a random row", stray_separator),
    "missing_column": Kind("metabase", "one column removed from header and rows", missing_column),
    "swapped_columns": Kind("metabase", "columns permuted (header and rows together)", swapped_columns,
                            must_load=True),
    "non_numeric_cell": Kind("metabase", "text in a random cell", non_numeric_cell),
    "nan_inf_cell": Kind("metabase", "NaN / inf spelt in a numeric cell", nan_inf_cell),
    "huge_value": Kind("metabase", "a huge, overflowing or subnormal number in a stamp or axis cell", huge_value),
    "declared_unit": Kind("metabase", "mg / mT / rad/s (etc.) declared while the numbers stay g, T, deg/s",
                          declared_unit),
    "converted_unit": Kind("metabase", "header and numbers consistently in mg, rad/s, µT, nT, G...", converted_unit,
                           must_load=True),
    "duplicated_stamp": Kind("metabase", "a row repeated, or a stamp repeated with other values", duplicated_stamp),
    "non_monotonic_time": Kind("metabase", "two rows up to 20 apart swapped", non_monotonic_time),
    "day_boundary": Kind("metabase", "the epoch jumps back a day / an hour / a second from a random row on",
                         day_boundary),
    "rate_50hz": Kind("metabase", "every 2nd/3rd/4th row kept (50, 33, 25 Hz)", rate_50hz),
    "single_row": Kind("metabase", "1 to 12 data rows only", single_row),
    "gap_seconds": Kind("metabase", "0.1–4 s of rows missing somewhere", gap_seconds),
    "semicolon_decimal_comma": Kind("metabase", "';' separator and ',' decimal (European Excel export)",
                                    semicolon_decimal_comma),
    "decimal_comma": Kind("metabase", "',' decimal with ',' still the separator, from a random row on",
                          decimal_comma),
    "quoted_cells": Kind("metabase", "every cell in double quotes", quoted_cells, must_load=True),
    "whitespace_padding": Kind("metabase", "spaces or tabs around every cell", whitespace_padding, must_load=True),
    "very_long_line": Kind("metabase", "one cell of 2 kB to 400 kB", very_long_line),
    "label_without_role": Kind("metabase", "a recording's label without its role word", label_without_role),
    "label_without_segment": Kind("metabase", "a recording's label without its segment word",
                                  label_without_segment),
    "label_two_roles": Kind("metabase", "a recording's label naming two roles", label_two_roles),
    "name_not_metabase": Kind("metabase", "one stream file renamed out of the MetaBase pattern", name_not_metabase),
    "two_files_same_stream": Kind("metabase", "a second file claiming the same stream of a recording",
                                  two_files_same_stream),
    "upper_case_extension": Kind("metabase", "a recording's files ending in .CSV or .Csv", upper_case_extension,
                                 must_load=True),
    "nominal_rate_in_name": Kind("metabase", "the file name declares another nominal rate", nominal_rate_in_name,
                                 must_load=True),
    "manifest_invalid_json": Kind("metabase", "session.json cut, or a stray character inserted/replaced",
                                  manifest_invalid_json),
    "manifest_wrong_types": Kind("metabase", "a session.json key given any JSON value", manifest_wrong_types),
    "manifest_not_an_object": Kind("metabase", "session.json a list, string, number or null",
                                   manifest_not_an_object),
    "manifest_unknown_words": Kind("metabase", "a recordings[] entry with an unknown role or segment",
                                   manifest_unknown_words),
    "manifest_paths_outside": Kind("metabase", "a recordings[] file outside the folder, absent or not a file",
                                   manifest_paths_outside),
    "manifest_bad_entries": Kind("metabase", "recordings[] entries without files, empty, doubled, with a sheet",
                                 manifest_bad_entries),
    "manifest_not_utf8": Kind("metabase", "session.json saved as Latin-1 / UTF-16", manifest_not_utf8),
    "xlsx_not_a_zip": Kind("xlsx", "a .xlsx that is empty, a CSV or random bytes", xlsx_not_a_zip),
    "xlsx_zip_not_workbook": Kind("xlsx", "a .xlsx that is a zip of other things", xlsx_zip_not_workbook),
    "xlsx_truncated": Kind("xlsx", "a .xlsx cut at a random byte", xlsx_truncated),
    "xlsx_extra_sheets": Kind("xlsx", "an extra empty / notes / duplicate sheet anywhere", xlsx_extra_sheets),
    "xlsx_empty_sheet": Kind("xlsx", "a workbook with only an empty sheet", xlsx_empty_sheet),
    "xlsx_text_cell": Kind("xlsx", "text in a numeric cell", xlsx_text_cell),
    "xlsx_odd_cell_types": Kind("xlsx", "a bool, date, formula or error value in a numeric cell",
                                xlsx_odd_cell_types),
    "xlsx_merged_cells": Kind("xlsx", "a range of cells merged (header or data)", xlsx_merged_cells),
    "xlsx_header_changed": Kind("xlsx", "a header cell emptied or renamed", xlsx_header_changed),
    "generic_header_unit": Kind("generic", "a generic CSV header cell without / with another unit",
                                generic_header_unit),
    "generic_column_missing": Kind("generic", "a generic CSV column removed", generic_column_missing),
    "generic_stream_blank": Kind("generic", "a generic CSV stream's cells blank from a random row on",
                                 generic_stream_blank),
    "generic_non_numeric": Kind("generic", "text, inf or nan in a generic CSV cell", generic_non_numeric),
}
