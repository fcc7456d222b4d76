r"""One continuous recording per sensor (issue 14 §3a) and the phyphox reader: accuracy of the split, speed of reading.

Usage: ``python -m benchmarks.continuous [--seeds 0-4] [--cycles 10] [--repeats 3]``

Per seed, the simulator's protocol for both sensors (figure-eight 60 s, standing 30 s, supine 30 s, the step-up
with ``--cycles``; 6 s transitions, :func:`estimators.simulation.protocol.leg_protocol`; each sensor its own
errors and mounting) is written as MetaBase files labelled ``continuo-…`` and as phyphox zips (the three-set
layout with ``meta/time.csv``), then read with :func:`app.pipeline.ingestion.load_session` (read, split, align).
The split's thresholds were set from the protocol's description (``estimators.protocol_split.SplitParams``),
never tuned on these seeds.  Printed per seed: the largest distance of a found boundary from the truth (every
part's start and end, the task's end excepted: it is the recording's), and the median wall time of
``load_session`` over ``--repeats`` after one warm-up, for both formats, with the part that is the split itself.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

EPOCH0_S = 1_678_700_000.0
MACS = {"thigh": "D4F1A2B3C4E5", "shank": "E8C2B1A0F9D7"}
WORDS = {"thigh": "muslo", "shank": "pierna"}


def _seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def _session(seed: int, cycles: int):
    from estimators import simulation as sim
    from estimators.simulation.protocol import leg_protocol

    from app.pipeline.ingestion import simulated_streams

    motion = sim.step_up(cycles, 0.17, "right", seed=seed)
    streams, truth = {}, {}
    for i, seg in enumerate(("thigh", "shank")):
        mount = sim.random_rotation(np.deg2rad(15.0), seed * 10 + i)
        traj, truth[seg] = leg_protocol(motion, seg, mount, figure_eight_seed=seed + i)
        imu = sim.simulate(traj, sim.ImuSpec.random(seed * 10 + i), seed=seed * 100 + i)
        streams[seg] = simulated_streams(imu, EPOCH0_S)
    return streams, truth


def _write(root: Path, streams: dict) -> dict[str, Path]:
    import json

    from app.pipeline.ingestion.metabase import write_recording_metabase
    from app.pipeline.ingestion.phyphox import write_phyphox

    out = {"metabase": root / "metabase", "phyphox": root / "phyphox"}
    for folder in out.values():
        folder.mkdir(parents=True)
        (folder / "session.json").write_text(json.dumps({"side": "right"}), encoding="utf-8")
    for seg, s in streams.items():
        write_recording_metabase(out["metabase"], f"continuo-{WORDS[seg]}-ML1-13032023-1", MACS[seg], s)
        t0 = min(t[0] for t, _ in s.values())
        write_phyphox(out["phyphox"] / f"continuo-{WORDS[seg]}.zip", {k: (t - t0, v) for k, (t, v) in s.items()},
                      epoch0_s=t0)
    return out


def _timed(folder: Path, repeats: int) -> tuple[float, float, object]:
    """Median wall time of load_session and of the split inside it (s), and the last session."""
    import estimators.protocol_split as ps
    from app.pipeline.ingestion import load_session
    from app.pipeline.ingestion import split as split_module

    inner: list[float] = []
    original = ps.split_protocol

    def timed_split(*args, **kwargs):
        t = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            inner.append(time.perf_counter() - t)

    split_module.split_protocol = timed_split  # measured where the ingestion calls it
    try:
        load_session(folder)  # warm-up
        walls, splits = [], []
        for _ in range(repeats):
            inner.clear()
            t = time.perf_counter()
            session = load_session(folder)
            walls.append(time.perf_counter() - t)
            splits.append(sum(inner))
    finally:
        split_module.split_protocol = original
    return statistics.median(walls), statistics.median(splits), session


def _error_s(session, truth) -> float:
    worst = 0.0
    for split in session.splits:
        for part, (a, b) in truth[split.segment].items():
            got_a, got_b = split.spans_s[part]
            worst = max(worst, abs(got_a - a), 0.0 if part == "task" else abs(got_b - b))
    return worst


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.continuous", description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", default="0-4")
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    print("| seed | worst boundary error (s) | MetaBase read+split+align (s) | of which split (s) | "
          "phyphox read+split+align (s) | of which split (s) |")
    print("| --- | --- | --- | --- | --- | --- |")
    errors = []
    for seed in _seeds(args.seeds):
        streams, truth = _session(seed, args.cycles)
        with tempfile.TemporaryDirectory() as tmp:
            folders = _write(Path(tmp), streams)
            wall_m, split_m, session = _timed(folders["metabase"], args.repeats)
            wall_p, split_p, session_p = _timed(folders["phyphox"], args.repeats)
        err = max(_error_s(session, truth), _error_s(session_p, truth))
        errors.append(err)
        print(f"| {seed} | {err:.2f} | {wall_m:.3f} | {split_m:.3f} | {wall_p:.3f} | {split_p:.3f} |")
    print(f"\nworst boundary error over {len(errors)} seeds: {max(errors):.2f} s (goal: within ~1 s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
