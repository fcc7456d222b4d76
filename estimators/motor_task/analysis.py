"""``analyse_task``: cycles → normalised curves, iterative rejection, phase timings and ranges of motion."""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.jsonable import json_ready
from estimators.motor_task import ANGLES
from estimators.motor_task.detection import detect_cycles, lowpass, task_span
from estimators.motor_task.registry import load_task_module
from estimators.motor_task.spec import EVENTS, MotorTaskParams, TaskSpec
from estimators.motor_task.tasks import get_task
from estimators.quality import QualityWarning

FloatArray = NDArray[np.float64]

ROM_STATS: tuple[str, ...] = ("max", "min", "range")
#: the reason code of a cycle the clinician excluded (every other code is the pipeline's own rejection)
EXCLUDED = "excluded_by_clinician"


class UnknownCycleError(ValueError):
    """An exclusion names a cycle that was not detected: ``index`` (0-based) of ``detected`` cycles."""

    def __init__(self, index: int, detected: int) -> None:
        super().__init__(f"cycle {index + 1} cannot be excluded: {detected} cycle(s) were detected")
        self.index, self.detected = index, detected


class NotCandidateError(ValueError):
    """An exclusion names a cycle the pipeline itself left out before any choice (incomplete, a turn...): there is
    nothing to exclude, and recording the clinician's exclusion beside the pipeline's reason would give it two."""

    def __init__(self, index: int) -> None:
        super().__init__(f"cycle {index + 1} cannot be excluded: the pipeline already left it out")
        self.index = index


@dataclass(frozen=True)
class RejectedCycle:
    """A detected cycle left out of the statistics.

    index : position among the detected cycles (0-based).   code : ``incomplete_start``, ``incomplete_end``,
    ``unmeasurable``, ``small_excursion``, ``rmse`` (the pipeline's reasons; gait adds ``turn`` and
    ``stride_time``) or :data:`EXCLUDED` (the clinician left it out: :func:`reject_cycles`' ``exclude``).
    message : a sentence for people.
    rmse_rad : (3,) RMSE of the normalised cycle to the mean of the accepted ones when it was rejected
    (``code == "rmse"``), rad; None otherwise.   iteration : rejection round (1-based; 0 for detection).
    """

    index: int
    code: str
    message: str
    rmse_rad: tuple[float, float, float] | None = None
    iteration: int = 0

    def to_dict(self) -> dict:
        return {"index": self.index, "reason": self.code, "message": self.message,
                "rmse_rad": None if self.rmse_rad is None else [float(x) for x in self.rmse_rad],
                "iteration": self.iteration}


def _stat(x: FloatArray) -> tuple[float, float]:
    """Mean and SD (ddof = 1) over axis 0; NaN when undefined (no / one value)."""
    x = np.asarray(x, dtype=np.float64)
    if len(x) == 0:
        return float("nan"), float("nan")
    return float(np.mean(x)), float(np.std(x, ddof=1)) if len(x) > 1 else float("nan")


@dataclass(frozen=True, eq=False)
class TaskAnalysis:
    """Result of :func:`analyse_task`.  Times in s on the recording's clock (``t0_s`` + sample / ``fs_hz``),
    angles in rad (convert to degrees only for reports).

    task : the :class:`TaskSpec` used.   params : the :class:`MotorTaskParams` used.
    task_span_s : (start, end) where the moving SD of flexion says the knee is in the task; None if never.
    events_s : (K, 5) per detected cycle, the events :data:`EVENTS` (NaN when unknown; for tasks without
        countermovement ``countermovement_peak`` is NaN).
    cycles_s : (K, 2) cycle [start, end): onset → next cycle's onset (or → rest_reached for the last one).
    accepted : (K,) bool, cycles in the statistics.   rejected : reasons for the others.
    curves_rad : (K, n_points, 3) normalised curves (NaN rows for incomplete cycles).
    mean_rad, sd_rad : (n_points, 3) mean and SD (ddof = 1) over the accepted cycles.
    rom_rad : (K, 3 angles, 3 stats max/min/range) per cycle over its samples (normalisation span).
    phase_s, phase_pct : (K, P) phase durations (s) and % of the normalisation span, phases of ``task``.
    warnings : quality warnings (no task motion, few cycles, rejection stopped early).
    """

    task: TaskSpec
    params: MotorTaskParams
    fs_hz: float
    task_span_s: tuple[float, float] | None
    events_s: FloatArray
    cycles_s: FloatArray
    accepted: NDArray[np.bool_]
    rejected: tuple[RejectedCycle, ...]
    curves_rad: FloatArray
    mean_rad: FloatArray
    sd_rad: FloatArray
    rom_rad: FloatArray
    phase_s: FloatArray
    phase_pct: FloatArray
    warnings: tuple[QualityWarning, ...] = field(default_factory=tuple)

    @property
    def n_detected(self) -> int:
        return len(self.events_s)

    @property
    def n_accepted(self) -> int:
        return int(np.sum(self.accepted))

    def rom_stats(self) -> dict[str, dict[str, dict[str, float]]]:
        """``{angle: {max|min|range: {"mean", "sd"}}}`` over the accepted cycles, rad."""
        r = self.rom_rad[self.accepted]
        return {a: {s: dict(zip(("mean", "sd"), _stat(r[:, i, j]))) for j, s in enumerate(ROM_STATS)}
                for i, a in enumerate(ANGLES)}

    def phase_stats(self) -> dict[str, dict[str, float]]:
        """``{phase: {mean_s, sd_s, mean_pct, sd_pct}}`` over the accepted cycles, plus ``"movement"``
        (onset → rest_reached) and ``"cycle"`` (onset → next onset, the cycles followed by another)."""
        acc = self.accepted
        out = {}
        for j, name in enumerate(self.task.phase_names):
            ms, ss = _stat(self.phase_s[acc, j])
            mp, sp = _stat(self.phase_pct[acc, j])
            out[name] = {"mean_s": ms, "sd_s": ss, "mean_pct": mp, "sd_pct": sp}
        move = self.events_s[acc, 4] - self.events_s[acc, 0]
        m, s = _stat(move)
        out["movement"] = {"mean_s": m, "sd_s": s}
        nxt = np.append(self.events_s[1:, 0], np.nan)
        cyc = (nxt - self.events_s[:, 0])[acc]
        m, s = _stat(cyc[np.isfinite(cyc)])
        out["cycle"] = {"mean_s": m, "sd_s": s}
        return out

    def to_dict(self) -> dict:
        """JSON-ready dict in the shape of ``results.json`` (DESIGN.md §4) but in **radians**: the app turns
        ``rom_rad`` into ``rom_deg`` and ``curves_rad`` into ``curves`` (degrees) for results.json.

        ``cycles.boundaries_s`` and ``cycles.events_s`` list every *detected* cycle (index = the ``index`` of
        ``cycles.rejected``); unknown times of incomplete cycles are None (NaN → None everywhere)."""
        d = {
            "task": self.task.name,
            "task_span_s": None if self.task_span_s is None else list(self.task_span_s),
            "cycles": {
                "detected": self.n_detected,
                "accepted": self.n_accepted,
                "accepted_indices": [int(i) for i in np.flatnonzero(self.accepted)],
                "rejected": [r.to_dict() for r in self.rejected],
                "boundaries_s": self.cycles_s,
                "events": list(EVENTS),
                "events_s": self.events_s,
            },
            "rom_rad": self.rom_stats(),
            "phases": self.phase_stats(),
            "curves_rad": {a: {"mean": self.mean_rad[:, i], "sd": self.sd_rad[:, i]} for i, a in enumerate(ANGLES)},
            "warnings": [w.to_dict() for w in self.warnings],
            "params": self.params.to_dict(),
        }
        return json_ready(d)


def normalise_cycles(angles: FloatArray, spans: FloatArray, n_points: int) -> FloatArray:
    """(K, n_points, 3) curves: each angle linearly interpolated at ``n_points`` equally spaced instants of its
    span (fractional samples, thesis ``normalizacion_ciclos``, eq. C1); NaN for spans that are not finite."""
    k = len(spans)
    out = np.full((k, n_points, angles.shape[1]), np.nan)
    grid = np.linspace(0.0, 1.0, n_points)
    idx = np.arange(len(angles), dtype=np.float64)
    for c in range(k):
        s, e = spans[c]
        if np.isfinite(s) and np.isfinite(e) and e > s:
            tq = s + (e - s) * grid
            for a in range(angles.shape[1]):
                out[c, :, a] = np.interp(tq, idx, angles[:, a])
    return out


def register_cycles(angles: FloatArray, events: FloatArray, complete: NDArray[np.bool_], n_points: int) -> FloatArray:
    """(K, n_points, 3) curves time-warped piecewise linearly so that every complete cycle's events (onset … back
    at rest, fractional samples) fall at their mean fractions of the movement (eq. C2'); NaN for the others."""
    k = len(events)
    out = np.full((k, n_points, angles.shape[1]), np.nan)
    cols = [j for j in range(events.shape[1]) if k and np.all(np.isfinite(events[complete, j]))] if k else []
    if not np.any(complete) or 0 not in cols or 4 not in cols:
        return normalise_cycles(angles, np.where(complete[:, None], events[:, [0, 4]], np.nan), n_points)
    ev = events[:, cols]
    frac = (ev - ev[:, :1]) / (ev[:, -1:] - ev[:, :1])
    knots_u = np.maximum.accumulate(np.mean(frac[complete], axis=0))
    grid = np.linspace(0.0, 1.0, n_points)
    idx = np.arange(len(angles), dtype=np.float64)
    for c in np.flatnonzero(complete):
        if not np.all(np.diff(ev[c]) >= 0) or ev[c, -1] <= ev[c, 0]:
            continue
        tq = np.interp(grid, knots_u, ev[c])
        for j in range(angles.shape[1]):
            out[c, :, j] = np.interp(tq, idx, angles[:, j])
    return out


def reject_cycles(curves: FloatArray, candidates: NDArray[np.bool_], p: MotorTaskParams, exclude=()
                  ) -> tuple[NDArray[np.bool_], list[RejectedCycle], bool]:
    """Iterative rejection (thesis ``media_ciclos``, eq. C2): while the worst accepted cycle's RMSE to the mean
    of the accepted ones exceeds its angle's threshold, reject it and recompute the mean.  Stops before fewer
    than ``min_accepted_cycles`` would remain (third value True then).

    exclude : 0-based indices of detected cycles the clinician left out.  They leave the candidates first (reason
        :data:`EXCLUDED`, iteration 0), so the RMSE rejection is computed on the cycles the clinician kept: one
        mechanism, one list of reasons.  :class:`UnknownCycleError` for an index outside the detected cycles,
        :class:`NotCandidateError` for a cycle that was no candidate (incomplete, a turn...: the pipeline's reason
        stands, one reason per cycle)."""
    acc = candidates.copy()
    thr = np.array([np.inf if x is None else x for x in p.rejection_rmse_rad])
    out: list[RejectedCycle] = []
    for i in sorted({int(i) for i in exclude}):
        if not 0 <= i < len(acc):
            raise UnknownCycleError(i, len(acc))
        if not acc[i]:
            raise NotCandidateError(i)
        out.append(RejectedCycle(i, EXCLUDED, "excluded by the clinician"))
        acc[i] = False
    it = 0
    while True:
        idx = np.flatnonzero(acc)
        if len(idx) < 2:
            return acc, out, False
        mean = curves[idx].mean(axis=0)
        rmse = np.sqrt(np.mean((curves[idx] - mean) ** 2, axis=1))  # (k, 3)
        excess = np.max(rmse / thr, axis=1)
        worst = int(np.argmax(excess))
        if excess[worst] <= 1.0:
            return acc, out, False
        if len(idx) - 1 < p.min_accepted_cycles:
            return acc, out, True
        it += 1
        a = int(np.argmax(rmse[worst] / thr))
        r = rmse[worst]
        msg = (f"{ANGLES[a]} RMSE to the mean (phase-registered) curve {r[a]:.3f} rad ({math.degrees(r[a]):.1f}°) exceeds "
               f"{thr[a]:.3f} rad ({math.degrees(thr[a]):.1f}°)")
        out.append(RejectedCycle(int(idx[worst]), "rmse", msg, tuple(float(x) for x in r), it))
        acc[idx[worst]] = False


def checked_inputs(angles_rad: ArrayLike, fs_hz: float, params: MotorTaskParams
                   ) -> tuple[FloatArray, float, MotorTaskParams]:
    """Every task analysis' inputs, validated: ``(angles (N, 3) float64, fs_hz float, params)``; a (N,) array is
    taken as flexion only.  TypeError for params of another type, ValueError for a wrong shape, non-finite
    angles or a rate that is not a positive number."""
    if not isinstance(params, MotorTaskParams):
        raise TypeError(f"params must be a MotorTaskParams, got {type(params).__name__}")
    a = np.asarray(angles_rad, dtype=np.float64)
    if a.ndim == 1:
        a = np.column_stack([a, np.zeros_like(a), np.zeros_like(a)])
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"angles_rad must have shape (N, 3) (flexion, adduction, internal rotation), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("angles_rad contains NaN or infinite values; interpolate or trim them before the analysis")
    if not (isinstance(fs_hz, (int, float, np.integer, np.floating)) and math.isfinite(fs_hz) and fs_hz > 0):
        raise ValueError(f"fs_hz must be a positive sampling rate in Hz, got {fs_hz!r}")
    return a, float(fs_hz), params


def analyse_task(angles_rad: ArrayLike, fs_hz: float, *, task: str | TaskSpec = "step_up",
                 params: MotorTaskParams | None = None, t0_s: float = 0.0,
                 inputs: Mapping[str, Any] | None = None, fit_flexion_rad: ArrayLike | None = None,
                 exclude=()) -> TaskAnalysis:
    """Cycles, phases, normalised mean ± SD curves and ranges of motion of a repetitive knee task.

    angles_rad : (N, 3) knee angles (flexion, adduction, internal rotation), rad, clinical signs, on a uniform
        grid; flexion drives the detection, all three are normalised.  A (N,) array is taken as flexion only.
    fs_hz : sampling rate, Hz.   task : a registered name (:data:`~estimators.motor_task.TASK_NAMES`: the
        task module's own ``analyse`` or ``PARAMS`` are used when it has them) or a :class:`TaskSpec`.
    params : :class:`MotorTaskParams` (defaults when None).   t0_s : time of sample 0, s.
    inputs : what else the caller has on the same grid (e.g. ``gyr_shank_rad_s``, ``shank_axis_sensor``,
        ``q_earth_thigh``...): a task module's own ``analyse`` receives those of them it names as keyword
        parameters (gait takes the shank gyroscope for its events, the step-up both gyroscopes for D7); the
        shared detector uses none.
    fit_flexion_rad : (N,) flexion for the least-squares event fits D5b/D5c instead of ``angles_rad[:, 0]``
        (the step-up's D7 flexion, :func:`~estimators.motor_task.detection.gyroscope_flexion`); the search
        (D1–D4), the curves and the ranges of motion keep the angles.
    exclude : 0-based indices of the detected cycles the clinician excluded (:func:`reject_cycles`); every task,
        its own ``analyse`` included, takes them.
    Returns a :class:`TaskAnalysis`.  Raises ValueError for a wrong shape, rate or non-finite angles.
    """
    if isinstance(task, str):  # a registered task: its own analysis or default parameters, if it has them
        spec = get_task(task)
        mod = load_task_module(task)
        own = getattr(mod, "analyse", None)
        if own is not None:
            wanted = inspect.signature(own).parameters
            extra = {k: v for k, v in (inputs or {}).items() if k in wanted and k not in ("params", "t0_s")}
            return own(angles_rad, fs_hz, params=params, t0_s=t0_s, exclude=exclude, **extra)
        if params is None:
            params = getattr(mod, "PARAMS", None)
    else:
        spec = get_task(task)
    a, fs_hz, p = checked_inputs(angles_rad, fs_hz, MotorTaskParams() if params is None else params)
    n_pts, n_ph = int(p.n_points), len(spec.phases)
    flex = lowpass(a[:, 0], fs_hz, p.lowpass_hz) if len(a) else a[:, 0]
    span = task_span(flex, fs_hz, p) if len(a) > 1 else None
    warnings: list[QualityWarning] = []
    y_fit = a[:, 0]
    if fit_flexion_rad is not None:
        y_fit = np.asarray(fit_flexion_rad, dtype=np.float64)
        if y_fit.shape != (len(a),) or not np.all(np.isfinite(y_fit)):
            raise ValueError(f"fit_flexion_rad must be a finite ({len(a)},) array, got shape {y_fit.shape}")
    cycles = detect_cycles(spec.sign * flex, fs_hz, span, spec, p, spec.sign * y_fit) if span is not None else []
    k = len(cycles)
    ev = np.array([c.events for c in cycles]).reshape(k, 5)
    complete = np.array([c.incomplete is None for c in cycles], dtype=bool)
    rejected = [RejectedCycle(i, c.incomplete, c.message) for i, c in enumerate(cycles) if c.incomplete is not None]
    if k > 1:  # continuous cycles: one split, so a cycle's end cannot lie after the next one's start
        over = np.flatnonzero(ev[:-1, 4] > ev[1:, 0])
        mid = 0.5 * (ev[over, 4] + ev[over + 1, 0])
        ev[over, 4], ev[over + 1, 0] = mid, mid
    # cycle boundaries (DESIGN.md §3): onset → back at rest; a rest after it (a pause) belongs to no cycle
    cyc = np.column_stack([ev[:, 0], ev[:, 4]]) if k else np.zeros((0, 2))
    if p.normalise_span == "movement":
        spans = cyc.copy()
    else:  # the thesis' span: onset → next onset (→ back at rest for the last), pauses included
        nxt = np.append(ev[1:, 0], np.nan) if k else np.zeros(0)
        end = np.where(np.isfinite(nxt) & (nxt >= ev[:, 4]), nxt, ev[:, 4]) if k else np.zeros(0)
        spans = np.column_stack([ev[:, 0], end]) if k else np.zeros((0, 2))
    spans[~complete] = np.nan
    curves = normalise_cycles(a, spans, n_pts)
    # C2 compares cycles registered on their events, so that natural cycle-to-cycle timing variability
    # (phase proportions SD 1–3 %, seed 004 Tables 8.1/8.3) is not mistaken for a bad cycle
    accepted, rej, stopped = reject_cycles(register_cycles(a, ev, complete, n_pts), complete, p, exclude)
    rejected += rej
    if stopped:
        warnings.append(QualityWarning("MOTOR_TASK_REJECTION_STOPPED",
                                       f"more cycles exceed the RMSE threshold, but rejection stopped to keep "
                                       f"{p.min_accepted_cycles} cycles; the mean curve may include poor cycles",
                                       {"min_cycles": p.min_accepted_cycles}))
    # events → durations
    idx = {e: i for i, e in enumerate(EVENTS)}
    ph = np.full((k, n_ph), np.nan)
    for j, phase in enumerate(spec.phases):
        ph[:, j] = ev[:, idx[phase.end]] - ev[:, idx[phase.start]] if k else 0.0
    dur = spans[:, 1] - spans[:, 0] if k else np.zeros(0)
    pct = 100.0 * ph / dur[:, None] if k else np.zeros((0, n_ph))
    # ranges of motion over the samples of each cycle's span
    rom = np.full((k, 3, 3), np.nan)
    for c in np.flatnonzero(complete):
        i0, i1 = int(math.ceil(spans[c, 0])), int(math.floor(spans[c, 1])) + 1
        seg = a[i0:i1]
        if len(seg):
            mx, mn = seg.max(axis=0), seg.min(axis=0)
            rom[c] = np.column_stack([mx, mn, mx - mn])
    sel = curves[accepted]
    mean = sel.mean(axis=0) if len(sel) else np.full((n_pts, 3), np.nan)
    sd = sel.std(axis=0, ddof=1) if len(sel) > 1 else np.full((n_pts, 3), np.nan)
    if span is None:
        warnings.append(QualityWarning("MOTOR_TASK_NO_MOTION",
                                       "the knee flexion never varies enough to contain a task; check the recording"))
    elif k == 0:
        warnings.append(QualityWarning("MOTOR_TASK_NO_CYCLES",
                                       f"no {spec.name} cycle reaching {spec.far_label} was found",
                                       {"task": spec.name, "far_label": spec.far_label}))
    n_acc = int(accepted.sum())
    if 0 < k and n_acc < p.min_accepted_cycles:
        warnings.append(QualityWarning("MOTOR_TASK_FEW_CYCLES",
                                       f"only {n_acc} usable cycle(s) of {k} detected; means and SDs are unreliable",
                                       {"accepted": n_acc, "detected": k}))
    scale = 1.0 / fs_hz
    span_s = None if span is None else (t0_s + span[0] * scale, t0_s + (span[1] - 1) * scale)
    return TaskAnalysis(
        task=spec, params=p, fs_hz=fs_hz, task_span_s=span_s,
        events_s=t0_s + ev * scale, cycles_s=t0_s + cyc * scale, accepted=accepted,
        rejected=tuple(sorted(rejected, key=lambda r: r.index)), curves_rad=curves, mean_rad=mean, sd_rad=sd,
        rom_rad=rom, phase_s=ph * scale, phase_pct=pct, warnings=tuple(warnings))
