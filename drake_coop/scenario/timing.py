"""The run's time grid: control period and plant step aligned (Drake's GitHub issue 15021),
run size."""

import math

from drake_coop.scenario.schema import Scenario, ScenarioError


def aligned_periods(control_period: float, time_step: float) -> tuple[float, float]:
    """Control period ``h`` and plant step ``dt`` adjusted so that their event times coincide.

    Drake schedules a periodic event at ``k * period`` (floating point). With ``h = 0.009`` and
    ``dt = 0.001``, ``k * 0.009`` and ``(9 k) * 0.001`` differ by one rounding now and then, and
    the simulator takes spurious ~1e-17 s steps between the plant's step and the controller's
    tick (Drake's GitHub issue 15021) — with the plant stepping *before* the controller reads
    its state.
    Rounding ``dt`` to ``53 − ceil(log2 N)`` significant bits (a relative change below 1e-14)
    makes ``h = N dt`` exact, and then ``k h`` and ``(N k) dt`` are the same real number rounded
    once: every control tick falls exactly on a plant step.

    Returns
    -------
    (h, dt) : tuple[float, float]
        With ``h == N * dt`` exactly, ``N = round(control_period / time_step)``.
    """
    N = int(round(control_period / time_step))
    if N == 1:
        return float(control_period), float(control_period)
    bits = 53 - math.ceil(math.log2(N))
    _, exponent = math.frexp(time_step)
    scale = 2.0 ** (bits - exponent)
    dt = round(time_step * scale) / scale
    return N * dt, dt


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
        Naming ``task.t_end`` and the period, with the limit.
    """
    ticks, steps = run_size(scenario, t_end)
    if ticks > MAX_TICKS:
        raise ScenarioError(
            f"task.t_end / control_period gives {ticks} control ticks, at most {MAX_TICKS} "
            f"(memory of the references and logs); shorten task.t_end or use --t-end")
    if steps > MAX_PLANT_STEPS:
        raise ScenarioError(
            f"task.t_end / plant.time_step gives {steps} plant steps, at most "
            f"{MAX_PLANT_STEPS}; shorten task.t_end, use --t-end or a larger plant.time_step")


def tick_of(t: float, h: float) -> int | None:
    """The tick index ``k`` if ``t`` is a sampling instant ``k h`` (to 1e-9 relative), else None."""
    k = round(t / h)
    return k if abs(t - k * h) <= 1e-9 * max(1.0, t) else None
