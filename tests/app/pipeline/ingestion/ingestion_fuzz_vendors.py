"""Fuzz kinds of issue 14: spreadsheet mangling of MetaBase files (rounded epochs, ';' and decimal commas, a
cut last line, rows copied), and the Xsens, Shimmer and APDM formats (sessions written by
:func:`write_vendor_session` from the same simulation as the others)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from ingestion_fuzz_metabase import GARBAGE, Draw, _lines, _metabase_file, _recording_files, _row, _save

SEGMENT_WORDS = {"thigh": "muslo", "shank": "pierna"}
ROLE_WORDS = {"mag_calibration": "calibracion-sensor", "standing": "standing", "lying": "laydown", "task": "step"}


def on_acc_grid(streams):
    """acc's stamps; gyr interpolated on them; mag on the nearest row (NaN elsewhere, or interpolated)."""
    t, acc = streams["acc"]
    tg, gyr = streams["gyr"]
    gyr = np.stack([np.interp(t, tg, gyr[:, i]) for i in range(3)], axis=1)
    tm, mag = streams["mag"]
    m = np.full((len(t), 3), np.nan)
    m[np.clip(np.searchsorted(t, tm), 0, len(t) - 1)] = mag
    filled = np.stack([np.interp(t, tm, mag[:, i]) for i in range(3)], axis=1)
    return t, acc, gyr, m, filled


def write_vendor_session(folder: Path, recordings, fmt: str) -> Path:
    """``recordings`` ``{(segment, role): {kind: (t_s epoch, values)}}`` as Xsens, Shimmer or APDM files."""
    from app.pipeline.ingestion.opal import write_opal
    from app.pipeline.ingestion.shimmer import write_shimmer
    from app.pipeline.ingestion.xsens import write_xsens
    folder.mkdir(parents=True, exist_ok=True)
    opal: dict[str, dict] = {}
    for (segment, role), streams in recordings.items():
        t, acc, gyr, mag, filled = on_acc_grid(streams)
        name = f"{ROLE_WORDS[role]}-{SEGMENT_WORDS[segment]}-ML1-13032023-1"
        if fmt == "xsens":
            field = np.nanmedian(np.linalg.norm(mag, axis=1))
            write_xsens(folder / f"{name}.txt", t - t[0], acc, gyr, mag / field,
                        device_id={"thigh": "00B42D4F", "shank": "00B42D50"}[segment])
        elif fmt == "sensorlogger":
            from app.pipeline.ingestion.sensorlogger import write_sensorlogger
            write_sensorlogger(folder / f"{name}.zip", streams, platform="android", total=segment == "thigh")
        elif fmt == "shimmer":
            write_shimmer(folder / f"{name}.csv", t * 1e3, acc, gyr, filled,
                          device={"thigh": "Shimmer_8A21", "shank": "Shimmer_8A22"}[segment])
        else:
            opal.setdefault(ROLE_WORDS[role], {})[f"XI-00123{'45'[segment == 'shank']}"] = {
                "label": f"Right {segment.capitalize()}", "rate_hz": 100.0, "t_s": t, "acc": acc, "gyr": gyr,
                "mag": filled}
    for role, sensors in opal.items():
        write_opal(folder / f"{role}-ML1-13032023-1.h5", sensors)
    return folder


# ------------------------------------------------------------------------------------------ mangling

def _excel_epoch_line(line: str, semicolon: bool) -> str:
    ms, rest = line.split(",", 1)
    out = f"{float(ms):.5E}".replace("E+0", "E+") + "," + rest
    return out.replace(",", ";").replace(".", ",") if semicolon else out


def excel_epoch(folder, draw):
    """Some files of one recording opened and saved in Excel: 'epoch (ms)' printed as 1.63552E+12."""
    files = _recording_files(folder, draw)
    chosen = [p for p in files if draw(st.booleans())] or [files[0]]
    for p in chosen:
        header, rows = _lines(p)
        _save(p, header, [_excel_epoch_line(r, False) for r in rows])
    return tuple(chosen)


def excel_epoch_semicolon(folder, draw):
    """One recording saved by Excel in Spanish: ';' separators, decimal commas, rounded epochs."""
    files = _recording_files(folder, draw)
    for p in files:
        header, rows = _lines(p)
        _save(p, header.replace(",", ";"), [_excel_epoch_line(r, True) for r in rows])
    return tuple(files)


def truncated_last_line(folder, draw):
    """The copy stopped inside the last line (no line break at the end)."""
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    cut = draw(st.integers(1, len(rows[-1]) - 1))
    p.write_bytes(("\n".join([header, *rows[:-1], rows[-1][:cut]])).encode())
    return (p,)


def rows_copied_exactly(folder, draw):
    """A block of 1–20 rows pasted again somewhere (every cell equal)."""
    p = _metabase_file(folder, draw)
    header, rows = _lines(p)
    i = _row(draw, rows)
    block = rows[i:i + draw(st.integers(1, 20))]
    j = draw(st.integers(0, len(rows)))
    _save(p, header, rows[:j] + block + rows[j:])
    return (p,)


# ---------------------------------------------------------------------------------------------- vendors

def _one(folder: Path, draw: Draw, pattern: str) -> Path:
    return draw(st.sampled_from(sorted(folder.glob(pattern))))


def _table_lines(p: Path) -> tuple[list[str], int]:
    """Lines of a text export and the index of its column-name line (after '//' or sep= lines)."""
    lines = p.read_text(encoding="utf-8").splitlines()
    k = 0
    while lines[k].startswith("//") or lines[k].startswith('"sep='):
        k += 1
    return lines, k


def xsens_text_cell(folder, draw):
    p = _one(folder, draw, "*.txt")
    lines, k = _table_lines(p)
    i = draw(st.integers(k + 1, len(lines) - 1))
    cells = lines[i].split("\t")
    cells[draw(st.integers(2, len(cells) - 1))] = draw(GARBAGE.filter(lambda s: "\t" not in s and s.strip()))
    lines[i] = "\t".join(cells)
    p.write_text("\n".join(lines) + "\n")
    return (p,)


def xsens_layout_variants(folder, draw):
    """Comma or ';' instead of tabs, the '//' preamble dropped or kept, CRLF: every MT Manager option."""
    p = _one(folder, draw, "*.txt")
    lines, k = _table_lines(p)
    sep = draw(st.sampled_from(["\t", ",", ";"]))
    body = [ln.replace("\t", sep) for ln in lines[k:]]
    pre = lines[:k] if draw(st.booleans()) else []
    p.write_bytes(("\r\n" if draw(st.booleans()) else "\n").join(pre + body).encode() + b"\n")
    return (p,)


def xsens_column_missing(folder, draw):
    p = _one(folder, draw, "*.txt")
    lines, k = _table_lines(p)
    names = lines[k].split("\t")
    j = draw(st.sampled_from([i for i, n in enumerate(names) if n[:4] in ("Acc_", "Gyr_", "Mag_")]))
    p.write_text("\n".join(lines[:k] + ["\t".join(c for i, c in enumerate(ln.split("\t")) if i != j)
                                        for ln in lines[k:]]) + "\n")
    return (p,)


def xsens_mag_in_micro_tesla(folder, draw):
    """The magnetometer written in µT under Xsens' normalised columns (×20 to ×60)."""
    p = _one(folder, draw, "*.txt")
    lines, k = _table_lines(p)
    f = draw(st.floats(20.0, 60.0))
    out = lines[:k + 1]
    for ln in lines[k + 1:]:
        c = ln.split("\t")
        c[-3:] = [x if x == "NaN" else f"{float(x) * f:.4f}" for x in c[-3:]]
        out.append("\t".join(c))
    p.write_text("\n".join(out) + "\n")
    return (p,)


def shimmer_units_row(folder, draw):
    p = _one(folder, draw, "*.csv")
    lines, k = _table_lines(p)
    cells = lines[k + 2].split("\t")
    cells[draw(st.integers(0, len(cells) - 1))] = draw(st.sampled_from(["", "mg", "rpm", "counts", "furlong"]))
    lines[k + 2] = "\t".join(cells)
    p.write_text("\n".join(lines) + "\n")
    return (p,)


def shimmer_sep_variants(folder, draw):
    """The 'sep=' line dropped, or tabs turned into commas with a matching 'sep=,' line."""
    p = _one(folder, draw, "*.csv")
    lines, k = _table_lines(p)
    if draw(st.booleans()):
        lines = lines[k:]
    else:
        lines = ['"sep=,"'] + [ln.replace("\t", ",") for ln in lines[k:]]
    p.write_text("\n".join(lines) + "\n")
    return (p,)


def opal_dataset_dropped(folder, draw):
    import h5py
    p = _one(folder, draw, "*.h5")
    with h5py.File(p, "a") as f:
        sid = draw(st.sampled_from(sorted(f["Sensors"])))
        del f["Sensors"][sid][draw(st.sampled_from(["Accelerometer", "Gyroscope", "Magnetometer", "Time"]))]
    return (p,)


def opal_truncated(folder, draw):
    p = _one(folder, draw, "*.h5")
    data = p.read_bytes()
    p.write_bytes(data[: draw(st.integers(0, len(data) - 1))])
    return (p,)


def sensorlogger_cell_garbage(folder, draw):
    """Text in a cell of one sensor file inside a Sensor Logger zip."""
    import zipfile
    p = _one(folder, draw, "*.zip")
    with zipfile.ZipFile(p) as z:
        files = {n: z.read(n).decode() for n in z.namelist()}
    member = draw(st.sampled_from(sorted(n for n in files if n != "Metadata.csv")))
    lines = files[member].splitlines()
    i = draw(st.integers(1, len(lines) - 1))
    cells = lines[i].split(",")
    cells[draw(st.integers(0, len(cells) - 1))] = draw(GARBAGE)
    lines[i] = ",".join(cells)
    files[member] = "\n".join(lines) + "\n"
    with zipfile.ZipFile(p, "w") as z:
        for n, text in files.items():
            z.writestr(n, text)
    return (p,)


def sensorlogger_member_dropped(folder, draw):
    import zipfile
    p = _one(folder, draw, "*.zip")
    with zipfile.ZipFile(p) as z:
        files = {n: z.read(n) for n in z.namelist()}
    gone = draw(st.sampled_from(sorted(n for n in files if n != "Metadata.csv")))
    with zipfile.ZipFile(p, "w") as z:
        for n, data in files.items():
            if n != gone:
                z.writestr(n, data)
    return (p,)


def sensorlogger_metadata(folder, draw):
    """Metadata.csv removed, emptied, cut after its header, or given garbage (device id, name and platform are
    optional: the recording must load)."""
    import zipfile
    p = _one(folder, draw, "*.zip")
    with zipfile.ZipFile(p) as z:
        files = {n: z.read(n).decode() for n in z.namelist()}
    how = draw(st.sampled_from(["drop", "empty", "header_only", "garbage", "garbage_id"]))
    if how == "drop":
        files.pop("Metadata.csv", None)
    elif how == "empty":
        files["Metadata.csv"] = ""
    elif how == "header_only":
        files["Metadata.csv"] = files.get("Metadata.csv", "version\n").splitlines()[0] + "\n"
    elif how == "garbage":
        files["Metadata.csv"] = draw(GARBAGE)
    else:
        files["Metadata.csv"] = "version,device id,platform\n3," + draw(GARBAGE).replace("\n", " ") + ",android\n"
    with zipfile.ZipFile(p, "w") as z:
        for n, text in files.items():
            z.writestr(n, text)
    return (p,)
