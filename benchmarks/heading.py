"""Knee angles with the magnetometer, the joint-constraint and the auto heading on simulated step-ups.

Each session: a step-up (both legs, 17 and 34 cm), thigh and shank sensors with the MetaMotionR error model
(``ImuSpec()``) and random mountings (≤ 15°); the magnetometer calibrated with the simulator's own hard and
soft iron and the gyroscope bias known at the start (the pipeline measures both; here they are oracles so
the table isolates the heading), segment calibration = the true mounting.  Both sensors run the default
filter in 9D and in 6D.  ``--disturb-deg`` rotates the field at the shank sensor about the vertical by that
angle (ramped in and out over 1 s) during the middle third of the task: a local field, norm and dip
unchanged, the kind no magnetometer check sees.

Seeds are split: ``--tune`` seeds choose the window length and the auto bound, the others report them.

    python -m benchmarks.heading --seeds 0-5 --disturb-deg 30        # table, all seeds
    python -m benchmarks.heading --tune 0-5 --seeds 0-11 --sweep     # window sweep on tune, report held out
    python -m benchmarks.heading --tune 0-5 --seeds 0-11 --sweep-power   # straight-knee weight k

Measured (default params: 10 s windows, k = 2, bound 6°; mean RMSE in degrees flexion / adduction / rotation,
``--tune 0-5 --seeds 0-11``, held-out seeds 6–11, shank field turned in the middle third):

==========  ===================  ===================  ===================  =====================
field       magnetometer         constraint (6D)      auto                 auto switched
==========  ===================  ===================  ===================  =====================
clean       0.29 / 0.26 / 0.47   0.28 / 0.41 / 0.84   0.29 / 0.26 / 0.47   0 of 6 (change 0.00°)
20°         0.42 / 2.60 / 6.28   0.28 / 0.41 / 0.84   0.28 / 0.41 / 0.84   6 of 6
30°         0.59 / 3.90 / 9.37   0.28 / 0.41 / 0.84   0.28 / 0.41 / 0.84   6 of 6
40°         0.79 / 5.19 / 12.45  0.28 / 0.41 / 0.84   0.28 / 0.41 / 0.84   6 of 6
==========  ===================  ===================  ===================  =====================

Tuning seeds 0–5 (30°): magnetometer 0.64 / 3.98 / 9.59, constraint 0.27 / 0.44 / 0.93, auto = constraint on 6/6,
clean auto = magnetometer.  (Those rows are with the 6° bound of then.  With the step-up bound of 1.5° used before 3°,
same command, held out: clean auto 0.29 / 0.33 / 0.60 with 3 of 6 switched; 30° auto = constraint on 6 of 6.)
Other filters, ``--seeds 6-9 --disturb-deg 30 --filter F`` (all held out), auto against
magnetometer on the disturbed sessions: madgwick 0.95 / 0.47 / 0.86 vs 1.66 / 6.05 / 14.34, guo 0.41 / 0.42 / 0.89 vs
0.97 / 5.22 / 12.85, valenti_kf 0.40 / 0.41 / 0.87 vs 1.21 / 4.70 / 11.06; clean D ≤ 2.4°, no clean session switched.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from estimators import heading, knee
from estimators import quaternion as quat
from estimators import simulation as sim
from estimators.orientation import make

DEG = np.pi / 180.0
CASES = [("right", 0.17), ("left", 0.34), ("right", 0.34), ("left", 0.17)]


def disturbed_mag(grid, angle_rad: float, start_s: float, stop_s: float, ramp_s: float = 1.0) -> np.ndarray:
    """Calibrated field of ``grid`` (the simulator's hard/soft iron removed by ``cal``), turned about the
    vertical by ``angle_rad`` between ``start_s`` and ``stop_s`` (linear ramps of ``ramp_s``)."""
    t = grid.t_s - grid.t_s[0]
    frac = np.clip(np.minimum((t - start_s) / ramp_s, (stop_s - t) / ramp_s), 0.0, 1.0)
    turn = quat.from_axis_angle([0.0, 0.0, 1.0], angle_rad * frac)
    m_e = grid.mag_earth_ut
    extra = quat.rotate(quat.conjugate(grid.q_earth_sensor), quat.rotate(turn, m_e) - m_e)
    return extra


def session(seed: int, side: str, height_m: float, disturb_rad: float, n_cycles: int = 8,
            filter_name: str = "chakamo", shape: str = "rest_between",
            disturb_span: tuple[float, float] = (1.0 / 3.0, 2.0 / 3.0)):
    """9D and 6D segment orientations of both segments and the true knee angles (see module docstring).

    ``disturb_span``: the part of the task (fractions of its duration) during which the shank's field is turned.
    """
    rng = np.random.default_rng(1000 + seed)
    leg = sim.step_up(n_cycles, height_m, side, shape=shape, seed=seed, facing_rad=float(rng.uniform(-np.pi, np.pi)))
    spec = sim.ImuSpec()
    filt = make(filter_name)
    dur = leg.t_s[-1] - leg.t_s[0]
    out = {}
    for k, name in enumerate(("thigh", "shank")):
        mount = sim.random_rotation(15 * DEG, seed=10 * seed + k)
        g = sim.simulate_on_grid(getattr(leg, name), spec, q_segment_sensor=mount, seed=100 * seed + k,
                                 lever_arm_m=getattr(leg, f"{name}_lever_arm_m"))
        mag = (g.mag - spec.mag.hard_iron_ut) @ np.linalg.inv(spec.mag.soft_iron).T
        if name == "shank" and disturb_rad != 0.0:
            mag = mag + disturbed_mag(g, disturb_rad, disturb_span[0] * dur, disturb_span[1] * dur)
        gyr = g.gyr - spec.gyr.bias_rad_s
        q_ss = quat.conjugate(mount)
        q9 = filt.estimate(g.acc, gyr, mag, fs_hz=g.fs_hz).orientation_
        q6 = filt.estimate(g.acc, gyr, None, fs_hz=g.fs_hz).orientation_
        out[name] = (knee.segment_orientation(q9, q_ss), knee.segment_orientation(q6, q_ss))
        t_true, fs = g.t_true_s, g.fs_hz
    truth = np.column_stack([np.interp(t_true, leg.t_s, leg.knee_angles_rad[:, i]) for i in range(3)])
    return out, truth, side, fs


def rmse_deg(q_f, q_t, truth, side) -> np.ndarray:
    ang = knee.knee_angles(knee.q_femur_tibia(q_f, q_t), side)
    return np.rad2deg(np.sqrt(np.mean(heading.wrap(ang - truth) ** 2, axis=0)))


def evaluate(s, params: heading.ConstraintHeadingParams, bound_rad: float) -> dict[str, tuple]:
    out, truth, side, fs = s
    (f9, f6), (t9, t6) = out["thigh"], out["shank"]
    res = {}
    for mode in ("magnetometer", "constraint", "auto"):
        ch = heading.choose_heading(f9, t9, fs_hz=fs, mode=mode, q_earth_femur_6d=f6, q_earth_tibia_6d=t6,
                                    params=params, bound_rad=bound_rad)
        res[mode] = (rmse_deg(ch.q_earth_femur, ch.q_earth_tibia, truth, side), ch.used, ch.disagreement_rad)
    c9 = heading.constraint_heading(f9, t9, fs_hz=fs, params=params)
    res["constraint_9d"] = (rmse_deg(f9, knee.apply_heading_offset(t9, c9.offset_rad), truth, side), "constraint",
                            np.nan)
    return res


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="0-3")
    ap.add_argument("--tune", default=None, help="seeds used to choose window_s (with --sweep); the rest held out")
    ap.add_argument("--disturb-deg", type=float, default=30.0)
    ap.add_argument("--cycles", type=int, default=8)
    ap.add_argument("--sweep", action="store_true", help="window_s in 3, 6, 10 s")
    ap.add_argument("--sweep-power", action="store_true", help="extension_weight_power in 0, 2, 8 (10 s windows)")
    ap.add_argument("--filter", default="chakamo")
    ap.add_argument("--shape", default="rest_between", choices=("rest_between", "thesis"),
                    help="simulated step-up (the bound was chosen on rest_between; thesis: seed 004's sequence)")
    a = ap.parse_args()
    seeds = _seeds(a.seeds)
    tune = set(_seeds(a.tune)) if a.tune else set()
    default = heading.ConstraintHeadingParams()
    configs = [(w, default.extension_weight_power) for w in ((3.0, 6.0, 10.0) if a.sweep else (default.window_s,))]
    if a.sweep_power:
        configs = [(default.window_s, k) for k in (0.0, 2.0, 8.0)]
    t0 = time.perf_counter()
    sessions = {}
    for seed in seeds:
        side, h = CASES[seed % len(CASES)]
        for dist in (0.0, a.disturb_deg):
            sessions[(seed, dist)] = session(seed, side, h, dist * DEG, a.cycles, a.filter, a.shape)
    print(f"# {len(sessions)} sessions simulated and filtered in {time.perf_counter() - t0:.0f} s "
          f"(filter {a.filter}, {a.cycles} cycles, shank field turned {a.disturb_deg:.0f}° in the middle third)")
    print("| window_s | k | split | field | heading | flexion | adduction | rotation | used constraint | D (deg) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for w, power in configs:
        params = heading.ConstraintHeadingParams(window_s=w, extension_weight_power=power)
        rows: dict[tuple, list] = {}
        for (seed, dist), s in sessions.items():
            split = "tune" if seed in tune else "held-out"
            for mode, (err, used, d) in evaluate(s, params, heading.DISAGREEMENT_BOUND_RAD).items():
                rows.setdefault((split, dist, mode), []).append((err, used == "constraint", d, seed))
        for (split, dist, mode), v in sorted(rows.items()):
            err = np.array([x[0] for x in v])
            d = np.array([x[2] for x in v])
            dtxt = "" if np.all(np.isnan(d)) else f"{np.rad2deg(np.nanmin(d)):.1f}–{np.rad2deg(np.nanmax(d)):.1f}"
            print(f"| {w:.0f} | {power:.0f} | {split} ({len(v)}) | {'disturbed' if dist else 'clean'} | {mode} | "
                  + " | ".join(f"{np.mean(err[:, i]):.2f} (max {np.max(err[:, i]):.2f})" for i in range(3))
                  + f" | {sum(x[1] for x in v)}/{len(v)} | {dtxt} |")
    # auto against magnetometer on the clean sessions: the change auto makes (should be nothing)
    params = heading.ConstraintHeadingParams()
    worst = 0.0
    for (_seed, dist), s in sessions.items():
        if dist:
            continue
        out, _, side, fs = s
        (f9, f6), (t9, t6) = out["thigh"], out["shank"]
        ch = heading.choose_heading(f9, t9, fs_hz=fs, q_earth_femur_6d=f6, q_earth_tibia_6d=t6)
        a9 = knee.knee_angles(knee.q_femur_tibia(f9, t9), side)
        aa = knee.knee_angles(knee.q_femur_tibia(ch.q_earth_femur, ch.q_earth_tibia), side)
        worst = max(worst, float(np.rad2deg(np.max(np.abs(heading.wrap(aa - a9))))))
    print(f"\nclean sessions: largest change auto makes to any knee angle vs magnetometer: {worst:.2f}°")


if __name__ == "__main__":
    main()
