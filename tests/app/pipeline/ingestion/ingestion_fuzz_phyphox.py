"""Fuzz kinds of the phyphox exports (issue 14): the session written by :func:`write_phyphox_session` from the same
simulation as the other formats — the thigh's recordings as the three-set zip (',' and '.'), the shank's as the
one-set zip with NaN padding (';' and decimal commas), both with ``meta/time.csv`` (the phone's clock)."""

from __future__ import annotations

import zipfile
from pathlib import Path

from hypothesis import strategies as st

from ingestion_fuzz_metabase import GARBAGE

SEGMENT_WORDS = {"thigh": "muslo", "shank": "pierna"}
ROLE_WORDS = {"mag_calibration": "calibracion-sensor", "standing": "standing", "lying": "laydown", "task": "step"}


def write_phyphox_session(folder: Path, recordings) -> Path:
    """``recordings`` ``{(segment, role): {kind: (t_s epoch, values)}}`` as phyphox zip exports."""
    from app.pipeline.ingestion.phyphox import write_phyphox
    folder.mkdir(parents=True, exist_ok=True)
    for (segment, role), streams in recordings.items():
        t0 = min(t[0] for t, _ in streams.values())
        rel = {k: (t - t0, v) for k, (t, v) in streams.items()}
        name = f"{ROLE_WORDS[role]}-{SEGMENT_WORDS[segment]}-ML1-13032023-1.zip"
        if segment == "thigh":
            write_phyphox(folder / name, rel, layout="zip", epoch0_s=t0)
        else:
            write_phyphox(folder / name, rel, layout="zip-one-set", separator=";", decimal=",", epoch0_s=t0)
    return folder


def _zip(folder: Path, draw) -> tuple[Path, dict[str, str]]:
    p = draw(st.sampled_from(sorted(folder.glob("*.zip"))))
    with zipfile.ZipFile(p) as z:
        return p, {n: z.read(n).decode("utf-8") for n in z.namelist()}


def _rezip(p: Path, files: dict[str, str]) -> None:
    with zipfile.ZipFile(p, "w", zipfile.ZIP_DEFLATED) as z:
        for n, text in files.items():
            z.writestr(n, text)


def _tables(files: dict[str, str]) -> list[str]:
    return sorted(n for n in files if not n.startswith("meta/"))


def phyphox_cell_garbage(folder, draw):
    """Text in a data cell of one of a zip's tables."""
    p, files = _zip(folder, draw)
    member = draw(st.sampled_from(_tables(files)))
    lines = files[member].splitlines()
    sep = ";" if ";" in lines[0] else ","
    i = draw(st.integers(1, len(lines) - 1))
    cells = lines[i].split(sep)
    cells[draw(st.integers(0, len(cells) - 1))] = draw(GARBAGE.filter(lambda s: s.strip().lower() not in
                                                                      ("nan", "inf", "-inf", "+inf", "")))
    lines[i] = sep.join(cells)
    files[member] = "\n".join(lines) + "\n"
    _rezip(p, files)
    return (p,)


def phyphox_linear_acceleration(folder, draw):
    """The acceleration exported without gravity ("Linear Acceleration x (m/s^2)")."""
    p, files = _zip(folder, draw)
    for n in _tables(files):
        head, rest = files[n].split("\n", 1)
        files[n] = head.replace('"Acceleration ', '"Linear Acceleration ') + "\n" + rest
    _rezip(p, files)
    return (p,)


def phyphox_sensor_dropped(folder, draw):
    """A sensor's columns (or its set) missing from a zip."""
    p, files = _zip(folder, draw)
    tables = _tables(files)
    if len(tables) > 1:
        del files[draw(st.sampled_from(tables))]
    else:
        (n,) = tables
        lines = files[n].splitlines()
        sep = ";" if ";" in lines[0] else ","
        start = 5 * draw(st.integers(0, 2))  # each sensor: Time, x, y, z, Absolute
        files[n] = "\n".join(sep.join(c for j, c in enumerate(ln.split(sep)) if not start <= j < start + 5)
                             for ln in lines) + "\n"
    _rezip(p, files)
    return (p,)


def phyphox_flavour(folder, draw):
    """One zip re-exported in another of phyphox's CSV flavours (separator and decimal mark)."""
    p, files = _zip(folder, draw)
    first = files[_tables(files)[0]].split("\n", 1)[0]
    written = (";", ",") if ";" in first else (",", ".")  # the flavour the session was written in: never the draw
    sep, dec = draw(st.sampled_from([f for f in [(",", "."), ("\t", "."), (";", ","), ("\t", ",")] if f != written]))
    for n in files:
        lines = files[n].splitlines()
        old = ";" if ";" in lines[0] else ","
        out = []
        for ln in lines:
            cells = ln.split(old)
            if old == ";":
                cells = [c.replace(",", ".") for c in cells]
            out.append(sep.join(c if c.startswith('"') else c.replace(".", dec) for c in cells))
        files[n] = "\n".join(out) + "\n"
    _rezip(p, files)
    return (p,)


def phyphox_device_meta(folder, draw):
    """``meta/device.csv`` removed, emptied, or given garbage / a unique-id row of garbage (it names the phone; the
    recording must load whatever it holds)."""
    p, files = _zip(folder, draw)
    how = draw(st.sampled_from(["drop", "empty", "garbage", "unique_id"]))
    if how == "drop":
        files.pop("meta/device.csv", None)
    elif how == "empty":
        files["meta/device.csv"] = ""
    elif how == "garbage":
        files["meta/device.csv"] = draw(GARBAGE)
    else:
        files["meta/device.csv"] = '"property","value"\n"uniqueID","' + draw(GARBAGE).replace('"', "") + '"\n'
    _rezip(p, files)
    return (p,)
