"""Protocols as clinics record them (issue 14 §3): the pipeline calibrates from whatever recordings the session has
and says which calibration it used; on simulated sessions against the simulator's truth.

(b) no figure-eight (factory-calibrated magnetometers): no ellipsoid fit, noted; (c) no supine: standing + the
task's hinge axes; (d) the task alone: refused when the task never holds the knee straight and still (a step-up that
starts in its flexed start posture), rather than reporting flexion from a flexed reference."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from app.pipeline.demo import accuracy, simulate_session, write_session
from app.pipeline.ingestion import load_session
from app.pipeline.results import build_results
from app.pipeline.session import PipelineError, ProcessOptions, process_session

ALL = ("mag_calibration", "standing", "lying", "task")


@pytest.fixture(scope="module")
def truth():
    return simulate_session(seed=3, side="right", n_cycles=6, accelerometer_errors=False)


def _process(truth, tmp_path, keep):
    t = replace(truth, recordings={k: v for k, v in truth.recordings.items() if k[1] in keep})
    write_session(tmp_path / "session", t)
    return process_session(load_session(tmp_path / "session"), ProcessOptions())  # as process_folder loads it


def test_without_the_figure_eight_the_factory_calibration_is_used_and_said(truth, tmp_path):
    outcome = _process(truth, tmp_path, ("standing", "lying", "task"))
    r = json.loads(json.dumps(build_results(outcome)))
    assert r["calibration"]["protocol"] == {"segment": "static", "magnetometer": ["factory"],
                                            "accelerometer": ["none"], "recordings": ["lying", "standing", "task"]}
    notes = {w["params"].get("variant") for w in r["quality"]["warnings"] if w["code"] == "ingestion_note"}
    assert "no_mag_calibration" in notes, r["quality"]["warnings"]
    # standing and supine alone hold gravity in one plane: the accelerometer bias is not observable, and said so
    acc_notes = [w["params"] for w in r["quality"]["warnings"] if w["code"] == "accelerometer_not_calibrated"]
    assert sorted(p["segment"] for p in acc_notes) == ["shank", "thigh"]
    assert {p["variant"] for p in acc_notes} == {"few_poses"}
    # the simulated sensors carry hard and soft iron, so the raw fields disagree: the hinge heading takes over
    assert r["quality"]["heading"]["used"] == "constraint"
    acc = accuracy(outcome, truth)
    assert acc["rmse_deg"]["flexion"] <= 1.0 and acc["rmse_deg"]["adduction"] <= 2.0, acc
    assert acc["rmse_deg"]["internal_rotation"] <= 2.0 and acc["cycles_found"] == acc["cycles_true"], acc


def test_without_the_supine_posture_the_hinge_axes_calibrate(truth, tmp_path):
    outcome = _process(truth, tmp_path, ("mag_calibration", "standing", "task"))
    assert {cal.method for cal in outcome.segments.values()} == {"standing_functional"}
    assert "no_lying" in {w.params.get("variant") for w in outcome.warnings if w.code == "ingestion_note"}
    r = build_results(outcome)
    assert r["calibration"]["protocol"]["segment"] == "standing_functional"
    assert all(s["supine_window_s"] is None for s in r["calibration"]["segment"].values())  # none was recorded
    acc = accuracy(outcome, truth)
    assert acc["rmse_deg"]["flexion"] <= 1.0 and acc["rmse_deg"]["adduction"] <= 2.0, acc
    assert acc["rmse_deg"]["internal_rotation"] <= 2.0 and acc["cycles_found"] == acc["cycles_true"], acc


@pytest.mark.parametrize("keep", [("mag_calibration", "task"), ("task",)])
def test_a_task_that_never_holds_the_knee_straight_is_refused_with_what_to_record(truth, tmp_path, keep):
    with pytest.raises(PipelineError, match="never held the knee straight and still; record 2 s standing still"):
        _process(truth, tmp_path, keep)


def test_a_posture_recorded_on_one_sensor_only_is_named_not_worked_around(truth, tmp_path):
    from app.pipeline.ingestion import IngestionError

    t = replace(truth, recordings={k: v for k, v in truth.recordings.items() if k != ("shank", "lying")})
    write_session(tmp_path / "session", t)
    with pytest.raises(IngestionError, match="missing recording"):
        load_session(tmp_path / "session")


def test_the_full_protocol_keeps_the_static_calibration(truth, tmp_path):
    outcome = _process(truth, tmp_path, ALL)
    r = build_results(outcome)
    assert r["calibration"]["protocol"]["segment"] == "static"
    assert r["calibration"]["protocol"]["magnetometer"] == ["ellipsoid"]
    assert r["calibration"]["protocol"]["accelerometer"] == ["bias"]


def test_the_accelerometer_bias_is_measured_on_the_protocols_still_poses(tmp_path):
    """The figure-eight's rests, standing and supine hold gravity in three directions: the bias the simulator put
    into each accelerometer is measured (up to the scale error it folds in) and removed before anything else."""
    from estimators import simulation as sim

    seed = 25
    truth = simulate_session(seed=seed, side="left", n_cycles=4)
    outcome = _process(truth, tmp_path, ALL)
    r = json.loads(json.dumps(build_results(outcome)))
    for i, seg in enumerate(("thigh", "shank")):
        b_true = sim.ImuSpec.random(seed * 10 + i).acc.bias_m_s2  # the demo's sensor (app.pipeline.demo)
        cal = r["calibration"]["accelerometer"][seg]
        assert cal["model"] == "bias" and cal["poses"] >= 3 and cal["information"] > 0.5, cal
        err = np.linalg.norm(np.array(cal["bias_m_s2"]) - b_true)
        assert err < 0.5 * np.linalg.norm(b_true), (seg, cal["bias_m_s2"], b_true)
    assert not [w for w in r["quality"]["warnings"] if w["code"] == "accelerometer_not_calibrated"]
