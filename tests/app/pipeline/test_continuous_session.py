"""A session of one continuous recording per sensor (issue 14 §3a): split, processed, reported.

Truth: the simulator's protocol parts joined with transitions (:func:`estimators.simulation.protocol.join`) at
known times, the step-up's true knee angles; real MetaBase exports from ``../shared/data`` when present."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from estimators import simulation as sim
from estimators.simulation.protocol import leg_protocol

from app.pipeline.ingestion import IngestionError, load_session, read_recording, simulated_streams
from app.pipeline.ingestion.metabase import write_recording_metabase
from app.pipeline.ingestion.split import split_recording
from app.pipeline.process import process_folder

EPOCH0_S = 1_678_700_000.0
MACS = {"thigh": "D4F1A2B3C4E5", "shank": "E8C2B1A0F9D7"}
REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "metabase"


def _continuous(seed: int = 0, n_cycles: int = 6):
    """Both sensors' continuous protocol (streams on the phone clock), the task motion and the truth spans (s
    from EPOCH0_S)."""
    motion = sim.step_up(n_cycles, 0.17, "right", seed=seed)
    streams, truth = {}, {}
    for i, seg in enumerate(("thigh", "shank")):
        mount = sim.random_rotation(np.deg2rad(15.0), seed * 10 + i)
        traj, truth[seg] = leg_protocol(motion, seg, mount, figure_eight_seed=seed + i)
        imu = sim.simulate(traj, sim.ImuSpec.random(seed * 10 + i), seed=seed * 100 + i)
        streams[seg] = simulated_streams(imu, EPOCH0_S)
    return streams, motion, truth


@pytest.fixture(scope="module")
def continuous():
    return _continuous()


def _write(folder: Path, streams: dict, word: str = "continuo") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for seg, s in streams.items():
        label = f"{word}-{'muslo' if seg == 'thigh' else 'pierna'}-ML1-13032023-1".lstrip("-")
        write_recording_metabase(folder, label, MACS[seg], s)
    (folder / "session.json").write_text(json.dumps({"side": "right"}), encoding="utf-8")
    return folder


def test_the_session_is_split_where_the_truth_says(tmp_path, continuous):
    streams, _, truth = continuous
    session = load_session(_write(tmp_path / "s", streams))
    assert sorted(session.recordings) == sorted((seg, role) for seg in ("thigh", "shank")
                                                for role in ("mag_calibration", "standing", "lying", "task"))
    assert {s.segment for s in session.splits} == {"thigh", "shank"}
    for split in session.splits:
        assert split.how == "role"
        for part, (a, b) in truth[split.segment].items():
            # spans count from the recording's first common sample: the simulated streams start within ms of it
            got_a, got_b = split.spans_s[part]
            assert abs(got_a - a) < 1.0, (split.segment, part, got_a, a)
            if part != "task":
                assert abs(got_b - b) < 1.0, (split.segment, part, got_b, b)
        assert session.recording(split.segment, "standing").source["role"].startswith("standing (from split")
    notes = [n for n in session.notes if getattr(n, "params", {}).get("variant") == "recording_split"]
    assert len(notes) == 2
    for lang, word in (("es", "dividida"), ("en", "split into"), ("pt", "dividida")):
        assert word in notes[0].message(lang)


def test_processed_like_four_recordings_and_written_to_results(tmp_path, continuous):
    streams, motion, truth = continuous
    outcome, _ = process_folder(_write(tmp_path / "s", streams), tmp_path / "out", reports=False)
    results = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    split = results["session"]["split"]
    assert set(split) == {"thigh", "shank"} and set(split["thigh"]["spans_s"]) == set(truth["thigh"])
    assert results["calibration"]["protocol"]["segment"] == "static"
    assert results["calibration"]["protocol"]["magnetometer"] == ["ellipsoid"]
    assert any(w["params"].get("variant") == "recording_split" for w in results["quality"]["technical_notes"])
    assert results["cycles"]["accepted"] == len(motion.cycles_s)
    # the knee angles against the truth: the task grid on the phone clock → the motion's own time
    t_motion = outcome.t0_s + outcome.t_s - EPOCH0_S - truth["thigh"]["task"][0]
    inside = (t_motion > motion.t_s[0]) & (t_motion < motion.t_s[-1])
    true_flex = np.rad2deg(motion.knee_angles_at(t_motion[inside])[:, 0])
    rmse = np.sqrt(np.nanmean((np.rad2deg(outcome.angles_rad[inside, 0]) - true_flex) ** 2))
    assert rmse < 3.0, rmse


def test_one_roleless_recording_per_sensor_is_split_too(tmp_path, continuous):
    streams, _, _ = continuous
    session = load_session(_write(tmp_path / "s", streams, word=""))
    assert {s.how for s in session.splits} == {"only recording"}
    assert ("shank", "lying") in session.recordings


def test_without_the_postures_the_refusal_says_what_it_found(tmp_path, continuous):
    streams, _, truth = continuous
    end = EPOCH0_S + truth["thigh"]["lying"][0]
    cut = {seg: {k: (t[t < end], v[t < end]) for k, (t, v) in s.items()} for seg, s in streams.items()}
    with pytest.raises(IngestionError) as err:
        load_session(_write(tmp_path / "s", cut))
    assert err.value.code == "split.no_posture"
    assert "continuo-pierna" in str(err.value) and "lying" in str(err.value)  # the shank is split first
    assert "supina" in err.value.message("es") or "tumbado" in err.value.message("es")
    assert "deitado" in err.value.message("pt")


@pytest.mark.skipif(not REAL.is_dir(), reason="../shared/data/metabase is absent")
def test_a_real_metabase_export_that_is_no_protocol_is_refused_for_that_reason():
    """The real exports are one sensor each and no knee protocol (their README): labelled continuous, the split
    must refuse them naming the posture it could not find, never crash or invent one."""
    files = sorted(REAL.glob("1_MetaWear_2021-10-29T10.18.39.911_EB942CED9472_*Hz_1.5.1.csv"))
    files = [f for f in files if any(k in f.name for k in ("Accelerometer", "Gyroscope", "Magnetometer"))]
    assert len(files) == 3
    rec = read_recording(files)
    try:
        parts, split, _ = split_recording(rec, "thigh", None, "role")
    except IngestionError as exc:
        assert exc.code == "split.no_posture" and files[0].name in str(exc)
    else:  # if it does split, each part is where the data say: postures still, the task after them
        assert split.spans_s["standing"][1] <= split.spans_s["lying"][0] <= split.spans_s["task"][0]


def test_the_web_upload_takes_the_continuous_role_and_its_check_shows_the_split(tmp_path, continuous):
    """Uploaded with ``role=continuous`` (the API's form field), the session's ingestion check splits it."""
    pytest.importorskip("fastapi")
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "web"))
    from fastapi.testclient import TestClient
    from web_helpers import clinic_token, make_settings, new_session

    from app.web.main import create_app

    streams, _, _ = continuous
    folder = _write(tmp_path / "files", streams, word="")   # no role word in the names: the form field says it
    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "C")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
        for seg in ("thigh", "shank"):
            word = "muslo" if seg == "thigh" else "pierna"
            files = [("files", (p.name, p.read_bytes(), "text/csv")) for p in sorted(folder.glob(f"{word}-*.csv"))]
            r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files,
                       data={"segment": seg, "role": "continuous"})
            assert r.status_code == 201, r.text
        ingestion = r.json()["ingestion"]
    assert ingestion["ok"] is True, ingestion
    assert sum("one continuous recording, split into" in m for m in ingestion["messages"]) == 2
    assert any(m.startswith("thigh lying:") for m in ingestion["messages"])


def test_session_json_moves_a_cut(tmp_path, continuous):
    """The clinician's correction: ``split`` in session.json replaces the automatic span of the roles it names."""
    streams, _, truth = continuous
    folder = _write(tmp_path / "s", streams)
    a, b = truth["thigh"]["standing"]
    moved = [round(a + 5.0, 1), round(b - 5.0, 1)]
    (folder / "session.json").write_text(json.dumps({"side": "right", "split": {"thigh": {"standing": moved}}}))
    session = load_session(folder)
    thigh = next(s for s in session.splits if s.segment == "thigh")
    shank = next(s for s in session.splits if s.segment == "shank")
    assert thigh.how == "session.json" and shank.how == "role"
    assert list(thigh.spans_s["standing"]) == moved
    assert abs(thigh.spans_s["lying"][0] - truth["thigh"]["lying"][0]) < 1.0     # the others stay automatic
    assert abs(session.recording("thigh", "standing").duration_s - (moved[1] - moved[0])) < 0.05


@pytest.mark.parametrize("split", [{"thigh": {"standing": [30, 10]}}, {"thigh": {"sitting": [1, 2]}},
                                   {"knee": {"standing": [1, 2]}}, {"thigh": {"standing": "65-95"}}])
def test_a_malformed_split_in_session_json_is_refused(tmp_path, continuous, split):
    streams, _, _ = continuous
    folder = _write(tmp_path / "s", streams)
    (folder / "session.json").write_text(json.dumps({"side": "right", "split": split}))
    with pytest.raises(IngestionError) as err:
        load_session(folder)
    assert err.value.code == "manifest.bad_split" and "session.json" in str(err.value)
    assert "segundos desde" in err.value.message("es")
