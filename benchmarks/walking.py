r"""Walking knee-flexion accuracy of every orientation method on simulated gait (issue 13 §5).

Usage
-----
``python -m benchmarks.walking [--seeds 0 1 2 ...] [--methods chakamo madgwick ...] [--modes 9d 6d]
[--calibrations known data] [--params chakamo:offline=false,mag_rejection=false] [--json OUT]``

Each seed draws one walk (:func:`estimators.simulation.gait.walking`): 5–15 s, in motion from the first
sample, cadence 100–120 steps/min, speed 1.1–1.5 m/s, heel strikes of 3–6 g at the shank and 1–2 g at
the thigh, 1–3° soft-tissue wobble, and a 180° turn on every third seed; both legs; sensors strapped
laterally with up to 15° misalignment and a sensor model drawn per unit (:meth:`ImuSpec.random`: gyroscope
bias ~1°/s, scale and axis errors) whose magnetometer is factory-calibrated (noise only: a walking clip has
no figure-eight).  Every method of :data:`estimators.orientation.METHODS` runs on every sensor, 9D and 6D;
knee angles use :mod:`estimators.knee` with two sensor-to-segment calibrations:

* ``known``: the simulator's mounting (sensor → skin; the wobble stays an error, as on a person);
* ``data``: data only, no posture: the flexion axes of both sensors by Seel et al.'s gyroscope constraint
  (:func:`estimators.joint_axis.estimate`), the long axis from the clip's mean specific force
  orthogonalised against it, and the axis sign that makes flexion skew positive (swing peak far above the
  median).  Flexion then carries an offset (the mean segment inclination), so read the offset-free columns.

9D runs use one earth frame for both sensors (δ = 0); 6D runs take the thigh–shank heading offset from the
hinge constraint over the clip (:func:`estimators.knee.heading_offset`, ``"hinge"``).  The row ``truth q``
uses the true sensor orientations: its error is the wobble's floor, which no filter can remove.

Metrics per clip and leg (flexion, degrees, against the bones' Grood & Suntay flexion): **ROM error** = mean
over the complete true strides of (estimated − true) per-stride flexion range; RMSE raw and with the mean
offset removed; Pearson r.  The table gives, per method, the mean and worst |ROM error| over all clips and
legs, the mean RMSEs, the lowest r, the number of clips whose |ROM error| exceeds 2°, and for diagnosis the
sensors' own RMS heading and inclination errors (thigh/shank, °; heading blank in 6D).  Goal (issue 13 §5):
the default's ROM error ≤ 2° and no worse than Madgwick's.

Held out: ``--params`` overrides are for diagnosis; choose them on one seed set and report them on another
(``--seeds``), quoting both.

Diagnosis, ``--offline-padding even``: for this run only, ``chakamo``'s offline smoother low-passes the
acceleration in its quasi-inertial frame with even (mirror) instead of odd edge padding (offline step 2 of
:mod:`estimators.orientation.chakamo`).  Odd padding extends the signal as :math:`2x_0 - x_k`, so on a clip
that starts or ends in motion the low-pass near the edge is pulled towards the first (last) sample's
*linear* acceleration (up to several g at a heel strike) and the inclination there is off by tens of
degrees; mirrored padding averages the linear acceleration out as the interior does.  The filter code is
not changed: the benchmark swaps the function for the run, to measure what the change would do.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from estimators import knee
from estimators import quaternion as quat
from estimators.orientation import DEFAULT_METHOD, METHODS, estimate
from estimators.simulation import ImuSpec, MagErrors, gait, random_rotation

FS_HZ = 100.0
ROM_GOAL_DEG = 2.0


@dataclass(frozen=True)
class LegClip:
    """One leg of one simulated walk on the 100 Hz grid, with its truth."""

    seed: int
    side: str
    t_s: np.ndarray
    acc: dict          # "thigh"/"shank" -> (N, 3) m/s²
    gyr: dict          # rad/s
    mag: dict          # µT
    q_true: dict       # true q_earth_sensor (N, 4)
    q_sensor_segment: dict  # known calibration (4,)
    flexion_true_rad: np.ndarray
    strides_s: np.ndarray   # (K, 2)
    info: dict


def leg_sensors(leg, side: str, rng: np.random.Generator, *, protocol_axes: bool = False):
    """Thigh and shank sensors of one leg as the walking benchmarks strap them: lateral mounts with up to 15°
    misalignment, MetaMotion-like errors with a factory-calibrated magnetometer; ``(grids, mounts, n, imus)`` with
    both grids cut to their common length ``n`` and the :class:`SimulatedImu` of each (as a file would stamp them).
    ``protocol_axes``: each sensor's axes along its segment's (+y up the segment, as the protocol wears them, seed
    004 §8.2) before the misalignment, instead of x up and z out of the skin."""
    if protocol_axes:
        mounts = tuple(random_rotation(np.deg2rad(15.0), rng) for _ in range(2))
    else:
        mounts = gait.lateral_mounting(side, np.deg2rad(15.0), seed=rng)
    specs = [replace(ImuSpec.random(rng), mag=MagErrors.noise_only()) for _ in range(2)]
    imus = gait.simulate_leg(leg, specs[0], specs[1], q_thigh_sensor=mounts[0], q_shank_sensor=mounts[1],
                             seed=int(rng.integers(2**31)))
    grids = [imu.on_grid() for imu in imus]
    return grids, mounts, min(len(g.t_s) for g in grids), imus


def clip(seed: int) -> list[LegClip]:
    """Both legs of the walk drawn by ``seed`` (module docstring)."""
    rng = np.random.default_rng([20261201, seed])
    duration = float(rng.uniform(5.0, 15.0))
    turn = float(rng.uniform(1.5, duration - 3.5)) if (seed % 3 == 2 and duration > 7.0) else None
    kw = dict(cadence_steps_min=float(rng.uniform(100.0, 120.0)), speed_m_s=float(rng.uniform(1.1, 1.5)),
              shank_impact_g=float(rng.uniform(3.0, 6.0)), thigh_impact_g=float(rng.uniform(1.0, 2.0)),
              shank_wobble_rad=float(np.deg2rad(rng.uniform(1.0, 3.0))),
              thigh_wobble_rad=float(np.deg2rad(rng.uniform(1.0, 3.0))),
              wobble_axis=rng.normal(size=3), facing_rad=float(rng.uniform(-np.pi, np.pi)))
    walk = gait.walking(duration, turn_at_s=turn, seed=rng, **kw)
    out = []
    for side in ("right", "left"):
        leg = walk.leg(side)
        grids, mounts, n, _ = leg_sensors(leg, side, rng)
        t_true = grids[0].t_true_s[:n]
        segs = ("thigh", "shank")
        out.append(LegClip(
            seed, side, grids[0].t_s[:n],
            {s: g.acc[:n] for s, g in zip(segs, grids)}, {s: g.gyr[:n] for s, g in zip(segs, grids)},
            {s: g.mag[:n] for s, g in zip(segs, grids)}, {s: g.q_earth_sensor[:n] for s, g in zip(segs, grids)},
            {s: quat.conjugate(m) for s, m in zip(segs, mounts)},
            leg.knee_angles_at(t_true)[:, 0], leg.motion.cycles_s,
            {"duration_s": duration, "turn": turn is not None, **{k: v for k, v in kw.items() if k != "wobble_axis"}}))
    return out


def data_calibration(c: LegClip) -> dict:
    """``q_sensor_segment`` of thigh and shank from the clip alone (Seel's axes + mean gravity), sign unresolved."""
    from estimators import joint_axis

    axes = joint_axis.estimate(c.acc["thigh"], c.gyr["thigh"], c.acc["shank"], c.gyr["shank"], fs_hz=FS_HZ)
    out = {}
    for seg, j in (("thigh", axes.j_a), ("shank", axes.j_b)):
        y = np.mean(c.acc[seg], axis=0)
        y = y - np.dot(y, j) * j
        y /= np.linalg.norm(y)
        out[seg] = quat.from_matrix(np.column_stack([np.cross(y, j), y, j]))
    return out


def _flip_z(q_sensor_segment: np.ndarray) -> np.ndarray:
    """The same long axis with the flexion axis reversed (x and z negated: a half turn about y)."""
    return quat.multiply(q_sensor_segment, quat.from_axis_angle([0.0, 1.0, 0.0], np.pi))


def flexion(q_thigh: np.ndarray, q_shank: np.ndarray, cal: dict, side: str, mode: str) -> np.ndarray:
    """Grood & Suntay flexion (rad) from sensor orientations and a calibration; 6D aligns the heading (hinge)."""
    qf = knee.segment_orientation(q_thigh, cal["thigh"])
    qt = knee.segment_orientation(q_shank, cal["shank"])
    delta = knee.heading_offset(qf, qt, method="hinge").offset_rad if mode == "6d" else 0.0
    return knee.knee_angles(knee.q_femur_tibia(qf, qt, delta), side)[:, 0]


def _signed_data_flexion(q_thigh, q_shank, cal, side, mode):
    best = None
    for c in (cal, {k: _flip_z(v) for k, v in cal.items()}):
        f = flexion(q_thigh, q_shank, c, side, mode)
        med = np.median(f)
        skew = (np.max(f) - med) - (med - np.min(f))
        if best is None or skew > best[0]:
            best = (skew, f)
    return best[1]


def score(flex_rad: np.ndarray, c: LegClip) -> dict:
    """ROM error (mean over true strides), RMSE raw / offset removed, Pearson r; degrees."""
    est, tru = np.rad2deg(flex_rad), np.rad2deg(c.flexion_true_rad)
    roms = []
    for a, b in c.strides_s:
        sel = (c.t_s >= a) & (c.t_s < b)
        if sel.sum() > 10:
            roms.append(np.ptp(est[sel]) - np.ptp(tru[sel]))
    d = est - tru
    return {"rom_err_deg": float(np.mean(roms)) if roms else float("nan"),
            "rmse_deg": float(np.sqrt(np.mean(d**2))),
            "rmse_offset_deg": float(np.sqrt(np.mean((d - d.mean()) ** 2))),
            "r": float(np.corrcoef(est, tru)[0, 1]), "strides": len(roms)}


def orientation_errors(q: np.ndarray, q_true: np.ndarray) -> tuple[float, float]:
    """RMS heading and inclination error (°) of one sensor (earth-frame error split about the vertical, as BROAD)."""
    e = quat.multiply(q, quat.conjugate(q_true))
    head = 2.0 * np.arctan2(np.abs(e[:, 3]), np.abs(e[:, 0]))
    inc = 2.0 * np.arctan2(np.hypot(e[:, 1], e[:, 2]), np.hypot(e[:, 0], e[:, 3]))
    return float(np.rad2deg(np.sqrt(np.mean(head**2)))), float(np.rad2deg(np.sqrt(np.mean(inc**2))))


class offline_padding:
    """Context manager: ``chakamo``'s zero-phase acceleration low-pass with ``padtype`` for the run (diagnosis)."""

    def __init__(self, padtype: str = "odd") -> None:
        self.padtype = padtype

    def __enter__(self):
        import estimators.orientation.chakamo as ck

        self._module, self._saved = ck, ck.zero_phase_lowpass
        if self.padtype != "odd":
            from estimators.orientation.chakamo_offline import butterworth

            def lowpass(acc_i, acc_ok, tau_acc_s, fs_hz, _pad=self.padtype):
                from scipy import signal

                n = acc_i.shape[0]
                idx = np.flatnonzero(acc_ok)
                if idx.size < n:
                    t = np.arange(n)
                    acc_i = np.stack([np.interp(t, idx, acc_i[idx, j]) for j in range(3)], axis=1)
                if n <= 9:
                    return np.repeat(acc_i.mean(axis=0, keepdims=True), n, axis=0)
                b, a = butterworth(tau_acc_s, fs_hz)
                pad = min(n - 1, int(np.ceil(3.0 * tau_acc_s * fs_hz)))
                return signal.filtfilt(b, a, acc_i, axis=0, padtype=_pad, padlen=pad)

            ck.zero_phase_lowpass = lowpass
        return self

    def __exit__(self, *exc) -> None:
        self._module.zero_phase_lowpass = self._saved


def parse_params(items: Sequence[str]) -> dict[str, dict]:
    """``["chakamo:offline=false,tau_acc_s=5"]`` → ``{"chakamo": {"offline": False, "tau_acc_s": 5.0}}``."""
    out: dict[str, dict] = {}
    for item in items:
        name, _, rest = item.partition(":")
        d = out.setdefault(name, {})
        for kv in filter(None, rest.split(",")):
            k, _, v = kv.partition("=")
            low = v.strip().lower()
            d[k.strip()] = True if low == "true" else False if low == "false" else float(v)
    return out


def evaluate(seeds: Sequence[int], methods: Sequence[str], modes: Sequence[str], calibrations: Sequence[str],
             params: dict[str, dict] | None = None, truth_row: bool = True) -> list[dict]:
    """One row per (seed, side, variant, calibration): the :func:`score` fields plus names."""
    params = params or {}
    rows = []
    for seed in seeds:
        for c in clip(seed):
            cals = {"known": c.q_sensor_segment}
            if "data" in calibrations:
                cals["data"] = data_calibration(c)
            variants = []
            if truth_row:
                variants.append(("truth q", "9d", c.q_true["thigh"], c.q_true["shank"]))
            for m in methods:
                for mode in modes:
                    q = [estimate(c.acc[s], c.gyr[s], c.mag[s] if mode == "9d" else None, fs_hz=FS_HZ, method=m,
                                  **params.get(m, {})) for s in ("thigh", "shank")]
                    variants.append((m if mode == "9d" else f"{m} 6D", mode, q[0], q[1]))
            for name, mode, qt, qs in variants:
                errs = [orientation_errors(q, c.q_true[seg]) for q, seg in ((qt, "thigh"), (qs, "shank"))]
                oe = {"head_thigh_deg": errs[0][0], "inc_thigh_deg": errs[0][1],
                      "head_shank_deg": errs[1][0], "inc_shank_deg": errs[1][1]}
                if mode == "6d":  # heading is arbitrary in 6D
                    oe["head_thigh_deg"] = oe["head_shank_deg"] = float("nan")
                for cal_name in calibrations:
                    cal = cals[cal_name]
                    f = (flexion(qt, qs, cal, c.side, mode) if cal_name == "known"
                         else _signed_data_flexion(qt, qs, cal, c.side, mode))
                    rows.append({"seed": seed, "side": c.side, "variant": name, "calibration": cal_name,
                                 **score(f, c), **oe, **c.info})
    return rows


def summary(rows: list[dict]) -> list[dict]:
    out = []
    keys = []
    for r in rows:
        k = (r["variant"], r["calibration"])
        if k not in keys:
            keys.append(k)
    for v, cal in keys:
        sel = [r for r in rows if r["variant"] == v and r["calibration"] == cal]
        e = np.array([r["rom_err_deg"] for r in sel])
        out.append({"variant": v, "calibration": cal, "n": len(sel), "rom_mean_abs_deg": float(np.mean(np.abs(e))),
                    "rom_mean_signed_deg": float(np.mean(e)), "rom_worst_deg": float(e[np.argmax(np.abs(e))]),
                    "rmse_deg": float(np.mean([r["rmse_deg"] for r in sel])),
                    "rmse_offset_deg": float(np.mean([r["rmse_offset_deg"] for r in sel])),
                    "r_min": float(np.min([r["r"] for r in sel])),
                    "over_goal": int(np.sum(np.abs(e) > ROM_GOAL_DEG)),
                    **{k: float(np.mean([r[k] for r in sel])) for k in
                       ("head_thigh_deg", "inc_thigh_deg", "head_shank_deg", "inc_shank_deg")}})
    return out


def print_table(summ: list[dict]) -> None:
    print(f"{'variant':<16} {'calib':<6} {'n':>3} {'ROM |err| mean':>14} {'signed':>7} {'worst':>7} "
          f"{'RMSE':>6} {'RMSE-off':>8} {'r min':>6} {'>2°':>4} | {'head T/S':>11} {'incl T/S':>11}")
    for s in summ:
        print(f"{s['variant']:<16} {s['calibration']:<6} {s['n']:>3} {s['rom_mean_abs_deg']:14.2f} "
              f"{s['rom_mean_signed_deg']:7.2f} {s['rom_worst_deg']:7.2f} {s['rmse_deg']:6.2f} "
              f"{s['rmse_offset_deg']:8.2f} {s['r_min']:6.3f} {s['over_goal']:>4} | "
              f"{s['head_thigh_deg']:5.1f}/{s['head_shank_deg']:<5.1f} {s['inc_thigh_deg']:5.1f}/{s['inc_shank_deg']:<5.1f}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.walking", description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(6)))
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    parser.add_argument("--modes", nargs="+", choices=("9d", "6d"), default=["9d", "6d"])
    parser.add_argument("--calibrations", nargs="+", choices=("known", "data"), default=["known", "data"])
    parser.add_argument("--params", nargs="*", default=[], metavar="METHOD:K=V,...")
    parser.add_argument("--per-clip", action="store_true", help="also print every clip's row")
    parser.add_argument("--offline-padding", choices=("odd", "even"), default="odd",
                        help="diagnosis: edge padding of chakamo's offline acceleration low-pass (odd = as shipped)")
    parser.add_argument("--json", metavar="OUT")
    args = parser.parse_args(argv)
    params = parse_params(args.params)
    t0 = time.perf_counter()
    with offline_padding(args.offline_padding):
        rows = evaluate(args.seeds, args.methods, args.modes, args.calibrations, params)
    print(f"walking: seeds {args.seeds}, both legs, methods {' '.join(args.methods)}, modes {' '.join(args.modes)}, "
          f"default {DEFAULT_METHOD}, overrides {params or 'none'}, chakamo offline padding {args.offline_padding} "
          f"({time.perf_counter() - t0:.0f} s)")
    if args.per_clip:
        for r in rows:
            print(f"  seed {r['seed']:>3} {r['side']:<5} {r['variant']:<16} {r['calibration']:<6} "
                  f"ROM {r['rom_err_deg']:+6.2f} RMSE {r['rmse_deg']:6.2f} off {r['rmse_offset_deg']:5.2f} "
                  f"r {r['r']:.3f} ({r['duration_s']:.1f} s{', turn' if r['turn'] else ''})")
    summ = summary(rows)
    print_table(summ)
    known = {s["variant"]: s for s in summ if s["calibration"] == "known"}
    if DEFAULT_METHOD in known and "madgwick" in known:
        d, m = known[DEFAULT_METHOD], known["madgwick"]
        ok = abs(d["rom_worst_deg"]) <= ROM_GOAL_DEG and d["rom_mean_abs_deg"] <= m["rom_mean_abs_deg"]
        print(f"goal (known mounting, 9D): {DEFAULT_METHOD} worst |ROM err| {abs(d['rom_worst_deg']):.2f}° ≤ "
              f"{ROM_GOAL_DEG}° and mean {d['rom_mean_abs_deg']:.2f}° ≤ madgwick {m['rom_mean_abs_deg']:.2f}°: "
              f"{'met' if ok else 'NOT met'}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"rows": rows, "summary": summ}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
