"""The kinds of malformed session files the ingestion fuzzer applies (``test_ingestion_fuzz.py``).

Each kind is one function ``mutate(folder, draw) -> files`` that damages (or harmlessly varies) exactly one
thing in a copy of a valid simulated session, using ``draw`` (a Hypothesis ``data.draw``) for everything
positional (which file, which row, which cell, what garbage), and returns the file(s) it touched: an error
must name one of them.  :data:`KINDS` is the table: name -> :class:`Kind` (format of the session it needs,
one-line description, the function, and ``must_load`` for variations a real export can have that ChakaMo
has to accept).

The MetaBase CSV kinds and the shared helpers are in :mod:`ingestion_fuzz_metabase`; the session.json, Excel
and generic CSV kinds are here.  Sizes are bounded (at most a few hundred kB of garbage) so that no example
can make a reader run long.  The generic CSV has per-stream time columns; the thesis workbooks have one
sheet ``data``.
"""

from __future__ import annotations

import datetime as dt
import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from hypothesis import strategies as st

from ingestion_fuzz_vendors import (excel_epoch, excel_epoch_semicolon, opal_dataset_dropped, opal_truncated,
                                    rows_copied_exactly, sensorlogger_cell_garbage, sensorlogger_member_dropped, sensorlogger_metadata, shimmer_sep_variants, shimmer_units_row, truncated_last_line,
                                    xsens_column_missing, xsens_layout_variants, xsens_mag_in_micro_tesla,
                                    xsens_text_cell)

from ingestion_fuzz_phyphox import (phyphox_cell_garbage, phyphox_device_meta, phyphox_flavour,
                                    phyphox_linear_acceleration, phyphox_sensor_dropped)
from ingestion_fuzz_metabase import (CELL_TEXT, GARBAGE, Draw, _drop_column, _lines, _save, _set_cell, converted_unit,
                                     day_boundary, decimal_comma, declared_unit, duplicated_stamp, empty,
                                     extra_columns, gap_seconds, header_only, huge_value, label_two_roles,
                                     label_without_role, label_without_segment, line_endings, missing_column,
                                     name_not_metabase, nan_inf_cell, nominal_rate_in_name, non_monotonic_time,
                                     non_numeric_cell, nul_bytes, other_stream_header, quoted_cells, random_bytes,
                                     rate_50hz, semicolon_decimal_comma, single_row, spliced_garbage_bytes,
                                     stray_separator, swapped_columns, truncated_mid_line, truncated_mid_number,
                                     two_files_same_stream, upper_case_extension, utf8_bom, utf16, very_long_line,
                                     whitespace_padding)


@dataclass(frozen=True)
class Kind:
    fmt: str                      # "metabase", "generic", "xlsx", "xsens", "shimmer", "opal", "sensorlogger", "phyphox"
    what: str                     # one line for the table
    mutate: Callable[[Path, Draw], tuple[Path, ...]]
    must_load: bool = False       # a harmless variation: the session has to load, and sanely


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


def manifest_split(folder, draw):
    """session.json "split" (the clinician's cuts of continuous recordings) given any JSON value, or cuts of
    random roles and seconds: refused as a malformed split, or loaded when well formed (no recording is continuous
    here, so well-formed cuts change nothing)."""
    p = _manifest(folder)
    data = json.loads(p.read_text())
    roles = st.sampled_from(["mag_calibration", "standing", "lying", "task", "sitting", ""])
    span = st.one_of(st.lists(st.one_of(st.floats(allow_nan=True), st.integers(-5, 500)), max_size=3), JSON_VALUES)
    data["split"] = draw(st.one_of(JSON_VALUES, st.dictionaries(st.sampled_from(["thigh", "shank", "knee"]),
                                                                st.dictionaries(roles, span, max_size=3), max_size=2)))
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
    return _drop_column(_generic_file(folder, draw), draw)


def generic_stream_blank(folder, draw):
    """Every cell of one stream's columns (or of one axis) left empty from some row on."""
    p = _generic_file(folder, draw)
    header, rows = _lines(p)
    k = draw(st.integers(0, 2))
    cols = draw(st.sampled_from([range(4 * k, 4 * k + 4), range(4 * k + 1, 4 * k + 4), [4 * k + 2]]))
    filled = [n for n, r in enumerate(rows) if any(r.split(",")[j] for j in cols)]  # a 20 Hz stream's rows are sparse
    i = filled[draw(st.integers(0, len(filled) - 1))]
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
                                    semicolon_decimal_comma, must_load=True),
    "excel_epoch": Kind("metabase", "epoch (ms) rounded by Excel (1.63552E+12) in some files of a recording",
                        excel_epoch, must_load=True),
    "excel_epoch_semicolon": Kind("metabase", "a recording saved by Excel in es/pt: ';', decimal commas, rounded "
                                  "epochs", excel_epoch_semicolon, must_load=True),
    "truncated_last_line": Kind("metabase", "the copy stopped inside the last line", truncated_last_line,
                                must_load=True),
    "rows_copied_exactly": Kind("metabase", "a block of rows pasted again anywhere", rows_copied_exactly,
                                must_load=True),
    "xsens_text_cell": Kind("xsens", "text in a cell of an MT Manager export", xsens_text_cell),
    "xsens_layout_variants": Kind("xsens", "',' or ';' for tabs, preamble dropped, CRLF", xsens_layout_variants,
                                  must_load=True),
    "xsens_column_missing": Kind("xsens", "an Acc/Gyr/Mag column removed", xsens_column_missing),
    "xsens_mag_in_micro_tesla": Kind("xsens", "µT numbers under the normalised magnetometer columns",
                                     xsens_mag_in_micro_tesla),
    "shimmer_units_row": Kind("shimmer", "a unit of the Consensys units row emptied or changed", shimmer_units_row),
    "shimmer_sep_variants": Kind("shimmer", "no 'sep=' line, or commas with 'sep=,'", shimmer_sep_variants,
                                 must_load=True),
    "opal_dataset_dropped": Kind("opal", "a sensor's dataset deleted from an APDM .h5", opal_dataset_dropped),
    "opal_truncated": Kind("opal", "an APDM .h5 cut at a random byte", opal_truncated),
    "sensorlogger_cell_garbage": Kind("sensorlogger", "text in a cell of a Sensor Logger zip's sensor file",
                                      sensorlogger_cell_garbage),
    "sensorlogger_member_dropped": Kind("sensorlogger", "a sensor file missing from a Sensor Logger zip",
                                        sensorlogger_member_dropped),
    "phyphox_cell_garbage": Kind("phyphox", "text in a data cell of a phyphox export's table", phyphox_cell_garbage),
    "phyphox_linear_acceleration": Kind("phyphox", "acceleration exported without gravity (Linear Acceleration)",
                                        phyphox_linear_acceleration),
    "phyphox_sensor_dropped": Kind("phyphox", "a sensor's set or columns missing from a phyphox zip",
                                   phyphox_sensor_dropped),
    "phyphox_device_meta": Kind("phyphox", "meta/device.csv removed, emptied or garbage (the phone's id is optional)",
                                phyphox_device_meta, must_load=True),
    "sensorlogger_metadata": Kind("sensorlogger", "Metadata.csv removed, emptied, header only or garbage",
                                  sensorlogger_metadata, must_load=True),
    "manifest_split": Kind("metabase", "session.json \"split\" given any value or random cuts", manifest_split),
    "phyphox_flavour": Kind("phyphox", "another of phyphox's CSV flavours (',', tab, ';'; '.' or ',' decimals)",
                            phyphox_flavour, must_load=True),
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
