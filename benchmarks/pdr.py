r"""Foot-mounted PDR on the IEZ walks: every method × stance detector, both sensors, beside the thesis.

Usage
-----
``python -m benchmarks.pdr [--data DIR] [--methods 9iez chakamo ...] [--detectors c123 pitch] [--json OUT]``
(≈ 10 s) prints, per method and detector, EP, ED (sample-wise), ED stance-to-stance, EA and the time per
walk (median of 3 runs after a JIT warm-up) for every file and sensor, then the means, then the means per
range configuration beside the thesis' Tables 5–8 (configurations C00 and C30 are among the shared walks;
the thesis averaged 30 walks per configuration) and Table 9 (detectors compared with 15IEZ+ZARU on C33).
The data is looked up in ``--data``, ``$CHAKAMO_IEZ_DIR`` or ``../shared/data/iez`` beside the repository;
without it the script says so and exits with status 2.

Data: 7 closed-loop walks of the 22.1 m rectangle, two foot-mounted MPU-6050 (README in the data folder).
Metrics: seed 001 eqs. 4.3–4.5 (:mod:`estimators.pdr.metrics`); ED stance-to-stance is ChakaMo's addition.
Note that stance-to-stance distances of *foot placements* are expected to fall short of the 22.1 m centre
line: every corner stride is a chord across the corner, and the inner foot walks a shorter rectangle than
the outer one (±0.1 m lateral offset ≈ ∓0.6 m of perimeter, 2π·0.1).  The last table measures it on the
simulator (:func:`estimators.simulation.footpath.lane_footprints`): the *true* stance-to-stance length of
one foot walking the 22.1 m lane, against 22.1 m, for corner radii, foot offsets and stride phases, and the
default method's estimate on one simulated walk of that kind.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from app.research.walk_ingestion import read_iez
from estimators.pdr import DETECTORS, METHODS, reconstruct
from estimators.pdr.metrics import stance_positions
from estimators.simulation.footpath import lane_footprints

DATA_ENV = "CHAKAMO_IEZ_DIR"
TRUE_DISTANCE_M = 22.1

# seed 001, Tables 5–8 (means of 30 walks per configuration; EP and ED as fractions, EA in m, time in s)
THESIS_CONFIGS = ("C00", "C03", "C30", "C33")
THESIS = {
    "ep": {"9iez": (0.02477, 0.02484, 0.04433, 0.02263), "9iez_mad": (0.12573, 0.04233, 0.18287, 0.04506),
           "9iez_kf": (0.02253, 0.02232, 0.04442, 0.02018), "15iez_zaru": (0.01471, 0.01342, 0.03561, 0.00982)},
    "ed": {"9iez": (0.21927, 0.22546, 0.18443, 0.18053), "9iez_mad": (1.56811, 0.23870, 1.73145, 0.23147),
           "9iez_kf": (0.21826, 0.24288, 0.17872, 0.20097), "15iez_zaru": (0.20237, 0.09579, 0.21085, 0.09566)},
    "ea_m": {"9iez": (0.18426, 0.77960, 1.06814, 0.58955), "9iez_mad": (1.76186, 0.61892, 1.44616, 0.40434),
             "9iez_kf": (0.20033, 0.78824, 1.07481, 0.59684), "15iez_zaru": (0.40666, 0.83520, 1.02897, 0.64060)},
    "time_s": {"9iez": (1.24708, 1.11387, 1.08599, 1.11654), "9iez_mad": (1.43080, 1.38165, 1.26690, 1.30850),
               "9iez_kf": (1.49051, 1.35805, 1.30649, 1.37733), "15iez_zaru": (1.36397, 1.25783, 1.19851, 1.23642)},
}
# Table 9: 15IEZ+ZARU, C33, mean (SD)
THESIS_T9 = {"c123": {"ep": (0.00402, 0.00092), "ed": (0.10393, 0.01503), "ea_m": (0.43265, 0.14002), "time_s": (1.76007, 0.55837)},
             "pitch": {"ep": (0.00864, 0.00227), "ed": (0.11238, 0.01097), "ea_m": (0.35009, 0.19183), "time_s": (1.91496, 0.92625)}}


def data_dir(explicit: str | None = None) -> Path | None:
    """The IEZ folder: ``explicit``, else ``$CHAKAMO_IEZ_DIR``, else ``../shared/data/iez`` beside the repo."""
    if explicit:
        return Path(explicit)
    if os.environ.get(DATA_ENV):
        return Path(os.environ[DATA_ENV])
    repo = Path(__file__).resolve().parents[1]
    for cand in (repo.parent / "shared" / "data" / "iez", repo.parent.parent / "shared" / "data" / "iez"):
        if cand.is_dir():
            return cand
    return None


def config_of(name: str) -> str:
    """Thesis configuration label ``C<acc code><gyr code>`` of sensor 1 (``conf-3030-...`` → ``C30``)."""
    return "C" + name.split("-")[1][:2]


def box_perimeter_m(pos_m: np.ndarray, stance: np.ndarray) -> float:
    """Perimeter of the stance positions' bounding box in their principal axes, m.

    The circuit is a 8.7 m × 2.1 m rectangle, but a foot does not step on its corners: with strides of
    ~1.1 m the polygon of stance positions cuts each corner, so even a perfect estimate has a stance-to-stance
    length a few per cent below 22.1 m.  The extent of the walked rectangle does not have that bias and checks
    the estimate's scale."""
    sp, _ = stance_positions(pos_m, stance)
    xy = sp[:, :2] - sp[:, :2].mean(axis=0)
    _, _, vt = np.linalg.svd(xy, full_matrices=False)
    along = xy @ vt.T
    return float(2.0 * np.sum(along.max(axis=0) - along.min(axis=0)))


def evaluate(folder: Path, methods, detectors, repeats: int = 3) -> list[dict]:
    """One row per file × sensor × method × detector: ep, ed, ed_stance, ed_box, ea_m, time_ms."""
    recs = [read_iez(f, s) for f in sorted(folder.glob("conf-*.csv")) for s in (1, 2)]
    rows = []
    for method in methods:
        for det in detectors:
            # JIT warm-up (compilation is cached on disk, this also warms the orientation filters)
            reconstruct(recs[0].t_s, recs[0].acc, recs[0].gyr, method=method, detector=det)
            for rec in recs:
                times = []
                for _ in range(repeats):
                    t0 = time.perf_counter()
                    res = reconstruct(rec.t_s, rec.acc, rec.gyr, method=method, detector=det,
                                      gyr_saturated=rec.gyr_saturated, gyr_range_rad_s=rec.gyr_range_rad_s)
                    times.append(time.perf_counter() - t0)
                m = res.metrics(TRUE_DISTANCE_M)
                rows.append({"file": rec.source, "config": config_of(rec.source), "sensor": rec.sensor,
                             "method": method, "detector": det, "samples": len(rec), "ep": m.ep, "ed": m.ed,
                             "ed_stance": m.ed_stance, "ea_m": m.ea_m, "time_ms": 1000 * float(np.median(times)),
                             "ed_box": box_perimeter_m(res.pos_m, res.stance) / TRUE_DISTANCE_M - 1.0})
    return rows


def _mean(rows, key):
    return float(np.mean([r[key] for r in rows])) if rows else float("nan")


def print_tables(rows: list[dict]) -> None:
    methods = list(dict.fromkeys(r["method"] for r in rows))
    dets = list(dict.fromkeys(r["detector"] for r in rows))
    print("Per walk (EP, ED, ED stance-to-stance in %, EA in m, time per walk in ms)")
    for det in dets:
        print(f"\n== detector {det} ==")
        print(f"{'file':30s} s | " + " | ".join(f"{m:^31s}" for m in methods))
        print(f"{'':32s} | " + " | ".join(f"{'EP':>5s} {'ED':>6s} {'EDs':>6s} {'EA':>5s} {'ms':>4s}" for _ in methods))
        keys = list(dict.fromkeys((r["file"], r["sensor"]) for r in rows))
        for f, s in keys:
            cells = []
            for m in methods:
                r = next(r for r in rows if r["file"] == f and r["sensor"] == s and r["method"] == m and r["detector"] == det)
                cells.append(f"{100 * r['ep']:5.2f} {100 * r['ed']:6.1f} {100 * r['ed_stance']:6.1f} {r['ea_m']:5.2f} {r['time_ms']:4.1f}")
            print(f"{f[:30]:30s} {s} | " + " | ".join(cells))
        cells = []
        for m in methods:
            sel = [r for r in rows if r["method"] == m and r["detector"] == det]
            cells.append(f"{100 * _mean(sel, 'ep'):5.2f} {100 * _mean(sel, 'ed'):6.1f} {100 * _mean(sel, 'ed_stance'):6.1f} "
                         f"{_mean(sel, 'ea_m'):5.2f} {_mean(sel, 'time_ms'):4.1f}")
        print(f"{'mean (14 walks)':32s} | " + " | ".join(cells))
        cells = []
        for m in methods:
            sel = [r for r in rows if r["method"] == m and r["detector"] == det]
            cells.append(f"{100 * _mean([dict(x=abs(r['ep'])) for r in sel], 'x'):5.2f} "
                         f"{100 * np.mean([abs(r['ed']) for r in sel]):6.1f} {100 * np.mean([abs(r['ed_stance']) for r in sel]):6.1f} "
                         f"{np.max([r['ea_m'] for r in sel]):5.2f} {np.max([r['time_ms'] for r in sel]):4.1f}")
        print(f"{'mean |.| (EA, ms: max)':32s} | " + " | ".join(cells))

    print("\nScale check (%): ED stance-to-stance against the 22.1 m circuit vs the perimeter of the stance positions'"
          " bounding box\n(principal axes) against it — the stance polygon cuts the corners, the box does not "
          "(benchmarks.pdr.box_perimeter_m)")
    for det in dets:
        for m in methods:
            sel = [r for r in rows if r["method"] == m and r["detector"] == det]
            print(f"  {det:6s} {m:12s} EDs {100 * _mean(sel, 'ed_stance'):6.1f}   box {100 * _mean(sel, 'ed_box'):6.1f}   "
                  f"box, median |.| {100 * float(np.median([abs(r['ed_box']) for r in sel])):5.1f}")

    print("\nBeside the thesis (Tables 5–8: 30 walks per configuration; ours: the shared walks of that configuration, "
          "both sensors, detector c123).  Columns: ours / thesis")
    for key, label, scale in (("ep", "EP (%) — Table 5", 100), ("ed", "ED sample-wise (%) — Table 6", 100),
                              ("ea_m", "EA (m) — Table 7", 1), ("time_ms", "time per walk (ms; thesis s ×1000) — Table 8", 1)):
        print(f"\n{label}")
        print(f"{'method':12s} " + " ".join(f"{c:>17s}" for c in THESIS_CONFIGS))
        for m in methods:
            cells = []
            for ci, c in enumerate(THESIS_CONFIGS):
                sel = [r for r in rows if r["method"] == m and r["detector"] == "c123" and r["config"] == c]
                ours = _mean(sel, key) * scale if sel else float("nan")
                tk = "time_s" if key == "time_ms" else key
                th = THESIS[tk][m][ci] * (1000 if key == "time_ms" else scale) if m in THESIS[tk] else float("nan")
                cells.append(f"{ours:8.2f} /{th:8.2f}")
            print(f"{m:12s} " + " ".join(cells))
    others = sorted({r["config"] for r in rows} - set(THESIS_CONFIGS))
    if others:
        print(f"(configurations without a thesis column: {', '.join(others)}; their rows are in the per-walk tables)")

    print("\nTable 9 — detectors with 15IEZ+ZARU (thesis: C33, mean ± SD of 30 walks; ours: all 14 walks)")
    for det in dets:
        sel = [r for r in rows if r["method"] == "15iez_zaru" and r["detector"] == det]
        if not sel:
            continue
        th = THESIS_T9.get(det)
        ours = (f"EP {100 * _mean(sel, 'ep'):.2f} ± {100 * np.std([r['ep'] for r in sel], ddof=1):.2f} %, "
                f"ED {100 * _mean(sel, 'ed'):.1f} ± {100 * np.std([r['ed'] for r in sel], ddof=1):.1f} %, "
                f"EA {_mean(sel, 'ea_m'):.2f} m, {_mean(sel, 'time_ms'):.1f} ms")
        thesis = (f"EP {100 * th['ep'][0]:.2f} ± {100 * th['ep'][1]:.2f} %, ED {100 * th['ed'][0]:.1f} ± {100 * th['ed'][1]:.1f} %, "
                  f"EA {th['ea_m'][0]:.2f} m, {1000 * th['time_s'][0]:.0f} ms") if th else "-"
        print(f"  {det:6s} ours: {ours}\n         thesis: {thesis}")


LANE_RADII_M = (0.0, 0.3, 0.5, 0.7)
LANE_OFFSETS_M = (-0.1, -0.05, 0.0, 0.05, 0.1)
LANE_PHASES = (0.5, 0.75, 1.0)


def lane_stance_error(corner_radius_m: float, lateral_offset_m: float, first_stride_fraction: float,
                      stride_length_m: float = 1.2) -> float:
    """(true stance-to-stance length − 22.1 m) / 22.1 m of one foot walking the simulated 22.1 m lane."""
    xy, _ = lane_footprints(stride_length_m=stride_length_m, corner_radius_m=corner_radius_m,
                            lateral_offset_m=lateral_offset_m, first_stride_fraction=first_stride_fraction)
    return float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)) / TRUE_DISTANCE_M - 1.0)


def print_lane_reference() -> None:
    """The ED stance-to-stance a perfect estimate has on the lane walk, and the default method's on one."""
    from estimators.simulation.imu import simulate_on_grid
    from estimators.simulation.motions import walking_foot
    from estimators.simulation.spec import ImuSpec

    print("\nReference of ED stance-to-stance (simulator, estimators.simulation.footpath): the TRUE stance-to-"
          "stance length\nof one foot walking the 22.1 m lane (8.95 m × 2.1 m centre line, clockwise, 1.2 m strides), "
          "against 22.1 m, %;\nmean [min, max] over the stride phase (first stride 0.5, 0.75, 1 × L)")
    print(f"{'corner radius':>14s} | " + " | ".join(f"foot offset {o:+.2f} m" for o in LANE_OFFSETS_M))
    for r in LANE_RADII_M:
        cells = []
        for o in LANE_OFFSETS_M:
            v = [100 * lane_stance_error(r, o, f) for f in LANE_PHASES]
            cells.append(f"{np.mean(v):5.1f} [{min(v):5.1f},{max(v):5.1f}]")
        print(f"{r:12.1f} m | " + " | ".join(f"{c:>21s}" for c in cells))
    walk = walking_foot(placements=lane_footprints(corner_radius_m=0.5, lateral_offset_m=-0.05), seed=4)
    g = simulate_on_grid(walk.trajectory, ImuSpec.noise_only(), fs_hz=100.0, seed=4)
    m = reconstruct(g.t_s, g.acc, g.gyr).metrics(TRUE_DISTANCE_M)
    print(f"Simulated walk (r 0.5 m, inner foot −0.05 m, sensor noise only), default method: ED stance-to-stance "
          f"{100 * m.ed_stance:.1f} % estimated, {100 * (walk.distance_m / TRUE_DISTANCE_M - 1):.1f} % true; "
          f"EP {100 * m.ep:.2f} %")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.pdr", description=__doc__.split("\n")[0])
    parser.add_argument("--data", help=f"IEZ folder (default: ${DATA_ENV} or ../shared/data/iez)")
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--detectors", nargs="+", default=list(DETECTORS), choices=DETECTORS)
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per walk (median reported)")
    parser.add_argument("--json", help="also write the rows as JSON here")
    args = parser.parse_args(argv)
    folder = data_dir(args.data)
    if folder is None or not folder.is_dir() or not any(folder.glob("conf-*.csv")):
        print(f"IEZ data not found: set {DATA_ENV}, pass --data, or place it in ../shared/data/iez", file=sys.stderr)
        return 2
    rows = evaluate(folder, args.methods, args.detectors, args.repeats)
    print_tables(rows)
    print_lane_reference()
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
