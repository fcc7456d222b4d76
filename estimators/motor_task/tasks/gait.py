r"""Gait (level walking): strides from initial contact to initial contact, stance and swing, knee parameters.

Inputs the pipeline passes to :func:`analyse` (beyond the knee angles): the shank gyroscope (bias-corrected,
sensor axes) and the shank's flexion axis in sensor coordinates, for the events; both sensors' orientations
and gyroscopes, for the turns.  Through :func:`~estimators.motor_task.analyse_task` (angles only) the
events come from the knee flexion alone (K1–K3 below, approximate, with a warning).

Cycle, events and phases
------------------------
* stride (``cycles_s``) = initial contact (IC) → next IC of the same leg; normalised to 0–100 %
  (``n_points`` = 101 points), as every task's curves;
* ``events_s`` columns (the task family's :data:`~estimators.motor_task.spec.EVENTS`): ``onset`` = IC,
  ``countermovement_peak`` = NaN, ``far_reached`` = toe-off (TO), ``far_left`` = mid-swing (MS),
  ``rest_reached`` = next IC;
* phases: **stance** = IC → TO, **swing** = TO → next IC (they sum to the stride).

Events from the shank gyroscope: :mod:`estimators.motor_task.gait_events` (Salarian et al. 2004; Aminian et al.
2002; Catalfamo et al. 2010).  Knee-only fallback (no gyroscope; flexion low-passed at ``lowpass_hz``):
K1 swing peaks: local maxima of flexion at least ``min_excursion_rad`` (20°) above the lowest flexion within
± 0.4 s; K2 IC: the flexion minimum of terminal swing, within 0.45 s after the swing peak (the knee is most
extended just before heel strike; Perry & Burnfield 2010, Ch. 4); K3 TO: the fastest flexion within 0.35 s
before the swing peak (initial swing).  MS is then unknown (NaN).

Walking bouts, turns and rejection (in order; reason codes of
:class:`~estimators.motor_task.analysis.RejectedCycle`)
-------------------------------------------------------------------------------------------------------
B1  An IC → IC interval shorter than ``min_stride_s`` or longer than ``max_stride_s`` is no stride: it ends
    one walking bout and the next IC starts another (``gait["bouts_s"]``: first IC → last IC of each run of
    consecutive strides that are not turns).
B2  ``turn``: any sample of the stride is turning (thigh or shank yaw rate, ``gait_events`` T1: 20°/s
    averaged over 1 s).  ``unmeasurable``: toe-off not found between the two ICs.
B3  ``stride_time``: the stride time differs from the median of the remaining strides by more than
    ``STRIDE_TIME_TOLERANCE`` (25 %: healthy stride-time CV is 1–3 %, Hausdorff et al. 1995; a longer
    stride is a hesitation, a shorter one a missed or false event).
B4  ``rmse``: the shared iterative rejection (:func:`~estimators.motor_task.analysis.reject_cycles`) on the
    strides registered on IC, TO, MS and next IC, flexion RMSE to the mean above
    ``rejection_rmse_rad[0]`` (8°), never below ``min_accepted_cycles`` strides.

Parameters (per accepted stride, then mean and SD with ddof = 1; ``TaskAnalysis.gait["parameters"]``)
-----------------------------------------------------------------------------------------------------
From the stride's flexion :math:`\phi` (input angles, linearly interpolated at 0.1 % steps of the stride):

* ``loading_response_peak_flexion_rad``: :math:`\max \phi` over 0–30 % (Winter 2009: 15–20° at 12–15 %);
* ``stance_min_flexion_rad``: :math:`\min \phi` from that peak to TO (3–5° at ~40 %);
* ``swing_peak_flexion_rad``, ``swing_peak_timing_pct``: :math:`\max \phi` from TO to the next IC and its
  time, % of the stride (60–65° at 70–73 %);
* ``flexion_rom_rad``: :math:`\max \phi - \min \phi` over the stride;
* ``stance_pct`` = 100 (TO − IC) / stride, ``swing_pct`` = 100 − ``stance_pct``;
* ``stride_time_s`` = next IC − IC; ``cadence_steps_min`` = 120 / ``stride_time_s`` (two steps a stride);
  both with ``cv_pct`` = 100 SD / mean (stride-to-stride variability).
"""

from __future__ import annotations

import math

from estimators.motor_task.gait_events import GaitEventParams
from estimators.motor_task.spec import MotorTaskParams, PhaseSpec, TaskSpec

__all__ = ["PARAMS", "PARAMETERS", "SPEC", "STRIDE_TIME_TOLERANCE", "GaitEventParams", "analyse"]

SPEC = TaskSpec(
    name="gait", excursion="flexion", countermovement=False,
    phases=(PhaseSpec("stance", "onset", "far_reached"), PhaseSpec("swing", "far_reached", "rest_reached")),
    far_label="peak swing flexion",
    description="level walking: strides from initial contact to initial contact; stance = IC → toe-off, "
                "swing = toe-off → next IC; events from the shank gyroscope (Salarian et al. 2004)")

#: the gait defaults: the package defaults (flexion RMSE rejection 8°, 101 points, at least 3 strides)
PARAMS = MotorTaskParams()

#: relative deviation of a stride time from the median that rejects the stride (B3)
STRIDE_TIME_TOLERANCE = 0.25

#: the gait parameters of ``TaskAnalysis.gait["parameters"]``, in report order (units in the names)
PARAMETERS: tuple[str, ...] = (
    "loading_response_peak_flexion_rad", "stance_min_flexion_rad", "swing_peak_flexion_rad", "flexion_rom_rad",
    "swing_peak_timing_pct", "stance_pct", "swing_pct", "stride_time_s", "cadence_steps_min")

_LOADING_RESPONSE_END = 0.30
_FINE_POINTS = 1001


def _gait_analysis_class():
    """:class:`TaskAnalysis` with a ``gait`` dict (made on first use: the analysis imports numpy)."""
    global _GaitAnalysis
    if _GaitAnalysis is None:
        from dataclasses import dataclass, field

        from estimators.jsonable import json_ready
        from estimators.motor_task.analysis import TaskAnalysis

        @dataclass(frozen=True, eq=False)
        class GaitAnalysis(TaskAnalysis):
            """:class:`TaskAnalysis` of the gait task plus ``gait``: the gait parameters (``"parameters"``:
            name → ``{"mean", "sd"}``, and ``"cv_pct"`` for stride time and cadence), ``"per_stride"`` (name →
            (K,) values per detected stride, NaN where not measured), ``"bouts_s"``, ``"turns_s"`` (start, end
            of each turning span), ``"events_source"`` (``"shank_gyroscope"`` or ``"knee_flexion"``) and
            ``"event_params"``.  Units are in the names (rad, %, s, steps/min); ``to_dict()["gait"]`` holds
            the same, JSON-ready."""

            gait: dict = field(default_factory=dict)

            def to_dict(self) -> dict:
                d = super().to_dict()
                d["gait"] = json_ready(self.gait)
                return d

        GaitAnalysis.__name__ = GaitAnalysis.__qualname__ = "GaitAnalysis"
        GaitAnalysis.__module__ = __name__
        _GaitAnalysis = GaitAnalysis
    return _GaitAnalysis


_GaitAnalysis = None


def __getattr__(name: str):
    if name == "GaitAnalysis":
        return _gait_analysis_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _knee_only_events(flex, fs_hz, p):
    """(ms, ic, to) fractional samples from the knee flexion alone (module docstring K1–K3); ms is NaN."""
    import numpy as np

    from estimators.motor_task.detection import lowpass
    from estimators.motor_task.gait_events import _parabola

    f = lowpass(flex, fs_hz, p.lowpass_hz)
    n = len(f)
    half, after, before = (max(1, int(round(s * fs_hz))) for s in (0.4, 0.45, 0.35))
    rate = np.gradient(f)
    ms, ic, to = [], [], []
    for i in range(1, n - 1):
        lo, hi = max(0, i - half), min(n, i + half + 1)
        if f[i] < f[lo:hi].max() or f[i] - f[lo:hi].min() < p.min_excursion_rad or f[i] == f[i - 1]:
            continue
        ms.append(np.nan)
        seg = f[i:min(n, i + after + 1)]
        k = i + int(np.argmin(seg))
        ic.append(_parabola(f, k) if 0 < k - i < len(seg) - 1 else np.nan)
        lo = max(0, i - before)
        k = lo + int(np.argmax(rate[lo:i])) if i - lo >= 2 else -1
        to.append(_parabola(rate, k) if k > lo else np.nan)
    return np.asarray(ms), np.asarray(ic), np.asarray(to)


def _stride_parameters(flex, ic, to, ic2, fs_hz):
    """One stride's parameters (module docstring), flexion in rad, times in fractional samples."""
    import numpy as np

    u = np.linspace(0.0, 1.0, _FINE_POINTS)
    phi = np.interp(ic + (ic2 - ic) * u, np.arange(len(flex), dtype=np.float64), flex)
    u_to = (to - ic) / (ic2 - ic)
    lr = u <= _LOADING_RESPONSE_END
    i_lr = int(np.argmax(np.where(lr, phi, -np.inf)))
    stance = (u >= u[i_lr]) & (u <= u_to)
    swing = u >= u_to
    i_sw = int(np.argmax(np.where(swing, phi, -np.inf)))
    stride_s = (ic2 - ic) / fs_hz
    return {"loading_response_peak_flexion_rad": phi[i_lr],
            "stance_min_flexion_rad": float(np.min(phi[stance])) if stance.any() else np.nan,
            "swing_peak_flexion_rad": phi[i_sw], "flexion_rom_rad": float(np.ptp(phi)),
            "swing_peak_timing_pct": 100.0 * u[i_sw], "stance_pct": 100.0 * u_to, "swing_pct": 100.0 * (1.0 - u_to),
            "stride_time_s": stride_s, "cadence_steps_min": 120.0 / stride_s}


def analyse(angles_rad, fs_hz: float, *, params: MotorTaskParams | None = None, t0_s: float = 0.0,
            gyr_shank_rad_s=None, shank_axis_sensor=None, q_earth_thigh=None, gyr_thigh_rad_s=None,
            q_earth_shank=None, event_params: GaitEventParams | None = None, exclude=()):
    """Strides, gait events, stance/swing, mean ± SD curves and gait parameters of a walking recording.

    angles_rad : (N, 3) knee angles (flexion, adduction, internal rotation), rad, clinical signs, uniform grid.
    fs_hz : sampling rate, Hz (all arrays on the same grid).   params : :class:`MotorTaskParams` (uses
        ``n_points``, ``rejection_rmse_rad``, ``min_accepted_cycles``; ``lowpass_hz`` and ``min_excursion_rad``
        in the knee-only fallback).   t0_s : time of sample 0, s.
    gyr_shank_rad_s : (N, 3) shank gyroscope, bias-corrected, rad/s, sensor axes.
    shank_axis_sensor : (3,) the shank's flexion axis (ISB segment z, to the right on both legs) in shank-sensor
        coordinates: ``quaternion.rotate(q_sensor_segment_shank, [0, 0, 1])`` of the segment calibration.
        Without both, the events come from the knee flexion (K1–K3; warning ``GAIT_EVENTS_FROM_KNEE``).
    q_earth_thigh, gyr_thigh_rad_s, q_earth_shank : (N, 4) orientations (earth z up) and (N, 3) thigh gyroscope
        for the turns (T1); either segment is enough (the shank uses ``gyr_shank_rad_s``); without any, turns
        are not checked (warning ``GAIT_TURNS_NOT_CHECKED``).
    event_params : :class:`GaitEventParams`.
    exclude : 0-based indices of the strides the clinician excluded
        (:func:`~estimators.motor_task.analysis.reject_cycles`).
    Returns a ``GaitAnalysis`` (a :class:`~estimators.motor_task.analysis.TaskAnalysis` with ``gait``).
    """
    import numpy as np

    from estimators.motor_task import ANGLES
    from estimators.motor_task.analysis import (RejectedCycle, checked_inputs, normalise_cycles, register_cycles,
                                                 reject_cycles)
    from estimators.motor_task.gait_events import detect_gait_events, sagittal_rate, turning_mask, yaw_rate
    from estimators.quality import QualityWarning

    a, fs_hz, p = checked_inputs(angles_rad, fs_hz, PARAMS if params is None else params)
    ep = GaitEventParams() if event_params is None else event_params
    n = len(a)

    def same_length(x, name, width):
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (n, width):
            raise ValueError(f"{name} must have shape ({n}, {width}) like angles_rad, got {x.shape}")
        return x

    warnings: list[QualityWarning] = []
    if gyr_shank_rad_s is not None and shank_axis_sensor is not None:
        omega = sagittal_rate(same_length(gyr_shank_rad_s, "gyr_shank_rad_s", 3), shank_axis_sensor)
        ev = detect_gait_events(omega, fs_hz, ep)
        ms, ic, to, source = ev.mid_swing, ev.initial_contact, ev.toe_off, "shank_gyroscope"
    else:
        ms, ic, to = _knee_only_events(a[:, 0], fs_hz, p)
        source = "knee_flexion"
        warnings.append(QualityWarning("GAIT_EVENTS_FROM_KNEE",
                                       "gait events estimated from knee flexion only (no shank gyroscope): initial "
                                       "contact and toe-off are approximate and mid-swing is unknown"))
    yaws = []
    if q_earth_thigh is not None and gyr_thigh_rad_s is not None:
        yaws.append(yaw_rate(same_length(q_earth_thigh, "q_earth_thigh", 4),
                             same_length(gyr_thigh_rad_s, "gyr_thigh_rad_s", 3)))
    if q_earth_shank is not None and gyr_shank_rad_s is not None:
        yaws.append(yaw_rate(same_length(q_earth_shank, "q_earth_shank", 4),
                             same_length(gyr_shank_rad_s, "gyr_shank_rad_s", 3)))
    if yaws:
        turning = turning_mask(yaws, fs_hz, ep)
    else:
        turning = np.zeros(n, dtype=bool)
        warnings.append(QualityWarning("GAIT_TURNS_NOT_CHECKED",
                                       "no segment orientations were given, so strides during turns were not "
                                       "excluded"))

    # strides: consecutive ICs (B1), the TO and MS of the later mid-swing peak inside
    rows = []
    valid = np.flatnonzero(np.isfinite(ic))
    for j0, j1 in zip(valid[:-1], valid[1:]):
        dur_s = (ic[j1] - ic[j0]) / fs_hz
        if not (ep.min_stride_s <= dur_s <= ep.max_stride_s) or ic[j1] <= ic[j0]:
            continue
        t_o = to[j1] if ic[j0] < to[j1] < ic[j1] else np.nan
        m_s = ms[j1] if ic[j0] < ms[j1] < ic[j1] else np.nan
        if np.isfinite(t_o) and np.isfinite(m_s) and t_o >= m_s:
            t_o = np.nan
        rows.append((ic[j0], np.nan, t_o, m_s, ic[j1]))
    k = len(rows)
    ev = np.array(rows, dtype=np.float64).reshape(k, 5)
    spans = ev[:, [0, 4]].copy()
    rejected: list[RejectedCycle] = []
    complete = np.ones(k, dtype=bool)
    for c in range(k):
        i0, i1 = int(math.floor(ev[c, 0])), int(math.ceil(ev[c, 4])) + 1
        if turning[max(0, i0):min(n, i1)].any():
            complete[c] = False
            rejected.append(RejectedCycle(c, "turn", "the stride is part of a turn (yaw rate above "
                                          f"{math.degrees(ep.turn_rate_rad_s):.0f}°/s averaged over "
                                          f"{ep.turn_window_s:g} s)"))
        elif not np.isfinite(ev[c, 2]):
            complete[c] = False
            rejected.append(RejectedCycle(c, "unmeasurable", "no toe-off was found between the two initial contacts"))
    stride_s = (ev[:, 4] - ev[:, 0]) / fs_hz
    if complete.any():
        med = float(np.median(stride_s[complete]))
        for c in np.flatnonzero(complete):
            if abs(stride_s[c] - med) > STRIDE_TIME_TOLERANCE * med:
                complete[c] = False
                rejected.append(RejectedCycle(c, "stride_time", f"stride time {stride_s[c]:.2f} s differs from the "
                                              f"median {med:.2f} s by more than {100 * STRIDE_TIME_TOLERANCE:.0f} %"))
    n_pts = int(p.n_points)
    curves = normalise_cycles(a, np.where(complete[:, None], spans, np.nan), n_pts)
    reg_ev = ev.copy()
    if not np.all(np.isfinite(reg_ev[complete, 3])):
        reg_ev[:, 3] = np.nan
    accepted, rej, stopped = reject_cycles(register_cycles(a, reg_ev, complete, n_pts), complete, p, exclude)
    rejected += rej
    if stopped:
        warnings.append(QualityWarning("MOTOR_TASK_REJECTION_STOPPED",
                                       f"more strides exceed the RMSE threshold, but rejection stopped to keep "
                                       f"{p.min_accepted_cycles} strides; the mean curve may include poor strides",
                                       {"min_cycles": p.min_accepted_cycles}))
    ph = np.column_stack([ev[:, 2] - ev[:, 0], ev[:, 4] - ev[:, 2]]) if k else np.zeros((0, 2))
    pct = 100.0 * ph / (spans[:, 1] - spans[:, 0])[:, None] if k else np.zeros((0, 2))
    rom = np.full((k, 3, 3), np.nan)
    per = {name: np.full(k, np.nan) for name in PARAMETERS}
    for c in range(k):
        i0, i1 = int(math.ceil(spans[c, 0])), int(math.floor(spans[c, 1])) + 1
        seg = a[i0:i1]
        if len(seg):
            mx, mn = seg.max(axis=0), seg.min(axis=0)
            rom[c] = np.column_stack([mx, mn, mx - mn])
        if np.isfinite(ev[c, 2]):
            for name, v in _stride_parameters(a[:, 0], ev[c, 0], ev[c, 2], ev[c, 4], fs_hz).items():
                per[name][c] = v
    params_out = {}
    for name in PARAMETERS:
        x = per[name][accepted]
        mean = float(np.mean(x)) if len(x) else float("nan")
        sd = float(np.std(x, ddof=1)) if len(x) > 1 else float("nan")
        params_out[name] = {"mean": mean, "sd": sd}
        if name in ("stride_time_s", "cadence_steps_min"):
            params_out[name]["cv_pct"] = 100.0 * sd / mean if len(x) > 1 else float("nan")
    # walking bouts: runs of consecutive strides that are not turns (B1)
    bouts, start = [], None
    for c in range(k):
        ok = not any(r.index == c and r.code == "turn" for r in rejected)
        joined = c > 0 and ev[c, 0] == ev[c - 1, 4]
        if ok and start is not None and joined:
            end = ev[c, 4]
        elif ok:
            if start is not None:
                bouts.append((start, end))
            start, end = ev[c, 0], ev[c, 4]
        elif start is not None:
            bouts.append((start, end))
            start = None
    if start is not None:
        bouts.append((start, end))
    d = np.diff(np.concatenate([[0], turning.astype(np.int8), [0]]))
    turns = list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))
    scale = 1.0 / fs_hz
    sel = curves[accepted]
    mean_c = sel.mean(axis=0) if len(sel) else np.full((n_pts, 3), np.nan)
    sd_c = sel.std(axis=0, ddof=1) if len(sel) > 1 else np.full((n_pts, 3), np.nan)
    if k == 0:
        warnings.append(QualityWarning("MOTOR_TASK_NO_CYCLES", "no gait stride (initial contact to initial contact) "
                                       "was found; check that the recording contains walking",
                                       {"task": SPEC.name, "far_label": SPEC.far_label}))
    n_acc = int(accepted.sum())
    if 0 < k and n_acc < p.min_accepted_cycles:
        warnings.append(QualityWarning("MOTOR_TASK_FEW_CYCLES",
                                       f"only {n_acc} usable stride(s) of {k} detected; means and SDs are unreliable",
                                       {"accepted": n_acc, "detected": k}))
    gait = {
        "events_source": source,
        "parameters": params_out,
        "per_stride": per,
        "bouts_s": [[float(t0_s + b0 * scale), float(t0_s + b1 * scale)] for b0, b1 in bouts],
        "turns_s": [[float(t0_s + b0 * scale), float(t0_s + b1 * scale)] for b0, b1 in turns],
        "event_params": dict(vars(ep)),
        "angles": list(ANGLES),
    }
    cls = _gait_analysis_class()
    span_s = None if k == 0 else (t0_s + ev[0, 0] * scale, t0_s + ev[-1, 4] * scale)
    return cls(task=SPEC, params=p, fs_hz=fs_hz, task_span_s=span_s, events_s=t0_s + ev * scale,
               cycles_s=t0_s + spans * scale, accepted=accepted,
               rejected=tuple(sorted(rejected, key=lambda r: (r.index, r.iteration))), curves_rad=curves,
               mean_rad=mean_c, sd_rad=sd_c, rom_rad=rom, phase_s=ph * scale, phase_pct=pct,
               warnings=tuple(warnings), gait=gait)
