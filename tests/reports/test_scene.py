"""3D knee scene: live viser scene, recorded .viser export, and the `chakamo view` loader.

Servers bind to 127.0.0.1 on a free port (port 0) and are stopped; nothing leaves the machine.
"""

from __future__ import annotations

import contextlib
import io
import json
import threading
import time

import numpy as np
import pytest

from estimators import quaternion as quat
from reports import scene
from reports.model import Patient, ReportInput

viser = pytest.importorskip("viser")

EVENTS = ["onset", "countermovement_peak", "far_reached", "far_left", "rest_reached"]


def make_input(side="right", n_cycles=3, fs_hz=100.0, language="en") -> ReportInput:
    """n_cycles step-up-like cycles of 3 s (flexion 60 → 70 → 0 → 60°), 1 s of rest before and after."""
    t = np.arange(0.0, 2.0 + 3.0 * n_cycles, 1.0 / fs_hz)
    phase = np.clip((t - 1.0) / 3.0, 0.0, n_cycles) % 1.0
    flexion = np.interp(phase, [0.0, 0.15, 0.45, 0.7, 1.0], [60.0, 70.0, 0.0, 0.0, 60.0])
    heading = np.deg2rad(40.0 + 10.0 * np.sin(0.5 * t))
    z = np.array([0.0, 0.0, 1.0])
    q_tibia = quat.multiply(quat.from_axis_angle(z, heading),
                            quat.multiply(quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2),
                                          quat.from_axis_angle(z, -np.deg2rad(0.45 * flexion))))
    q_femur = quat.multiply(q_tibia, quat.from_axis_angle(z, np.deg2rad(flexion)))
    angles = np.stack([flexion, 0.1 * flexion, -0.05 * flexion], axis=1)
    bounds = [[1.0 + 3.0 * k, 4.0 + 3.0 * k] for k in range(n_cycles)]
    results = {"side": side, "cycles": {
        "detected": n_cycles, "accepted": n_cycles - 1, "rejected": [{"index": 1, "reason": "test"}],
        "boundaries_s": bounds, "accepted_indices": [k for k in range(n_cycles) if k != 1],
        "events": EVENTS, "events_s": [[b[0], b[0] + 0.45, b[0] + 1.35, b[0] + 2.1, b[1]] for b in bounds]}}
    q_id = np.array([1.0, 0.0, 0.0, 0.0])
    return ReportInput(results=results, t_s=t, angles_deg=angles,
                       q_earth_sensor={"thigh": q_femur.copy(), "shank": q_tibia.copy()},
                       q_earth_segment={"femur": q_femur, "tibia": q_tibia},
                       q_sensor_segment={"thigh": q_id, "shank": q_id}, patient=Patient(side=side),
                       language=language)


@pytest.fixture
def server():
    with contextlib.redirect_stdout(io.StringIO()):
        srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    with contextlib.redirect_stdout(io.StringIO()):
        srv.stop()


def _snapshot(srv):
    return scene.read_scene(srv.get_scene_serializer().serialize())


def test_build_scene_creates_the_named_nodes_and_gui(server):
    ri = make_input()
    knee = scene.build_scene(server, ri)
    names = {m.get("name") for _, m in _snapshot(server)["messages"]}
    assert {"/knee", "/knee/tibia", "/knee/tibia/femur", "/ground"} <= names
    types = {m["name"]: m["type"] for _, m in _snapshot(server)["messages"] if m.get("name") and "props" in m}
    assert types["/knee/tibia"] == "MeshMessage" and types["/knee/tibia/femur"] == "MeshMessage"
    assert knee.nodes.tibia.name == "/knee/tibia" and knee.nodes.femur.name == "/knee/tibia/femur"
    # the femur hangs on the knee: [0, L_tibia, 0] in the tibia frame
    np.testing.assert_allclose(knee.nodes.femur.position, [0.0, knee.data.tibia_length_m, 0.0])
    # jump-to-cycle offers the whole task and the two accepted cycles (1 and 3), in English
    assert knee.cycle.options == ("Whole task", "Cycle 1 (1.0–4.0 s)", "Cycle 3 (7.0–10.0 s)")
    assert [n.label for n in knee.angle_numbers] == ["Flexion + (°)", "Adduction + (°)", "Internal rotation + (°)"]


def test_show_time_drives_the_chain_with_the_segment_orientations(server):
    ri = make_input()
    knee = scene.build_scene(server, ri)
    i = knee.show_time(2.345)
    assert ri.t_s[i] == pytest.approx(2.35)
    q_t, q_f = ri.q_earth_segment["tibia"][i], ri.q_earth_segment["femur"][i]
    np.testing.assert_allclose(knee.nodes.tibia.wxyz, q_t, atol=1e-12)
    # world orientation of the femur node = /knee ⊗ tibia ⊗ femur = heading removal ⊗ q_earth_femur
    q_world_femur = quat.multiply(knee.nodes.knee.wxyz, quat.multiply(knee.nodes.tibia.wxyz, knee.nodes.femur.wxyz))
    assert float(quat.angle_between(q_world_femur, quat.multiply(knee.data.q_view_earth, q_f))) < 1e-9
    assert [n.value for n in knee.angle_numbers] == pytest.approx(np.round(ri.angles_deg[i], 1).tolist())
    # heading removal: the leg faces +x on average
    x = quat.rotate(quat.multiply(knee.data.q_view_earth, ri.q_earth_segment["tibia"]), np.array([1.0, 0, 0]))
    assert np.mean(np.arctan2(x[:, 1], x[:, 0])) == pytest.approx(0.0, abs=0.01)


def test_playback_controls(server):
    ri = make_input()
    knee = scene.build_scene(server, ri)
    knee.step(0.5)                                            # paused: nothing moves
    assert knee.time_s == pytest.approx(0.0)
    knee.play.value = True
    knee.step(0.5)
    assert knee.time_s == pytest.approx(0.5)
    assert knee.time_slider.value == pytest.approx(0.5)
    knee.speed.value = "2"
    knee.step(0.5)
    assert knee.time_s == pytest.approx(1.5)
    knee.cycle.value = "Cycle 3 (7.0–10.0 s)"                 # jump to cycle 3 and loop inside it
    assert knee.time_s == pytest.approx(7.0)
    np.testing.assert_allclose(knee.nodes.tibia.wxyz, ri.q_earth_segment["tibia"][700], atol=1e-12)
    knee.step(1.4)
    assert knee.time_s == pytest.approx(9.8)
    knee.step(1.0)                                            # past the cycle's end: back to its start
    assert knee.time_s == pytest.approx(7.0)
    knee.time_slider.value = 3.0                              # dragging the slider moves the scene
    np.testing.assert_allclose(knee.nodes.tibia.wxyz, ri.q_earth_segment["tibia"][300], atol=1e-12)
    stop = threading.Event()
    runner = threading.Thread(target=knee.run, args=(stop,), kwargs={"fps": 100.0})
    runner.start()
    time.sleep(0.2)
    stop.set()
    runner.join(timeout=5.0)
    assert not runner.is_alive()


def _orientation_frames(recording, name):
    return [(t, np.array(m["wxyz"])) for t, m in recording["messages"]
            if m["type"] == "SetOrientationMessage" and m.get("name") == name]


def test_export_writes_a_recording_with_the_frames_of_the_task(tmp_path):
    ri = make_input()
    path = scene.export_scene(ri, tmp_path / "scene.viser")
    assert path.stat().st_size > 10_000
    rec = scene.read_scene(path)
    assert rec["viserVersion"] == viser.__version__
    data = scene.SceneData.from_report_input(ri)
    idx = data.frame_indices(scene.SCENE_RATE_HZ)
    assert len(idx) == int(round((ri.t_s[-1] - ri.t_s[0]) * scene.SCENE_RATE_HZ)) + 1
    assert rec["durationSeconds"] == pytest.approx(len(idx) / scene.SCENE_RATE_HZ)
    times = [t for t, _ in rec["messages"]]
    assert times == sorted(times)
    created = [m["name"] for t, m in rec["messages"] if t == 0.0 and m["type"] == "MeshMessage"]
    assert created == ["/knee/tibia", "/knee/tibia/femur"]
    # one tibia and one femur orientation per frame where the pose changes, at k / rate, equal to the
    # segment orientations of the task's sample nearest to that time
    tibia = _orientation_frames(rec, "/knee/tibia")
    femur = _orientation_frames(rec, "/knee/tibia/femur")
    q_t, q_tf = data.q_earth_tibia[idx], data.q_tibia_femur[idx]
    moving = np.flatnonzero(np.any(~np.isclose(np.diff(q_t, axis=0), 0.0, atol=1e-8), axis=1)) + 1
    assert len(tibia) == 1 + len(moving)                      # + the creation snapshot at t = 0
    for (t, q), k in zip(tibia[1:], moving):
        assert t == pytest.approx(k / scene.SCENE_RATE_HZ)
        np.testing.assert_allclose(q, q_t[k], atol=1e-12)
    moving_f = np.flatnonzero(np.any(~np.isclose(np.diff(q_tf, axis=0), 0.0, atol=1e-8), axis=1)) + 1
    assert len(femur) == 1 + len(moving_f) and len(moving_f) > 0.5 * len(idx)
    for (t, q), k in zip(femur[1:], moving_f):
        assert t == pytest.approx(k / scene.SCENE_RATE_HZ)
        np.testing.assert_allclose(q, q_tf[k], atol=1e-12)
    labels = [m["updates"]["text"] for _, m in rec["messages"] if m["type"] == "SceneNodeUpdateMessage"]
    assert len(labels) >= len(idx) // scene.LABEL_EVERY - 5 and labels[0].startswith("t 0.2 s   Flex ")


def test_fast_recording_equals_the_public_handle_path():
    ri = make_input(n_cycles=1, side="left", language="es")
    data = scene.SceneData.from_report_input(ri)
    recordings = []
    for fast in (True, False):
        with contextlib.redirect_stdout(io.StringIO()):
            srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
        try:
            recordings.append(scene.read_scene(scene._record(srv, data, 20.0, 4, fast=fast).serialize()))
        finally:
            with contextlib.redirect_stdout(io.StringIO()):
                srv.stop()
    fast, public = recordings
    assert fast["durationSeconds"] == public["durationSeconds"]
    assert fast["messages"] == public["messages"]
    assert any("Flex" in str(m) and "," in m["updates"]["text"] for _, m in fast["messages"]
               if m["type"] == "SceneNodeUpdateMessage")           # decimal comma in Spanish


def test_export_binds_only_to_loopback(monkeypatch, tmp_path):
    hosts = []
    real = viser.ViserServer

    def spy(*args, **kwargs):
        hosts.append(kwargs.get("host", args[0] if args else None))
        return real(*args, **kwargs)

    monkeypatch.setattr(viser, "ViserServer", spy)
    scene.export_scene(make_input(n_cycles=1), tmp_path / "s.viser", rate_hz=10.0)
    assert hosts == ["127.0.0.1"]


def test_read_scene_rejects_garbage_and_static_client_is_shipped():
    with pytest.raises(ValueError, match="too short"):
        scene.read_scene(b"abc")
    client = scene.static_client_path()
    assert client.is_file() and client.stat().st_size > 100_000
    html = scene.scene_html(make_input(n_cycles=1), rate_hz=5.0)
    assert "window.__VISER_EMBED_DATA__=" in html


def test_scene_input_is_validated():
    ri = make_input()
    with pytest.raises(ValueError, match="femur"):
        scene.SceneData.from_report_input(ReportInput(
            results=ri.results, t_s=ri.t_s, angles_deg=ri.angles_deg, q_earth_sensor={},
            q_earth_segment={"tibia": ri.q_earth_segment["tibia"]}, q_sensor_segment={}))
    with pytest.raises(ValueError, match="rate_hz"):
        scene.SceneData.from_report_input(ri).frame_indices(0.0)


# ---------------------------------------------------------------- app/pipeline/view.py


def _write_out_dir(path, ri, drop=None):
    path.mkdir(parents=True, exist_ok=True)
    results = dict(ri.results, session={"language": "pt", "patient_id": "P-7", "date": "2024-01-02"})
    (path / "results.json").write_text(json.dumps(results), encoding="utf-8")
    series = {"t_s": ri.t_s, "angles_deg": ri.angles_deg,
              "q_earth_segment_femur": ri.q_earth_segment["femur"],
              "q_earth_segment_tibia": ri.q_earth_segment["tibia"],
              "q_earth_sensor_thigh": ri.q_earth_sensor["thigh"], "q_earth_sensor_shank": ri.q_earth_sensor["shank"],
              "q_sensor_segment_thigh": np.array([1.0, 0, 0, 0]), "q_sensor_segment_shank": np.array([1.0, 0, 0, 0])}
    if drop:
        series.pop(drop)
    np.savez_compressed(path / "timeseries.npz", **series)
    return path


def test_load_view_input_reads_what_process_writes(tmp_path):
    from app.pipeline.view import load_view_input

    ri = make_input(n_cycles=1)
    out = _write_out_dir(tmp_path / "out", ri)
    loaded = load_view_input(out)
    np.testing.assert_array_equal(loaded.t_s, ri.t_s)
    np.testing.assert_array_equal(loaded.angles_deg, ri.angles_deg)
    np.testing.assert_array_equal(loaded.q_earth_segment["femur"], ri.q_earth_segment["femur"])
    np.testing.assert_array_equal(loaded.q_earth_sensor["shank"], ri.q_earth_sensor["shank"])
    assert loaded.language == "pt" and loaded.patient.name_or_id == "P-7" and loaded.patient.side == "right"
    assert load_view_input(out, language="en").language == "en"
    assert loaded.results["cycles"] == ri.results["cycles"]


def test_load_view_input_errors_say_what_to_do(tmp_path):
    from app.pipeline.view import ViewInputError, load_view_input

    with pytest.raises(ViewInputError, match="results.json not found.*chakamo process"):
        load_view_input(tmp_path)
    out = _write_out_dir(tmp_path / "out", make_input(n_cycles=1), drop="q_earth_segment_tibia")
    with pytest.raises(ViewInputError, match="lacks q_earth_segment_tibia"):
        load_view_input(out)
    (out / "results.json").write_text("{not json", encoding="utf-8")
    with pytest.raises(ViewInputError, match="not a readable results file"):
        load_view_input(out)


def test_serve_view_runs_until_stopped(tmp_path):
    from app.pipeline.view import serve_view

    out = _write_out_dir(tmp_path / "out", make_input(n_cycles=1))
    stop = threading.Event()
    errors = []

    def target():
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                serve_view(out, host="127.0.0.1", port=0, stop=stop)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    runner = threading.Thread(target=target)
    runner.start()
    time.sleep(0.5)
    stop.set()
    runner.join(timeout=10.0)
    assert not runner.is_alive() and errors == []
