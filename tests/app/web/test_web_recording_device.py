"""Sensor serials stored with the recordings on the server (issue 14 §4): each uploaded file's MAC from its name,
served with the recording, and the stored devices' provenance check (one sensor on both segments).

Truth: the MACs the project's MetaBase writer put into the names, and the MAC of the real, renamed-device
export in ``../shared/data/metabase`` (its README), when present."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.pipeline.ingestion.metabase import write_recording_metabase
from app.pipeline.ingestion.provenance import check_stored_sensors, sensor_of_file_name

from web_helpers import clinic_token, make_settings, new_session

REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "metabase"
MACS = {"thigh": "D4F1A2B3C4E5", "shank": "E8C2B1A0F9D7"}


def _streams(seconds: float = 3.0):
    t = 1_678_700_000.0 + np.arange(0, seconds, 0.01)
    tm = t[::5]
    rest = np.tile([0.0, 9.81, 0.0], (len(t), 1))
    return {"acc": (t, rest), "gyr": (t, np.zeros((len(t), 3))), "mag": (tm, np.tile([20.0, 0.0, -40.0], (len(tm), 1)))}


@pytest.fixture
def client(tmp_path):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "D")
    with TestClient(create_app(settings)) as c:
        yield c, h


def test_each_file_keeps_the_mac_its_name_carries(client, tmp_path):
    c, h = client
    _, sid = new_session(c, h)
    files = []
    (tmp_path / "f").mkdir()
    for seg, device in (("thigh", "MetaWear"), ("shank", "Werable1")):   # any device name (issue 14 §1)
        files += write_recording_metabase(tmp_path / "f", f"step-{seg}", MACS[seg], _streams())
        if device != "MetaWear":
            files = [p.rename(p.with_name(p.name.replace("_MetaWear_", f"_{device}_"))) if seg in p.name else p
                     for p in files]
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
               files=[("files", (p.name, p.read_bytes(), "text/csv")) for p in files])
    assert r.status_code == 201, r.text
    got = {rec["file_name"]: rec["device"] for rec in r.json()["recordings"]}
    assert len(got) == 6
    for name, device in got.items():
        assert device == MACS["thigh" if "thigh" in name else "shank"], name
    session = c.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert {rec["device"] for rec in session["recordings"]} == set(MACS.values())


def test_a_file_without_a_serial_in_its_name_has_none(client):
    c, h = client
    _, sid = new_session(c, h)
    r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
               files=[("files", ("step-muslo.csv", b"time (s),acc_x (g)\n0,1\n", "text/csv"))])
    assert r.status_code == 201 and r.json()["recordings"][0]["device"] is None


@pytest.mark.skipif(not REAL.is_dir(), reason="../shared/data/metabase is absent")
def test_the_real_renamed_device_export_gives_its_mac():
    names = sorted(p.name for p in REAL.glob("260_Werable1_*_Accelerometer_*.csv"))
    assert names and sensor_of_file_name(names[0]) == "F1E55E2FE95F"


def test_one_stored_device_on_both_segments_is_found():
    rows = [("a_MetaWear_x.csv", "thigh", MACS["thigh"]), ("b.csv", "shank", MACS["thigh"]),
            ("c.csv", "shank", MACS["shank"]), ("d.csv", None, MACS["shank"])]
    (finding,) = check_stored_sensors(rows)
    assert finding.code == "check.sensor_both_segments" and finding.params["sensor"] == MACS["thigh"]
    assert finding.params["thigh_file"] == "a_MetaWear_x.csv" and finding.params["shank_file"] == "b.csv"
    assert all(finding.message(lang) for lang in ("es", "en", "pt"))
    assert check_stored_sensors(rows[2:]) == []


def test_the_wizard_keeps_no_copy_of_the_metabase_name_rule():
    """The browser takes each recording's sensor from the server's ``device`` (one rule, on the server), so no
    MetaBase file-name pattern (which recognised only the device name "MetaWear") is left in the wizard."""
    wizard = (Path(__file__).resolve().parents[3] / "static" / "views" / "wizard.js").read_text(encoding="utf-8")
    assert "_MetaWear_" not in wizard and "Hz(?:" not in wizard
    assert ".device" in wizard


def test_the_session_answers_one_sensor_on_both_segments_in_every_language(client, tmp_path):
    c, h = client
    _, sid = new_session(c, h)
    (tmp_path / "f").mkdir()
    for seg, role in (("thigh", "standing"), ("shank", "task")):   # the thigh's sensor recorded both
        files = write_recording_metabase(tmp_path / "f", f"{role}-{seg}", MACS["thigh"], _streams())
        r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, data={"segment": seg, "role": role},
                   files=[("files", (p.name, p.read_bytes(), "text/csv")) for p in files])
        assert r.status_code == 201, r.text
    (w,) = c.get(f"/api/v1/sessions/{sid}", headers=h).json()["sensor_warnings"]
    assert w["code"] == "check.sensor_both_segments" and w["params"]["sensor"] == MACS["thigh"]
    assert w["params"]["thigh_file"].startswith("standing-thigh") and w["params"]["shank_file"].startswith("task-shank")
    assert set(w["message"]) == {"es", "en", "pt"} and len(set(w["message"].values())) == 3
