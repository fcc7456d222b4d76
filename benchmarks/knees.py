r"""Limb symmetry index on simulated four-sensor walks against the asymmetry put in (issue 15 §2).

Usage
-----
``python -m benchmarks.knees [--seeds 0-9] [--gains 0.7,0.8,0.9,1.0] [--write DIR]``

Each draw is :func:`app.pipeline.demo.simulate_walk_knees` (14 s walk after a 2 s stand, both legs, four
factory-calibrated sensors with the simulator's noise, bias and up to 12° misalignment, heel strikes and
soft-tissue wobble) with the left knee's flexion scaled by ``gain``
(:func:`estimators.simulation.gait.walking` ``knee_gain``), written as MetaBase files whose names carry the side,
read by :func:`app.pipeline.ingestion.load_knees` and processed by :func:`app.pipeline.knees.process_knees` with the
left knee involved.  Truth: the LSI of the flexion parameters is ``100 × gain`` (every left flexion is ``gain`` ×
the same stride draw of the right's), of the timing parameters 100 % (both legs share the stride clock).  The
table prints, per parameter, the median and worst |LSI − truth| in percentage points over every draw.

Nothing here was tuned: the LSI has no parameter.  The choice of which parameters carry an LSI (flexion and timing,
not the adduction or rotation ranges) was made on seed 1 at gain 0.8 (``tests/app/pipeline/test_knees_session.py``);
the other seeds and gains are held out.  Simulator-only: no real four-sensor recording is in ``../shared``.

``--write DIR`` only writes one such session (seed 1, gain 0.8, patient side left) into DIR, e.g. for
``python -m benchmarks.cold --session DIR --task gait`` (the four-sensor cold-start goal: ≤ 2.5 s wall).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np


def _seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def run(seeds: list[int], gains: list[float]) -> dict[str, list[float]]:
    """``{parameter: [LSI − truth, ...]}`` over every (seed, gain)."""
    from app.pipeline.demo import simulate_walk_knees, write_knees_session
    from app.pipeline.ingestion import load_knees
    from app.pipeline.knees import LSI_GAIT, process_knees
    from app.pipeline.results import build_knees_results
    from app.pipeline.session import ProcessOptions

    flexion = {"loading_response_peak_flexion", "swing_peak_flexion", "flexion_rom"}
    errors: dict[str, list[float]] = {name: [] for name, _, _ in LSI_GAIT}
    with tempfile.TemporaryDirectory(prefix="chakamo_knees_") as tmp:
        for seed in seeds:
            for gain in gains:
                folder = Path(tmp) / f"s{seed}_{gain}"
                write_knees_session(folder, simulate_walk_knees(seed=seed, knee_gain={"left": gain}))
                knees = process_knees(load_knees(folder), ProcessOptions(task="gait", involved="left"))
                for p in build_knees_results(knees)["symmetry"]["parameters"]:
                    truth = 100.0 * gain if p["name"] in flexion else 100.0
                    errors[p["name"]].append(np.nan if p["lsi_pct"] is None else p["lsi_pct"] - truth)
                print(f"seed {seed} gain {gain:.2f}: swing peak LSI "
                      f"{errors['swing_peak_flexion'][-1] + 100 * gain:.1f} % (truth {100 * gain:.0f} %)", flush=True)
    return errors


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seeds", default="0-9", help="walk seeds, e.g. 0-9 (default)")
    parser.add_argument("--gains", default="0.7,0.8,0.9,1.0", help="left knee flexion gains (default 0.7,0.8,0.9,1.0)")
    parser.add_argument("--write", type=Path, default=None, help="only write one four-sensor session into this folder")
    args = parser.parse_args(argv)
    if args.write is not None:
        from app.pipeline.demo import simulate_walk_knees, write_knees_session

        write_knees_session(args.write, simulate_walk_knees(seed=1, knee_gain={"left": 0.8}), patient_side="left")
        print(args.write)
        return 0
    seeds, gains = _seeds(args.seeds), [float(g) for g in args.gains.split(",")]
    errors = run(seeds, gains)
    print("\n| LSI parameter | draws | median abs error (points) | worst abs error (points) |")
    print("| --- | --- | --- | --- |")
    for name, e in errors.items():
        a = np.abs(np.asarray(e, dtype=float))
        print(f"| {name} | {np.isfinite(a).sum()} | {np.nanmedian(a):.2f} | {np.nanmax(a):.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
