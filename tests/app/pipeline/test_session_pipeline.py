"""The knee session pipeline end to end on simulated sessions with known truth (issue 3 goals)."""

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

from app.cli.main import main
from app.pipeline.demo import accuracy, simulate_session, write_session
from app.pipeline.session import HEADING_DRIFT_TASK_WARN_RAD, PipelineError, ProcessOptions
from app.pipeline.process import process_folder

GOALS_DEG = {"flexion": 1.0, "adduction": 2.0, "internal_rotation": 2.0}


# The goal's conditions (issue 3): noise, gyroscope bias, hard/soft iron, mounting up to 15°, clock drift.
@pytest.fixture(scope="module")
def right_session():
    return simulate_session(seed=3, side="right", n_cycles=6, accelerometer_errors=False)


@pytest.fixture(scope="module")
def left_session():
    return simulate_session(seed=4, side="left", n_cycles=6, accelerometer_errors=False)


def check_goals(outcome, truth):
    acc = accuracy(outcome, truth)
    for angle, limit in GOALS_DEG.items():
        assert acc["rmse_deg"][angle] <= limit, (angle, acc)
    assert acc["cycles_found"] == acc["cycles_true"] == len(truth.motion.cycles_s)
    assert acc["phase_boundary_max_error_pct"] <= 2.0
    return acc


@pytest.mark.parametrize("fmt", ["metabase", "generic", "xlsx"])
def test_every_input_format_meets_the_accuracy_goals(fmt, right_session, tmp_path):
    write_session(tmp_path / "session", right_session, fmt)
    outcome, written = process_folder(tmp_path / "session", tmp_path / "out", reports=False)
    assert [p.name for p in written] == ["results.json", "timeseries.npz"]
    check_goals(outcome, right_session)


def test_left_leg_keeps_clinical_signs(left_session, tmp_path):
    write_session(tmp_path / "session", left_session)
    outcome, _ = process_folder(tmp_path / "session", tmp_path / "out", reports=False)
    assert outcome.side == "left"
    check_goals(outcome, left_session)


def test_realistic_accelerometer_errors_are_calibrated_away(right_session, tmp_path):
    """With accelerometer bias and scale errors too (the demo's sensor) the angles are as accurate as without them
    (within 0.2°): the bias, measured on the protocol's still poses, is removed before calibration and filtering.
    Before that correction the bias tilted each vertical: flexion 0.49°, adduction 0.63° on this session (0.06° and
    0.16° with the correction), and through the magnetic dip rotation."""
    truth = simulate_session(seed=3, side="right", n_cycles=6)
    write_session(tmp_path / "session", truth)
    outcome, _ = process_folder(tmp_path / "session", tmp_path / "out", reports=False)
    assert {c.model for c in outcome.acc.values()} == {"bias"}
    acc = accuracy(outcome, truth)
    write_session(tmp_path / "clean", right_session)  # the same session, accelerometers without bias or scale error
    clean, _ = process_folder(tmp_path / "clean", tmp_path / "out_clean", reports=False)
    ref = accuracy(clean, right_session)
    for angle in ("flexion", "adduction", "internal_rotation"):
        assert acc["rmse_deg"][angle] <= ref["rmse_deg"][angle] + 0.2, (angle, acc, ref)
    # and the goals this test held before the correction, whatever the clean run reads
    assert acc["rmse_deg"]["flexion"] <= 1.0 and acc["rmse_deg"]["adduction"] <= 2.0
    assert acc["rmse_deg"]["internal_rotation"] <= 3.5
    assert acc["cycles_found"] == 6


def test_results_json_follows_the_contract(right_session, tmp_path):
    write_session(tmp_path / "session", right_session)
    assert main(["process", str(tmp_path / "session"), "--out", str(tmp_path / "out"), "--lang", "en"]) == 0
    written = {p.name for p in (tmp_path / "out").iterdir()}
    assert written == {"results.json", "timeseries.npz", "report.pdf", "angles.xlsx", "quaternions.xlsx",
                       "report.html", "scene.viser"}
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    assert r["side"] == "right" and r["task"] == "step_up"
    assert r["filter"]["name"] == "chakamo"
    assert r["angles"] == ["flexion", "adduction", "internal_rotation"]
    assert r["cycles"]["detected"] == 6 and r["cycles"]["accepted"] == 6 and r["cycles"]["rejected"] == []
    assert len(r["cycles"]["boundaries_s"]) == 6
    for angle in r["angles"]:
        assert set(r["rom_deg"][angle]) == {"max", "min", "range"}
        assert set(r["rom_deg"][angle]["range"]) == {"mean", "sd"}
        assert len(r["curves"][angle]["mean"]) == len(r["curves"][angle]["sd"]) == 101
    assert 40.0 < r["rom_deg"]["flexion"]["range"]["mean"] < 100.0  # degrees, not radians
    for phase in ("impulse", "extension", "fall"):
        assert set(r["phases"][phase]) == {"mean_s", "sd_s", "mean_pct", "sd_pct"}
    assert sum(r["phases"][p]["mean_pct"] for p in ("impulse", "extension", "fall")) == pytest.approx(100.0, abs=0.5)
    assert set(r["calibration"]["magnetometer"]) == {"thigh", "shank"}
    assert set(r["calibration"]["segment"]) == {"thigh", "shank"}
    # figure-eight rests, standing, supine: three directions for three bias parameters, so the fit is unchecked
    assert {(a["model"], a["directions"], a["validated"]) for a in r["calibration"]["accelerometer"].values()} == {
        ("bias", 3, False)}
    assert all(set(w) == {"code", "message", "params"} for w in r["quality"]["warnings"])
    assert r["software"]["version"]
    assert r["session"]["language"] == "en"
    # the filter's full parameter set, not only the (empty) overrides
    assert r["filter"]["overrides"] == {}
    assert r["filter"]["params"]["tau_acc_s"] == 3.0 and r["filter"]["params"]["offline"] is True
    # standing and supine gravities about a right angle apart (the postures were distinct)
    for seg in ("thigh", "shank"):
        assert 80.0 < r["calibration"]["segment"][seg]["angle_between_postures_deg"] < 100.0, seg
    # the heading check over the task's full-extension holds ran on every accepted cycle, and found no drift
    heading = r["quality"]["heading_task"]
    assert len(heading["offsets_deg"]) == len(heading["spans_s"]) == 6
    assert heading["change_deg"] < np.rad2deg(HEADING_DRIFT_TASK_WARN_RAD)
    assert "heading_drift" not in {w["code"] for w in r["quality"]["warnings"]}


@pytest.mark.parametrize("seed, side", [(3, "right"), (4, "left")])
def test_functional_calibration_recovers_a_rolled_lying_posture(seed, side, tmp_path):
    """A leg lying rolled 15° outwards spoils the static frames (adduction ~10°, rotation ~5° RMSE); the
    functional option (femur on the task's flexion axis, tibia's rotation zeroed standing) halves the errors
    or better (benchmarks.pipeline_accuracy --supine-roll-out 15 --calibration functional: worst of 10 seeds
    0.3° / 5.2° / 3.2°; seeds where Seel's axis is well posed ≤ 1.7°)."""
    truth = simulate_session(seed=seed, side=side, n_cycles=6, accelerometer_errors=False, supine_roll_out_deg=15.0)
    write_session(tmp_path / "session", truth)
    static, _ = process_folder(tmp_path / "session", tmp_path / "static", reports=False)
    s = accuracy(static, truth)["rmse_deg"]
    assert s["adduction"] > 9.0 and s["internal_rotation"] > 4.5
    assert main(["process", str(tmp_path / "session"), "--out", str(tmp_path / "functional"),
                 "--calibration", "functional"]) == 0
    outcome, _ = process_folder(tmp_path / "session", tmp_path / "again", ProcessOptions(calibration="functional"),
                                reports=False)
    f = accuracy(outcome, truth)["rmse_deg"]
    assert f["flexion"] <= 0.5 and f["adduction"] <= 6.0 and f["internal_rotation"] <= 3.5, f
    assert f["adduction"] < 0.6 * s["adduction"] and f["internal_rotation"] < 0.7 * s["internal_rotation"]
    seg = json.loads((tmp_path / "functional" / "results.json").read_text())["calibration"]["segment"]
    assert seg["thigh"]["method"] == seg["shank"]["method"] == "functional"
    assert 5.0 < seg["thigh"]["axis_change_deg"] < 25.0 and 5.0 < seg["shank"]["axis_change_deg"] < 25.0


def test_warnings_carry_params_and_translate(right_session, tmp_path):
    """A 4 s figure-eight of the thigh (coverage low) and elapsed-time files (no epoch): every warning of
    results.json carries its params, the magnetometer's with the sensor the pipeline put in front, and
    prints in Spanish and Portuguese (reports.warning_text) without falling back to English."""
    from reports.warning_text import warning_text

    recs = dict(right_session.recordings)
    fig8 = recs[("thigh", "mag_calibration")]
    t0 = fig8["acc"][0][0]
    recs[("thigh", "mag_calibration")] = {k: (t[t - t0 < 4.0], v[t - t0 < 4.0]) for k, (t, v) in fig8.items()}
    write_session(tmp_path / "session", replace(right_session, recordings=recs), "generic")
    process_folder(tmp_path / "session", tmp_path / "out", ProcessOptions(calibration="functional"), reports=False)
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    warnings = r["quality"]["warnings"]
    mag = [w for w in warnings if w["code"].startswith("MAG_")]
    assert mag and all(w["message"].startswith("Thigh sensor: ") and w["params"]["segment"] == "thigh" for w in mag)
    notes = r["quality"]["technical_notes"]  # how the files were read: apart from the clinical warnings
    assert all(w["code"] == "ingestion_note" for w in notes)
    # streams without epoch time stamps (assumed to start together) are a clinical warning: the timing is uncertain
    assert not [w for w in notes if w["params"]["variant"] == "no_epoch"]
    no_epoch = [w for w in warnings if w["code"] == "ingestion_note" and w["params"]["variant"] == "no_epoch"]
    assert {(w["params"]["segment"], w["params"]["role"]) for w in no_epoch} \
        == {(s, role) for s in ("thigh", "shank") for role in ("mag_calibration", "standing", "lying", "task")}
    for w in warnings + notes:
        assert isinstance(w["params"], dict), w
        for lang in ("es", "pt"):
            text, translated = warning_text(w, lang, r)
            assert translated and text != w["message"], (lang, w)


def test_calibration_option_is_checked():
    with pytest.raises(PipelineError, match="calibration must be one of static, functional"):
        ProcessOptions(calibration="dynamic")


def test_task_option_is_checked_before_computing():
    from app.choices import TASK_NAMES

    with pytest.raises(PipelineError, match=f"task must be one of {', '.join(TASK_NAMES)}.*'stepup'"):
        ProcessOptions(task="stepup")


def test_heading_option_is_checked():
    with pytest.raises(PipelineError, match="heading must be one of auto, magnetometer, constraint.*'compass'"):
        ProcessOptions(heading="compass")


def test_cli_passes_the_task(right_session, tmp_path, capsys):
    """``--task`` reaches the analysis: a step-up read as a seated extension (also an extension to a hold)
    reports that task's phases; a name not in estimators.motor_task.TASKS is refused by the parser."""
    write_session(tmp_path / "session", right_session)
    assert main(["process", str(tmp_path / "session"), "--out", str(tmp_path / "out"),
                 "--task", "seated_knee_extension"]) == 0
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    assert r["task"] == "seated_knee_extension"
    assert {"extension", "hold", "flexion"} <= set(r["phases"]) and "impulse" not in r["phases"]
    with pytest.raises(SystemExit) as exc:
        main(["process", str(tmp_path / "session"), "--out", str(tmp_path / "bad"), "--task", "jump"])
    assert exc.value.code == 2 and "invalid choice: 'jump'" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_heading_drift_during_the_task_is_warned(tmp_path):
    """The field at the shank turns slowly about the vertical during the task (1.5°/s: a drifting local
    disturbance; norm and dip unchanged, so the magnetic checks stay silent).  With the magnetometer heading
    forced and the plain weighted-mean offline heading, the relative heading of the full-extension holds changes
    by ~9°, above the 5° limit, and ``heading_drift`` (variant ``task``) is warned, translated with its numbers
    (the robust heading (15b) holds one offset instead: no drift, the disagreement warned; with the default offline
    passes' field-measured vertical bias (13a) it follows the turning field: drift warned).  The default (``auto``) sees the
    magnetometers disagree with the knee's hinge constraint, takes the constraint's heading and says so
    (``magnetic_heading_unreliable``), and its rotation is then closer to the truth.  The normal session's
    absence of both is asserted in the contract test."""
    from reports.warning_text import warning_text

    truth = simulate_session(seed=3, side="right", n_cycles=9, accelerometer_errors=False,
                             shank_task_field_turn_rad_s=float(np.deg2rad(1.5)))
    write_session(tmp_path / "session", truth)
    auto, _ = process_folder(tmp_path / "session", tmp_path / "auto", reports=False)
    r_auto = json.loads((tmp_path / "auto" / "results.json").read_text())
    assert r_auto["quality"]["heading"]["mode"] == "auto" and r_auto["quality"]["heading"]["used"] == "constraint"
    assert "magnetic_heading_unreliable" in {w["code"] for w in r_auto["quality"]["warnings"]}
    # the default filter's robust offline heading (chakamo (15b)) holds a steady, still wrong, offset through a
    # field that turns all task long: no drift across the holds, but the disagreement is said.  That holds without
    # the offline passes' field-measured vertical bias (13a): with it, a field turning at a constant rate about the
    # vertical reads, to the field, as a vertical gyroscope bias (this session's 1.5 s rests are too short to pin
    # the bias: rest_min_s), so the heading follows the turning field (18.7° across the holds) and the drift is said
    steady, _ = process_folder(tmp_path / "session", tmp_path / "steady", ProcessOptions(
        heading="magnetometer", filter_params={"offline_mag_bias": False}), reports=False)
    r_steady = json.loads((tmp_path / "steady" / "results.json").read_text())
    assert r_steady["quality"]["heading_task"]["change_deg"] < 5.0
    assert {"magnetic_heading_disagrees"} <= {w["code"] for w in r_steady["quality"]["warnings"]}
    following, _ = process_folder(tmp_path / "session", tmp_path / "following", ProcessOptions(heading="magnetometer"),
                                  reports=False)
    r_following = json.loads((tmp_path / "following" / "results.json").read_text())
    assert {"magnetic_heading_disagrees", "heading_drift"} <= {w["code"] for w in r_following["quality"]["warnings"]}
    assert (accuracy(auto, truth)["rmse_deg"]["internal_rotation"]
            < accuracy(following, truth)["rmse_deg"]["internal_rotation"])
    # the plain weighted-mean heading (offline_heading_width_rad=0) follows the turning field: drift is warned
    forced, _ = process_folder(tmp_path / "session", tmp_path / "out", ProcessOptions(
        heading="magnetometer", filter_params={"offline_heading_width_rad": 0.0}), reports=False)
    assert accuracy(auto, truth)["rmse_deg"]["internal_rotation"] < accuracy(forced, truth)["rmse_deg"]["internal_rotation"]
    assert accuracy(auto, truth)["rmse_deg"]["internal_rotation"] < accuracy(steady, truth)["rmse_deg"]["internal_rotation"]
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    assert r["quality"]["heading"]["used"] == "magnetometer"
    drift = [w for w in r["quality"]["warnings"] if w["code"] == "heading_drift"]
    assert len(drift) == 1 and drift[0]["params"]["variant"] == "task", r["quality"]["warnings"]
    p = drift[0]["params"]
    assert p["change_deg"] > 6.0 and p["holds"] == 9 and p["last_deg"] > p["first_deg"]  # turned one way
    assert r["quality"]["heading_task"]["change_deg"] == pytest.approx(p["change_deg"])
    assert "magnetic_disturbance" not in {w["code"] for w in r["quality"]["warnings"]}
    for lang in ("es", "pt"):
        text, translated = warning_text(drift[0], lang, r)
        assert translated and f"{p['change_deg']:.1f}".replace(".", ",") in text, (lang, text)


def test_task_recording_cut_inside_the_first_cycle(right_session, tmp_path):
    """Both task recordings start halfway through the first cycle's extension: cycle 0 is detected,
    rejected as incomplete (the reason recorded in results.json), the others kept, and warned."""
    m = right_session.motion
    cut_s = right_session.role_epoch_s["task"] + 0.5 * (m.phases_s[0, 1] + m.phases_s[0, 2])
    recs = dict(right_session.recordings)
    for seg in ("thigh", "shank"):
        recs[(seg, "task")] = {k: (t[t >= cut_s], v[t >= cut_s]) for k, (t, v) in recs[(seg, "task")].items()}
    write_session(tmp_path / "session", replace(right_session, recordings=recs))
    process_folder(tmp_path / "session", tmp_path / "out", reports=False)
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    assert r["cycles"]["detected"] == 6 and r["cycles"]["accepted"] == 5
    assert [(c["index"], c["reason"]) for c in r["cycles"]["rejected"]] == [(0, "incomplete_start")]
    assert r["cycles"]["per_cycle"][0]["accepted"] is False
    rejected = [w for w in r["quality"]["warnings"] if w["code"] == "cycles_rejected"]
    assert len(rejected) == 1 and rejected[0]["params"] == {"rejected": 1, "detected": 6}


def test_guo_filter_meets_the_goals_and_keeps_the_first_cycle(right_session, tmp_path):
    """Guo's fast Kalman filter (the issue's named default) converges before the first cycle (the thesis lost it)."""
    write_session(tmp_path / "session", right_session)
    outcome, _ = process_folder(tmp_path / "session", tmp_path / "out", ProcessOptions(filter_name="guo"),
                                reports=False)
    check_goals(outcome, right_session)
    assert outcome.analysis.accepted[0] and outcome.analysis.n_accepted == 6
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    assert r["filter"]["name"] == "guo" and r["filter"]["params"]


def test_thesis_angle_option(right_session, tmp_path):
    write_session(tmp_path / "session", right_session)
    outcome, _ = process_folder(tmp_path / "session", tmp_path / "out", ProcessOptions(angle_method="thesis_zyx"))
    acc = accuracy(outcome, right_session)
    assert acc["rmse_deg"]["flexion"] <= 1.5  # ZYX differs from Grood & Suntay mostly off the sagittal plane


def test_missing_recording_is_named_and_nothing_is_written(right_session, tmp_path, capsys):
    session = tmp_path / "session"
    write_session(session, right_session)
    for f in session.glob("standing-muslo*Gyroscope*"):  # the thigh's standing gyroscope export is missing
        f.unlink()
    code = main(["process", str(session), "--out", str(tmp_path / "out")])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and last.startswith("chakamo process: error:")
    assert "standing-muslo" in last and "Gyroscope" in last  # names the recording and what is missing
    assert not (tmp_path / "out").exists()


def test_side_must_be_known(right_session, tmp_path):
    session = tmp_path / "session"
    write_session(session, right_session)
    (session / "session.json").write_text(json.dumps({"step_height_m": 0.17}))
    with pytest.raises(PipelineError, match="side"):
        process_folder(session, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    outcome, _ = process_folder(session, tmp_path / "out", ProcessOptions(side="right"))
    assert outcome.side == "right"


def test_only_one_sensor(right_session, tmp_path, capsys):
    session = tmp_path / "session"
    write_session(session, right_session)
    for f in session.glob("*pierna*"):
        f.unlink()
    assert main(["process", str(session), "--out", str(tmp_path / "out")]) == 2
    assert "shank" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_failed_run_leaves_earlier_results_untouched(right_session, tmp_path):
    session = tmp_path / "session"
    write_session(session, right_session)
    out = tmp_path / "out"
    process_folder(session, out)
    before = (out / "results.json").read_bytes()
    broken = tmp_path / "broken"
    shutil.copytree(session, broken)
    next(broken.glob("*Accelerometer*")).write_text("epoc (ms),timestamp (-0000),elapsed (s),x-axis (g)\n")
    with pytest.raises(ValueError):
        process_folder(broken, out)
    assert (out / "results.json").read_bytes() == before


def test_swapped_segments_are_refused(right_session, tmp_path, capsys):
    session = tmp_path / "session"
    write_session(session, right_session)
    for f in list(session.glob("*.csv")):  # the thigh's files named as the shank's and vice versa
        swapped = f.name.replace("muslo", "@").replace("pierna", "muslo").replace("@", "pierna")
        f.rename(session / swapped)
    assert main(["process", str(session), "--out", str(tmp_path / "out")]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "swapped" in last and "thigh" in last and "shank" in last and ".csv" in last
    assert not (tmp_path / "out").exists()


def test_relative_paths_as_in_the_readme(right_session, tmp_path, monkeypatch):
    """The README runs ``chakamo demo --out out/demo``: relative folders must work (they once were joined twice)."""
    monkeypatch.chdir(tmp_path)
    write_session(tmp_path / "rel" / "session", right_session)
    assert main(["process", "rel/session", "--out", "rel/out"]) == 0
    assert (tmp_path / "rel" / "out" / "results.json").is_file()


def test_patient_block_from_session_json(right_session, tmp_path):
    """session.json's patient fields (README) reach the reports' patient block as typed."""
    from app.pipeline.results import build_results, report_input

    session = tmp_path / "session"
    write_session(session, right_session)
    manifest = json.loads((session / "session.json").read_text())
    manifest |= {"name": "Ana Núñez", "professional": "Dra. Peña", "weight_kg": 61.5, "height_m": 1.64,
                 "observations": "=dolor anterior; 3 días"}
    (session / "session.json").write_text(json.dumps(manifest, ensure_ascii=False))
    outcome, _ = process_folder(session, tmp_path / "out", reports=False)
    patient = report_input(outcome, build_results(outcome)).patient
    assert (patient.name_or_id, patient.professional, patient.weight_kg, patient.height_m, patient.observations) == (
        "Ana Núñez", "Dra. Peña", 61.5, 1.64, "=dolor anterior; 3 días")
    assert patient.side == "right"


def test_step_up_reference_cycle_time_is_the_cycle_mean(right_session, tmp_path):
    """results.json ``reference`` ``cycle_s`` is the session's mean cycle time, which the simulator knows: the
    mean of its true cycles' durations (and the pipeline's own boundaries).  It was the sum of every entry of
    ``phases``, which also holds "movement" and "cycle", about 3x the cycle and flagged "H"."""
    write_session(tmp_path / "session", right_session)
    outcome, _ = process_folder(tmp_path / "session", tmp_path / "out", reports=False)
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    true_cycle_s = float(np.mean(np.diff(right_session.motion.cycles_s, axis=1)))
    found = np.asarray(r["cycles"]["boundaries_s"], dtype=float)
    cycle = r["reference"]["parameters"]["cycle_s"]
    assert cycle["value"] == pytest.approx(true_cycle_s, abs=0.05)
    assert cycle["value"] == pytest.approx(float(np.mean(found[:, 1] - found[:, 0])), abs=0.03)
