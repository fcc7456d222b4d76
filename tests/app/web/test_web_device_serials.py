"""Sensor serials read from every format that carries one (issue 14 §4), stored with the recordings on the server
and used by its same-sensor check.

Truth: the serial each format's public description puts in the file, written by the project's own writers —
Xsens MT Manager's ``// DeviceId:`` preamble line, Shimmer Consensys's ``Shimmer_XXXX`` column prefix, Sensor
Logger's ``device id`` column of ``Metadata.csv``, a phyphox ``meta/device.csv`` ``uniqueID`` row — and, for the
APDM Opal ``.h5``, the ``/Sensors/<id>`` group name.  A phyphox export with only
``deviceModel`` (a model, not a serial) stores none."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.pipeline.ingestion.phyphox import write_phyphox
from app.pipeline.ingestion.sensorlogger import write_sensorlogger
from app.pipeline.ingestion.shimmer import write_shimmer
from app.pipeline.ingestion.xsens import write_xsens

from web_helpers import clinic_token, make_settings, new_session

EPOCH0_S = 1_678_700_000.0


def _still(seconds: float = 4.0, fs: float = 100.0):
    t = np.arange(0, seconds, 1 / fs)
    acc = np.tile([0.0, 0.0, 9.81], (len(t), 1)) + 0.01 * np.random.default_rng(0).standard_normal((len(t), 3))
    gyr = 0.001 * np.random.default_rng(1).standard_normal((len(t), 3))
    mag = np.tile([20.0, 0.0, -40.0], (len(t), 1))
    return t, acc, gyr, mag


def _xsens(folder: Path, name: str, serial: str) -> Path:
    t, acc, gyr, mag = _still()
    return write_xsens(folder / f"{name}.csv", t, acc, gyr, mag / np.linalg.norm(mag[0]), device_id=serial)


def _shimmer(folder: Path, name: str, serial: str) -> Path:
    t, acc, gyr, mag = _still()
    return write_shimmer(folder / f"{name}.csv", (EPOCH0_S + t) * 1e3, acc, gyr, mag, device=f"Shimmer_{serial}")


def _sensorlogger(folder: Path, name: str, serial: str) -> Path:
    t, acc, gyr, mag = _still()
    te = EPOCH0_S + t
    return write_sensorlogger(folder / f"{name}.zip", {"acc": (te, acc), "gyr": (te, gyr), "mag": (te, mag)},
                              device_id=serial)


def _phyphox(folder: Path, name: str, serial: str | None) -> Path:
    t, acc, gyr, mag = _still()
    return write_phyphox(folder / f"{name}.zip", {"acc": (t, acc), "gyr": (t, gyr), "mag": (t, mag)},
                         epoch0_s=EPOCH0_S, unique_id=serial)


#: format → (writer, the serial it writes for the thigh, for the shank, the serial as read)
FORMATS = {
    "xsens": (_xsens, "00B42D4F", "00B42D50", str.upper),
    "shimmer": (_shimmer, "8A21", "8A22", lambda s: f"Shimmer_{s}"),
    "sensorlogger": (_sensorlogger, "3f2c9a10-0b7e-4c1e-9d0a-5e1b2c3d4e5f", "77aa0c01-1b2c-4d3e-8f40-112233445566",
                     str),
    "phyphox": (_phyphox, "a1b2c3d4e5f60718", "0918f7e6d5c4b3a2", str),
}


@pytest.fixture
def client(tmp_path):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "V")
    with TestClient(create_app(settings)) as c:
        yield c, h


def _upload(c, h, sid, path: Path, segment: str):
    kind = "application/zip" if path.suffix == ".zip" else "text/csv"
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, data={"segment": segment, "role": "task"},
               files=[("files", (path.name, path.read_bytes(), kind))])
    assert r.status_code == 201, r.text
    return r.json()


@pytest.mark.parametrize("fmt", sorted(FORMATS))
def test_the_serial_in_the_file_is_stored_with_its_recording(client, tmp_path, fmt):
    c, h = client
    write, thigh, shank, shown = FORMATS[fmt]
    _, sid = new_session(c, h, external_id=f"S-{fmt}")
    thigh_file = write(tmp_path, "thigh-task", thigh)
    _upload(c, h, sid, thigh_file, "thigh")
    answer = _upload(c, h, sid, write(tmp_path, "shank-task", shank), "shank")
    assert answer["ingestion"]["ok"] is True, answer["ingestion"]
    session = c.get(f"/api/v1/sessions/{sid}", headers=h).json()
    devices = {r["file_name"]: r["device"] for r in session["recordings"]}
    suffix = thigh_file.suffix
    assert devices == {f"thigh-task{suffix}": shown(thigh), f"shank-task{suffix}": shown(shank)}
    assert session["sensor_warnings"] == []


@pytest.mark.parametrize("fmt", sorted(FORMATS))
def test_one_sensor_on_both_segments_is_found_by_the_server(client, tmp_path, fmt):
    c, h = client
    write, thigh, _, shown = FORMATS[fmt]
    _, sid = new_session(c, h, external_id=f"B-{fmt}")
    _upload(c, h, sid, write(tmp_path, "thigh-task", thigh), "thigh")
    _upload(c, h, sid, write(tmp_path, "shank-task", thigh), "shank")   # the same sensor strapped on the shank
    warnings = c.get(f"/api/v1/sessions/{sid}", headers=h).json()["sensor_warnings"]
    assert [w["code"] for w in warnings] == ["check.sensor_both_segments"]
    assert warnings[0]["params"]["sensor"] == shown(thigh)
    assert set(warnings[0]["message"]) == {"es", "en", "pt"}


def test_a_phyphox_export_names_a_model_not_a_serial(client, tmp_path):
    """``deviceModel`` alone ("Pixel 7" on both phones) is no serial: nothing stored, no same-sensor warning."""
    c, h = client
    _, sid = new_session(c, h, external_id="P-model")
    _upload(c, h, sid, _phyphox(tmp_path, "thigh-task", None), "thigh")
    _upload(c, h, sid, _phyphox(tmp_path, "shank-task", None), "shank")
    session = c.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert [r["device"] for r in session["recordings"]] == [None, None]
    assert session["sensor_warnings"] == []


def test_apdm_sensor_ids_are_read_from_the_file(tmp_path):
    pytest.importorskip("h5py")
    from app.pipeline.ingestion import load_session
    from app.pipeline.ingestion.opal import write_opal

    t, acc, gyr, mag = _still()
    sensors = {sid: {"label": label, "rate_hz": 100, "t_s": EPOCH0_S + t, "acc": acc, "gyr": gyr, "mag": mag}
               for sid, label in (("SI-001234", "Right Thigh"), ("SI-005678", "Right Shank"))}
    write_opal(tmp_path / "task.h5", sensors)
    session = load_session(tmp_path)
    ids = {seg: rec.source["sensor_id"] for (seg, _), rec in session.recordings.items()}
    assert ids == {"thigh": "SI-001234", "shank": "SI-005678"}
