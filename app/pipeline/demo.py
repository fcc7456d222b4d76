"""``chakamo demo``: a realistic simulated session with known truth, processed like a real one.

The simulator (:mod:`estimators.simulation`) makes two MetaMotionR-like sensors (noise, gyroscope
bias and drift, scale and axis errors, hard and soft iron, up to 15° mounting misalignment, clock
drift, streams starting milliseconds apart, 20 Hz magnetometer) on the thigh and shank of one leg
recording the protocol of seed 004 §8.4: a figure-eight per sensor, standing, supine lying and ten
single-leg step-up cycles.  The recordings are written as real MetaBase CSV files with the quirks of
real exports (the ``epoc``/``timestamp`` header dialect, '.' in the time of day, Spanish labels, a
stream running on after the others), processed by :func:`app.pipeline.process.process_folder` — the code path
of ``chakamo process`` — and compared with the truth: knee-angle RMSE, cycles found, phase boundaries.

Output: ``OUT/session/`` (the files), the outputs of ``chakamo process`` (``OUT/results.json``, the
reports), ``OUT/demo_accuracy.json`` and ``OUT/demo_truth.npz`` (the task's true knee angles, cycles and
phase events: :func:`truth_npz`), the last two written all-or-nothing like the others.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from estimators import simulation as sim
from estimators.motor_task import ANGLES, EVENTS
from estimators.simulation.knee import LegMotion

from app.choices import SIDE_NAMES
from app.pipeline.ingestion import (
    session_label, simulated_streams, write_generic_csv, write_session_metabase, write_thesis_xlsx,
)
from app.pipeline.session import ProcessOptions, SessionOutcome
from app.pipeline.process import process_folder
from app.pipeline.results import write_outputs
from reports.warning_text import is_technical

EPOCH0_S = 1_795_341_600.0  # 2026-11-22 10:00 UTC: the phone clock of the simulated session
STEP_HEIGHT_M = 0.17
MOUNTING_MAX_DEG = 15.0


@dataclass(frozen=True, eq=False)
class SimulatedSession:
    """Streams of one simulated session and its truth.

    recordings : ``{(segment, role): {"acc"|"gyr"|"mag": (t_s on the phone clock, values)}}``.
    motion : the task's :class:`LegMotion` (true knee angles, cycles, phases).
    role_epoch_s : ``{role: start on the phone clock}`` (both sensors of a role start together).
    """

    recordings: dict
    motion: LegMotion
    role_epoch_s: dict[str, float]
    side: str
    step_height_m: float


def simulate_session(*, seed: int, side: str, n_cycles: int, accelerometer_errors: bool = True,
                     supine_roll_out_deg: float = 0.0, shank_task_field_turn_rad_s: float = 0.0,
                     motion: LegMotion | None = None, step_height_m: float = STEP_HEIGHT_M,
                     mounting_max_deg: float = MOUNTING_MAX_DEG, gyr_run_on_s: float = 1.5) -> SimulatedSession:
    """Simulate the four recordings of both sensors (module docstring).

    ``accelerometer_errors=False`` keeps the accelerometer ideal but for its noise: the conditions of the
    issue's accuracy goal (noise, gyroscope bias, hard/soft iron, mounting, clock drift).  With them, a
    0.1–0.3 m/s² accelerometer bias tilts each sensor's vertical by up to ~1.7°, which the 63° magnetic
    dip turns into ~3° of heading and so of knee rotation; the pipeline measures that bias on the still poses
    of the figure-eight's rests and the two postures (:mod:`estimators.accelerometer`) and removes it.
    ``supine_roll_out_deg`` lets the leg lie rolled outwards (toes out) in the supine recording.
    ``shank_task_field_turn_rad_s`` turns the magnetic field at the shank sensor about the vertical at that
    rate during the task only (a slowly drifting local disturbance, :func:`estimators.simulation.simulate`'s
    ``mag_field_turn_rad_s``): the shank's heading drifts away from the thigh's while norm and dip stay right.
    ``motion`` replaces the default task (:func:`estimators.simulation.step_up` with ``n_cycles`` at
    ``step_height_m``), e.g. another step-up shape with pauses (``benchmarks/robustness.py``);
    ``mounting_max_deg`` bounds each sensor's random misalignment.  ``gyr_run_on_s``: the thigh's gyroscope runs on
    this long after its other streams stopped (a real export's quirk; the task's last seconds are then cut).
    """
    if motion is None:
        motion = sim.step_up(n_cycles, step_height_m, side, seed=seed)
    postures = {"standing": sim.standing(30.0, side), "lying": sim.supine(30.0, side, roll_out_rad=np.deg2rad(supine_roll_out_deg))}
    epochs = {"mag_calibration": EPOCH0_S, "standing": EPOCH0_S + 180.0, "lying": EPOCH0_S + 230.0,
              "task": EPOCH0_S + 300.0}
    recordings = {}
    for i, seg in enumerate(("thigh", "shank")):
        clock = replace(sim.ClockSpec.metamotion(), clock_drift_ppm=(40.0, 8000.0)[i])  # shank clock 0.8 % fast
        spec = sim.ImuSpec.random(seed * 10 + i, clock=clock)
        if not accelerometer_errors:
            spec = replace(spec, acc=sim.AccErrors.noise_only())
        mount = sim.random_rotation(np.deg2rad(mounting_max_deg), seed * 10 + i)
        lever = motion.thigh_lever_arm_m if seg == "thigh" else motion.shank_lever_arm_m
        fig8 = sim.simulate(sim.figure_eight(60.0, seed=seed + i), spec, seed=seed * 100 + i)
        recordings[(seg, "mag_calibration")] = simulated_streams(fig8, epochs["mag_calibration"] + 80.0 * i)
        for j, (role, leg) in enumerate(postures.items()):
            imu = sim.simulate(getattr(leg, seg), spec, q_segment_sensor=mount, lever_arm_m=lever,
                               seed=seed * 100 + 10 * (j + 1) + i)
            recordings[(seg, role)] = simulated_streams(imu, epochs[role])
        turn_rad_s = shank_task_field_turn_rad_s if seg == "shank" else 0.0
        imu = sim.simulate(getattr(motion, seg), spec, q_segment_sensor=mount, lever_arm_m=lever,
                           seed=seed * 100 + 50 + i, mag_field_turn_rad_s=turn_rad_s)
        recordings[(seg, "task")] = simulated_streams(imu, epochs["task"], run_on_s={"gyr": gyr_run_on_s} if i == 0 and gyr_run_on_s else None)
    return SimulatedSession(recordings, motion, epochs, side, step_height_m)


def write_session(folder: Path, session: SimulatedSession, fmt: str = "metabase") -> list[Path]:
    """Write ``session`` as MetaBase CSV (with real exports' quirks), the thesis' Excel or generic CSV files.

    Excel and generic CSV carry elapsed seconds only: each recording's times count from its role's start,
    which both sensors share (the assumption ingestion makes for those formats).
    """
    manifest = {"side": session.side, "patient_id": "DEMO-001"}
    if session.step_height_m is not None:  # a step-up's; other tasks have none
        manifest["step_height_m"] = session.step_height_m
    if fmt == "metabase":
        return write_session_metabase(folder, session.recordings, lang="es", dialect="epoc", time_sep=".",
                                      manifest=manifest, patient_id="DEMO-001", date_ddmmyyyy="22112026")
    if fmt not in ("xlsx", "generic"):
        raise ValueError(f"unknown session format {fmt!r}; use metabase, xlsx or generic")
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for (seg, role), streams in session.recordings.items():
        t0 = session.role_epoch_s[role] if role != "mag_calibration" else streams["acc"][0][0]
        acc, gyr, mag = ((streams[k][0] - t0, streams[k][1]) for k in ("acc", "gyr", "mag"))
        name = session_label(seg, role, "DEMO-001", "22112026", lang="en")
        if fmt == "xlsx":
            gyr_on_acc = np.stack([np.interp(acc[0], gyr[0], gyr[1][:, i]) for i in range(3)], axis=1)
            written.append(write_thesis_xlsx(folder / f"{name}.xlsx", acc, gyr_on_acc, mag))
        else:
            written.append(write_generic_csv(folder / f"{name}.csv", acc, gyr, mag))
    path = folder / "session.json"
    path.write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
    return [*written, path]


#: the side words written into a two-knee session's labels (Spanish, as the demo's other labels)
SIDE_LABEL_WORDS = {"right": "derecha", "left": "izquierda"}
#: one MAC per sensor of a two-knee session: (side, segment) → MAC
KNEE_MACS = {("right", "thigh"): "D4F1A2B3C4E5", ("right", "shank"): "E8C2B1A0F9D7",
             ("left", "thigh"): "C1D2E3F4A5B6", ("left", "shank"): "F6E5D4C3B2A1"}


def simulate_walk_knees(*, seed: int, duration_s: float = 14.0, knee_gain: dict[str, float] | None = None,
                        mounting_max_deg: float = 12.0) -> dict[str, SimulatedSession]:
    """Both legs of one simulated walk (:func:`estimators.simulation.gait.walking`: normative curves, heel strikes,
    soft-tissue wobble, a 2 s stand first), four factory-calibrated sensors with the simulator's noise, bias and
    misalignment (up to ``mounting_max_deg``): ``{side: SimulatedSession}`` of task recordings only.
    ``knee_gain`` scales one leg's flexion (a known asymmetry: ``{"left": 0.8}`` → an LSI of 80 % on flexion peaks
    and ROM with the left knee involved)."""
    from estimators.simulation import gait

    walk = gait.walking(duration_s, standing_start_s=2.0, seed=seed, knee_gain=knee_gain)
    epoch = EPOCH0_S + 300.0
    out = {}
    for j, side in enumerate(("right", "left")):
        leg = walk.leg(side)
        ids = [seed * 10 + 2 * j + i for i in range(2)]
        mounts = [sim.random_rotation(np.deg2rad(mounting_max_deg), k) for k in ids]
        specs = [replace(sim.ImuSpec.random(k), mag=sim.MagErrors.noise_only()) for k in ids]
        imu_t, imu_s = gait.simulate_leg(leg, *specs, q_thigh_sensor=mounts[0], q_shank_sensor=mounts[1],
                                         seed=seed * 10 + j)
        recs = {("thigh", "task"): simulated_streams(imu_t, epoch), ("shank", "task"): simulated_streams(imu_s, epoch)}
        out[side] = SimulatedSession(recs, leg.motion, {"task": epoch}, side, None)
    return out


def write_knees_session(folder: Path, knees: dict[str, SimulatedSession], *, patient_side: str | None = None
                        ) -> list[Path]:
    """Write both knees of :func:`simulate_walk_knees` into one folder as MetaBase CSV files whose labels name the
    side (``izquierda-tarea-muslo-...``), with a ``session.json`` giving the patient's (involved) side if any."""
    from app.pipeline.ingestion import write_recording_metabase

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for side, session in knees.items():
        for (seg, role), streams in session.recordings.items():
            label = f"{SIDE_LABEL_WORDS[side]}-" + session_label(seg, role, "DEMO-001", "22112026", lang="es")
            written += write_recording_metabase(folder, label, KNEE_MACS[(side, seg)], streams)
    manifest = {"patient_id": "DEMO-001", **({"side": patient_side} if patient_side else {})}
    path = folder / "session.json"
    path.write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
    return [*written, path]


#: the simulator's phase events (the columns of ``LegMotion.phases_s`` and of ``demo_truth.npz``
#: ``phases_s``), named as the motor-task analysis names its events, and their columns in ``events_s``
TRUTH_PHASE_EVENTS = ("onset", "countermovement_peak", "far_left", "rest_reached")
TRUTH_EVENT_COLUMNS = [EVENTS.index(e) for e in TRUTH_PHASE_EVENTS]


def accuracy(outcome: SessionOutcome, truth: SimulatedSession, task_epoch_s: float | None = None) -> dict:
    """Knee-angle RMSE (°) over the task, cycles found, and phase-boundary errors (% of the true cycle).

    ``task_epoch_s``: where the task's time stamps start on the truth's clock — by default the phone-clock
    start for epoch stamps (MetaBase), 0 for elapsed stamps (Excel, generic CSV: :func:`write_session`).
    """
    motion = truth.motion
    if task_epoch_s is None:
        epoch_stamps = outcome.session.task_pair()[0].time_base == "epoch"
        task_epoch_s = truth.role_epoch_s["task"] if epoch_stamps else 0.0
    t_true = np.clip(outcome.t0_s + outcome.t_s - task_epoch_s, motion.t_s[0], motion.t_s[-1])
    err = np.rad2deg(outcome.angles_rad - motion.knee_angles_at(t_true))
    rmse = {a: float(np.sqrt(np.nanmean(err[:, i] ** 2))) for i, a in enumerate(ANGLES)}
    a = outcome.analysis
    onsets = outcome.t0_s + a.events_s[:, 0] - task_epoch_s
    true_cycles = motion.cycles_s
    found, worst_pct = 0, 0.0
    for k, (t_start, t_end) in enumerate(true_cycles):
        if not np.isfinite(onsets).any():
            break
        j = int(np.nanargmin(np.abs(onsets - t_start)))
        duration = t_end - t_start
        if abs(onsets[j] - t_start) > 0.25 * duration:
            continue
        found += 1
        detected = outcome.t0_s + a.events_s[j, TRUTH_EVENT_COLUMNS] - task_epoch_s
        worst_pct = max(worst_pct, float(np.nanmax(np.abs(detected - motion.phases_s[k])) / duration * 100))
    return {"rmse_deg": rmse, "cycles_true": int(len(true_cycles)), "cycles_found": found,
            "cycles_accepted": int(a.n_accepted), "phase_boundary_max_error_pct": worst_pct}




def truth_npz(truth: SimulatedSession) -> bytes:
    """The task's ground truth as ``demo_truth.npz``, so the demo's outputs can be scored by anyone.

    Arrays: ``t_s`` (M,) true time from the task recording's start, s (the simulator's dense grid);
    ``knee_angles_deg`` (M, 3) true Grood & Suntay angles (clinical signs), degrees, named by ``angle_names``;
    ``cycles_s`` (K, 2) true cycle [start, end); ``phases_s`` (K, 4) true phase events, named by
    ``phase_events`` (:data:`TRUTH_PHASE_EVENTS`); ``task_epoch_s`` the phone-clock time of ``t_s = 0`` (the
    MetaBase files' epoch stamps minus it give the truth's time, up to the sensor's clock drift); ``side``.
    """
    m = truth.motion
    buf = io.BytesIO()
    np.savez_compressed(
        buf, t_s=m.t_s, knee_angles_deg=np.rad2deg(m.knee_angles_rad), angle_names=np.array(ANGLES),
        cycles_s=m.cycles_s, phases_s=m.phases_s, phase_events=np.array(TRUTH_PHASE_EVENTS),
        task_epoch_s=np.float64(truth.role_epoch_s["task"]), side=np.array(truth.side))
    return buf.getvalue()


def run_demo(out_dir: Path, *, seed: int = 7, side: str = "right", n_cycles: int = 10,
             filter_name: str | None = None) -> dict:
    """Simulate, write, process and score one session; print the accuracy; return it."""
    if side not in SIDE_NAMES:
        raise ValueError(f"--side must be right or left, got {side!r}")
    if not 3 <= n_cycles <= 30:
        raise ValueError(f"--cycles must be between 3 and 30, got {n_cycles}")
    out_dir = Path(out_dir)
    session_dir = out_dir / "session"
    truth = simulate_session(seed=seed, side=side, n_cycles=n_cycles)
    write_session(session_dir, truth)
    options = ProcessOptions() if filter_name is None else ProcessOptions(filter_name=filter_name)
    outcome, _ = process_folder(session_dir, out_dir, options)
    acc = accuracy(outcome, truth)
    acc["filter"] = options.filter_name
    write_outputs(out_dir, {"demo_accuracy.json": json.dumps(acc, indent=2) + "\n",
                            "demo_truth.npz": truth_npz(truth)})

    print(f"Simulated session ({side} leg, {n_cycles} step-up cycles of {100 * STEP_HEIGHT_M:.0f} cm, two sensors "
          f"mounted up to {MOUNTING_MAX_DEG:.0f}° off, MetaBase files) in {session_dir}")
    print(f"Processed with filter {options.filter_name!r}: results in {out_dir / 'results.json'}\n")
    print("Knee angles against the simulated truth (RMSE over the task):")
    for name, value in acc["rmse_deg"].items():
        print(f"  {name:<18} {value:5.2f}°")
    print(f"Cycles: {acc['cycles_found']} of {acc['cycles_true']} true cycles found, {acc['cycles_accepted']} accepted; "
          f"phase boundaries within {acc['phase_boundary_max_error_pct']:.2f} % of the cycle")
    for w in outcome.warnings:  # the clinical warnings, then the technical notes (reports.warning_text.is_technical)
        if not is_technical(w):
            print(f"  warning [{w.code}] {w.message}")
    for w in outcome.warnings:
        if is_technical(w):
            print(f"  technical note [{w.code}] {w.message}")
    return acc
