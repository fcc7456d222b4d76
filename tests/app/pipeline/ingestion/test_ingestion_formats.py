"""Other vendors' formats, each written by the project from the format's public description: Xsens MT
Manager exports (normalised magnetometer), Shimmer Consensys CSV, the generic CSV's normalised unit."""

import numpy as np
import pytest

from app.pipeline.ingestion import IngestionError, load_session
from app.pipeline.ingestion.session import read_recording, sniff
from app.pipeline.ingestion.shimmer import write_shimmer
from app.pipeline.ingestion.units import normalised_field
from app.pipeline.ingestion.writers import session_label
from app.pipeline.ingestion.xsens import write_xsens


def _on_acc_grid(streams):
    """acc's stamps; gyr interpolated on them; mag on the nearest row every 5th (NaN elsewhere)."""
    t, acc = streams["acc"]
    tg, gyr = streams["gyr"]
    gyr = np.stack([np.interp(t, tg, gyr[:, i]) for i in range(3)], axis=1)
    tm, mag = streams["mag"]
    m = np.full((len(t), 3), np.nan)
    rows = np.clip(np.searchsorted(t, tm), 0, len(t) - 1)
    m[rows] = mag
    return t, acc, gyr, m


@pytest.fixture(scope="module")
def xsens_dir(tmp_path_factory, sim_session):
    d = tmp_path_factory.mktemp("xsens")
    ids = {"thigh": "00B42D4F", "shank": "00B42D50"}
    for (segment, role), streams in sim_session[0].items():
        t, acc, gyr, mag = _on_acc_grid(streams)
        field = np.nanmedian(np.linalg.norm(mag, axis=1))
        write_xsens(d / f"{session_label(segment, role, 'ML1', '13032023')}.txt", t - t[0], acc, gyr, mag / field,
                    device_id=ids[segment], delimiter="\t" if role != "lying" else ",")
    return d


def test_xsens_session_loads_with_a_normalised_magnetometer(xsens_dir, sim_session):
    assert all(sniff(p) == "xsens" for p in xsens_dir.glob("*.txt"))
    session = load_session(xsens_dir)
    assert len(session.recordings) == 8
    raw = session.raw[("thigh", "task")]
    assert raw.fmt == "xsens" and raw.sensor_id == "00B42D4F" and raw.mag.mag_unit == "normalised"
    t, acc, gyr, _ = _on_acc_grid(sim_session[0][("thigh", "task")])
    np.testing.assert_allclose(raw.acc.values, acc, atol=1e-6)              # m/s² as written
    np.testing.assert_allclose(raw.gyr.values, gyr, atol=1e-6)              # rad/s as written
    np.testing.assert_allclose(raw.acc.t_s, t - t[0], atol=1e-4)           # SampleTimeFine wrapped and unwrapped
    thigh, shank = session.task_pair()
    assert thigh.mag_normalised and shank.mag_normalised and thigh.flags["mag_field_ut"] is None
    norm = np.linalg.norm(thigh.mag[np.isfinite(thigh.mag).all(axis=1)], axis=1)
    assert 0.9 < np.median(norm) < 1.1                                       # never scaled to µT
    assert any(getattr(n, "params", {}).get("variant") == "mag_normalised" for n in session.notes)


def test_xsens_field_strength_from_session_json(xsens_dir, tmp_path):
    import json
    import shutil
    d = tmp_path / "s"
    shutil.copytree(xsens_dir, d)
    (d / "session.json").write_text(json.dumps({"mag_field_ut": 48.5}))
    session = load_session(d)
    assert session.task_pair()[0].flags["mag_field_ut"] == 48.5 and session.task_pair()[0].mag_normalised
    (d / "session.json").write_text(json.dumps({"mag_field_ut": 4850}))
    with pytest.raises(IngestionError, match="give the local magnetic field strength in µT"):
        load_session(d)


def test_xsens_without_acc_is_refused_naming_the_columns(tmp_path):
    p = write_xsens(tmp_path / "step-muslo-1.txt", np.arange(300) / 100, np.ones((300, 3)) * 5.7,
                    np.zeros((300, 3)), np.ones((300, 3)) / np.sqrt(3))
    lines = p.read_text().splitlines()
    p.write_text("\n".join(ln.replace("Acc_", "FreeAcc_") if ln.startswith("Packet") else ln for ln in lines))
    with pytest.raises(IngestionError) as exc:
        read_recording([p])
    assert exc.value.code == "xsens.columns_missing" and "Acc_X" in str(exc.value) and "FreeAcc" in str(exc.value)
    assert "MT Manager" in exc.value.message("es") and "exporte-a de novo" in exc.value.message("pt")


def test_xsens_magnetometer_in_micro_tesla_is_not_taken_for_normalised(tmp_path):
    """Numbers of ~45 (µT) under Xsens' normalised unit: refused, not silently read as a huge normalised field."""
    n = 300
    p = write_xsens(tmp_path / "step-muslo-1.txt", np.arange(n) / 100, np.tile([0.0, 0.0, 9.81], (n, 1)),
                    np.zeros((n, 3)), np.tile([20.0, 0.0, -40.0], (n, 1)))
    with pytest.raises(IngestionError) as exc:
        read_recording([p])
    assert exc.value.code == "unit.implausible_normalised" and p.name in str(exc.value)


@pytest.fixture(scope="module")
def shimmer_dir(tmp_path_factory, sim_session):
    d = tmp_path_factory.mktemp("shimmer")
    for (segment, role), streams in sim_session[0].items():
        t, acc, gyr, mag = _on_acc_grid(streams)
        ok = np.isfinite(mag).all(axis=1)       # Shimmer samples the magnetometer on every row: fill it
        mag = np.stack([np.interp(t, t[ok], mag[ok, i]) for i in range(3)], axis=1)
        write_shimmer(d / f"{session_label(segment, role, 'ML1', '13032023', lang='pt')}.csv", t * 1e3, acc, gyr,
                      mag, device={"thigh": "Shimmer_8A21", "shank": "Shimmer_8A22"}[segment],
                      delimiter="\t" if segment == "thigh" else ",", sep_line=role != "task")
    return d


def test_shimmer_session_loads_in_si_units(shimmer_dir, sim_session):
    assert {sniff(p) for p in shimmer_dir.glob("*.csv")} == {"shimmer"}
    session = load_session(shimmer_dir)
    raw = session.raw[("shank", "task")]
    assert raw.fmt == "shimmer" and raw.sensor_id == "Shimmer_8A22" and raw.acc.time_base == "epoch"
    t, acc, gyr, _ = _on_acc_grid(sim_session[0][("shank", "task")])
    np.testing.assert_allclose(raw.acc.t_s, t, atol=1e-3)                   # Unix ms → s
    np.testing.assert_allclose(raw.acc.values, acc, atol=1e-5)
    np.testing.assert_allclose(raw.gyr.values, gyr, atol=1e-6)              # deg/s → rad/s
    mag = raw.mag.values
    assert 20.0 < np.median(np.linalg.norm(mag, axis=1)) < 70.0 and raw.mag.mag_unit == "µT"   # local_flux → µT
    assert not session.task_pair()[0].mag_normalised


def test_shimmer_without_units_row_is_refused(shimmer_dir, tmp_path):
    p = next(shimmer_dir.glob("degrau-coxa*.csv"))
    q = tmp_path / p.name
    lines = p.read_text().splitlines()
    q.write_text("\n".join(lines[:1] + lines[3:]) + "\n")          # no CAL and units rows (no sep line here)
    with pytest.raises(IngestionError) as exc:
        read_recording([q])
    assert exc.value.code == "shimmer.no_units_row" and q.name in str(exc.value)


@pytest.mark.parametrize("unit,expected", [("normalised", (True, None)), ("normalized", (True, None)),
                                           ("a.u.", (True, None)), ("normalised 48.5 uT", (True, 48.5)),
                                           ("normalised 0.485 G", (True, 48.5)), ("uT", (False, None))])
def test_normalised_unit_spellings(unit, expected):
    ok, field = normalised_field(unit)
    assert ok == expected[0] and (field == pytest.approx(expected[1]) if expected[1] else field is None)


def test_generic_csv_normalised_magnetometer_with_field(tmp_path):
    n = 400
    t = np.arange(n) / 100.0
    lines = ["time (s),acc_x (m/s2),acc_y (m/s2),acc_z (m/s2),gyr_x (rad/s),gyr_y (rad/s),gyr_z (rad/s),"
             "mag_x (normalised 48.5 uT),mag_y (normalised 48.5 uT),mag_z (normalised 48.5 uT)"]
    for k in range(n):
        lines.append(f"{t[k]:.2f},0.1,0.2,9.8,0.01,0.02,0.03,0.6,0.0,-0.8")
    p = tmp_path / "step-muslo-1.csv"
    p.write_text("\n".join(lines) + "\n")
    rec = read_recording([p])
    assert rec.mag.mag_unit == "normalised" and rec.mag.field_ut == pytest.approx(48.5)
    np.testing.assert_allclose(rec.mag.values[0], [0.6, 0.0, -0.8])        # kept normalised, never × 48.5


@pytest.fixture(scope="module")
def opal_dir(tmp_path_factory, sim_session):
    from app.pipeline.ingestion.opal import write_opal
    d = tmp_path_factory.mktemp("opal")
    names = {"mag_calibration": "calibration", "standing": "standing", "lying": "supine", "task": "step"}
    for role, name in names.items():
        sensors = {}
        for segment, sid, label in (("thigh", "XI-001234", "Right Thigh"), ("shank", "XI-001235", "Right Shank")):
            t, acc, gyr, mag = _on_acc_grid(sim_session[0][(segment, role)])
            ok = np.isfinite(mag).all(axis=1)
            mag = np.stack([np.interp(t, t[ok], mag[ok, i]) for i in range(3)], axis=1)
            sensors[sid] = {"label": label, "rate_hz": 100.0, "t_s": t, "acc": acc, "gyr": gyr, "mag": mag}
        write_opal(d / f"{name}.h5", sensors)
    return d


def test_apdm_opal_files_one_recording_per_sensor(opal_dir, sim_session):
    session = load_session(opal_dir)
    assert len(session.recordings) == 8
    raw = session.raw[("shank", "task")]
    assert raw.fmt == "apdm-opal" and raw.sensor_id == "XI-001235" and raw.segment.value == "shank"
    assert raw.extras["side"].value == "right" and raw.acc.time_base == "epoch"
    t, acc, gyr, _ = _on_acc_grid(sim_session[0][("shank", "task")])
    np.testing.assert_allclose(raw.acc.t_s, t, atol=1e-6)                   # µs since 1970 → s
    np.testing.assert_allclose(raw.gyr.values, gyr, atol=1e-12)


def test_apdm_opal_file_with_two_sensors_needs_the_sensor_named(opal_dir):
    with pytest.raises(IngestionError) as exc:
        read_recording([opal_dir / "step.h5"])
    assert exc.value.code == "opal.which_sensor" and "XI-001234 (Right Thigh)" in str(exc.value)
    rec = read_recording([opal_dir / "step.h5"], sensor="XI-001234")
    assert rec.segment.value == "thigh" and rec.role.value == "task"


def test_apdm_dataset_of_a_wrong_shape_is_damaged_not_too_large(tmp_path, opal_dir, monkeypatch):
    """An accelerometer dataset of shape (N, 4) was refused as ``opal.too_large`` ("export shorter recordings")
    though it holds 200 samples; it is a damaged file (``opal.bad_shape``), named before a byte is read.  Too many
    sensors is still ``opal.too_large``, of ``/Sensors``."""
    from app.pipeline.ingestion import opal
    from app.pipeline.ingestion.opal import write_opal

    t = 1.7e9 + np.arange(200) / 100.0
    one = {"label": "Right Thigh", "rate_hz": 100.0, "t_s": t, "acc": np.tile([0.0, 0.0, 9.81, 0.0], (200, 1)),
           "gyr": np.zeros((200, 3)), "mag": np.tile([20.0, 0.0, -40.0], (200, 1))}
    path = write_opal(tmp_path / "step.h5", {"XI-001234": one})
    with pytest.raises(IngestionError) as exc:
        read_recording([path])
    assert exc.value.code == "opal.bad_shape" and exc.value.params["dataset"] == "/Sensors/XI-001234/Accelerometer"
    assert "(200, 4)" in exc.value.message("es") and "(200, 3)" in exc.value.message("pt")
    monkeypatch.setattr(opal, "MAX_SENSORS", 1)
    with pytest.raises(IngestionError) as exc:
        read_recording([opal_dir / "step.h5"], sensor="XI-001234")
    assert exc.value.code == "opal.too_large" and exc.value.params["dataset"] == "/Sensors"


def test_apdm_file_not_hdf5_is_refused(tmp_path):
    p = tmp_path / "step.h5"
    p.write_text("not hdf5")
    with pytest.raises(IngestionError) as exc:
        read_recording([p])
    assert exc.value.code == "opal.cannot_open" and p.name in exc.value.message("pt")


def test_an_hdf5_file_of_another_layout_is_not_called_an_old_apdm_file(tmp_path):
    """An HDF5 file of a dataset's own layout (BROAD's ``imu_acc``, ``imu_gyr``… in ``../shared/data/broad``) was
    refused as an APDM file of an older version, to be "exported again from Mobility Lab"; it is named as HDF5 that
    is not an APDM recording, with what it holds.  An APDM file without ``/Sensors`` (its ``FileFormatVersion``
    says it is APDM's) is still asked to be exported again."""
    import h5py

    other, old = tmp_path / "trial.hdf5", tmp_path / "old.h5"
    with h5py.File(other, "w") as f:
        f["imu_acc"] = np.zeros((4, 3))
        f["opt_quat"] = np.zeros((4, 4))
    with h5py.File(old, "w") as f:
        f.attrs["FileFormatVersion"] = 3
        f["Data"] = np.zeros(3)
    for path, code in ((other, "opal.not_apdm"), (old, "opal.not_v5")):
        with pytest.raises(IngestionError) as exc:
            read_recording([path])
        assert exc.value.code == code
    with pytest.raises(IngestionError) as exc:
        read_recording([other])
    for lang in ("es", "en", "pt"):
        text = exc.value.message(lang)
        assert "trial.hdf5" in text and "imu_acc, opt_quat" in text and "Mobility Lab" in text and "CSV" in text


@pytest.mark.parametrize("platform,total", [("android", True), ("android", False), ("ios", False)])
def test_sensor_logger_zips_give_specific_force(tmp_path, sim_session, platform, total):
    """TotalAcceleration, or Accelerometer (no gravity) + Gravity; iPhone's default frames negated back."""
    from app.pipeline.ingestion.sensorlogger import write_sensorlogger
    for (segment, role), streams in sim_session[0].items():
        write_sensorlogger(tmp_path / f"{session_label(segment, role, 'ML1', '13032023', lang='en')}.zip", streams,
                           platform=platform, total=total)
    session = load_session(tmp_path)
    raw = session.raw[("thigh", "standing")]
    t, f = sim_session[0][("thigh", "standing")]["acc"]
    assert raw.fmt == "sensor-logger" and raw.sensor_id == "Pixel 7" and raw.acc.time_base == "epoch"
    np.testing.assert_allclose(raw.acc.t_s, t, atol=1e-6)                   # ns since 1970 → s
    np.testing.assert_allclose(raw.acc.values, f, atol=2e-6)               # specific force, gravity up
    np.testing.assert_allclose(raw.gyr.values, sim_session[0][("thigh", "standing")]["gyr"][1], atol=1e-6)
    ios_noted = any(getattr(n, "params", {}).get("variant") == "phone_ios_frames" for n in session.notes)
    assert ios_noted == (platform == "ios")


def test_sensor_logger_zip_without_gyroscope_is_refused(tmp_path, sim_session):
    import zipfile
    from app.pipeline.ingestion.sensorlogger import write_sensorlogger
    p = write_sensorlogger(tmp_path / "step-thigh.zip", sim_session[0][("thigh", "task")])
    q = tmp_path / "step-thigh-2.zip"
    with zipfile.ZipFile(p) as zin, zipfile.ZipFile(q, "w") as zout:
        for name in zin.namelist():
            if name not in ("Gyroscope.csv", "Accelerometer.csv"):
                zout.writestr(name, zin.read(name))
    with pytest.raises(IngestionError) as exc:
        read_recording([q])
    assert exc.value.code == "phone.files_missing" and "Gyroscope.csv" in str(exc.value)
    assert "grabe de nuevo" in exc.value.message("es")


def test_the_names_an_hdf5_file_holds_are_cut_in_its_refusal(tmp_path):
    """A review: one dataset named with 5 000 characters made a 5 334-character refusal.  Each name is cut at 40
    characters and the list at eight names, as ``opal.cannot_open`` cuts its reason."""
    import h5py

    path = tmp_path / "long.hdf5"
    with h5py.File(path, "w") as f:
        f["a" * 5000] = np.zeros(2)
        for k in range(12):
            f[f"d{k:02d}"] = np.zeros(2)
    with pytest.raises(IngestionError) as exc:
        read_recording([path])
    assert exc.value.code == "opal.not_apdm"
    for lang in ("es", "en", "pt"):
        text = exc.value.message(lang)
        assert len(text) < 600 and "a" * 39 + "…, d00, d01" in text and "a" * 41 not in text, text
        assert "d06, …" in text and "d07" not in text, text
