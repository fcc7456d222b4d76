"""Task specifications (which way the knee moves, which phases a cycle has) and the analysis parameters.

Standard library only (no numpy, scipy or numba): the registry (:mod:`.registry`) and the task modules
(:mod:`.tasks`) import it to describe tasks without loading the numerics.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

__all__ = ["EVENTS", "MotorTaskParams", "PhaseSpec", "TaskSpec"]

#: The five events of every cycle, in time order (see the package docstring, "Events").
EVENTS: tuple[str, ...] = ("onset", "countermovement_peak", "far_reached", "far_left", "rest_reached")


@dataclass(frozen=True)
class PhaseSpec:
    """One phase of a cycle: the span from event ``start`` to event ``end`` (names from :data:`EVENTS`)."""

    name: str
    start: str
    end: str

    def __post_init__(self) -> None:
        for e in (self.start, self.end):
            if e not in EVENTS:
                raise ValueError(f"phase {self.name!r}: unknown event {e!r}; valid events are {EVENTS}")
        if EVENTS.index(self.end) <= EVENTS.index(self.start):
            raise ValueError(f"phase {self.name!r}: end event {self.end!r} must come after {self.start!r}")


@dataclass(frozen=True)
class TaskSpec:
    """A repetitive knee task as the detector sees it.

    name : key in :data:`~estimators.motor_task.TASKS` and the ``task`` of ``results.json``.
    excursion : ``"extension"`` when each repetition moves from a flexed rest towards full extension
        (step-up, seated knee extension); ``"flexion"`` when it moves from an extended rest into
        flexion (squat).  The detector works on ``y = -flexion`` or ``y = +flexion`` so that the
        excursion always goes up.
    countermovement : the repetition starts with a small movement the *other* way (the step-up
        impulse: flexion first rises 5–10° before the extension); gives the ``countermovement_peak`` event.
    phases : the reported phases, consecutive and covering onset → rest_reached.
    far_label : what the far plateau is called in messages ("full extension", "deepest flexion").
    heading_bound : which disagreement bound ``--heading auto`` uses for this task before it takes the joint
        constraint's heading (:func:`estimators.heading.choose_heading`): ``"disturbed"`` (default,
        :data:`estimators.heading.DISTURBED_BOUND_RAD`, 6°) or ``"tilt"``
        (:data:`~estimators.heading.DISAGREEMENT_BOUND_RAD`, 3°), set only by tasks whose motion the tilt bound
        was chosen and held out on (the step-up, ``benchmarks.robustness``): on simulated walking 1.5° switched 2 of
        12 clean sessions for a worse rotation (0.41 → 0.81°), and squats and seated extensions have no simulator
        yet.
    """

    name: str
    excursion: str
    countermovement: bool
    phases: tuple[PhaseSpec, ...]
    far_label: str
    description: str = ""
    heading_bound: str = "disturbed"

    def __post_init__(self) -> None:
        if self.excursion not in ("extension", "flexion"):
            raise ValueError(f"TaskSpec.excursion must be 'extension' or 'flexion', got {self.excursion!r}")
        if not self.phases:
            raise ValueError("TaskSpec.phases must not be empty")
        if self.heading_bound not in ("disturbed", "tilt"):
            raise ValueError(f"TaskSpec.heading_bound must be 'disturbed' or 'tilt', got {self.heading_bound!r}")
        if self.phases[0].start != "onset" or self.phases[-1].end != "rest_reached":
            raise ValueError("TaskSpec.phases must run from 'onset' to 'rest_reached'")
        for a, b in zip(self.phases[:-1], self.phases[1:]):
            if a.end != b.start:
                raise ValueError(f"TaskSpec.phases must be consecutive: {a.name!r} ends at {a.end!r} "
                                 f"but {b.name!r} starts at {b.start!r}")
        if not self.countermovement and any("countermovement_peak" in (p.start, p.end) for p in self.phases):
            raise ValueError("a task without countermovement cannot use the 'countermovement_peak' event")

    @property
    def sign(self) -> float:
        """``y = sign * flexion`` makes the excursion go up."""
        return -1.0 if self.excursion == "extension" else 1.0

    @property
    def phase_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.phases)


@dataclass(frozen=True)
class MotorTaskParams:
    """Parameters of :func:`~estimators.motor_task.analyse_task`; every value in SI units and radians.

    lowpass_hz : zero-phase Butterworth (2nd order, run forward and backward) cut-off used for the
        *detection* only; curves and ROM use the angles as given.  Default 5 Hz.
    activity_window_s : window of the moving SD of flexion that finds the task span (thesis
        ``deteccion_inicio/final_tarea_motora``).  Default 1.0 s.
    activity_sd_rad : the moving SD above which the knee is "in the task".  Default 2° (0.0349 rad).
    stationary_rad_s : |flexion rate| below which the knee is "still" (rests, holds, turning points).
        Default 12°/s (0.209 rad/s).
    merge_gap_s : still runs separated by less than this are merged (noise).  Default 0.1 s.
    level_window_s : the plateau level next to a transition is the median over this much of the
        plateau.  Default 0.3 s.
    min_excursion_rad : smallest rest → far-plateau amplitude that makes a cycle.  Default 20°.
    min_countermovement_rad : smallest countermovement (impulse) that counts as one; a smaller one gives an
        impulse of zero duration.  Default 1.5°.
    min_edge_rest_s : rest needed before the first and after the last cycle when it touches the recording's edge
        (the knee seen at rest from the first / until the last sample).  Default 0.1 s.  A rest inside the
        recording needs twice this (a turning point, the impulse's peak of a recording that starts during the
        impulse, is still for ~0.15 s), and the fitted onset / return to rest must lie inside the recording;
        else the cycle is incomplete.  Chosen on seeds 0–99 of ``benchmarks/robustness.py``: complete cycles
        recorded with 0.02–0.2 s of rest at an edge have edge still runs of 0.15–0.19 s (the run also holds the
        slow start or end of the movement), a cycle the recording cut at its onset 0.09 s.  It was 0.2 s for
        every rest, which rejected the complete edge cycles of seeds 5 and 35.
    min_pause_s : shortest rest between the end of a fall and the next impulse that counts as a pause (which
        ends the cycle before it); a shorter one, or one the fit cannot tell from noise (D5c's BIC test), makes
        the two cycles meet at one split.  Default 0.03 s.  A merged rest costs its whole length: the merged
        split follows the fast fall's end, not the slow impulse's start, so the next onset comes early by the
        rest; the old 0.1 s merged real rests of 0.07–0.09 s (2.3 % and 2.9 % of the cycle on held-out seeds 186
        and 143 of ``benchmarks/robustness.py``) and could cost 5 % of a 2 s cycle, where 0.03 s costs at most
        1.5 %.  Without it (0) the BIC test keeps phantom rests of 1–2 samples on continuous cycles, which shift
        the onsets by a sample and bend the mean curve of fast cycles (held-out seed 156: flexion curve 0.67° →
        1.05°).  On the tuning seeds 0–12 and those with rests under 0.25 s (2, 20, 30, 31, 62, 80, 96) every
        phantom rest was ≤ 0.02 s (69 continuous junctions) and every real rest of ≥ 0.03 s was kept at its length.
        Applied as :meth:`min_pause_samples`: never under 3 samples (0.03 s is 1.5 samples at 50 Hz, where the
        BIC test kept 2-sample phantom rests on continuous cycles).
    boundary_model : ``"min_jerk"`` (default): each transition's start and end are those of the
        minimum-jerk movement fitting its 10 %…90 % crossing times; ``"threshold"``: the instants the
        knee is ``boundary_threshold_rad`` away from the plateau it leaves / reaches.
    boundary_threshold_rad : threshold of the ``"threshold"`` model.  Default 2°.
    normalise_span : ``"movement"`` (default): a cycle is normalised, and phase % computed, over
        onset → rest_reached (the phases add up to 100 %, as in the thesis' Table 8.1; a pause in the
        start posture does not stretch the curve); ``"cycle"``: over onset → next onset.
    n_points : points of a normalised cycle (0 … 100 %).  Default 101.
    rejection_rmse_rad : per angle (flexion, adduction, internal rotation) the largest RMSE of a
        normalised cycle to the mean of the accepted ones; ``None`` does not check that angle.
        Default (8°, None, None).
    min_accepted_cycles : rejection stops before fewer cycles than this would remain.  Default 3.
    gyro_crossover_hz : when the task's analysis has both gyroscopes (step-up), the least-squares event fits
        (D5b, D5c) use the flexion whose variations faster than this come from the integrated gyroscopes and
        slower ones from the angles (D7, :func:`~estimators.motor_task.detection.gyroscope_flexion`).  Default
        0.05 Hz, chosen on seeds 0–99 of ``benchmarks/robustness.py`` (0.2 Hz left 1.2 % of a slow cycle on
        seed 10, 0.05 Hz 0.2 %).
    """

    lowpass_hz: float = 5.0
    activity_window_s: float = 1.0
    activity_sd_rad: float = math.radians(2.0)
    stationary_rad_s: float = math.radians(12.0)
    merge_gap_s: float = 0.1
    level_window_s: float = 0.3
    min_excursion_rad: float = math.radians(20.0)
    min_countermovement_rad: float = math.radians(1.5)
    min_edge_rest_s: float = 0.1
    min_pause_s: float = 0.03
    boundary_model: str = "min_jerk"
    boundary_threshold_rad: float = math.radians(2.0)
    normalise_span: str = "movement"
    n_points: int = 101
    rejection_rmse_rad: tuple[float | None, float | None, float | None] = (
        math.radians(8.0), None, None)
    min_accepted_cycles: int = 3
    gyro_crossover_hz: float = 0.05

    def min_pause_samples(self, fs_hz: float) -> float:
        r"""``min_pause_s`` in samples at ``fs_hz``, floored at 3: :math:`\max(t_{pause} f_s,\ 3)`.  The phantom
        rests the BIC test lets through on continuous cycles are 1–2 samples long at any rate (≤ 0.02 s at 100 Hz,
        0.04 s at 50 Hz), so a rest must be at least 3 samples to count."""
        return max(self.min_pause_s * fs_hz, 3.0)

    def __post_init__(self) -> None:
        positive = ("lowpass_hz", "activity_window_s", "activity_sd_rad", "stationary_rad_s", "level_window_s",
                    "min_excursion_rad", "boundary_threshold_rad", "gyro_crossover_hz")
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"MotorTaskParams.{name} must be a positive finite number, got {v!r}")
        for name in ("merge_gap_s", "min_countermovement_rad", "min_edge_rest_s", "min_pause_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"MotorTaskParams.{name} must be a finite number >= 0, got {v!r}")
        if self.boundary_model not in ("min_jerk", "threshold"):
            raise ValueError(f"MotorTaskParams.boundary_model must be 'min_jerk' or 'threshold', "
                             f"got {self.boundary_model!r}")
        if self.normalise_span not in ("movement", "cycle"):
            raise ValueError(f"MotorTaskParams.normalise_span must be 'movement' or 'cycle', "
                             f"got {self.normalise_span!r}")
        if int(self.n_points) != self.n_points or self.n_points < 3:
            raise ValueError(f"MotorTaskParams.n_points must be an integer >= 3, got {self.n_points!r}")
        r = tuple(self.rejection_rmse_rad)
        if len(r) != 3 or any(x is not None and not (math.isfinite(x) and x > 0) for x in r):
            raise ValueError("MotorTaskParams.rejection_rmse_rad must be three positive thresholds in rad "
                             f"(or None to skip an angle), got {self.rejection_rmse_rad!r}")
        object.__setattr__(self, "rejection_rmse_rad", r)
        if int(self.min_accepted_cycles) != self.min_accepted_cycles or self.min_accepted_cycles < 1:
            raise ValueError(f"MotorTaskParams.min_accepted_cycles must be an integer >= 1, "
                             f"got {self.min_accepted_cycles!r}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["rejection_rmse_rad"] = list(self.rejection_rmse_rad)
        return d
