"""Every real file in ``../shared/data`` (``metabase``, ``iez``) is read or refused for the right reason, through
both the command line (``chakamo process``, in Spanish) and the web API (upload, then the session's check in every
language) — issue 14's first goal.  Skipped cleanly when the data is absent (a clone without ``../shared``).

Truth: the data's READMEs.  The three MetaBase exports are one sensor each, of no knee protocol, made on three
days (2019, 2020 and 2021; the 2019 and 2020 ones by one sensor, MAC F1E55E2FE95F, renamed "Werable1" by its
user): as a session each is refused for its missing second sensor, and any two of them for sharing no time.
The iez walks are raw int16 counts without a header (an MPU-6050 logger's own layout, no format ChakaMo reads):
refused, naming the file as not of a format ChakaMo reads.  The BROAD trials are HDF5 files of the dataset's own
layout (``imu_acc``, ``opt_quat``…, no ``/Sensors``): refused by the command line as HDF5 that is not an APDM Opal
recording, naming what they hold (they were asked to be "exported again from Mobility Lab", as an old APDM file
would be); the web upload takes no HDF5 file at all (415, ``request.file_type``, naming the file).  Each MetaBase recording itself is read
(acc, gyro 100 Hz, magnetometer 20 Hz, the MAC from its name)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from app.pipeline.ingestion import read_recording

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
META, IEZ, BROAD = DATA / "metabase", DATA / "iez", DATA / "broad"
pytestmark = pytest.mark.skipif(not (META.is_dir() and IEZ.is_dir()), reason="../shared/data is absent")


def _recordings() -> dict[str, list[Path]]:
    """The MetaBase exports by recording (label + start), their streams (Pressure too: it must be ignored)."""
    out: dict[str, list[Path]] = {}
    for p in sorted(META.glob("*.csv")):
        parts = p.name.split("_")
        out.setdefault(f"{parts[0]}_{parts[2][:10]}", []).append(p)
    return out


def _imu(files: list[Path]) -> list[str]:
    return [p.name for p in files if "Pressure" not in p.name]


def _cases() -> list[tuple[str, list[Path], dict | None, str, str]]:
    """``(name, files, session.json or None, expected code, a file the message must name)``."""
    if not META.is_dir():
        return []
    recs = _recordings()
    keys = sorted(recs)
    cases = []
    for k in keys:   # as exported: no segment or role in the names
        cases.append((f"{k}-as-is", recs[k], None, "session.no_sensor", _imu(recs[k])[0]))
        cases.append((f"{k}-as-thigh-task", recs[k], {"recordings": [{"files": _imu(recs[k]), "segment": "thigh",
                                                                      "role": "task"}]},
                      "session.one_sensor", ""))
    for a, b in ((keys[0], keys[1]), (keys[0], keys[2])):   # two sensors' "task" made on different days
        manifest = {"recordings": [{"files": _imu(recs[a]), "segment": "thigh", "role": "task"},
                                   {"files": _imu(recs[b]), "segment": "shank", "role": "task"}]}
        cases.append((f"{a}+{b}", recs[a] + recs[b], manifest, "align.no_overlap_pair", _imu(recs[a])[0]))
    cases.append(("metabase-all", sorted(META.glob("*.csv")), None, "session.no_sensor", ""))
    for p in sorted(IEZ.glob("*.csv")):
        cases.append((p.stem, [p], None, "session.no_recordings", p.name))
    for p in sorted(BROAD.glob("*.hdf5")):   # one IMU and optical truth in BROAD's own HDF5 layout, not APDM's
        cases.append((p.stem, [p], None, "opal.not_apdm", p.name))
    return cases


CASES = _cases()


def _folder(tmp_path: Path, files: list[Path], manifest: dict | None) -> Path:
    folder = tmp_path / "session"
    folder.mkdir(parents=True)
    for p in files:
        shutil.copy(p, folder / p.name)
    if manifest is not None:
        (folder / "session.json").write_text(json.dumps(manifest), encoding="utf-8")
    return folder


def test_every_real_file_is_in_a_case():
    covered = {p.name for _, files, _, _, _ in CASES for p in files}
    assert covered == {p.name for p in [*META.glob("*.csv"), *IEZ.glob("*.csv"), *BROAD.glob("*.hdf5")]}


@pytest.mark.parametrize("k", sorted(_recordings()) if META.is_dir() else [])
def test_each_metabase_recording_is_read(k):
    rec = read_recording([META / n for n in _imu(_recordings()[k])])
    assert [round(s.fs_hz) for s in rec.streams] == [100, 100, 20]
    assert rec.sensor_id in ("F1E55E2FE95F", "EB942CED9472")


@pytest.mark.parametrize("name,files,manifest,code,names", CASES, ids=[c[0] for c in CASES])
def test_the_command_line_refuses_it_for_the_right_reason(tmp_path, name, files, manifest, code, names):
    folder = _folder(tmp_path, files, manifest)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    chakamo = "import sys; from app.cli import console; sys.argv[0] = 'chakamo'; console()"
    run = subprocess.run([sys.executable, "-c", chakamo, "process", str(folder), "--out", str(tmp_path / "out"),
                          "--lang", "es"], capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode != 0 and not (tmp_path / "out" / "results.json").exists()
    error = run.stderr.strip().splitlines()[-1]
    key = {"session.no_sensor": "no se encontró ningún sensor", "session.one_sensor": "solo se encontró el sensor",
           "align.no_overlap_pair": "se solapan solo", "session.no_recordings": "no se encontró ninguna grabación",
           "opal.not_apdm": "un archivo HDF5 que no es una grabación de APDM Opal"}
    assert key[code] in error and names in error, error


@pytest.mark.parametrize("name,files,manifest,code,names", CASES, ids=[c[0] for c in CASES])
def test_the_api_refuses_it_for_the_right_reason(tmp_path, name, files, manifest, code, names):
    from fastapi.testclient import TestClient

    sys.path.insert(0, str(Path(__file__).resolve().parent / "web"))
    from web_helpers import clinic_token, make_settings, new_session

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "Real")
    upload = [("files", (p.name, p.read_bytes(), "text/csv" if p.suffix == ".csv" else "application/x-hdf5"))
              for p in files]
    if manifest is not None:
        upload.append(("files", ("session.json", json.dumps(manifest).encode(), "application/json")))
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
        r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=upload)
        if code == "opal.not_apdm":   # the web upload takes no HDF5 at all (APDM's .h5 is read by the command line)
            assert r.status_code == 415 and r.json()["code"] == "request.file_type", r.text
            assert all(names in text and ".hdf5" in text for text in r.json()["message"].values())
            return
        assert r.status_code == 201, r.text
        ingestion = c.get(f"/api/v1/sessions/{sid}", headers=h).json()["ingestion"]
        stored = c.get(f"/api/v1/sessions/{sid}", headers=h).json()["recordings"]
    assert ingestion["ok"] is False, ingestion
    assert names in ingestion["error"]
    assert set(ingestion["error_message"]) == {"es", "en", "pt"}
    assert ingestion["error_message"]["en"] == ingestion["error"] != ingestion["error_message"]["es"]
    from app.pipeline.ingestion import IngestionError  # the same refusal the command line gave, by its code
    with pytest.raises(IngestionError) as exc:
        from app.pipeline.ingestion import load_session

        load_session(_folder(tmp_path / "cli", files, manifest))
    assert exc.value.code == code
    assert exc.value.message("es").split(": ", 1)[-1][:40] in ingestion["error_message"]["es"]
    # the MetaBase files keep the sensor's MAC on the server
    assert {r["device"] for r in stored if r["file_name"].startswith(("1_", "260_"))} <= {"F1E55E2FE95F", "EB942CED9472"}
