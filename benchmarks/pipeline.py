r"""Speed and memory of one knee session through ``chakamo process`` (issue 3 goals: ≤ 1 s, ≤ 300 MB).

Usage: ``python -m benchmarks.pipeline [--cycles 10] [--repeats 5] [--filter NAME] [--format metabase|generic|xlsx]
[--outputs results|all]``

The read and alignment alone of every supported format (issue 14's goal, ≤ 0.3 s) is
``python -m benchmarks.read_formats``.

``--outputs results`` (issue 3's goal) writes ``results.json`` and ``timeseries.npz`` only and never imports the
report libraries; ``all`` (the default, issue 4's goal ≤ 0.5 s for the outputs) adds the PDF, Excel, HTML and
3D scene.  Run each in its own process: the peak resident memory is per process.

The demo's simulated session (two sensors × four recordings: 60 s figure-eight, 30 s standing,
30 s supine, the step-up task; ~3.5 min of data per sensor) is written once as files, then processed
``--repeats`` times after one warm-up run (numba compilation, imports).  Printed: the wall time of
the whole job (reading and aligning the files, calibrations, both orientation filters, knee angles,
cycle analysis, writing ``results.json``) and of each stage, median over the repeats; the peak of
Python allocations during one run (``tracemalloc``) and the process's peak resident memory (which
includes the interpreter, numpy, scipy and numba themselves).
"""

from __future__ import annotations

import argparse
import resource
import statistics
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Sequence
from pathlib import Path

from estimators.orientation import DEFAULT_METHOD, METHODS


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.pipeline", description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--filter", choices=METHODS, default=DEFAULT_METHOD)
    parser.add_argument("--format", choices=("metabase", "generic", "xlsx"), default="metabase")
    parser.add_argument("--outputs", choices=("results", "all"), default="all")
    args = parser.parse_args(argv)

    from app.pipeline.demo import simulate_session, write_session
    from app.pipeline.session import ProcessOptions
    from app.pipeline.process import process_folder

    with_reports = args.outputs == "all"

    work = Path(tempfile.mkdtemp(prefix="chakamo-bench-"))
    truth = simulate_session(seed=7, side="right", n_cycles=args.cycles)
    files = write_session(work / "session", truth, args.format)
    size_mb = sum(f.stat().st_size for f in files) / 1e6
    options = ProcessOptions(filter_name=args.filter)

    stages: dict[str, list[float]] = {}
    last = {"t": 0.0, "stage": ""}

    def progress(stage: str, fraction: float) -> None:
        now = time.perf_counter()
        if last["stage"]:
            stages.setdefault(last["stage"], []).append(now - last["t"])
        last.update(t=now, stage=stage)

    process_folder(work / "session", work / "out", options, reports=with_reports)  # warm-up: compilation, imports
    totals = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        last.update(t=start, stage="")
        process_folder(work / "session", work / "out", options, progress=progress, reports=with_reports)
        end = time.perf_counter()
        stages.setdefault(last["stage"], []).append(end - last["t"])
        totals.append(end - start)
    tracemalloc.start()
    process_folder(work / "session", work / "out", options, reports=with_reports)
    _, peak_bytes = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB on Linux

    n_task = sum(len(s["acc"][0]) for (seg, role), s in truth.recordings.items() if role == "task") // 2
    print(f"pipeline: {args.cycles}-cycle session, {len(files)} {args.format} files ({size_mb:.1f} MB), "
          f"task {n_task / 100:.0f} s, filter {args.filter}, outputs: {args.outputs}; "
          f"median of {args.repeats} runs after warm-up")
    print(f"{'stage':<20} {'ms':>8}")
    print("-" * 29)
    for stage, values in stages.items():
        print(f"{stage:<20} {1e3 * statistics.median(values):8.1f}")
    print("-" * 29)
    print(f"{'total (wall)':<20} {1e3 * statistics.median(totals):8.1f}")
    print(f"peak Python allocations during one run: {peak_bytes / 1e6:.0f} MB; process peak RSS: {rss_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
