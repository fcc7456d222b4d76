"""phyphox exports (CSV flavours, the zip of sets with meta/time.csv, Excel), written by the project from the app's
public export description, read back against the simulated values they were written from."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from app.pipeline.ingestion import IngestionError, load_session, read_recording
from app.pipeline.ingestion.phyphox import _java_sci, looks_like_phyphox, write_phyphox

EPOCH0_S = 1_678_700_000.25


@pytest.fixture(scope="module")
def streams(sim_session):
    recordings, _ = sim_session
    s = recordings[("thigh", "task")]
    t0 = min(t[0] for t, _ in s.values())
    return {k: (t - t0, v) for k, (t, v) in s.items()}


@pytest.mark.parametrize("layout,sep,dec", [("zip", ",", "."), ("zip-one-set", ";", ","), ("zip", "\t", ","),
                                            ("csv", "\t", "."), ("csv", ",", "."), ("xlsx", ",", ".")])
def test_every_layout_reads_back_the_values_in_si(tmp_path, streams, layout, sep, dec):
    ext = {"xlsx": "xlsx", "csv": "csv"}.get(layout, "zip")
    p = write_phyphox(tmp_path / f"step-muslo-ML1.{ext}", streams, layout=layout, separator=sep, decimal=dec,
                      epoch0_s=EPOCH0_S)
    assert looks_like_phyphox(p)
    rec = read_recording([p])
    assert rec.fmt == "phyphox" and rec.role.value == "task" and rec.segment.value == "thigh"
    for kind in ("acc", "gyr", "mag"):
        got, (t, v) = getattr(rec, kind), streams[kind]
        zipped = layout.startswith("zip")
        assert got.time_base == ("epoch" if zipped else "elapsed")
        np.testing.assert_allclose(got.t_s - (EPOCH0_S if zipped else 0.0), t, atol=1e-6)
        np.testing.assert_allclose(got.values, v, rtol=1e-8, atol=1e-9)   # 10 significant digits in the file


def test_numbers_are_written_as_phyphox_writes_them():
    """Java's DecimalFormat("0.000000000E0"): no '+', no padded exponent, the chosen decimal mark."""
    assert _java_sci(9.80665, ".") == "9.806650000E0"
    assert _java_sci(-0.0012345, ".") == "-1.234500000E-3"
    assert _java_sci(12345.0, ",") == "1,234500000E4"
    assert _java_sci(0.0, ".") == "0.000000000E0"
    assert _java_sci(float("nan"), ".") == "NaN"


def test_a_session_of_phyphox_zips_loads(tmp_path, sim_session):
    recordings, _ = sim_session
    words = {"thigh": "muslo", "shank": "pierna", "mag_calibration": "calibracion", "standing": "standing",
             "lying": "laydown", "task": "step"}
    for (seg, role), s in recordings.items():
        t0 = min(t[0] for t, _ in s.values())
        write_phyphox(tmp_path / f"{words[role]}-{words[seg]}-ML1.zip", {k: (t - t0, v) for k, (t, v) in s.items()},
                      epoch0_s=t0, old_names=seg == "shank")
    session = load_session(tmp_path)
    assert len(session.recordings) == 8
    thigh, shank = session.task_pair()
    assert thigh.source["format"] == "phyphox" and np.array_equal(thigh.t_s, shank.t_s)


def _one_sensor_csv(path, kind, t, v):
    names = {"acc": "Acceleration {} (m/s^2)", "gyr": "Gyroscope {} (rad/s)", "mag": "Magnetic field {} (µT)"}[kind]
    lines = [",".join(['"Time (s)"'] + [f'"{names.format(a)}"' for a in "xyz"])]
    lines += [",".join(_java_sci(x, ".") for x in (tk, *vk)) for tk, vk in zip(t, v)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_three_experiments_exported_apart_are_one_recording_in_session_json(tmp_path, streams):
    for kind, title in (("acc", "Acceleration with g"), ("gyr", "Gyroscope"), ("mag", "Magnetometer")):
        _one_sensor_csv(tmp_path / f"step-muslo {title}.csv", kind, *streams[kind])
    rec = read_recording(sorted(tmp_path.glob("step-muslo *.csv")))
    assert rec.label == "step-muslo" and rec.segment.value == "thigh"
    np.testing.assert_allclose(rec.gyr.values, streams["gyr"][1], rtol=1e-8, atol=1e-9)
    with pytest.raises(IngestionError) as err:
        read_recording([tmp_path / "step-muslo Gyroscope.csv"])
    assert err.value.code == "phyphox.sensors_missing"
    assert "Acceleration with g, Magnetometer" in str(err.value) and "session.json" in str(err.value)


def test_acceleration_without_gravity_is_refused_in_each_language(tmp_path, streams):
    p = write_phyphox(tmp_path / "step-muslo.zip", streams)
    with zipfile.ZipFile(p) as z:
        files = {n: z.read(n).decode() for n in z.namelist()}
    files["Accelerometer.csv"] = files["Accelerometer.csv"].replace('"Acceleration ', '"Linear Acceleration ')
    with zipfile.ZipFile(p, "w") as z:
        for n, text in files.items():
            z.writestr(n, text)
    with pytest.raises(IngestionError) as err:
        read_recording([p])
    assert err.value.code == "phyphox.linear_acceleration"
    assert "Acceleration with g" in str(err.value)
    assert "Aceleración con g" in err.value.message("es") and "Aceleração com g" in err.value.message("pt")


def test_a_wrong_unit_in_a_header_is_named(tmp_path, streams):
    p = write_phyphox(tmp_path / "step-muslo.csv", streams, layout="csv")
    p.write_text(p.read_text(encoding="utf-8").replace("(rad/s)", "(furlong/s)", 1), encoding="utf-8")
    with pytest.raises(IngestionError) as err:
        read_recording([p])
    assert err.value.code == "phyphox.unit_unknown" and "furlong/s" in str(err.value)


def test_session_json_lists_the_exports(tmp_path, streams):
    for seg in ("muslo", "pierna"):
        write_phyphox(tmp_path / f"a-{seg}.zip", streams, epoch0_s=EPOCH0_S)
    (tmp_path / "session.json").write_text(json.dumps({"recordings": [
        {"files": ["a-muslo.zip"], "role": "task"}, {"files": ["a-pierna.zip"], "role": "task"}]}))
    session = load_session(tmp_path)
    assert sorted(session.recordings) == [("shank", "task"), ("thigh", "task")]


def test_a_set_of_workbooks_is_read_one_workbook_at_a_time(tmp_path, streams, monkeypatch):
    """Three experiments exported apart as Excel (one sensor each): read as one recording, each value as written,
    with one workbook open at a time (each may hold its sheets' XML, up to 64 MB: they were all open at once), and
    a workbook opened once when it is alone (the sniff's opening is the reader's)."""
    import openpyxl

    from app.pipeline.ingestion.xlsx_cells import Workbook

    names = {"acc": "Acceleration {} (m/s^2)", "gyr": "Gyroscope {} (rad/s)", "mag": "Magnetic field {} (µT)"}
    for kind, title in (("acc", "Acceleration with g"), ("gyr", "Gyroscope"), ("mag", "Magnetometer")):
        book = openpyxl.Workbook()   # a one-sensor experiment's Excel export: its set on one sheet
        book.active.append(["Time (s)"] + [names[kind].format(a) for a in "xyz"])
        for tk, vk in zip(*streams[kind]):
            book.active.append([float(tk), *map(float, vk)])
        book.save(tmp_path / f"step-muslo {title}.xlsx")
    open_now, most, opened = set(), [0], []
    real_init, real_close = Workbook.__init__, Workbook.close

    def opening(wb, path):
        real_init(wb, path)
        open_now.add(id(wb))
        opened.append(path)
        most[0] = max(most[0], len(open_now))

    def closing(wb):
        open_now.discard(id(wb))
        real_close(wb)

    monkeypatch.setattr(Workbook, "__init__", opening)
    monkeypatch.setattr(Workbook, "close", closing)
    rec = read_recording(sorted(tmp_path.glob("step-muslo *.xlsx")))
    assert rec.label == "step-muslo" and most[0] == 1 and not open_now
    for kind, s in zip(("acc", "gyr", "mag"), (rec.acc, rec.gyr, rec.mag)):
        np.testing.assert_allclose(s.values, streams[kind][1], rtol=1e-8, atol=1e-9)
    opened.clear()
    (tmp_path / "alone").mkdir()
    one = write_phyphox(tmp_path / "alone" / "step-muslo-ML1.xlsx", streams, layout="xlsx")
    read_recording([one])
    assert opened == [one]
