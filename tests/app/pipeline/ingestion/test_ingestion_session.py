"""load_session end to end on simulated sessions: MetaBase (3 languages, both dialects), Excel, generic, manifest."""

import copy
import json
import pickle

import numpy as np
import pytest

from app.pipeline.ingestion import (ROLES, SEGMENTS, load_session, session_label, write_generic_csv, write_session_metabase,
                           write_thesis_xlsx)
from app.pipeline.ingestion.writers import DEFAULT_MACS


def _check_complete(session):
    assert set(session.recordings) == {(s, r) for s in SEGMENTS for r in ROLES}
    for (seg, role), rec in session.recordings.items():
        assert rec.segment == seg and rec.role == role and rec.fs_hz == 100.0
        assert rec.acc.shape == rec.gyr.shape == rec.mag.shape == (len(rec.t_s), 3)
        assert 9.0 < np.median(np.linalg.norm(rec.acc, axis=1)) < 10.7        # m/s²
        assert 30.0 < np.median(np.linalg.norm(rec.mag, axis=1)) < 70.0       # µT
    thigh, shank = session.task_pair()
    assert np.array_equal(thigh.t_s, shank.t_s) and thigh.t0_s == shank.t0_s


@pytest.mark.parametrize("lang,dialect,sep", [("es", "epoch", ":"), ("en", "epoc", "."), ("pt", "epoch", ".")])
def test_metabase_session_in_three_languages(tmp_path, sim_session, lang, dialect, sep):
    streams, _ = sim_session
    write_session_metabase(tmp_path, streams, patient_id="ML1", lang=lang, dialect=dialect, time_sep=sep,
                           high_step=(lang == "en"))
    s = load_session(tmp_path)
    _check_complete(s)
    task = s.recording("thigh", "task")
    assert task.source["format"] == "metabase" and "MetaBase label" in task.source["role"]
    assert len(task.source["files"]) == 3
    assert s.metadata.value("patient_id") == "ML1"
    assert s.metadata.value("step_height_m") == (0.34 if lang == "en" else 0.17)
    assert s.metadata.value("side") is None and s.manifest is None
    assert s.task[1].flags["pair_rate_ratio"] == pytest.approx(1 / 1.008, rel=5e-4)   # shank clock 0.8 % fast
    # the pair's clock-drift note reaches the user, once
    (drift,) = [n for n in s.notes if getattr(n, "params", {}).get("variant") == "clock_drift"]
    assert drift.startswith("shank task: ") and drift.params["pct"] == pytest.approx(-0.79, abs=0.02)


def test_manifest_maps_sensors_and_gives_side(tmp_path, sim_session):
    """Labels without the segment (thesis 'tipo-ID-#' labels): the manifest's MAC map decides."""
    streams, _ = sim_session
    from app.pipeline.ingestion.metabase import write_recording_metabase
    words = {"mag_calibration": "calibracion", "standing": "standing", "lying": "laydown", "task": "step"}
    for (seg, role), st in streams.items():
        write_recording_metabase(tmp_path, f"{words[role]}-ML-1", DEFAULT_MACS[seg], st)
    with pytest.raises(Exception, match="no sensor found"):
        load_session(tmp_path)
    (tmp_path / "session.json").write_text(json.dumps(
        {"side": "izquierda", "step_height_m": 0.34, "patient_id": "ML",
         "sensors": {DEFAULT_MACS["thigh"]: "muslo", DEFAULT_MACS["shank"].lower(): "shank"}}))
    s = load_session(tmp_path)
    _check_complete(s)
    assert s.metadata.side.value == "left" and s.metadata.side.method == "session.json"
    assert s.metadata.value("step_height_m") == 0.34
    assert "session.json" in s.recording("shank", "lying").source["segment"]


def test_manifest_lists_recordings_with_any_names(tmp_path, sim_session):
    streams, _ = sim_session
    entries = []
    for i, ((seg, role), st) in enumerate(streams.items()):
        p = write_generic_csv(tmp_path / f"rec{i}.csv", st["acc"], st["gyr"], st["mag"])
        entries.append({"files": [p.name], "segment": {"thigh": "coxa", "shank": "pierna"}[seg],
                        "role": {"mag_calibration": "calibration", "standing": "de pie", "lying": "deitado",
                                 "task": "task"}[role]})
    (tmp_path / "session.json").write_text(json.dumps({"recordings": entries}, ensure_ascii=False))
    s = load_session(tmp_path)
    _check_complete(s)
    r = s.recording("thigh", "standing")
    assert r.source["format"] == "generic-csv" and "recordings[" in r.source["role"]
    assert r.time_base == "elapsed"          # generic CSV with seconds: no common clock


@pytest.mark.parametrize("name", ["../outside.csv", "/etc/hostname", "sub/../../outside.csv"])
def test_manifest_may_not_name_files_outside_the_folder(tmp_path, name):
    (tmp_path / "outside.csv").write_text("a,b\n1,2\n")
    folder = tmp_path / "session"
    folder.mkdir()
    (folder / "session.json").write_text(json.dumps({"recordings": [{"files": [name]}]}))
    with pytest.raises(ValueError, match="not a file inside the session folder"):
        load_session(folder)


def test_thesis_excel_session(tmp_path, sim_session):
    streams, _ = sim_session
    words = {"mag_calibration": "calibracion-sensor", "standing": "standing", "lying": "laydown", "task": "step"}
    for (seg, role), st in streams.items():
        n = len(st["acc"][0])
        name = f"{words[role]}-{ {'thigh': 'muslo', 'shank': 'pierna'}[seg]}-ML1-13032023-1" + \
            ("-H" if role == "task" else "") + ".xlsx"
        write_thesis_xlsx(tmp_path / name, st["acc"], st["gyr"][1][:n], st["mag"],
                          extra_sheets=("Hoja2",) if role == "standing" else ())
    s = load_session(tmp_path)
    _check_complete(s)
    assert s.metadata.value("step_height_m") == 0.34 and s.metadata.value("date") == "2023-03-13"
    assert s.recording("thigh", "task").source["format"] == "thesis-xlsx"
    assert any("sheet 'data' of" in n for n in s.notes)
    assert all("assumed to start together" in " ".join(r.flags["notes"]) for r in s.recordings.values())


def test_session_label_round_trips_through_recognition():
    from app.pipeline.ingestion.labels import recognise_role, recognise_segment
    for lang in ("es", "en", "pt"):
        for seg in SEGMENTS:
            for role in ROLES:
                label = session_label(seg, role, "P7", "01022024", lang=lang)
                assert recognise_role(label).value == role and recognise_segment(label).value == seg


def test_demo_style_session_with_a_stream_running_on(tmp_path):
    """simulated_streams → write_session_metabase → load_session: the gyroscope's extra 1.5 s is cut and noted."""
    from estimators import simulation as sim
    from app.pipeline.ingestion import simulated_streams
    leg = sim.step_up(n_cycles=1, step_height_m=0.17, side="left", seed=3)
    recs = {}
    for j, seg in enumerate(SEGMENTS):
        clock = sim.ClockSpec.metamotion()
        for role, traj in (("mag_calibration", sim.figure_eight(8.0, seed=j)), ("standing", sim.standing(3.0).thigh),
                           ("lying", sim.supine(3.0).thigh), ("task", getattr(leg, seg))):
            imu = sim.simulate(traj, sim.ImuSpec.random(j, clock), seed=j)
            recs[(seg, role)] = simulated_streams(imu, 1.7e9, run_on_s={"gyr": 1.5} if role == "task" else None)
    write_session_metabase(tmp_path, recs, manifest={"side": "left"})
    s = load_session(tmp_path)
    thigh, shank = s.task_pair()
    assert any("gyr ran on 1.5" in n for n in thigh.flags["notes"])
    # the session's note names segment and role, in the sentence and in the params the reports translate
    (note,) = [n for n in s.notes if n.startswith("thigh task: gyr ran on")]
    assert note.params["seconds"] == pytest.approx(1.5, abs=0.05) and f"{note.params['seconds']:.2f} s" in note
    assert {k: note.params[k] for k in ("variant", "stream", "segment", "role")} == {
        "variant": "stream_cut_after", "stream": "gyr", "segment": "thigh", "role": "task"}
    for clone in (pickle.loads(pickle.dumps(note)), copy.deepcopy(note)):
        assert clone == note and clone.params == note.params
    assert s.metadata.value("side") == "left" and len(s.recordings) == 8
