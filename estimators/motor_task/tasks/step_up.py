"""Single-leg step-up (seed 004 §8.1, Fig. 8.2, Tables 8.1/8.3; DESIGN.md §3).

Rest flexed with the foot on the step (0 % of the cycle) → *impulse*: flexion first rises 5–10° while the
other foot pushes off (peak flexion, ~30 % in Fig. 8.2; the thesis measured 34 %) → *extension* to ~0°,
held while the body stands on the leg (~50 %) → *fall* from leaving full extension back to the start
posture (75 %: the other foot touches the floor; 100 %: at rest).  The exact cycle and phase definition
used by the detector is in the :mod:`estimators.motor_task` docstring.
"""

from estimators.motor_task.spec import PhaseSpec, TaskSpec

SPEC = TaskSpec(
    name="step_up", excursion="extension", countermovement=True,
    phases=(PhaseSpec("impulse", "onset", "countermovement_peak"),
            PhaseSpec("extension", "countermovement_peak", "far_left"),
            PhaseSpec("fall", "far_left", "rest_reached")),
    far_label="full extension",
    description="single-leg step-up (seed 004 §8.1; DESIGN.md §3): rest flexed on the step, impulse "
                "(flexion rises 5–10°), extension to ~0° held, fall back to the start posture")
