"""The motor-task registry: one line per task, readable without importing any numerics.

A task is one module plus one line of :data:`TASK_INFO`.  The module (``TaskInfo.module``) defines

* ``SPEC`` — its :class:`~estimators.motor_task.spec.TaskSpec` (``SPEC.name`` = the registry name,
  ``SPEC.phase_names`` = ``TaskInfo.phases``);
* optionally ``PARAMS`` — the task's default :class:`~estimators.motor_task.spec.MotorTaskParams`
  (the package defaults when absent);
* optionally ``analyse(angles_rad, fs_hz, *, params, t0_s) -> TaskAnalysis`` — its own analysis, for a
  task that the excursion detector of :mod:`estimators.motor_task.detection` does not fit (e.g. gait,
  whose cycles run from heel strike to heel strike); without it :func:`~estimators.motor_task.analyse_task`
  runs the shared excursion detector on ``SPEC``.

Adding a task (e.g. gait): write ``estimators/motor_task/tasks/gait.py`` with ``SPEC`` (and ``analyse`` if the
shared detector does not fit), append ``TaskInfo("gait", "Gait", ("stance", "swing"),
"estimators.motor_task.tasks.gait")`` to :data:`TASK_INFO`; ``tests/estimators/test_motor_task_contract.py``
then runs the contract over it (give it a synthetic-repetition generator there).

This module imports the standard library only, so the CLI, the API's ``/options`` and the UI can list the
tasks (:data:`TASK_NAMES`, :data:`TASK_INFO`) without loading numpy, scipy or numba.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from types import ModuleType

__all__ = ["TASK_INFO", "TASK_NAMES", "TaskInfo", "load_task_module", "task_info"]


@dataclass(frozen=True)
class TaskInfo:
    """One registered motor task.

    name : the task's key (``--task``, ``results.json`` ``task``).   label : English label for people (the app
    translates it).   phases : the phase names of a cycle, in time order (they sum to the cycle).
    module : dotted path of the module holding ``SPEC`` (and optionally ``PARAMS``, ``analyse``).
    """

    name: str
    label: str
    phases: tuple[str, ...]
    module: str


#: Every registered task, in the order the app lists them (the default, ``step_up``, first).
TASK_INFO: tuple[TaskInfo, ...] = (
    TaskInfo("step_up", "Single-leg step-up", ("impulse", "extension", "fall"),
             "estimators.motor_task.tasks.step_up"),
    TaskInfo("seated_knee_extension", "Seated knee extension", ("extension", "hold", "flexion"),
             "estimators.motor_task.tasks.seated_knee_extension"),
    TaskInfo("squat", "Squat", ("descent", "hold", "ascent"), "estimators.motor_task.tasks.squat"),
    TaskInfo("gait", "Gait", ("stance", "swing"), "estimators.motor_task.tasks.gait"),
)

#: The registered task names, in :data:`TASK_INFO` order.
TASK_NAMES: tuple[str, ...] = tuple(t.name for t in TASK_INFO)


def task_info(name: str) -> TaskInfo:
    """The :class:`TaskInfo` of a registered task; ValueError naming the valid tasks otherwise."""
    for t in TASK_INFO:
        if t.name == name:
            return t
    raise ValueError(f"unknown task {name!r}; valid tasks are {list(TASK_NAMES)}")


def load_task_module(name: str) -> ModuleType:
    """Import and return the module of a registered task (checks that its ``SPEC`` matches the registry)."""
    info = task_info(name)
    mod = import_module(info.module)
    spec = getattr(mod, "SPEC", None)
    if spec is None or spec.name != info.name or tuple(spec.phase_names) != info.phases:
        raise RuntimeError(f"task module {info.module} does not define a SPEC matching its registry line "
                           f"(name {info.name!r}, phases {info.phases})")
    return mod
