"""One resolved plan of a run: its time grid, tick indices, grasp height and arms.

Computed once from a scenario (:func:`plan_run`) and read by everyone that needs these numbers
(the references, the diagram, the runner), instead of each of them recomputing them:

* ``h``, ``dt`` — control period and plant step, aligned so that every tick is a plant step
  (:func:`~drake_coop.scenario.aligned_periods`);
* ``k_grasp``, ``k_release`` — the first held and the first released control tick
  (``⌈t_grasp/h⌉``, ``⌈t_release/h⌉``): the only instants where the plant changes;
* ``k_end`` — the last tick of the run (``min(t_end, task.t_end)``);
* ``z_grasp`` — the contact points' height at the grasp (``circle_top_z − lift_height``);
* ``arms`` — each robot's :class:`~drake_coop.plant.arms.Arm` (base, constraints,
  kinematics).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import Scenario, Task
from drake_coop.scenario.timing import aligned_periods


def grasp_ticks(task: Task, h: float) -> tuple[int, int]:
    """First held tick and first released tick: ``(⌈t_grasp/h⌉, ⌈t_release/h⌉)``."""
    return (int(math.ceil(task.t_grasp / h - 1e-6)), int(math.ceil(task.t_release / h - 1e-6)))


def num_ticks_until(t: float, h: float) -> int:
    """Index of the last control tick at or before ``t``."""
    return int(math.floor(t / h + 1e-6))


@dataclass(frozen=True)
class RunPlan:
    """The resolved numbers of one run (see the module's docstring)."""

    scenario: Scenario
    h: float
    dt: float
    t_end: float
    k_end: int
    k_grasp: int
    k_release: int
    z_grasp: float
    arms: tuple[Arm, ...]

    @property
    def switches(self) -> dict[int, bool]:
        """Ticks where the grasp switches on (True) and off (False), within the run."""
        return {k: held for k, held in ((self.k_grasp, True), (self.k_release, False))
                if k < self.k_end}

    @property
    def stops(self) -> list[int]:
        """Where the runner stops the simulation: where the plant changes, and the end."""
        return sorted({*self.switches, self.k_end})


def plan_run(scenario: Scenario, t_end: float | None = None) -> RunPlan:
    """The plan of a run of ``scenario`` to ``min(t_end, task.t_end)``."""
    h, dt = aligned_periods(scenario.control_period, scenario.plant.time_step)
    task = scenario.task
    T = task.t_end if t_end is None else min(t_end, task.t_end)
    k_grasp, k_release = grasp_ticks(task, h)
    return RunPlan(scenario=scenario, h=h, dt=dt, t_end=T, k_end=num_ticks_until(T, h),
                   k_grasp=k_grasp, k_release=k_release,
                   z_grasp=task.circle_top_z - task.lift_height,
                   arms=tuple(Arm(r, task) for r in scenario.robots))
