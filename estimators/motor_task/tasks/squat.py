"""Squat: rest standing (~0° flexion), flex down, (hold), extend back up.

Phases (events of :data:`~estimators.motor_task.spec.EVENTS`): descent = onset → deepest flexion reached,
hold = deepest flexion reached → left, ascent = left → back at rest standing.  Tested on synthetic
minimum-jerk repetitions only (no recording).
"""

from estimators.motor_task.spec import PhaseSpec, TaskSpec

SPEC = TaskSpec(
    name="squat", excursion="flexion", countermovement=False,
    phases=(PhaseSpec("descent", "onset", "far_reached"),
            PhaseSpec("hold", "far_reached", "far_left"),
            PhaseSpec("ascent", "far_left", "rest_reached")),
    far_label="deepest flexion",
    description="squat: rest standing (~0°), flex down, (hold), extend back up")
