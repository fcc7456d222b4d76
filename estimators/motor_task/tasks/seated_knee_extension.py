"""Seated knee extension: rest seated at ~90° flexion, extend to ~0°, (hold), flex back.

Phases: extension = onset → full extension reached, hold = reached → left, flexion = left → back at rest.
Tested on synthetic minimum-jerk repetitions only (no recording).
"""

from estimators.motor_task.spec import PhaseSpec, TaskSpec

SPEC = TaskSpec(
    name="seated_knee_extension", excursion="extension", countermovement=False,
    phases=(PhaseSpec("extension", "onset", "far_reached"),
            PhaseSpec("hold", "far_reached", "far_left"),
            PhaseSpec("flexion", "far_left", "rest_reached")),
    far_label="full extension",
    description="seated knee flexion-extension: rest at ~90° flexion, extend, (hold), flex back")
