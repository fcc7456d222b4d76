"""Readers and writers: MetaBase CSV (both dialects), thesis Excel, generic CSV; the real MetaBase export."""

from pathlib import Path

import numpy as np
import pytest

from app.pipeline.ingestion import (read_generic_csv, read_metabase_csv, read_thesis_xlsx, write_generic_csv,
                           write_metabase_csv, write_thesis_xlsx)
from app.pipeline.ingestion.metabase import file_name, parse_file_name

G = 9.80665
SHARED = Path(__file__).resolve().parents[5] / "shared" / "data" / "metabase"


def _streams(seed=0, n=300, t0=1_678_700_000.0):
    rng = np.random.default_rng(seed)
    t = t0 + 0.003 + np.arange(n) / 100.0
    acc = np.column_stack([np.sin(t - t0), np.cos(t - t0), 9.5 + 0 * t]) + 0.1 * rng.normal(size=(n, 3))
    gyr = 0.5 * rng.normal(size=(n, 3))
    tm = t0 + 0.017 + np.arange(n // 5) / 20.0
    mag = np.array([3.0, 20.0, -40.0]) + rng.normal(size=(len(tm), 3))
    return (t, acc), (t, gyr), (tm, mag)


@pytest.mark.parametrize("dialect,sep,tz", [("epoch", ":", -13.0), ("epoc", ".", 2.0)])
def test_metabase_round_trip_within_printed_precision(tmp_path, dialect, sep, tz):
    for kind, (t, v) in zip(("acc", "gyr", "mag"), _streams()):
        ms = np.round(t * 1e3).astype(np.int64)
        rate = 20.0 if kind == "mag" else 100.0
        p = tmp_path / file_name("step-muslo-ML1-13032023-1", int(ms[0]), "EB:94:2C:ED:94:72", kind, rate,
                                 utc_offset_h=tz)
        write_metabase_csv(p, kind, ms, v, dialect=dialect, time_sep=sep, utc_offset_h=tz)
        head, first = p.read_text().splitlines()[:2]
        assert head.startswith(f"{dialect} (ms),{'time' if dialect == 'epoch' else 'timestamp'} (")
        time_str = first.split(",")[1]
        assert time_str[13] == sep and time_str[16] == sep      # HH?MM?SS.mmm
        s = read_metabase_csv(p)
        assert s.kind == kind and s.nominal_fs_hz == rate and s.time_base == "epoch"
        np.testing.assert_allclose(s.t_s, ms / 1e3, rtol=0, atol=1e-6)
        tol = {"acc": 0.0005 * G, "gyr": np.deg2rad(0.0005), "mag": 0.0005}[kind]   # half the last printed digit
        np.testing.assert_allclose(s.values, v, rtol=0, atol=tol * 1.0001)
        assert s.declared_unit == {"acc": "g", "gyr": "deg/s", "mag": "T"}[kind]


def test_metabase_file_name_parts():
    n = parse_file_name(Path("1_MetaWear_2021-10-29T10.18.39.911_EB942CED9472_Magnetometer_20.000Hz_1.5.1.csv"))
    assert n == {"label": "1", "device": "MetaWear", "datetime": "2021-10-29T10.18.39.911", "mac": "EB942CED9472",
                 "stream": "Magnetometer", "rate": "20.000", "firmware": "1.5.1"}
    assert parse_file_name(Path("notes.csv")) is None


@pytest.mark.parametrize("name,label,device,mac", [
    ("260_Werable1_2020-10-31T15.11.37.108_F1E55E2FE95F_Gyroscope_100.000Hz_1.5.0.csv", "260", "Werable1",
     "F1E55E2FE95F"),                                                   # renamed by its user (real export)
    ("step_muslo_ML1_MetaWearA0_2023-03-13T10.00.00.000_D4F1A2B3C4E5_Accelerometer_100.000Hz_1.7.3.csv",
     "step_muslo_ML1", "MetaWearA0", "D4F1A2B3C4E5"),                   # a label with '_'
    ("MetaWear_2023-03-13T10.00.00_D4:F1:A2:B3:C4:E5_Magnetometer_25Hz.csv", "", "MetaWear", "D4F1A2B3C4E5"),
])
def test_metabase_file_names_any_device_and_newer_layouts(name, label, device, mac):
    n = parse_file_name(Path(name))
    assert (n["label"], n["device"], n["mac"]) == (label, device, mac)


def test_metabase_nan_rows_are_missing_samples(tmp_path):
    (t, v), _, _ = _streams()
    v = v.copy()
    v[10:13] = np.nan
    p = write_metabase_csv(tmp_path / "a.csv", "acc", np.round(t * 1e3), v)
    s = read_metabase_csv(p, "acc")
    assert np.isnan(s.values[10:13]).all() and np.isfinite(s.values[:10]).all()


def test_thesis_excel_round_trip(tmp_path):
    (t, acc), (_, gyr), (tm, mag) = _streams()
    p = write_thesis_xlsx(tmp_path / "step-muslo-ML1-13032023-1-H.xlsx", (t, acc), gyr, (tm, mag))
    a, g, m, note = read_thesis_xlsx(p)
    assert note == "sheet 'data'"
    assert a.time_base == g.time_base == m.time_base == "elapsed"
    np.testing.assert_allclose(a.t_s, np.round(t - t[0], 3), atol=1e-9)
    np.testing.assert_allclose(m.t_s, np.round(tm - tm[0], 3), atol=1e-9)
    np.testing.assert_allclose(a.values, acc, atol=0.0005 * G * 1.0001)
    np.testing.assert_allclose(g.values, gyr, atol=np.deg2rad(0.0005) * 1.0001)
    np.testing.assert_allclose(m.values, mag, rtol=5e-5 * 1.0001)     # 5 significant digits in T
    assert len(m.t_s) == len(tm) < len(a.t_s)                         # shorter 20 Hz columns


def test_thesis_excel_extra_sheet_is_skipped_and_noted(tmp_path):
    (t, acc), (_, gyr), (tm, mag) = _streams()
    p = write_thesis_xlsx(tmp_path / "x.xlsx", (t, acc), gyr, (tm, mag), extra_sheets=("Hoja2", "grafico"))
    *_, note = read_thesis_xlsx(p)
    assert note.startswith("sheet 'data' of ") and "Hoja2" in note


@pytest.mark.parametrize("header_style", ["paren", "suffix"])
def test_generic_csv_units_from_header(tmp_path, header_style):
    (t, acc), (_, gyr), (tm, mag) = _streams()
    if header_style == "paren":
        p = write_generic_csv(tmp_path / "g.csv", (t - t[0], acc), (t - t[0], gyr), (tm - t[0], mag))
        a, g, m = read_generic_csv(p)
        np.testing.assert_allclose(a.values, acc, atol=1e-6)
        np.testing.assert_allclose(m.t_s, tm - t[0], atol=1e-6)
    else:  # one time column, units as name suffixes, acc in g, gyr in deg/s, mag in nT, mag every 5th row
        lines = ["t_s,acc_x_g,acc_y_g,acc_z_g,gyr_x_deg_s,gyr_y_deg_s,gyr_z_deg_s,mag_x_nt,mag_y_nt,mag_z_nt"]
        for k in range(len(t)):
            m_cells = ",".join(f"{x * 1e3:.3f}" for x in mag[k // 5]) if k % 5 == 0 else ",,"
            lines.append(f"{k / 100:.2f}," + ",".join(f"{x / G:.6f}" for x in acc[k]) + ","
                         + ",".join(f"{np.rad2deg(x):.6f}" for x in gyr[k]) + "," + m_cells)
        p = tmp_path / "g2.csv"
        p.write_text("\n".join(lines) + "\n")
        a, g, m = read_generic_csv(p)
        np.testing.assert_allclose(a.values, acc, atol=1e-5)
        np.testing.assert_allclose(g.values, gyr, atol=1e-7)
        np.testing.assert_allclose(m.values, mag[: len(m.values)], atol=1e-6)
        assert len(m.t_s) == len(t) // 5 and m.fs_hz == pytest.approx(20.0)
        assert (a.declared_unit, g.declared_unit, m.declared_unit) == ("g", "deg_s", "nt")
    assert a.kind == "acc" and g.kind == "gyr" and m.kind == "mag"


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/data/metabase not present")
def test_real_metabase_export_units_and_rates():
    files = {k: next(SHARED.glob(f"1_MetaWear_2021-*_{k}_*.csv")) for k in ("Accelerometer", "Gyroscope", "Magnetometer")}
    acc, gyr, mag = (read_metabase_csv(files[k]) for k in ("Accelerometer", "Gyroscope", "Magnetometer"))
    assert (acc.kind, gyr.kind, mag.kind) == ("acc", "gyr", "mag")
    assert acc.fs_hz == pytest.approx(100.0, rel=1e-3) and gyr.fs_hz == pytest.approx(100.0, rel=1e-3)
    assert mag.fs_hz == pytest.approx(20.0, rel=1e-3)
    assert acc.nominal_fs_hz == 100.0 and mag.nominal_fs_hz == 20.0
    # first rows of the files: -0.981 g; -0.061 deg/s; -0.000048687 T
    assert acc.values[0, 0] == pytest.approx(-0.981 * G)
    assert gyr.values[0, 0] == pytest.approx(np.deg2rad(-0.061))
    assert mag.values[0, 0] == pytest.approx(-48.687)
    assert 9.0 < np.median(np.linalg.norm(acc.values, axis=1)) < 10.6          # gravity in m/s²
    assert 20.0 < np.median(np.linalg.norm(mag.values, axis=1)) < 150.0        # µT (earth + hard iron)
    from app.pipeline.ingestion.units import check_gyro_unit, gyro_scale_ratio
    check_gyro_unit(acc, gyr)                                                   # deg/s declared and consistent
    # too few 0.5 s windows where gravity turns > 15° to judge the unit: check_gyro_unit leaves it unchecked
    assert gyro_scale_ratio(acc, gyr) is None
    assert acc.t_s[0] == pytest.approx(1635517120.016) and gyr.t_s[0] - acc.t_s[0] == pytest.approx(0.009, abs=1e-6)


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/data/metabase not present")
def test_real_metabase_export_aligns_and_is_not_a_session():
    from app.pipeline.ingestion import IngestionError, align_recording, load_session, read_recording
    rec = read_recording(sorted(SHARED.glob("1_MetaWear_2021-*.csv")))
    assert rec.fmt == "metabase" and rec.sensor_id == "EB942CED9472" and rec.role is None and rec.segment is None
    a = align_recording(rec, 100.0, "thigh", "task")
    assert a.fs_hz == 100.0 and 130.0 < a.duration_s < 131.0          # mag stops 0.84 s before acc/gyr
    assert any("acc ran on 0.8" in n for n in a.flags["notes"]) and not any(a.flags["nan_rows"].values())
    with pytest.raises(IngestionError, match="role and segment not recognised") as exc:
        load_session(SHARED)                                           # labels '1', '260': no role, no segment
    assert all(f"{label}_{device}_" in str(exc.value) for label, device in (("1", "MetaWear"), ("260", "Werable1")))
    assert exc.value.code == "session.no_sensor"


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/data/metabase not present")
@pytest.mark.parametrize("pattern,mac,firmware,first_acc_g", [
    ("260_Werable1_*", "F1E55E2FE95F", "1.5.0", 0.685),       # the device renamed by its user
    ("1_MetaWear_2019-*", "F1E55E2FE95F", "1.4.5", 0.715),    # firmware 1.4.5, with a Pressure stream
])
def test_real_metabase_exports_of_any_device_name_are_read(pattern, mac, firmware, first_acc_g):
    from app.pipeline.ingestion import align_recording, read_recording
    rec = read_recording(sorted(SHARED.glob(pattern)))        # the Pressure file is ignored
    assert rec.fmt == "metabase" and rec.sensor_id == mac and rec.extras["firmware"].value == firmware
    assert rec.acc.values[0, 0] == pytest.approx(first_acc_g * G) and rec.acc.nominal_fs_hz == 100.0
    assert rec.mag.nominal_fs_hz == 20.0 and rec.mag.fs_hz == pytest.approx(20.0, rel=0.02)
    assert rec.extras["started"].value == {"1.5.0": "2020-10-31T15:11:37", "1.4.5": "2019-09-14T13:41:43"}[firmware]
    a = align_recording(rec, 100.0, "thigh", "task")
    assert 70.0 < a.duration_s < 145.0 and 9.0 < np.nanmedian(np.linalg.norm(a.acc, axis=1)) < 10.6


def test_generic_csv_with_epoch_ms(tmp_path):
    (t, acc), (_, gyr), (tm, mag) = _streams()
    lines = ["epoch (ms),acc_x (m/s2),acc_y (m/s2),acc_z (m/s2),gyr_x (rad/s),gyr_y (rad/s),gyr_z (rad/s),"
             "mag_time (epoch ms),mag_x (µT),mag_y (µT),mag_z (µT)"]
    for k in range(len(t)):
        m = f"{round(tm[k] * 1e3)}," + ",".join(f"{x:.4f}" for x in mag[k]) if k < len(tm) else ",,,"
        lines.append(f"{round(t[k] * 1e3)}," + ",".join(f"{x:.5f}" for x in (*acc[k], *gyr[k])) + "," + m)
    p = tmp_path / "e.csv"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    a, g, m = read_generic_csv(p)
    assert a.time_base == m.time_base == "epoch"
    np.testing.assert_allclose(m.t_s, np.round(tm * 1e3) / 1e3, atol=1e-6)
    np.testing.assert_allclose(m.values, mag, atol=5e-5)
