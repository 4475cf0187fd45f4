"""One resolved plan of a run: its time grid, tick indices, grasp height and arms.

Computed by :func:`plan_run` once per simulated run (the runner passes it to the references;
the stability map's operating point and the benchmark make their own plan of the same
scenario):

* ``h``, ``dt`` — control period and plant step, aligned so that every tick is a plant step
  (:func:`time_grid`: the one place a scenario's periods are aligned, by
  :func:`~drake_coop.control.timing.aligned_periods`; the plant builder, the diagram, the
  runner, identification and the benchmark read it);
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

from drake_coop.control.timing import aligned_periods
from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import Scenario, ScenarioError, Task

#: Largest run (control ticks of ``h``, and plant steps) accepted: the references and the
#: logs cost about 5 kB per tick (1 GB at the limit), a plant step about 50 µs.
MAX_TICKS = 200_000
MAX_PLANT_STEPS = 20_000_000


def time_grid(scenario: Scenario) -> tuple[float, float]:
    """``(h, dt)``: the scenario's control period and plant step on one exact grid
    (``h = N dt``, :func:`~drake_coop.control.timing.aligned_periods`)."""
    return aligned_periods(scenario.control_period, scenario.plant.time_step)


def _run_end(scenario: Scenario, t_end: float | None) -> float:
    return scenario.task.t_end if t_end is None else min(t_end, scenario.task.t_end)


def run_size(scenario: Scenario, t_end: float | None = None) -> tuple[int, int]:
    """Control ticks and plant steps of a run to ``min(t_end, task.t_end)``."""
    h, dt = time_grid(scenario)
    T = _run_end(scenario, t_end)
    return int(T / h) + 1, int(T / dt)


def check_run_size(scenario: Scenario, t_end: float | None = None) -> None:
    """Refuse a run shorter than one control period, or whose work (ticks, plant steps)
    exceeds :data:`MAX_TICKS` or :data:`MAX_PLANT_STEPS`, before anything is built.

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
    h, dt = time_grid(scenario)
    task = scenario.task
    T = _run_end(scenario, t_end)
    k_grasp, k_release = grasp_ticks(task, h)
    return RunPlan(scenario=scenario, h=h, dt=dt, t_end=T, k_end=num_ticks_until(T, h),
                   k_grasp=k_grasp, k_release=k_release,
                   z_grasp=task.circle_top_z - task.lift_height,
                   arms=tuple(Arm(r, task) for r in scenario.robots))
