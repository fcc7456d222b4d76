"""``chakamo demo``: the estimator core end to end on a simulated sensor with known truth.

One simulated MetaMotionR-like sensor (noise, gyroscope bias and drift, scale errors, hard and soft
iron, clock offsets, 20 Hz magnetometer interpolated onto the 100 Hz grid) records

1. a figure-eight magnetometer calibration (60 s) → ellipsoid fit and its quality figures;
2. a varied motion of ``duration_s`` → every orientation filter, 9D on the calibrated field and 6D,

and the accuracy against the simulator's truth is printed and written to ``OUT/filters.json``.
The knee-pipeline issue replaces this with a whole simulated session.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from estimators import __version__
from estimators import quaternion as quat
from estimators.magnetometer import fit_ellipsoid
from estimators.orientation import DEFAULT_METHOD, METHODS, make
from estimators.simulation import ImuSpec, motions, simulate_on_grid

FS_HZ = 100.0


def _inclination_error_rad(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    up_est = quat.rotate(quat.conjugate(q_est), [0.0, 0.0, 1.0])
    up_true = quat.rotate(quat.conjugate(q_true), [0.0, 0.0, 1.0])
    return np.arccos(np.clip(np.sum(up_est * up_true, axis=-1), -1.0, 1.0))


def _rms_deg(err_rad: np.ndarray) -> float:
    return float(np.rad2deg(np.sqrt(np.mean(np.square(err_rad)))))


def run_demo(out_dir: Path, *, seed: int = 7, duration_s: float = 60.0) -> dict:
    """Simulate, calibrate, estimate, score; print a table and write ``filters.json``; return the results."""
    if not np.isfinite(duration_s) or duration_s < 10.0:
        raise ValueError(f"--duration must be at least 10 s, got {duration_s}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    spec = ImuSpec.random(seed)

    calib_grid = simulate_on_grid(motions.figure_eight(60.0, seed=seed), spec, fs_hz=FS_HZ, seed=seed)
    calibration = fit_ellipsoid(calib_grid.mag)
    q = calibration.quality
    print(f"Magnetometer calibration (figure-eight, 60 s): field {calibration.field_ut:.1f} µT, "
          f"residual {q.residual_rms_ut:.2f} µT, coverage {100 * q.coverage_fraction:.0f} % of directions"
          + ("" if not q.warnings else "; warnings: " + ", ".join(w.code for w in q.warnings)))

    grid = simulate_on_grid(motions.rotations(duration_s, seed=seed + 1, translation_m=0.05), spec,
                            fs_hz=FS_HZ, seed=seed + 1)
    mag = calibration.apply(grid.mag)
    rows = []
    for name in METHODS:
        method = make(name)
        for mode in ("9d", "6d"):
            supported = method.supports_9d if mode == "9d" else method.supports_6d
            if not supported:
                continue
            method.estimate(grid.acc[:200], grid.gyr[:200], mag[:200] if mode == "9d" else None, fs_hz=FS_HZ)  # JIT warm-up
            t0 = time.perf_counter()
            q_est = method.estimate(grid.acc, grid.gyr, mag if mode == "9d" else None, fs_hz=FS_HZ).orientation_
            us_per_sample = 1e6 * (time.perf_counter() - t0) / len(q_est)
            row = {
                "method": name,
                "mode": mode,
                "inclination_rmse_deg": _rms_deg(_inclination_error_rad(q_est, grid.q_earth_sensor)),
                "us_per_sample": us_per_sample,
            }
            if mode == "9d":
                row["total_rmse_deg"] = _rms_deg(quat.angle_between(q_est, grid.q_earth_sensor))
            rows.append(row)

    print(f"\nOrientation accuracy against the simulated truth ({duration_s:.0f} s of motion at {FS_HZ:.0f} Hz, "
          f"default method: {DEFAULT_METHOD})")
    print(f"{'method':<12} {'mode':<4} {'total RMSE °':>13} {'inclination RMSE °':>19} {'µs/sample':>10}")
    for r in rows:
        total = f"{r['total_rmse_deg']:.2f}" if "total_rmse_deg" in r else "—"
        print(f"{r['method']:<12} {r['mode']:<4} {total:>13} {r['inclination_rmse_deg']:>19.2f} {r['us_per_sample']:>10.2f}")

    result = {
        "software": {"version": __version__},
        "simulation": {"seed": seed, "duration_s": duration_s, "fs_hz": FS_HZ},
        "calibration": {"magnetometer": calibration.to_dict()},
        "filters": rows,
    }
    path = out_dir / "filters.json"
    path.write_text(json.dumps(result, indent=2, default=float))
    print(f"\nWritten: {path}")
    return result
