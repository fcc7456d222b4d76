r"""Reading and aligning a 10-cycle session in every supported format (issue 14 goal: ≤ 0.3 s after warm-up).

Usage: ``python -m benchmarks.read_formats [--cycles 10] [--repeats 5] [--formats metabase,xsens,...]``

The demo's simulated session (:func:`app.pipeline.demo.simulate_session`: two sensors × figure-eight 60 s,
standing 30 s, supine 30 s and the step-up with ``--cycles``) is written by the project's own writers in each
format — MetaBase, generic CSV, the thesis' xlsx (:func:`app.pipeline.demo.write_session`), Xsens MT Manager
(normalised magnetometer), APDM Opal ``.h5`` (one file per role, both sensors), Shimmer Consensys, Sensor Logger
and phyphox zips — and, as ``continuous``, each sensor's whole protocol in one MetaBase recording
(:func:`benchmarks.continuous._session`, split when read).  Timed: :func:`app.pipeline.ingestion.load_session`
(read, convert, split, align every recording) plus ``Session.task_pair()`` (the two task recordings on one grid),
median of ``--repeats`` after one warm-up, as wall time and as this process' CPU time (``time.process_time``: the
part the machine's load does not inflate, as long as the reading is single-threaded), with the load average
beside them (the machine is shared).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import shutil
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

FORMATS = ("metabase", "generic", "xlsx", "xsens", "apdm", "shimmer", "sensorlogger", "phyphox", "continuous")
GOAL_S = 0.3


def _on_grid(streams):
    """acc's stamps; gyr and mag interpolated on them (Xsens, APDM and Shimmer sample all three on one clock)."""
    t, acc = streams["acc"]
    on = [np.stack([np.interp(t, ts, v[:, i]) for i in range(3)], axis=1) for ts, v in (streams["gyr"], streams["mag"])]
    return t, acc, on[0], on[1]


def write_format(folder: Path, session, fmt: str) -> None:
    """The demo ``session`` (:class:`app.pipeline.demo.SimulatedSession`) as a session folder in ``fmt``."""
    from app.pipeline.demo import write_session
    from app.pipeline.ingestion.writers import session_label

    if fmt in ("metabase", "generic", "xlsx"):
        write_session(folder, session, fmt)
        return
    folder.mkdir(parents=True)
    (folder / "session.json").write_text(json.dumps({"side": session.side, "step_height_m": session.step_height_m}),
                                         encoding="utf-8")
    ids = {"thigh": "00B42D4F", "shank": "00B42D50"}
    if fmt == "apdm":
        from app.pipeline.ingestion.opal import write_opal

        for role in ("mag_calibration", "standing", "lying", "task"):
            sensors = {}
            for seg, label in (("thigh", "Right Thigh"), ("shank", "Right Shank")):
                t, acc, gyr, mag = _on_grid(session.recordings[(seg, role)])
                sensors[ids[seg]] = {"label": label, "rate_hz": 100.0, "t_s": t, "acc": acc, "gyr": gyr, "mag": mag}
            name = {"mag_calibration": "calibration", "lying": "supine", "task": "step"}.get(role, role)
            write_opal(folder / f"{name}-DEMO-001.h5", sensors)   # both sensors: the segment from their labels
        return
    for (seg, role), streams in session.recordings.items():
        name = session_label(seg, role, "DEMO-001", "22112026", lang="en")
        if fmt == "xsens":
            from app.pipeline.ingestion.xsens import write_xsens

            t, acc, gyr, mag = _on_grid(streams)
            field = float(np.median(np.linalg.norm(mag, axis=1)))
            write_xsens(folder / f"{name}.txt", t - t[0], acc, gyr, mag / field, device_id=ids[seg])
        elif fmt == "shimmer":
            from app.pipeline.ingestion.shimmer import write_shimmer

            t, acc, gyr, mag = _on_grid(streams)
            write_shimmer(folder / f"{name}.csv", t * 1e3, acc, gyr, mag, device=f"Shimmer_{ids[seg][-4:]}")
        elif fmt == "sensorlogger":
            from app.pipeline.ingestion.sensorlogger import write_sensorlogger

            write_sensorlogger(folder / f"{name}.zip", streams, device_id=ids[seg])
        elif fmt == "phyphox":
            from app.pipeline.ingestion.phyphox import write_phyphox

            t0 = min(t[0] for t, _ in streams.values())
            write_phyphox(folder / f"{name}.zip", {k: (t - t0, v) for k, (t, v) in streams.items()}, epoch0_s=t0)
        else:
            raise ValueError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")


def write_continuous(folder: Path, cycles: int) -> None:
    """Each sensor's whole protocol as one MetaBase recording (split when read)."""
    from benchmarks.continuous import _session, _write

    streams, _ = _session(0, cycles)
    written = _write(folder, streams)["metabase"]
    for p in written.iterdir():
        p.rename(folder / p.name)


def timed(folder: Path, repeats: int) -> tuple[float, float, int]:
    """Median wall and CPU seconds of load_session + task_pair over ``repeats`` after a warm-up; task samples."""
    from app.pipeline.ingestion import load_session

    thigh, _ = load_session(folder).task_pair()   # warm-up: imports, numba kernels, file cache
    walls, cpus = [], []
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        load_session(folder).task_pair()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return statistics.median(walls), statistics.median(cpus), len(thigh.t_s)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.read_formats", description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--formats", default=",".join(FORMATS))
    args = parser.parse_args(argv)
    formats = [f for f in args.formats.split(",") if f]
    unknown = set(formats) - set(FORMATS)
    if unknown:
        parser.error(f"unknown formats {sorted(unknown)}; use {', '.join(FORMATS)}")

    from app.pipeline.demo import simulate_session

    session = simulate_session(seed=7, side="right", n_cycles=args.cycles)
    work = Path(tempfile.mkdtemp(prefix="chakamo-read-"))
    try:
        return _table(args, formats, session, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _table(args, formats, session, work: Path) -> int:
    print(f"read + align of a {args.cycles}-cycle session, median of {args.repeats} after warm-up "
          f"(goal ≤ {GOAL_S} s); load average at start {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'format':<14} {'files':>5} {'MB':>6} {'task s':>7} {'wall s':>7} {'CPU s':>7} {'load':>5}  goal (CPU)")
    print("-" * 68)
    for fmt in formats:
        folder = work / fmt
        if fmt == "continuous":
            folder.mkdir()
            write_continuous(folder, args.cycles)
        else:
            write_format(folder, session, fmt)
        files = [p for p in folder.iterdir() if p.name != "session.json"]
        size = sum(p.stat().st_size for p in files) / 1e6
        wall, cpu, n_task = timed(folder, args.repeats)
        print(f"{fmt:<14} {len(files):>5} {size:>6.1f} {n_task / 100:>7.0f} {wall:>7.3f} {cpu:>7.3f} "
              f"{os.getloadavg()[0]:>5.1f}  {'met' if cpu <= GOAL_S else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
