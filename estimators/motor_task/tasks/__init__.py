"""The registered tasks' specifications: :data:`TASKS` (name → :class:`TaskSpec`) and :func:`get_task`.

One module per task in this package (``SPEC``, optionally ``PARAMS`` and ``analyse``: see
:mod:`estimators.motor_task.registry`); importing this package imports every task module, which therefore
keep any numpy/scipy import inside their functions.
"""

from __future__ import annotations

from estimators.motor_task.registry import TASK_INFO, load_task_module
from estimators.motor_task.spec import EVENTS, MotorTaskParams, PhaseSpec, TaskSpec

__all__ = ["EVENTS", "TASKS", "MotorTaskParams", "PhaseSpec", "TaskSpec", "get_task"]

#: name → :class:`TaskSpec` of every registered task, in registry order.
TASKS: dict[str, TaskSpec] = {t.name: load_task_module(t.name).SPEC for t in TASK_INFO}


def get_task(task: str | TaskSpec) -> TaskSpec:
    """The :class:`TaskSpec` for a name in :data:`TASKS` (or the spec itself)."""
    if isinstance(task, TaskSpec):
        return task
    try:
        return TASKS[task]
    except (KeyError, TypeError):
        raise ValueError(f"unknown task {task!r}; valid tasks are {sorted(TASKS)}") from None
