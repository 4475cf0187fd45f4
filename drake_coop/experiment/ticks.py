"""A run's time grid: the control period and plant step aligned, the run's size checked, the
ticks of the grasp and of a time.

:func:`time_grid` is the one place a scenario's periods are aligned (by
:func:`~drake_coop.control.timing.aligned_periods`: ``h = N dt``, so that every control tick
is a plant step); the run plan (:mod:`drake_coop.experiment.plan`), the plant builder, the
diagram, the runner, identification and the benchmark read it.
"""

from __future__ import annotations

import math

from drake_coop.control.timing import aligned_periods
from drake_coop.scenario.schema import Scenario, ScenarioError, Task

__all__ = ["MAX_PLANT_STEPS", "MAX_TICKS", "check_run_size", "grasp_ticks", "num_ticks_until",
           "run_size", "time_grid"]

#: Largest run (control ticks of ``h``, and plant steps) accepted: the references and the
#: logs cost about 5 kB per tick (1 GB at the limit), a plant step about 50 µs.
MAX_TICKS = 200_000
MAX_PLANT_STEPS = 20_000_000


def time_grid(scenario: Scenario) -> tuple[float, float]:
    """``(h, dt)``: the scenario's control period and plant step on one exact grid
    (``h = N dt``, :func:`~drake_coop.control.timing.aligned_periods`), s.

    Parameters
    ----------
    scenario : Scenario
        The scenario whose ``control_period`` and ``plant.time_step`` are aligned.
    """
    return aligned_periods(scenario.control_period, scenario.plant.time_step)


def _run_end(scenario: Scenario, t_end: float | None) -> float:
    return scenario.task.t_end if t_end is None else min(t_end, scenario.task.t_end)


def run_size(scenario: Scenario, t_end: float | None = None) -> tuple[int, int]:
    """The numbers ``(ticks, steps)`` of control ticks and plant steps of a run to
    ``min(t_end, task.t_end)``.

    Parameters
    ----------
    scenario, t_end
        As in :func:`check_run_size`.
    """
    h, dt = time_grid(scenario)
    T = _run_end(scenario, t_end)
    return int(T / h) + 1, int(T / dt)


def check_run_size(scenario: Scenario, t_end: float | None = None) -> None:
    """Refuse a run shorter than one control period, or whose work (ticks, plant steps)
    exceeds :data:`MAX_TICKS` or :data:`MAX_PLANT_STEPS`, before anything is built.

    Parameters
    ----------
    scenario : Scenario
        The run's scenario (its task, control period and plant step).
    t_end : float or None
        The run's end, s; None for the task's.

    Raises
    ------
    ScenarioError
        Naming ``task.t_end`` (or ``t_end``) and the period, with the limit.
    """
    h, _ = time_grid(scenario)
    T = _run_end(scenario, t_end)
    if not T >= h:
        name = "task.t_end" if t_end is None or t_end >= scenario.task.t_end else "t_end"
        raise ScenarioError(f"{name}: the run ({T:g} s) is shorter than one control period "
                            f"(h = {h:g} s); it must last at least h")
    ticks, steps = run_size(scenario, t_end)
    if ticks > MAX_TICKS:
        raise ScenarioError(
            f"task.t_end / control_period gives {ticks} control ticks, at most {MAX_TICKS} "
            f"(memory of the references and logs); shorten task.t_end or use --t-end")
    if steps > MAX_PLANT_STEPS:
        raise ScenarioError(
            f"task.t_end / plant.time_step gives {steps} plant steps, at most "
            f"{MAX_PLANT_STEPS}; shorten task.t_end, use --t-end or a larger plant.time_step")


def grasp_ticks(task: Task, h: float) -> tuple[int, int]:
    """The first held tick and first released tick: ``(⌈t_grasp/h⌉, ⌈t_release/h⌉)``.

    Parameters
    ----------
    task : Task
        The task.
    h : float
        The control period, s.
    """
    return (int(math.ceil(task.t_grasp / h - 1e-6)), int(math.ceil(task.t_release / h - 1e-6)))


def num_ticks_until(t: float, h: float) -> int:
    """The index of the last control tick at or before ``t``.

    Parameters
    ----------
    t : float
        The time, s.
    h : float
        The control period, s.
    """
    return int(math.floor(t / h + 1e-6))
