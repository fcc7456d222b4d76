r"""Speed: µs per sample of every orientation method, 9D and 6D, beside ``ahrs`` and VQF.

Usage
-----
``python -m benchmarks.speed [--samples 60000] [--ahrs-samples 6000] [--repeats 5] [--methods ...] [--json OUT]``

Each project method (``estimators.orientation.METHODS``; a method whose module is not written yet is
skipped with a note) is timed through the public call ``estimate(acc, gyr, mag, fs_hz=..., method=...)``,
so input validation and the initial alignment are included, as a user pays them:

* *first call* — the first call of the process on a short input (1000 samples), after the method's module
  was imported (the import time is noted separately): numba compilation of the kernel.  By default numba's on-disk cache is pointed at a fresh temporary folder so this really is a
  compilation; ``--warm-cache`` keeps the normal cache (then it is the cache load);
* *steady state* — the median over ``--repeats`` calls on ``--samples`` samples, in µs per sample.

Comparison rows: VQF 2.1.2 (C++ via Cython; ``offlineVQF`` and ``VQF.updateBatch``) on the same samples,
and the pure-Python ``ahrs`` 0.4.0 filters (Madgwick, FKF, AQUA), which are ~10⁴ times slower, on only
``--ahrs-samples`` samples (said so in the table).  The input is the project simulator's varied rotation
sequence at 100 Hz (``estimators.simulation.motions.rotations``, rests and turns up to 300 °/s, small
translations) recorded by a sensor with a MetaMotionR-like error model (``ImuSpec.random``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

FS_HZ = 100.0
FIRST_CALL_SAMPLES = 1000


def simulated_imu(n: int, fs_hz: float = FS_HZ, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``acc, gyr, mag`` ``(n, 3)`` of the project simulator's varied rotations with a MetaMotionR-like error model."""
    from estimators.simulation import ImuSpec, motions, simulate_on_grid

    duration_s = n / fs_hz + 1.0
    grid = simulate_on_grid(motions.rotations(duration_s, seed=seed, translation_m=0.05), ImuSpec.random(seed),
                            fs_hz=fs_hz, seed=seed)
    return grid.acc[:n], grid.gyr[:n], grid.mag[:n]


def _time_call(fn: Callable[[], Any], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _row(method: str, mode: str, n: int, per_call_s: float, first_s: float | None, repeats: int, note: str = "") -> dict:
    return {"method": method, "mode": mode, "samples": n, "us_per_sample": per_call_s / n * 1e6,
            "first_call_s": first_s, "repeats": repeats, "note": note}


def _variants(name: str) -> list[tuple[str, dict[str, Any]]]:
    """A method's rows: its defaults, plus its causal pass when the default is an offline smoother."""
    from dataclasses import fields

    from estimators import orientation

    variants: list[tuple[str, dict[str, Any]]] = [(name, {})]
    params = {f.name: f.default for f in fields(orientation.get_method(name).params_type)}
    if params.get("offline") is True:
        variants.append((f"{name}_causal", {"offline": False}))
    return variants


def bench_project(names: Sequence[str], data: tuple, repeats: int) -> tuple[list[dict], list[str]]:
    """Time the project's methods; ``(rows, notes)``."""
    from estimators import orientation

    acc, gyr, mag = data
    n = acc.shape[0]
    rows, notes = [], []
    short = slice(0, FIRST_CALL_SAMPLES)
    for name in names:
        try:
            start = time.perf_counter()
            variants = _variants(name)  # imports the module, so that the first call is the compilation
            import_s = time.perf_counter() - start
        except (ImportError, NotImplementedError) as exc:
            notes.append(f"skipped {name}: {type(exc).__name__}: {exc}")
            continue
        for label, params in variants:
            for mode in ("9d", "6d"):
                m = mag if mode == "9d" else None
                m_short = None if m is None else m[short]
                try:
                    start = time.perf_counter()
                    orientation.estimate(acc[short], gyr[short], m_short, fs_hz=FS_HZ, method=name, **params)
                    first_s = time.perf_counter() - start
                except Exception as exc:  # noqa: BLE001 - e.g. no 6D variant, or a method still being written
                    notes.append(f"skipped {label} {mode}: {type(exc).__name__}: {exc}")
                    continue
                per_call = _time_call(
                    lambda m=m, name=name, params=params: orientation.estimate(acc, gyr, m, fs_hz=FS_HZ, method=name,
                                                                    **params), repeats)
                note = f"import {import_s:.2f} s" if mode == "9d" and label == name else ""
                rows.append(_row(label, mode, n, per_call, first_s, repeats, note))
    return rows, notes


def bench_vqf(data: tuple, repeats: int) -> tuple[list[dict], list[str]]:
    try:
        import vqf
    except ImportError as exc:
        return [], [f"skipped vqf: {exc}"]
    acc, gyr, mag = (np.ascontiguousarray(a) for a in data)
    n = acc.shape[0]
    rows = []
    for mode, m in (("9d", mag), ("6d", None)):
        rows.append(_row("vqf_offline", mode, n, _time_call(lambda m=m: vqf.offlineVQF(gyr, acc, m, 1 / FS_HZ), repeats),
                         None, repeats, "C++"))
        rows.append(_row("vqf_online", mode, n,
                         _time_call(lambda m=m: vqf.VQF(1 / FS_HZ).updateBatch(gyr, acc, m), repeats), None, repeats, "C++"))
    return rows, []


def bench_ahrs(data: tuple, n_samples: int, repeats: int) -> tuple[list[dict], list[str]]:
    from benchmarks.broad import COMPARISONS

    acc, gyr, mag = (a[:n_samples] for a in data)
    rows = []
    for key in ("ahrs_madgwick", "ahrs_fkf", "ahrs_aqua"):
        fn, modes, _ = COMPARISONS[key]
        for mode in modes:
            m = mag if mode == "9d" else None
            try:
                per_call = _time_call(lambda fn=fn, m=m: fn(acc, gyr, m, FS_HZ), repeats)
            except ImportError as exc:
                return rows, [f"skipped ahrs: {exc}"]
            rows.append(_row(key, mode, n_samples, per_call, None, repeats, f"pure Python, {n_samples} samples"))
    return rows, []


def format_table(rows: Sequence[dict]) -> str:
    width = max(len(r["method"]) for r in rows)
    head = f"{'method':<{width}} | mode | {'µs/sample':>10} | {'first call s':>12} | {'samples':>7} | note"
    lines = [head, "-" * len(head)]
    for r in rows:
        first = f"{r['first_call_s']:12.3f}" if r["first_call_s"] is not None else f"{'':>12}"
        lines.append(f"{r['method']:<{width}} | {r['mode']:>4} | {r['us_per_sample']:10.3f} | {first} | "
                     f"{r['samples']:>7} | {r['note']}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.speed", description=__doc__.split("\n")[0])
    parser.add_argument("--samples", type=int, default=60000, help="samples per timed call (default 60000)")
    parser.add_argument("--ahrs-samples", type=int, default=6000, help="samples for the slow ahrs filters")
    parser.add_argument("--repeats", type=int, default=5, help="timed calls per row; the median is reported")
    parser.add_argument("--methods", nargs="+", metavar="NAME", help="project methods (default: all)")
    parser.add_argument("--no-ahrs", action="store_true", help="skip the ahrs rows")
    parser.add_argument("--warm-cache", action="store_true", help="keep numba's on-disk cache (first call = load)")
    parser.add_argument("--json", metavar="OUT", help="also write the rows to this JSON file")
    args = parser.parse_args(argv)
    if args.samples < FIRST_CALL_SAMPLES or args.repeats < 1 or args.ahrs_samples < 10:
        parser.error(f"--samples must be >= {FIRST_CALL_SAMPLES}, --repeats >= 1, --ahrs-samples >= 10")

    cache_dir = None
    if not args.warm_cache:
        if "numba" in sys.modules:
            print("note: numba already imported; the first-call column may be a cache load", file=sys.stderr)
        cache_dir = tempfile.TemporaryDirectory(prefix="chakamo-numba-")
        os.environ["NUMBA_CACHE_DIR"] = cache_dir.name

    from estimators.orientation import METHODS

    names = args.methods or list(METHODS)
    data = simulated_imu(args.samples)
    print(f"speed: simulated rotations (MetaMotionR-like errors), {args.samples} samples at {FS_HZ:g} Hz, median of {args.repeats} calls; "
          f"numba cache {'warm' if args.warm_cache else 'cold (first call = compilation)'}", flush=True)
    rows, notes = bench_project(names, data, args.repeats)
    for part in (bench_vqf(data, args.repeats),
                 ([], []) if args.no_ahrs else bench_ahrs(data, args.ahrs_samples, max(1, min(args.repeats, 3)))):
        rows += part[0]
        notes += part[1]
    print(format_table(rows) if rows else "no method could be timed")
    for note in notes:
        print(note)
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "notes": notes}, indent=1))
    if cache_dir is not None:
        cache_dir.cleanup()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
