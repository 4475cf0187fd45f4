"""The run's size on its time grid (the grid itself is :mod:`drake_coop.control.timing`)."""

from drake_coop.control.timing import aligned_periods, tick_of
from drake_coop.scenario.schema import Scenario, ScenarioError

__all__ = ["aligned_periods", "tick_of", "run_size", "check_run_size", "MAX_TICKS",
           "MAX_PLANT_STEPS"]


# --------------------------------------------------------------------------- ranges


#: Largest run (control ticks of ``h``, and plant steps) accepted: the references and the
#: logs cost about 5 kB per tick (1 GB at the limit), a plant step about 50 µs.
MAX_TICKS = 200_000
MAX_PLANT_STEPS = 20_000_000


def run_size(scenario: Scenario, t_end: float | None = None) -> tuple[int, int]:
    """Control ticks and plant steps of a run to ``min(t_end, task.t_end)``."""
    h, dt = aligned_periods(scenario.control_period, scenario.plant.time_step)
    T = scenario.task.t_end if t_end is None else min(t_end, scenario.task.t_end)
    return int(T / h) + 1, int(T / dt)


def check_run_size(scenario: Scenario, t_end: float | None = None) -> None:
    """Refuse a run whose work (ticks, plant steps) exceeds :data:`MAX_TICKS` or
    :data:`MAX_PLANT_STEPS`, before anything is built.

    Raises
    ------
    ScenarioError
        Naming ``task.t_end`` (or ``t_end``) and the period, with the limit; also a run
        shorter than one control period (nothing to control).
    """
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    T = scenario.task.t_end if t_end is None else min(t_end, scenario.task.t_end)
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
