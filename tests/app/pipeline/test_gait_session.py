"""A walking session through the whole pipeline (issue 15 §1 contract): ``chakamo process DIR --task gait`` on a folder
that holds only the two task recordings (factory-calibrated sensors: no figure-eight, no postures), simulated by
``estimators.simulation.gait`` (Winter/Perry normative curves, heel strikes, soft-tissue wobble, sensor errors,
12° mounting misalignment, 2 s standing before the walk); scored against the simulator's truth."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from app.cli.main import main
from app.pipeline.demo import EPOCH0_S, SimulatedSession, accuracy, write_session
from app.pipeline.ingestion import load_session, simulated_streams
from app.pipeline.session import ProcessOptions, process_session
from estimators import simulation as sim
from estimators.simulation import gait


def _walk_session(seed: int, side: str) -> SimulatedSession:
    leg = gait.walking(14.0, standing_start_s=2.0, seed=seed).leg(side)
    mounts = [sim.random_rotation(np.deg2rad(12.0), seed * 10 + i) for i in range(2)]
    specs = [replace(sim.ImuSpec.random(seed * 10 + i), mag=sim.MagErrors.noise_only()) for i in range(2)]  # factory
    imu_t, imu_s = gait.simulate_leg(leg, *specs, q_thigh_sensor=mounts[0], q_shank_sensor=mounts[1], seed=seed)
    epoch = EPOCH0_S + 300.0
    recs = {("thigh", "task"): simulated_streams(imu_t, epoch), ("shank", "task"): simulated_streams(imu_s, epoch)}
    return SimulatedSession(recs, leg.motion, {"task": epoch}, side, None)


def test_a_task_only_walking_session_through_the_cli(tmp_path, capsys):
    truth = _walk_session(1, "right")
    write_session(tmp_path / "session", truth)
    assert main(["process", str(tmp_path / "session"), "--out", str(tmp_path / "out"), "--task", "gait",
                 "--lang", "pt"]) == 0
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    assert r["task"] == "gait" and r["calibration"]["protocol"]["segment"] == "task_functional"
    assert r["calibration"]["protocol"]["magnetometer"] == ["factory"]
    n_true = len(truth.motion.cycles_s)
    assert n_true - 1 <= r["cycles"]["accepted"] <= r["cycles"]["detected"] <= n_true + 1
    p = r["gait"]["parameters"]
    assert set(p) >= {"loading_response_peak_flexion_deg", "stance_min_flexion_deg", "swing_peak_flexion_deg",
                      "flexion_rom_deg", "swing_peak_timing_pct", "stance_pct", "swing_pct", "stride_time_s",
                      "cadence_steps_min"}
    assert 50.0 < p["swing_peak_flexion_deg"]["mean"] < 70.0 and 55.0 < p["stance_pct"]["mean"] < 65.0
    assert p["cadence_steps_min"]["mean"] == pytest.approx(110.0, abs=5.0)
    ref = r["reference"]  # the normative band (estimators.motor_task.reference), compared with the same means
    assert ref["kind"] == "normative" and "Perry" in ref["source"] and set(ref["parameters"]) <= set(p)
    for name, band in ref["parameters"].items():
        assert band["value"] == pytest.approx(p[name]["mean"])
        flagged = name in ("flexion_rom_deg", "swing_peak_timing_pct", "stance_pct")  # independent of the zero
        assert band["within_band"] == ((band["low"] <= band["value"] <= band["high"]) if flagged else None), name
    # the walker stands at 2°: its normal stance minimum reads below 3–5° and is shown, not flagged "L"
    assert ref["parameters"]["stance_min_flexion_deg"]["interpretation"] is None and ref["outside"] == []
    npz = np.load(tmp_path / "out" / "timeseries.npz")
    assert npz["angles_deg"].shape == (len(npz["t_s"]), 3)
    assert (tmp_path / "out" / "report.pdf").stat().st_size > 10_000


@pytest.mark.parametrize("seed, side", [(2, "left"), (3, "right")])
def test_walking_flexion_from_the_task_alone_against_the_truth(tmp_path, seed, side):
    truth = _walk_session(seed, side)
    write_session(tmp_path / "session", truth)
    outcome = process_session(load_session(tmp_path / "session"), ProcessOptions(task="gait"))
    acc = accuracy(outcome, truth)
    # the task-only calibration on gait: flexion offset ≤ 3° (estimators/functional.py), so RMSE a few degrees
    assert acc["rmse_deg"]["flexion"] <= 3.0 and acc["rmse_deg"]["adduction"] <= 3.5, acc
