"""Every bad input of issue 3 gives one IngestionError naming the file and saying what to do."""

import json
import re
import shutil

import numpy as np
import pytest

from app.pipeline.ingestion import IngestionError, load_session, read_metabase_csv, read_thesis_xlsx, write_metabase_csv
from app.pipeline.ingestion.excel import HEADER, _openpyxl
from app.pipeline.ingestion.metabase import parse_file_name


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory, sim_session):
    from app.pipeline.ingestion import write_session_metabase
    d = tmp_path_factory.mktemp("session")
    write_session_metabase(d, sim_session[0], patient_id="ML1")
    return d


def _file(folder, label_start, stream):
    (p,) = folder.glob(f"{label_start}*_{stream}_*.csv")
    return p


def _rewrite(path, scale=1.0, step=1):
    """Rewrite a MetaBase file with its values scaled (in project units) and every ``step``-th row kept."""
    s = read_metabase_csv(path)
    write_metabase_csv(path, s.kind, np.round(s.t_s[::step] * 1e3).astype(np.int64), s.values[::step] * scale)


def _error(folder, **kw) -> str:
    with pytest.raises(IngestionError) as exc:
        load_session(folder, **kw)
    return str(exc.value)


def test_good_session_loads_and_ignores_stray_files(folder):
    (folder / "notes.csv").write_text("fecha,comentario\n13/03/2023,ok\n")
    (folder / "results.json").write_text("{}")
    p = _file(folder, "step-muslo", "Accelerometer")
    (folder / p.name.replace("Accelerometer", "Temperature")).write_text("epoch (ms),time,elapsed (s),temp (C)\n")
    s = load_session(folder)
    assert len(s.recordings) == 8 and any("ignored notes.csv" in n for n in s.notes)


def test_missing_recording(folder):
    for p in folder.glob("standing-pierna*"):
        p.unlink()
    msg = _error(folder)
    assert "missing recording(s): standing of the shank" in msg and str(folder) in msg and "Name files like" in msg


def test_only_one_sensor(folder):
    for p in folder.glob("*-pierna-*"):
        p.unlink()
    msg = _error(folder)
    assert "only the thigh sensor found" in msg and "shank" in msg


def test_missing_stream_file(folder):
    _file(folder, "laydown-muslo", "Magnetometer").unlink()
    msg = _error(folder)
    assert "laydown-muslo" in msg and "no Magnetometer file" in msg


@pytest.mark.parametrize("stream,scale,unit", [("Accelerometer", 1000.0, "mg"), ("Magnetometer", 1000.0, "mT"),
                                               ("Magnetometer", 1e6, "µT")])
def test_wrong_units_by_magnitude(folder, stream, scale, unit):
    p = _file(folder, "standing-muslo", stream)
    _rewrite(p, scale)
    msg = _error(folder)
    assert p.name in msg and f"look like {unit}" in msg and "column header" in msg


def test_a_weak_static_field_loads_and_a_unit_mistake_is_still_refused(folder):
    """A posture held where the hard iron nearly cancels the earth's field reads a few µT (simulated MetaMotion
    errors: 4.1 and 4.3 µT): it loads; a factor-100 unit mistake (~0.5 µT) is still refused."""
    from app.pipeline.ingestion import load_session

    p = _file(folder, "standing-muslo", "Magnetometer")
    original = p.read_text()
    _rewrite(p, 0.08)  # ~4 µT
    load_session(folder)
    p.write_text(original)
    _rewrite(p, 0.01)  # ~0.5 µT: gauss read as µT
    msg = _error(folder)
    assert p.name in msg and "magnetometer's typical field" in msg


def test_rad_per_s_declared_as_deg_per_s(folder):
    p = _file(folder, "calibracion-sensor-muslo", "Gyroscope")   # figure-eight: plenty of rotation
    _rewrite(p, np.pi / 180.0)                                    # file now holds rad/s numbers under (deg/s)
    msg = _error(folder)
    assert p.name in msg and "look like rad/s" in msg


def test_deg_per_s_declared_as_rad_per_s(folder):
    p = _file(folder, "calibracion-sensor-pierna", "Gyroscope")
    p.write_text(p.read_text().replace("(deg/s)", "(rad/s)"))
    msg = _error(folder)
    assert p.name in msg and "look like deg/s" in msg


def test_unknown_unit(folder):
    p = _file(folder, "step-muslo", "Accelerometer")
    p.write_text(p.read_text().replace("(g)", "(furlong)"))
    msg = _error(folder)
    assert p.name in msg and "(furlong)" in msg


@pytest.mark.parametrize("damage,expect", [
    ("empty", "the file is empty"),
    ("header_only", "header but no data rows"),
    ("cut_mid_file", "cells but the header has"),
    ("text_cell", "is not a number"),
    ("stamp_repeats", "repeats at"),
    ("backwards", "goes back in time"),
    ("short", "too short"),
])
def test_damaged_files(folder, damage, expect):
    p = _file(folder, "step-pierna", "Gyroscope")
    lines = p.read_text().splitlines()
    if damage == "empty":
        lines = []
    elif damage == "header_only":
        lines = lines[:1]
    elif damage == "cut_mid_file":
        lines[70] = lines[70][: lines[70].index(",", 30)]
    elif damage == "text_cell":
        cells = lines[40].split(",")
        cells[4] = "0,12".replace(",", ";")
        lines[40] = ",".join(cells)
    elif damage == "stamp_repeats":        # one stamp twice with other values: not a copy, cannot be dropped
        cells = lines[50].split(",")
        cells[4] = "12.345"
        lines.insert(51, ",".join(cells))
    elif damage == "backwards":
        lines[60], lines[61] = lines[61], lines[60]
    elif damage == "short":
        lines = lines[:6]
    p.write_text("\n".join(lines) + ("\n" if lines else ""))
    msg = _error(folder)
    assert p.name in msg and expect in msg
    if damage in ("text_cell", "stamp_repeats", "backwards"):
        assert " row" in msg                                  # says where
    if damage in ("stamp_repeats", "backwards"):              # seconds from the start and the wall clock, no 1.6e+09
        assert re.search(r"at \d+\.\d{3} s \(20\d\d-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3} UTC\)", msg), msg
        assert "e+09" not in msg


@pytest.mark.parametrize("damage,variant", [
    ("truncated", "truncated_last_row"),
    ("duplicate", "duplicate_rows"),
    ("semicolons", "csv_semicolon"),
    ("semicolons_decimal_comma", "csv_semicolon"),
])
def test_repairable_damage_loads_with_a_note(folder, damage, variant):
    """A cut last line, rows copied exactly, Excel's es/pt CSV (';' and decimal commas): dropped or read, noted."""
    p = _file(folder, "step-pierna", "Gyroscope")
    lines = p.read_text().splitlines()
    n_rows = len(lines) - 1
    before = read_metabase_csv(p)
    if damage == "truncated":
        lines[-1] = lines[-1][: lines[-1].index(",", 30)]
    elif damage == "duplicate":
        lines[50:50] = lines[50:53]
    elif damage == "semicolons":
        lines = [ln.replace(",", ";") for ln in lines]
    else:
        lines = [ln.replace(",", ";").replace(".", ",") for ln in lines]
    p.write_text("\n".join(lines) + ("" if damage == "truncated" else "\n"))
    session = load_session(folder)
    notes = [n for n in session.notes if getattr(n, "params", {}).get("variant") == variant]
    assert len(notes) == 1 and p.name in notes[0] and notes[0].params["segment"] == "shank", session.notes
    gyr = session.raw[("shank", "task")].gyr
    assert len(gyr.t_s) == {"truncated": n_rows - 1}.get(damage, n_rows)
    assert np.all(np.diff(gyr.t_s) > 0) and np.isfinite(gyr.values).all()
    k = len(gyr.t_s)                               # the numbers are those before the damage
    np.testing.assert_array_equal(gyr.values, before.values[:k])
    np.testing.assert_array_equal(gyr.t_s, before.t_s[:k])


def test_50_hz_data_refused_with_advice_and_accepted_on_request(folder):
    for stream in ("Accelerometer", "Gyroscope"):
        _rewrite(_file(folder, "step-muslo", stream), step=2)
    msg = _error(folder)
    assert "step-muslo" in msg and "50.0 Hz, expected 100 Hz" in msg and "--any-rate" in msg
    s = load_session(folder, expected_fs_hz=None)
    assert s.recording("thigh", "task").fs_hz == 50.0 and s.recording("shank", "task").fs_hz == 100.0
    thigh, shank = s.task_pair()
    assert thigh.fs_hz == shank.fs_hz == 50.0 and np.array_equal(thigh.t_s, shank.t_s)


def test_two_recordings_for_one_role(folder):
    for p in list(folder.glob("step-muslo*")):
        shutil.copy(p, p.with_name(p.name.replace("step-muslo-ML1-13032023-1", "step-muslo-ML1-13032023-2")))
    msg = _error(folder)
    assert "are both the task recording of the thigh" in msg and "keep one" in msg


def test_manifest_errors(folder):
    (folder / "session.json").write_text("{\"side\": \"right\",}")
    assert "session.json: not valid JSON (line 1" in _error(folder)
    (folder / "session.json").write_text(json.dumps({"sides": "right"}))
    assert "unknown keys ['sides']" in _error(folder)
    (folder / "session.json").write_text(json.dumps({"side": "up"}))
    assert "side = 'up'" in _error(folder)


def _workbook(path, sheets):
    wb = _openpyxl().Workbook()
    wb.remove(wb.active)
    for name, good in sheets:
        ws = wb.create_sheet(name)
        ws.append(HEADER if good else ["fecha", "notas"])
        for k in range(200):
            ws.append([k / 100, 0.0, 0.0, 1.0, 0.1, 0.2, 0.3] + ([k / 20, 2e-5, 1e-5, -4e-5] if k < 40 else []))
    wb.save(path)


def test_excel_sheets(tmp_path):
    _workbook(tmp_path / "one.xlsx", [("notas", False), ("datos", True)])
    *_, note = read_thesis_xlsx(tmp_path / "one.xlsx")
    assert note == "sheet 'datos' of ['notas', 'datos']"
    _workbook(tmp_path / "two.xlsx", [("a", True), ("b", True)])
    with pytest.raises(IngestionError, match=r"two.xlsx: several sheets \(a, b\) have the thesis layout.*session.json"):
        read_thesis_xlsx(tmp_path / "two.xlsx")
    _workbook(tmp_path / "none.xlsx", [("a", False)])
    with pytest.raises(IngestionError, match=r"none.xlsx: none of its sheets has the thesis layout.*cell A1"):
        read_thesis_xlsx(tmp_path / "none.xlsx")
    (tmp_path / "bad.xlsx").write_bytes(b"not a zip")
    with pytest.raises(IngestionError, match="bad.xlsx: cannot be opened as an Excel workbook"):
        read_thesis_xlsx(tmp_path / "bad.xlsx")


def test_swapped_segments_are_not_judged_here(folder):
    """Files alone cannot show a thigh sensor labelled shank: ingestion accepts it (the pipeline checks signals)."""
    for p in list(folder.glob("*-muslo-*")) + list(folder.glob("*-pierna-*")):
        n = parse_file_name(p)
        swapped = n["label"].replace("muslo", "TMP").replace("pierna", "muslo").replace("TMP", "pierna")
        p.rename(p.with_name(p.name.replace(n["label"], swapped)))
    assert len(load_session(folder).recordings) == 8


def test_gyro_unit_check_ratio(sim_session):
    """θ_acc/θ_gyr ≈ 0.2–1.5 with the right unit, ×57 or ÷57 with the wrong one (units module docstring)."""
    from pathlib import Path

    from app.pipeline.ingestion import Stream
    from app.pipeline.ingestion.units import gyro_scale_ratio
    st = sim_session[0][("thigh", "mag_calibration")]
    acc = Stream("acc", *st["acc"], "g", Path("a.csv"))
    ratio = {}
    for name, f in (("right", 1.0), ("rad_as_deg", np.pi / 180), ("deg_as_rad", 180 / np.pi)):
        ratio[name] = gyro_scale_ratio(acc, Stream("gyr", st["gyr"][0], st["gyr"][1] * f, "deg/s", Path("g.csv")))
    assert 0.2 < ratio["right"] < 1.5 and ratio["rad_as_deg"] > 5.0 and ratio["deg_as_rad"] < 0.05
    still = sim_session[0][("thigh", "standing")]
    assert gyro_scale_ratio(Stream("acc", *still["acc"], "g", Path("a.csv")),
                            Stream("gyr", *still["gyr"], "deg/s", Path("g.csv"))) is None   # no motion: no verdict


def test_ambiguous_label_is_reported_and_a_manifest_can_settle_it(folder):
    for p in list(folder.glob("standing-muslo*")):
        p.rename(p.with_name(p.name.replace("standing-muslo", "standing-step-muslo")))
    msg = _error(folder)
    assert "missing recording(s): standing of the thigh" in msg and "names more than one role" in msg
    files = sorted(p.name for p in folder.glob("standing-step-muslo*"))
    entries = [{"files": files, "role": "standing"}]
    for p in folder.glob("*Accelerometer*"):
        if not p.name.startswith("standing-step"):
            stem = p.name.split("_Accelerometer_")[0]
            entries.append({"files": sorted(q.name for q in folder.glob(stem + "_*"))})
    (folder / "session.json").write_text(json.dumps({"recordings": entries}))
    s = load_session(folder)
    assert "session.json" in s.recording("thigh", "standing").source["role"]
