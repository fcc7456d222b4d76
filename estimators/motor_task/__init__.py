r"""Motor-task analysis: cycles, phases, normalised mean ± SD curves, rejection and ranges of motion.

Pure numerics on the knee angles of a task recording (rad, clinical signs, uniform rate); radians and
seconds throughout — :meth:`TaskAnalysis.to_dict` gives ``rom_rad`` and ``curves_rad``, which the app converts
to the degrees of ``results.json`` (``rom_deg``, ``curves``).

Example::

    from estimators.motor_task import analyse_task
    res = analyse_task(angles_rad, fs_hz=100.0, task="step_up")        # angles_rad: (N, 3)
    res.cycles_s, res.events_s, res.phase_stats(), res.rom_stats(), res.mean_rad, res.sd_rad
    from estimators.motor_task import TASK_NAMES, TASK_INFO       # the task list, without numerics

Source: seed 004 §8.1 (the task) and §8.6.1 (``deteccion_inicio/final_tarea_motora``,
``deteccion_extension``, ``deteccion_impulso_caida``, ``ciclos_tarea_motora``, ``normalizacion_ciclos``,
``media_ciclos``); the cycle and phase definitions are DESIGN.md §3.

Tasks
-----
A task is one module plus one registry line (:mod:`.registry`: :data:`TASK_INFO`, :data:`TASK_NAMES`,
stdlib only, so that listing the tasks loads no numerics); :data:`TASKS` maps names to their
:class:`TaskSpec`.  Registered: ``step_up`` (default), ``squat``, ``seated_knee_extension``.

Cycle, events and phases (the exact definition)
-----------------------------------------------
Every repetition moves the knee from a *rest* posture to a *far plateau* and back.  Working on
:math:`y = s\,\phi` (flexion :math:`\phi`; :math:`s=-1` when the far plateau is full extension, :math:`+1`
for squats) the excursion always goes up.  Each cycle has five events (:data:`EVENTS`):
``onset`` → ``countermovement_peak`` (tasks with a countermovement only) → ``far_reached`` → ``far_left`` →
``rest_reached``.

Single-leg **step-up** (DESIGN.md §3; seed 004 §8.1, Fig. 8.2, Tables 8.1/8.3):

* **cycle start** (``onset``): the instant the knee leaves the flexed start posture (foot on the step) to start
  the impulse.  When the previous cycle's fall runs straight into this impulse (the thesis' continuous
  repetitions) it is the instant the flexion is stillest between them, which is also where the previous
  cycle ends: one split.
* **impulse** = onset → peak flexion (``countermovement_peak``: flexion first rises 5–10°);
* **extension** = peak flexion → leaving full extension (``far_left``: the knee reached ~0° and held it);
* **fall** = leaving full extension → back at rest in the start posture (``rest_reached``);
* **cycle** = onset → back at rest (``cycles_s``); the three phases sum to it.  A rest in the start posture
  between the end of a fall and the next impulse that lasts at least ``min_pause_s`` (0.03 s) and is
  distinguishable from noise (D5c) is a *pause*: it ends the cycle before it and belongs to no cycle; so
  does the rest before the first and after the last cycle.
* Where this departs from the thesis: the thesis (``ciclos_tarea_motora``) cut the recording at the
  fall/impulse splits, so a rest or pause between repetitions was counted in the cycle before it and
  its phase percentages were of onset → next onset.  Here a pause is in no cycle, so the
  percentages are of onset → back at rest, as the thesis' Table 8.1 reports them (they add up to
  100 %); ``normalise_span="cycle"`` restores the thesis' onset → next onset span for comparison.  The
  boundaries are where the knee's movements start and end, as fitted by minimum-jerk models (D5–D5c), and
  not where a threshold is crossed.

``seated_knee_extension`` (extension, hold, flexion) and ``squat`` (descent, hold, ascent) reuse the
machinery without the countermovement; they are tested only on synthetic minimum-jerk repetitions.

Detection (sample units, :mod:`.detection`)
-------------------------------------------
D1  Smoothing: zero-phase 2nd-order Butterworth low-pass of flexion (``lowpass_hz``, 5 Hz) for the search;
    the least-squares fits D5b/D5c use the unsmoothed flexion (the low-pass bends a slow impulse's start).
D2  Task span (thesis ``deteccion_inicio/final_tarea_motora``): the first and last sample whose centred
    moving SD of flexion (``activity_window_s``) exceeds ``activity_sd_rad``.
D3  Excursions (thesis ``deteccion_extension``): runs of :math:`y` above the midline between its 5th and 95th
    percentiles in the span, with ±15 % hysteresis.  One excursion = one cycle.  The far plateau is the
    still run (|dy/dt| < ``stationary_rad_s``, runs closer than ``merge_gap_s`` merged) holding the
    excursion's maximum.
D4  Between two excursions (thesis ``deteccion_impulso_caida``): the countermovement peak is the minimum of
    :math:`y` (maximum flexion); the split is the stillest sample before it (rate averaged over 0.2 s, then
    the plain rate) at least ``min_countermovement_rad``/2 above it, and the rest level the median of
    :math:`y` around the split.  A countermovement smaller than ``min_countermovement_rad`` is none (impulse
    of 0 s; the rest is then the still run at the lowest point).
D5  Transitions between two still levels :math:`L_0 \to L_1` (peak → far plateau, far plateau → rest):
    minimum-jerk movements (Flash & Hogan 1985)
    :math:`y(t) = L_0 + (L_1-L_0)\,m((t-t_0)/T),\ m(\tau) = 10\tau^3-15\tau^4+6\tau^5`, timed from the crossing
    times :math:`c_f = t_0 + T\tau_f` of the fractions :math:`f = 0.1 … 0.9` (least-squares slope :math:`T`;
    start = mean of :math:`c_f - T\tau_f` over :math:`f \le 0.5`, end = mean of :math:`c_f + T(1-\tau_f)`
    over :math:`f \ge 0.5`).  The peak-flexion event is the extension's start.
D5b First impulse (a rest before it, no fall): :func:`.detection.fit_onset`, least squares of
    :math:`L + A\,m((t-t_0)/(t_{peak}-t_0))` over every sample from the rest to the peak.
D5c Fall → (rest) → impulse: :func:`.detection.fit_split`, one least-squares fit from leaving the far
    plateau to the next peak of a minimum-jerk fall to :math:`L`, a rest at :math:`L` and a minimum-jerk
    impulse, linear in the three levels; the fall's end :math:`t_1` and the onset :math:`t_0 \ge t_1` by a
    coarse-to-fine grid.  The rest is kept only if :math:`t_0-t_1 \ge` ``min_pause_s`` (default 0.03 s) and the
    Bayesian information criterion prefers it; otherwise :math:`t_1 = t_0`.  A fitted impulse smaller than
    ``min_countermovement_rad`` is none.
D6  ``boundary_model="threshold"``: instead, the instants the knee is ``boundary_threshold_rad`` away from the
    level it leaves / reaches (a clinical convention, later than D5 by construction).
D7  Step-up with both gyroscopes (the pipeline passes them): the fits D5b/D5c run on a flexion whose variations
    faster than ``gyro_crossover_hz`` (0.05 Hz) come from the integrated gyroscopes and slower ones from the
    angles (:func:`.detection.gyroscope_flexion`): an accelerometer bias makes the smoothed orientations' flexion
    ramp ~1° before an impulse while the knee is still.
Completeness: a cycle whose excursion touches the recording's start/end, that has no rest before/after it
(``min_edge_rest_s`` for the first/last when the rest touches the edge, twice that inside), whose first onset or
last return to rest is not fitted inside the recording, with a transition that cannot be measured, or with an
amplitude below ``min_excursion_rad`` is rejected with the reason codes of :class:`RejectedCycle`.

Cycles (thesis ``ciclos_tarea_motora``, ``normalizacion_ciclos``, ``media_ciclos``; :mod:`.analysis`)
----------------------------------------------------------------------------------------------------
C1  Normalisation: each angle linearly interpolated at ``n_points`` (101) equally spaced instants of the
    cycle, onset → back at rest (``normalise_span="movement"``, default) or onset → next onset (``"cycle"``).
C2  Rejection (thesis ``media_ciclos``): the cycles are first registered on their events — time-warped
    piecewise linearly so that each event falls at its mean fraction of the cycle
    (:func:`~estimators.motor_task.analysis.register_cycles`) — so that natural timing variability (phase
    proportions SD 1–3 %, Tables 8.1/8.3) is not taken for a bad cycle; then the cycle with the largest
    RMSE to the mean of the accepted ones relative to its angle's threshold (``rejection_rmse_rad``,
    flexion 8°) is rejected if above 1 (reason ``rmse``, the RMSE in its message), the mean is recomputed,
    and so on; it stops before fewer than ``min_accepted_cycles`` would remain (warning).  Shape and
    amplitude errors (a converging filter's offset, a stumble) are still rejected.
C3  Statistics over the accepted cycles, SD with ddof = 1: curves mean ± SD per angle (from C1, not
    registered); phase durations (s) and % per cycle, then averaged; ROM per angle: max, min, range over the
    samples of each cycle (the input angles, not the smoothed ones).

Accuracy on the simulator (``tests/estimators/test_motor_task*.py``: both step-up shapes, 17 and 34 cm, both
legs, pauses of 0–6 s, rests of 0.5–3 s, cycles of 2–6 s, 0.5° RMS white noise on all angles + 2° drift of
flexion): every cycle found and accepted, every boundary within 2 % of the cycle (≤ 0.1 % without noise).
"""

from estimators.motor_task.registry import TASK_INFO, TASK_NAMES, TaskInfo, task_info
from estimators.motor_task.spec import EVENTS, MotorTaskParams, PhaseSpec, TaskSpec

#: the three knee angles of every curve, in column order (kept here, stdlib, for the app's labels)
ANGLES: tuple[str, ...] = ("flexion", "adduction", "internal_rotation")

# Names loaded on first use (PEP 562), so that importing this package and reading TASK_INFO / TASK_NAMES
# loads neither numpy nor scipy: the analysis (numpy, scipy.signal) only when it is called.
_LAZY = {
    "QualityWarning": "estimators.motor_task.analysis", "RejectedCycle": "estimators.motor_task.analysis",
    "EXCLUDED": "estimators.motor_task.analysis", "UnknownCycleError": "estimators.motor_task.analysis",
    "NotCandidateError": "estimators.motor_task.analysis",
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


__all__ = [
    "ANGLES",
    "EVENTS",
    "EXCLUDED",
    "TASKS",
    "TASK_INFO",
    "TASK_NAMES",
    "MotorTaskParams",
    "PhaseSpec",
    "QualityWarning",
    "RejectedCycle",
    "TaskAnalysis",
    "TaskInfo",
    "TaskSpec",
    "UnknownCycleError",
    "NotCandidateError",
    "analyse_task",
    "get_task",
    "normalise_cycles",
    "reject_cycles",
    "task_info",
]
