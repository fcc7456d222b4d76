"""``chakamo walk``: a foot-mounted walk file → trajectory, strides and metrics (JSON) and a 2D plot (SVG).

JSON (shared/DESIGN.md §4, extended)::

    {"metrics": {"ep", "ed", "ed_stance", "ea_m", "distance_m", "distance_stance_m", "true_distance_m"},
     "trajectory": {"t_s": [...], "pos_m": [[x, y, z], ...], "vel_m_s": [...], "q_earth_sensor": [...],
                    "stance": [0/1, ...]},
     "strides": [{"start_s", "end_s", "length_m", "duration_s", "cadence_strides_min", "speed_m_s"}, ...],
     "summary": {"n_strides", "mean_stride_length_m", "mean_stride_duration_s", "cadence_strides_min",
                 "cadence_steps_min", "mean_speed_m_s", "duration_s"},
     "method": name, "detector": name, "input": {"file", "format", "sensor", "samples",
               "gyr_saturated_samples", "acc_saturated_samples"}}

The metrics EP / ED / EA assume a closed-loop walk of ``true_distance_m`` (22.1 m, the IEZ circuit);
pass ``true_distance_m=None`` for other walks (then ED is relative to the stance-to-stance estimate).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from html import escape
from pathlib import Path
from typing import Any

import numpy as np

from app.research.walk_ingestion import read_walk
from estimators.pdr import DEFAULT_DETECTOR, DEFAULT_METHOD, PdrResult, reconstruct

IEZ_CIRCUIT_M = 22.1

__all__ = ["IEZ_CIRCUIT_M", "run_walk", "trajectory_svg"]


def _round(a: np.ndarray, nd: int) -> list:
    return np.round(np.asarray(a, dtype=np.float64), nd).tolist()


def trajectory_svg(result: PdrResult, *, title: str = "", size_px: int = 640) -> str:
    """A self-contained SVG of the horizontal trajectory (x east, y north; equal axes; 1 m grid),
    stance positions as dots, start (green) and end (red)."""
    xy = result.pos_m[:, :2]
    lo = xy.min(axis=0) - 0.5
    hi = xy.max(axis=0) + 0.5
    span = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    margin = 40.0
    scale = (size_px - 2 * margin) / span
    w = (hi[0] - lo[0]) * scale + 2 * margin
    h = (hi[1] - lo[1]) * scale + 2 * margin

    def px(p: np.ndarray) -> tuple[float, float]:
        return margin + (p[0] - lo[0]) * scale, h - margin - (p[1] - lo[1]) * scale

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0f}" height="{h:.0f}" '
             f'viewBox="0 0 {w:.0f} {h:.0f}" font-family="sans-serif" font-size="12">',
             f'<rect width="{w:.0f}" height="{h:.0f}" fill="white"/>']
    for gx in range(int(np.ceil(lo[0])), int(np.floor(hi[0])) + 1):
        x0, _ = px(np.array([gx, 0.0]))
        parts.append(f'<line x1="{x0:.1f}" y1="{margin - 10:.1f}" x2="{x0:.1f}" y2="{h - margin + 10:.1f}" stroke="#ddd"/>')
    for gy in range(int(np.ceil(lo[1])), int(np.floor(hi[1])) + 1):
        _, y0 = px(np.array([0.0, gy]))
        parts.append(f'<line x1="{margin - 10:.1f}" y1="{y0:.1f}" x2="{w - margin + 10:.1f}" y2="{y0:.1f}" stroke="#ddd"/>')
    step = max(1, len(xy) // 2000)
    pts = " ".join(f"{a:.1f},{b:.1f}" for a, b in (px(p) for p in xy[::step]))
    parts.append(f'<polyline points="{pts}" fill="none" stroke="#1f5fa8" stroke-width="1.5"/>')
    from estimators.pdr.metrics import stance_positions

    sp, _ = stance_positions(result.pos_m, result.stance)
    for p in sp:
        a, b = px(p[:2])
        parts.append(f'<circle cx="{a:.1f}" cy="{b:.1f}" r="2.5" fill="#1f5fa8"/>')
    for p, col in ((xy[0], "#2a9d3a"), (xy[-1], "#c0392b")):
        a, b = px(p)
        parts.append(f'<circle cx="{a:.1f}" cy="{b:.1f}" r="5" fill="{col}"/>')
    parts.append(f'<text x="{margin:.0f}" y="20">{escape(title)} (grid 1 m; green start, red end)</text>')
    parts.append("</svg>")
    return "\n".join(parts)


def run_walk(path: str | Path, *, fmt: str = "iez", sensor: int = 1, method: str = DEFAULT_METHOD,
             detector: str = DEFAULT_DETECTOR, json_out: str | Path | None = None,
             plot_out: str | Path | None = None, true_distance_m: float | None = IEZ_CIRCUIT_M) -> dict[str, Any]:
    """Read a walk, reconstruct it, write the JSON (``json_out``) and the SVG plot (``plot_out``); return the dict."""
    rec = read_walk(path, fmt=fmt, sensor=sensor)
    res = reconstruct(rec.t_s, rec.acc, rec.gyr, method=method, detector=detector, gyr_saturated=rec.gyr_saturated,
                      gyr_range_rad_s=None if np.isnan(rec.gyr_range_rad_s) else rec.gyr_range_rad_s)
    m = res.metrics(true_distance_m)
    strides = [asdict(s) for s in res.strides]
    summary: dict[str, Any] = {"n_strides": len(strides), "mean_stride_length_m": None, "mean_stride_duration_s": None,
                               "cadence_strides_min": None, "cadence_steps_min": None, "mean_speed_m_s": None,
                               "duration_s": float(res.t_s[-1] - res.t_s[0])}
    if strides:
        lengths = np.array([s["length_m"] for s in strides])
        durs = np.array([s["duration_s"] for s in strides])
        mean_dur = float(durs.mean())
        summary.update(mean_stride_length_m=float(lengths.mean()), mean_stride_duration_s=mean_dur,
                       cadence_strides_min=60.0 / mean_dur, cadence_steps_min=120.0 / mean_dur,
                       mean_speed_m_s=float(lengths.sum() / durs.sum()))
    out: dict[str, Any] = {
        "metrics": {k: float(v) for k, v in asdict(m).items()},
        "trajectory": {"t_s": _round(res.t_s, 4), "pos_m": _round(res.pos_m, 4), "vel_m_s": _round(res.vel_m_s, 4),
                       "q_earth_sensor": _round(res.q_earth_sensor, 6), "stance": res.stance.astype(int).tolist()},
        "strides": strides,
        "summary": summary,
        "method": res.method,
        "detector": res.detector,
        "input": {"file": rec.source, "format": fmt, "sensor": sensor, "samples": len(rec),
                  "gyr_saturated_samples": int(rec.gyr_saturated.sum()),
                  "acc_saturated_samples": int(rec.acc_saturated.sum())},
    }
    if json_out is not None:
        Path(json_out).parent.mkdir(parents=True, exist_ok=True)
        Path(json_out).write_text(json.dumps(out))
    if plot_out is not None:
        Path(plot_out).parent.mkdir(parents=True, exist_ok=True)
        Path(plot_out).write_text(trajectory_svg(res, title=f"{rec.source} sensor {sensor}, {res.method}"))
    return out

