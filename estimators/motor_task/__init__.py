r"""Motor-task analysis: cycles, phases, normalised mean ± SD curves, rejection and ranges of motion.

Pure numerics on the knee angles of a task recording (rad, clinical signs, uniform rate); radians and
seconds throughout — :meth:`TaskAnalysis.to_dict` gives ``rom_rad`` and ``curves_rad``, which the app converts
to the degrees of ``results.json`` (``rom_deg``, ``curves``).

Example::

    from estimators.motor_task import analyse_task
    res = analyse_task(angles_rad, fs_hz=100.0, task="step_up")        # angles_rad: (N, 3)
    res.cycles_s, res.events_s, res.phase_stats(), res.rom_stats(), res.mean_rad, res.sd_rad

Source: seed 004 §8.1 (the task) and §8.6.1 (``deteccion_inicio/final_tarea_motora``,
``deteccion_extension``, ``deteccion_impulso_caida``, ``ciclos_tarea_motora``, ``normalizacion_ciclos``,
``media_ciclos``); the cycle and phase definitions are DESIGN.md §3.

Cycle, events and phases
------------------------
Every repetition of a task moves the knee from a *rest* posture to a *far plateau* and back.  Working on
:math:`y = s\,\phi` (flexion :math:`\phi`; :math:`s=-1` when the far plateau is full extension, :math:`+1`
for squats) the excursion always goes up.  Each cycle has five events (:data:`EVENTS`):

``onset`` (leaves rest) → ``countermovement_peak`` (tasks with a countermovement only) → ``far_reached`` →
``far_left`` → ``rest_reached``.

For the single-leg **step-up** (DESIGN.md §3): the cycle starts at rest in the flexed start posture (60° at
17 cm, 90° at 34 cm); *impulse* = onset → peak flexion (flexion first rises 5–10°, the countermovement);
*extension* = peak flexion → leaving full extension (reaching ~0° and holding it); *fall* = leaving full
extension → back at rest in the start posture.  ``cycles_s`` = onset → next onset (→ rest_reached for a
cycle not followed by another), exactly the simulator's ``cycles_s``; events ``[0, 1, 3, 4]`` are its
``phases_s``.  The phases of each task are a :class:`TaskSpec` (:data:`TASKS`): ``seated_knee_extension``
(extension, hold, flexion) and ``squat`` (descent, hold, ascent) reuse the machinery; they are tested only
on synthetic minimum-jerk repetitions (noise, drift), never on recordings.

Detection (sample units, :mod:`.detection`)
-------------------------------------------
D1  Smoothing: zero-phase 2nd-order Butterworth low-pass of flexion (``lowpass_hz``, 5 Hz), detection only.
D2  Task span (thesis ``deteccion_inicio/final_tarea_motora``): the first and last sample whose centred
    moving SD of flexion (``activity_window_s``) exceeds ``activity_sd_rad``; scanning from both ends makes a
    pause mid-task harmless.
D3  Excursions (thesis ``deteccion_extension``): runs of :math:`y` above the midline between its 5th and 95th
    percentiles in the span, with ±15 % hysteresis.  One excursion = one cycle.  The far plateau is the
    still run (|dy/dt| < ``stationary_rad_s``, runs closer than ``merge_gap_s`` merged) holding the
    excursion's maximum (a single sample for a turning point).
D4  Between two excursions (thesis ``deteccion_impulso_caida``): the countermovement peak is the minimum of
    :math:`y` (maximum flexion) and the rest is the longest still run before it that stays at least
    ``min_countermovement_rad``/2 above it (the slowest sample when the knee never stops, i.e. continuous
    cycles).  A countermovement smaller than ``min_countermovement_rad`` is none: impulse of 0 s.
    Plateau levels next to a transition are medians over ``level_window_s`` of the plateau.
D5  Transition boundaries.  Each transition between two still levels :math:`L_0 \to L_1` (rest → peak,
    peak → far plateau, far plateau → rest) is modelled as a minimum-jerk movement (the shape of human
    point-to-point movements, Flash & Hogan 1985):
    :math:`y(t) = L_0 + (L_1-L_0)\,m((t-t_0)/T),\ m(\tau) = 10\tau^3-15\tau^4+6\tau^5`.  The crossing
    times :math:`c_f` of the fractions :math:`f = 0.1 … 0.9` (searched outward from the 50 % crossing, so
    noise at the ends cannot move them) satisfy :math:`c_f = t_0 + T\tau_f`, :math:`m(\tau_f) = f`;
    :math:`T` is their least-squares slope, the start :math:`t_0` the mean of :math:`c_f - T\tau_f` over
    :math:`f \le 0.5` and the end the mean of :math:`c_f + T(1-\tau_f)` over :math:`f \ge 0.5`.  A pure
    threshold on a smooth start is late by ~0.1–0.2 s; this estimate is unbiased for minimum-jerk
    movements and uses only the well-conditioned middle of the transition.  The peak flexion event is the
    mean of the impulse end and the extension start.
D6  ``boundary_model="threshold"``: instead, the instants the knee is ``boundary_threshold_rad`` away from the
    level it leaves / reaches (a clinical convention, later than D5 by construction).
Completeness: a cycle whose excursion touches the recording's start/end, that has no rest before/after it
(``min_edge_rest_s`` for the first/last), a transition that cannot be measured, or an amplitude below
``min_excursion_rad`` is rejected with the reason codes of :class:`RejectedCycle`.

Cycles (thesis ``ciclos_tarea_motora``, ``normalizacion_ciclos``, ``media_ciclos``; :mod:`.analysis`)
----------------------------------------------------------------------------------------------------
C1  Normalisation: each angle linearly interpolated at ``n_points`` (101) equally spaced instants of the
    normalisation span — onset → rest_reached (``normalise_span="movement"``, default: phases add up to
    100 % as in the thesis' Table 8.1, and a pause in the start posture does not stretch the curve nor
    make the last cycle, which has no rest after it, look different) or onset → next onset (``"cycle"``).
C2  Rejection: mean of the accepted normalised cycles; the cycle with the largest RMSE to it relative to its
    angle's threshold (``rejection_rmse_rad``, flexion 8° by default) is rejected if above 1, the mean is
    recomputed, and so on; it stops before fewer than ``min_accepted_cycles`` would remain (warning).
C3  Statistics over the accepted cycles, SD with ddof = 1: curves mean ± SD per angle; phase durations (s)
    and % of the span per cycle, then averaged; ROM per angle: max, min, range over the samples of each
    cycle's span (the input angles, not the smoothed ones).

Accuracy on the simulator, as ``tests/estimators/test_motor_task.py`` checks it (``simulation.step_up``,
5 and 15 cycles, 17 and 34 cm, 0.5° RMS noise on all angles + 2° drift of flexion): every cycle found and
accepted, every boundary (onset, peak, leaving extension, back at rest) within 2 % of the cycle duration
(0.3 % without noise).
"""

from estimators.motor_task.registry import TASK_INFO, TASK_NAMES, TaskInfo, task_info
from estimators.motor_task.spec import EVENTS, MotorTaskParams, PhaseSpec, TaskSpec

#: the three knee angles of every curve, in column order (kept here, stdlib, for the app's labels)
ANGLES: tuple[str, ...] = ("flexion", "adduction", "internal_rotation")

# Names loaded on first use (PEP 562), so that importing this package and reading TASK_INFO / TASK_NAMES
# loads neither numpy nor scipy: the analysis (numpy, scipy.signal) only when it is called.
_LAZY = {
    "QualityWarning": "estimators.motor_task.analysis", "RejectedCycle": "estimators.motor_task.analysis",
    "TaskAnalysis": "estimators.motor_task.analysis", "analyse_task": "estimators.motor_task.analysis",
    "normalise_cycles": "estimators.motor_task.analysis", "reject_cycles": "estimators.motor_task.analysis",
    "TASKS": "estimators.motor_task.tasks", "get_task": "estimators.motor_task.tasks",
}


def __getattr__(name: str):
    if name in _LAZY:
        from importlib import import_module
        value = getattr(import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ANGLES", "EVENTS", "MotorTaskParams", "PhaseSpec", "QualityWarning", "RejectedCycle", "TASKS",
           "TASK_INFO", "TASK_NAMES", "TaskAnalysis", "TaskInfo", "TaskSpec", "analyse_task", "get_task",
           "normalise_cycles", "reject_cycles", "task_info"]
