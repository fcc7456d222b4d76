"""MetaBase CSV kinds of the ingestion fuzzer, and the helpers every kind uses (see ``ingestion_fuzz_kinds``).

Each function ``mutate(folder, draw) -> files`` damages one stream file of a copy of the simulated session;
files are ``epoc (ms),timestamp (+0000),elapsed (s),x-axis (g),y-axis (g),z-axis (g)`` (the demo's dialect).
"""

from __future__ import annotations

import re
import shutil
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
    pattern = draw(st.lists(st.sampled_from(["\r\n", "\r", "\n"]), min_size=1, max_size=4)
                   .filter(lambda p: set(p) != {"\n"}))  # all-LF is the file as written: no change
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


def _drop_column(p: Path, draw: Draw) -> tuple[Path]:
    """One column of CSV ``p`` (any of its header's) removed from every line."""
    header, rows = _lines(p)
    j = draw(st.integers(0, len(header.split(",")) - 1))
    drop = lambda line: ",".join(c for k, c in enumerate(line.split(",")) if k != j)  # noqa: E731
    _save(p, drop(header), [drop(r) for r in rows])
    return (p,)


def missing_column(folder, draw):
    return _drop_column(_metabase_file(folder, draw), draw)


def swapped_columns(folder, draw):
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    order = draw(st.permutations(range(6)).filter(lambda o: list(o) != list(range(6))))  # not the identity
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
