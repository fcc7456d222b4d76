"""Every protocol (issue 14 §3) with either calibration option: it completes with angles against the simulator's
truth, or is refused with a translated message — never a crash.  ``--calibration functional`` once reached the
posture protocol's refinement (femur on Seel's flexion axis, tibia zeroed on the *standing* 9D headings) from the
task-only protocol, which has no standing orientations (``TypeError: 'NoneType' object is not subscriptable``), and
from standing + task without a figure-eight, whose standing headings carry the uncalibrated hard iron.

Truth: ``app.pipeline.demo.simulate_session`` (step-ups, hard and soft iron, 12° mountings) for the protocols with
a standing posture, the simulated walk with a 2 s standing start (``estimators.simulation.gait``) for the task alone;
the bounds are those of ``test_protocols.py`` and ``test_task_only_hard_iron.py``.  The posture protocol without a
figure-eight has no calibrated heading for the functional refinement and is refused with what to do."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from app.pipeline.demo import EPOCH0_S, SimulatedSession, accuracy, simulate_session, write_session
from app.pipeline.ingestion import load_session, simulated_streams
from app.pipeline.session import PipelineError, ProcessOptions, process_session
from estimators import quaternion as quat
from estimators import simulation as sim
from estimators.simulation import gait

from test_task_only_hard_iron import _walk  # the same walk (this folder is on sys.path: no packages)

PROTOCOLS = {"full": ("mag_calibration", "standing", "lying", "task"), "no_figure_eight": ("standing", "lying", "task"),
             "no_supine": ("mag_calibration", "standing", "task"), "standing_task": ("standing", "task"),
             "task_only": ("mag_calibration", "task"), "task_only_no_figure_eight": ("task",)}


@pytest.fixture(scope="module")
def step_up():
    return simulate_session(seed=3, side="right", n_cycles=6, accelerometer_errors=False)


@pytest.mark.parametrize("calibration", ["static", "functional"])
@pytest.mark.parametrize("protocol", list(PROTOCOLS))
def test_each_protocol_completes_or_is_refused_in_words(step_up, tmp_path, protocol, calibration):
    keep = PROTOCOLS[protocol]
    if "standing" in keep:
        truth, task = step_up, "step_up"
    else:  # a step-up starts flexed on the step: the task alone needs the walk's standing start
        truth, task = _walk(1, "right")[0], "gait"
        if "mag_calibration" in keep:
            full = simulate_session(seed=1, side="right", n_cycles=1, accelerometer_errors=False)
            truth = replace(truth, recordings={**truth.recordings, **{k: v for k, v in full.recordings.items()
                                                                      if k[1] == "mag_calibration"}})
    truth = replace(truth, recordings={k: v for k, v in truth.recordings.items() if k[1] in keep})
    write_session(tmp_path / "session", truth)
    refused = protocol == "no_figure_eight" and calibration == "functional"
    try:
        outcome = process_session(load_session(tmp_path / "session"), ProcessOptions(task=task, calibration=calibration))
    except PipelineError as exc:
        assert refused, f"{protocol}/{calibration} refused: {exc}"
        assert exc.code == "pipeline.functional_needs_figure_eight"
        for lang, words in (("en", "figure-eight"), ("es", "ocho"), ("pt", "oito")):
            assert words in exc.message(lang) and "{" not in exc.message(lang)
        return
    assert not refused, "the functional calibration ran on the uncalibrated magnetometers' headings"
    acc = accuracy(outcome, truth)
    # the functional femur absorbs the adduction that moves with flexion: ~3.5° on simulated step-ups (session.py)
    max_adduction = 4.0 if calibration == "functional" and protocol == "full" else 3.0
    assert acc["rmse_deg"]["flexion"] <= 3.0 and acc["rmse_deg"]["adduction"] <= max_adduction, acc
    assert acc["rmse_deg"]["internal_rotation"] <= 3.0, acc


@pytest.mark.parametrize("seed", [1, 2])
def test_a_shank_sensor_turned_round_is_named_not_taken_for_a_missing_standing_start(tmp_path, seed):
    """Without a figure-eight the hinge axes' relative sign comes from the mounting rule (both sensors worn alike,
    :mod:`estimators.functional` F2 i).  A shank sensor turned 180° about its long axis breaks it: the walk (with its
    2 s standing start) was refused as "never still while straight; record 2 s of standing still"."""
    leg = gait.walking(14.0, standing_start_s=2.0, seed=seed).leg("right")
    mounts = [sim.random_rotation(np.deg2rad(12.0), seed * 10 + i) for i in range(2)]
    mounts[1] = quat.multiply(quat.from_axis_angle([0.0, 1.0, 0.0], np.pi), mounts[1])  # the shank turned round
    specs = [sim.ImuSpec.random(seed * 10 + i) for i in range(2)]
    imu_t, imu_s = gait.simulate_leg(leg, *specs, q_thigh_sensor=mounts[0], q_shank_sensor=mounts[1], seed=seed)
    epoch = EPOCH0_S + 300.0
    recs = {("thigh", "task"): simulated_streams(imu_t, epoch), ("shank", "task"): simulated_streams(imu_s, epoch)}
    write_session(tmp_path / "session", SimulatedSession(recs, leg.motion, {"task": epoch}, "right", None))
    with pytest.raises(PipelineError) as caught:
        process_session(load_session(tmp_path / "session"), ProcessOptions(task="gait"))
    exc = caught.value
    assert exc.code == "pipeline.sensor_turned_round", exc
    for lang, words in (("en", "not seem to be worn on the same side of the leg"), ("es", "mismo lado de la pierna"),
                        ("pt", "mesmo lado da perna")):
        assert words in exc.message(lang) and "{" not in exc.message(lang), exc.message(lang)


@pytest.mark.parametrize("seed", [11, 12])  # held out: the 30° margin gap was chosen on seeds 1-8
def test_standing_and_task_with_a_shank_turned_round_is_refused_not_reported_48_degrees_off(tmp_path, seed):
    """Standing + task without a figure-eight: the standing reference keeps the overshoot small, so a shank sensor
    turned 180° about its long axis (x and z negated in every stream) went through with ~48° of flexion RMSE.
    Worn alike, the same session completes."""
    truth = simulate_session(seed=seed, side="right", n_cycles=6, accelerometer_errors=False)
    flip = np.array([-1.0, 1.0, -1.0])
    for turned in (False, True):
        recs = {(seg, role): {k: (t, v * flip if turned and seg == "shank" else v) for k, (t, v) in st.items()}
                for (seg, role), st in truth.recordings.items() if role in ("standing", "task")}
        t = replace(truth, recordings=recs)
        write_session(tmp_path / f"s{turned}", t)
        if not turned:
            outcome = process_session(load_session(tmp_path / f"s{turned}"), ProcessOptions())
            assert accuracy(outcome, t)["rmse_deg"]["flexion"] <= 1.0
            continue
        with pytest.raises(PipelineError) as caught:
            process_session(load_session(tmp_path / f"s{turned}"), ProcessOptions())
        assert caught.value.code == "pipeline.sensor_turned_round", caught.value
        assert "mismo lado de la pierna" in caught.value.message("es")
