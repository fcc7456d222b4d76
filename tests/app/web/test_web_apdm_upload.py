"""APDM Opal ``.h5`` through the web API (issue 14 §2, "every file … through both the CLI and the API").

Truth: the simulator's session (:func:`app.pipeline.demo.simulate_session`), written by the project's own APDM v5
writer (:func:`app.pipeline.ingestion.opal.write_opal`, from the format's public description: ``/Sensors/<id>/
{Accelerometer,Gyroscope,Magnetometer,Time}``, a ``Label 0`` per sensor), one file per protocol recording holding
both sensors, as Mobility Lab exports them.  Uploaded like any recording, the session is checked, processed by the
job runner and finds the simulated cycles.  An HDF5 file of another layout named ``.h5`` is stored, then refused by
the check as not an APDM recording (``opal.not_apdm``, naming the file and what it holds, in es/en/pt); a ``.h5``
that is no HDF5 at all as ``opal.cannot_open``; a dataset declaring more samples than the cap as ``opal.too_large``
before any of it is read."""

from __future__ import annotations

import numpy as np
import pytest

from web_helpers import clinic_token, new_session, wait_job

h5py = pytest.importorskip("h5py")

IDS = {"thigh": "XI-001234", "shank": "XI-001235"}
NAMES = {"mag_calibration": "calibration", "standing": "standing", "lying": "supine", "task": "step"}


def _on_grid(streams):
    """Gyroscope and magnetometer on the accelerometer's times (an Opal samples all three together)."""
    t, acc = streams["acc"]
    out = [t, acc]
    for kind in ("gyr", "mag"):
        tk, v = streams[kind]
        ok = np.isfinite(v).all(axis=1)
        out.append(np.stack([np.interp(t, tk[ok], v[ok, i]) for i in range(3)], axis=1))
    return out


@pytest.fixture(scope="module")
def apdm_session(tmp_path_factory):
    from app.pipeline.demo import simulate_session
    from app.pipeline.ingestion.opal import write_opal

    truth = simulate_session(seed=7, side="right", n_cycles=6)
    folder = tmp_path_factory.mktemp("apdm")
    for role, name in NAMES.items():
        sensors = {}
        for seg in ("thigh", "shank"):
            t, acc, gyr, mag = _on_grid(truth.recordings[(seg, role)])
            sensors[IDS[seg]] = {"label": f"Right {seg.title()}", "rate_hz": 100.0, "t_s": t, "acc": acc,
                                 "gyr": gyr, "mag": mag}
        write_opal(folder / f"{name}-DEMO-001.h5", sensors)
    return folder, truth


def _files(paths):
    return [("files", (p.name, p.read_bytes(), "application/x-hdf5")) for p in paths]


def test_an_apdm_session_is_uploaded_checked_and_processed(client, settings, apdm_session):
    folder, truth = apdm_session
    h = clinic_token(settings, "Opal")
    _, sid = new_session(client, h, external_id="OPAL-1")
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=_files(sorted(folder.glob("*.h5"))))
    assert r.status_code == 201, r.text
    assert r.json()["ingestion"]["ok"] is True, r.json()["ingestion"]
    session = client.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert len(session["recordings"]) == 4
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "en"}, headers=h)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["job_id"], h)
    assert job["status"] == "done", job
    results = client.get(f"/api/v1/sessions/{sid}/results", headers=h).json()
    assert results["cycles"]["detected"] >= 6, results["cycles"]   # the simulated six steps (the demo's checks too)


def _refused(client, settings, path, external_id):
    h = clinic_token(settings, "Opal")
    _, sid = new_session(client, h, external_id=external_id)
    r = client.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=_files([path]))
    assert r.status_code == 201, r.text      # stored: its content is judged by the check, as a CSV's is
    ingestion = r.json()["ingestion"]
    assert ingestion["ok"] is False, ingestion
    return ingestion


def _same_refusal(ingestion, path, code: str) -> None:
    """The server's refusal is the command line's (by its code), in es/en/pt, naming the file."""
    from app.pipeline.ingestion import IngestionError, read_recording

    with pytest.raises(IngestionError) as exc:
        read_recording([path])
    assert exc.value.code == code
    texts = ingestion["error_message"]
    assert set(texts) == {"es", "en", "pt"} and texts["en"] == ingestion["error"] != texts["es"], ingestion
    for lang in ("es", "en", "pt"):
        assert path.name in texts[lang], texts
        assert exc.value.message(lang).split(": ", 1)[-1][:40] in texts[lang], (lang, texts)


def test_a_non_apdm_hdf5_named_h5_is_refused_as_not_apdm(client, settings, tmp_path):
    p = tmp_path / "trial-01.h5"
    with h5py.File(p, "w") as f:   # a dataset's own layout (BROAD-like): no /Sensors, no FileFormatVersion
        f["imu_acc"] = np.zeros((10, 3))
        f["opt_quat"] = np.zeros((10, 4))
    ingestion = _refused(client, settings, p, "H5-OTHER")
    _same_refusal(ingestion, p, "opal.not_apdm")
    assert all("imu_acc, opt_quat" in text for text in ingestion["error_message"].values())


def test_a_h5_that_is_not_hdf5_is_refused_as_unreadable(client, settings, tmp_path):
    p = tmp_path / "step.h5"
    p.write_bytes(b"time,acc_x\n0,1\n")
    _same_refusal(_refused(client, settings, p, "H5-TEXT"), p, "opal.cannot_open")


def test_a_declared_size_beyond_the_cap_is_refused_before_it_is_read(tmp_path, monkeypatch):
    from app.pipeline.ingestion import IngestionError, read_recording
    from app.pipeline.ingestion import opal

    t = 1_678_700_000.0 + np.arange(200) / 100.0
    z = np.zeros((200, 3))
    p = opal.write_opal(tmp_path / "step.h5", {"XI-1": {"label": "Right Thigh", "t_s": t, "acc": z, "gyr": z,
                                                         "mag": z}})
    monkeypatch.setattr(opal, "MAX_SAMPLES", 199)
    with pytest.raises(IngestionError) as exc:
        read_recording([p])
    assert exc.value.code == "opal.too_large" and "/Sensors/XI-1/" in str(exc.value)
    assert all(p.name in exc.value.message(lang) for lang in ("es", "en", "pt"))
