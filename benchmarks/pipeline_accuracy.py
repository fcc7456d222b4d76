r"""Knee-angle accuracy of the whole pipeline on simulated sessions with known truth (issue 3's goal).

Usage: ``python -m benchmarks.pipeline_accuracy [--seeds 10] [--cycles 6] [--filter NAME]
[--accelerometer-errors] [--calibration static|functional] [--supine-roll-out DEG]``

Each seed simulates a session (:func:`app.pipeline.demo.simulate_session`; odd seeds the right leg, even seeds the
left), writes it as MetaBase files, processes it with ``chakamo process``'s code path and compares with the
truth.  By default the sensors carry the goal's error set — noise, gyroscope bias, hard and soft iron, up to
15° mounting misalignment, clock drift; ``--accelerometer-errors`` adds accelerometer bias, scale and axis
errors (the demo's sensor); ``--supine-roll-out`` lets the leg lie rolled outwards in the supine
recording, which ``--calibration functional`` is for.  Prints per seed and the worst: RMSE of flexion, adduction and internal
rotation (°), cycles found of the true ones, the largest phase-boundary error (% of the cycle) and, for the
functional calibration, which flexion axis was used (``seel``, or ``relative`` when Seel's estimate disagreed
with the filters' relative motion and the pipeline warned ``functional_axis_uncertain``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from estimators.orientation import DEFAULT_METHOD, METHODS


def _axis(outcome) -> str:
    """Which flexion axis the functional calibration used ("-" for the static calibration)."""
    if outcome.options.calibration != "functional":
        return "-"
    return "relative" if any(w.code == "functional_axis_uncertain" for w in outcome.warnings) else "seel"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.pipeline_accuracy", description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--cycles", type=int, default=6)
    parser.add_argument("--filter", choices=METHODS, default=DEFAULT_METHOD)
    parser.add_argument("--accelerometer-errors", action="store_true")
    parser.add_argument("--calibration", choices=("static", "functional"), default="static")
    parser.add_argument("--supine-roll-out", type=float, default=0.0, metavar="DEG")
    args = parser.parse_args(argv)

    from app.pipeline.demo import accuracy, simulate_session, write_session
    from app.pipeline.session import ProcessOptions
    from app.pipeline.process import process_folder

    print(f"pipeline accuracy: {args.seeds} simulated sessions, {args.cycles} step-up cycles, filter {args.filter}, "
          f"accelerometer errors {'on' if args.accelerometer_errors else 'off (the goal conditions)'}, "
          f"{args.calibration} calibration, supine rolled out {args.supine_roll_out:g}°")
    print(f"{'seed':>4} {'side':<5} {'flexion °':>9} {'adduction °':>11} {'rotation °':>10} {'cycles':>7} {'phase %':>8} {'axis':>8}")
    rows = []
    for seed in range(1, args.seeds + 1):
        side = "right" if seed % 2 else "left"
        truth = simulate_session(seed=seed, side=side, n_cycles=args.cycles,
                                 accelerometer_errors=args.accelerometer_errors,
                                 supine_roll_out_deg=args.supine_roll_out)
        work = Path(tempfile.mkdtemp(prefix="chakamo-acc-"))
        write_session(work / "session", truth)
        outcome, _ = process_folder(work / "session", work / "out", ProcessOptions(filter_name=args.filter, calibration=args.calibration),
                                    reports=False)
        a = accuracy(outcome, truth)
        r = a["rmse_deg"]
        rows.append([r["flexion"], r["adduction"], r["internal_rotation"], a["phase_boundary_max_error_pct"]])
        print(f"{seed:>4} {side:<5} {r['flexion']:9.2f} {r['adduction']:11.2f} {r['internal_rotation']:10.2f} "
              f"{a['cycles_found']:>3}/{a['cycles_true']:<3} {a['phase_boundary_max_error_pct']:8.2f} {_axis(outcome):>8}")
    worst = np.max(rows, axis=0)
    print(f"{'worst':>10} {worst[0]:9.2f} {worst[1]:11.2f} {worst[2]:10.2f} {'':>7} {worst[3]:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
