"""The delay margin of a scenario's loop, with and without delay compensation, for any arm.

The margin is the largest computation delay ``d`` (from the measurement to the torque acting;
``robots[].timing.computation_delay``, whole plant steps from 0 to the control period ``h``)
for which the one-period map at the free operating point (:mod:`drake_coop.stability`) gives
``ρ < 1`` at every delay from 0 to ``d``. It is computed twice:

``without``
    delay compensation off (``robots[].timing.prediction_horizon`` unset): the paper's block;
``with``
    the controller predicting its inputs over the horizon ``p``
    (:mod:`drake_coop.control.delay`): the scenario's own ``prediction_horizon`` where it sets
    one, else ``p = d`` at each delay ``d > 0`` (a horizon matched to the delay).

The verdict of ``serve`` uses the margin of the scenario as it runs (``with`` when it sets a
horizon, else ``without``). The map models delays up to ``h`` only: a loop stable there has
a margin of *at least* ``h`` (``at_least``). When no margin can be given, :attr:`Margin.reason`
says why in one line (the loop unstable with no delay, the map failing on this scenario)
instead of a number. The delay is put on the arms named (``robots``; default every arm),
the others kept at theirs. The map is computed on the scenario ``drake-coop gains`` checks its
gains on (:func:`~drake_coop.stability.task_check.map_copy`: a ``contact`` scenario's
``planes`` copy, no object model): the free point's loop is the arms' alone.
"""

from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass, field
from typing import Callable

__all__ = ["Margin", "DelayMargins", "delay_margins", "margin_line"]


@dataclass
class Margin:
    """One delay margin (see the module's docstring).

    Attributes
    ----------
    margin_s : float or None
        The margin ``d``, s; None when it cannot be given (:attr:`reason`).
    at_least : bool
        Stable at every delay the map models (up to ``h``): the margin is at least that.
    reason : str
        Why there is no margin (one line), else ``''``.
    horizon : str
        The prediction horizon used: ``off``, ``matched`` (``p = d``) or ``<p> s``.
    rho : list of float
        ρ at each delay checked (0, dt, 2 dt, ...), up to the first unstable one.
    delays_s : list of float
        Those delays, s.
    """

    margin_s: float | None
    at_least: bool = False
    reason: str = ""
    horizon: str = "off"
    rho: list[float] = field(default_factory=list)
    delays_s: list[float] = field(default_factory=list)


@dataclass
class DelayMargins:
    """The margins without and with delay compensation, and the one of the scenario as it is.

    Attributes
    ----------
    without : Margin
        Compensation off.
    with_compensation : Margin
        Compensation on.
    as_configured : str
        ``without`` or ``with``: which one the scenario runs.
    robots : list of str
        The arms delayed.
    """

    without: Margin
    with_compensation: Margin
    as_configured: str
    robots: list[str]

    @property
    def configured(self) -> Margin:
        """The margin of the scenario as it runs.

        Returns
        -------
        Margin
            ``with_compensation`` or ``without``.
        """
        return self.with_compensation if self.as_configured == "with" else self.without

    def as_dict(self) -> dict:
        """The margins as JSON-ready data (``run.json``).

        Returns
        -------
        dict
            ``without``, ``with``, ``as_configured``, ``robots``, ``line``.
        """
        return {"without": asdict(self.without), "with": asdict(self.with_compensation),
                "as_configured": self.as_configured, "robots": list(self.robots),
                "line": margin_line(self)}


def _describe(row: dict) -> str:
    if row.get("status") == "error":
        return f"the stability map failed on this scenario ({row.get('message', '')})"
    if row.get("status") == "unstable":
        states = row.get("slowest_states", "")
        return (f"the loop is unstable with no delay (rho = {row['rho']:.4g} at the free point"
                + (f", slowest states {states}" if states else "")
                + "): derive its gains with drake-coop gains")
    if row.get("status") == "no_equilibrium":
        return "the free point has no equilibrium (Newton did not converge): no margin"
    if row.get("status") == "step_dependent":
        return f"the map is not resolved at this step: {row.get('message', '')}"
    return f"rho = {row.get('rho')}: no margin"


def _one(scenario, robots: set[str], horizon: str, epsilon: float,
         rows: Callable[[str], dict]) -> Margin:
    from drake_coop.experiment.ticks import time_grid
    from drake_coop.scenario.loading import dump_scenario

    h, dt = time_grid(scenario)
    out = Margin(margin_s=None, horizon=horizon)
    steps = int(round(h / dt))
    for step in range(steps + 1):
        d = step * dt
        s = copy.deepcopy(scenario)
        for robot in s.robots:
            if robot.name not in robots:
                continue
            robot.timing.computation_delay = d
            if horizon == "off":
                robot.timing.prediction_horizon = None
            elif horizon == "matched":
                robot.timing.prediction_horizon = d if d > 0 else None
        row = dict(rows(dump_scenario(s)))
        rho = float(row.get("rho", math.nan))
        row.setdefault("status", "stable" if rho < 1.0 else "unstable")
        out.delays_s.append(d)
        out.rho.append(rho)
        if row["status"] != "stable":
            if step == 0:
                out.reason = _describe(row)
            return out
        out.margin_s = d
    out.at_least = True
    return out


def delay_margins(scenario, *, robots: list[str] | None = None, epsilon: float = 1e-5,
                  rows: Callable[[str], dict] | None = None) -> DelayMargins:
    """The margins of ``scenario`` without and with delay compensation (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The scenario (its gains, arms and timing).
    robots : list of str or None
        The arms whose delay is varied; None for every arm.
    epsilon : float
        The central differences' step of the map.
    rows : Callable[[str], dict] or None
        ``rows(scenario_yaml) -> row`` at the free point (default: the map's,
        :func:`~drake_coop.stability.grid.point_rows`); given for tests.

    Returns
    -------
    DelayMargins
        Both margins and which one the scenario runs.

    Raises
    ------
    ValueError
        A name in ``robots`` the scenario does not have.
    """
    names = [r.name for r in scenario.robots]
    chosen = set(names if robots is None else robots)
    unknown = sorted(chosen - set(names))
    if unknown:
        raise ValueError(f"robots: {', '.join(unknown)} not in the scenario "
                         f"({', '.join(names)})")
    from drake_coop.stability.task_check import map_copy

    scenario = map_copy(scenario)[0]      # the loop gains checks: contact → planes, no model
    if rows is None:
        from drake_coop.stability.grid import point_rows

        def rows(text: str) -> dict:
            return point_rows(text, ["free"], epsilon)[0]

    seen: dict[str, dict] = {}
    compute = rows

    def rows(text: str) -> dict:          # d = 0 is the same loop with and without
        if text not in seen:
            seen[text] = compute(text)
        return seen[text]

    horizons = {r.timing.prediction_horizon for r in scenario.robots if r.name in chosen}
    fixed = next(iter(horizons)) if len(horizons) == 1 else None
    configured = "with" if any(h is not None for h in horizons) else "without"
    without = _one(scenario, chosen, "off", epsilon, rows)
    if fixed is not None:
        with_c = _one(scenario, chosen, "configured", epsilon, rows)
        with_c.horizon = f"{fixed:g} s"
    else:
        with_c = _one(scenario, chosen, "matched", epsilon, rows)
    return DelayMargins(without=without, with_compensation=with_c, as_configured=configured,
                        robots=[n for n in names if n in chosen])


def _text(m: Margin) -> str:
    if m.margin_s is None:
        return m.reason
    last = len(m.rho) - (1 if m.at_least else 2)     # the delay of the margin itself
    return (f"{'>= ' if m.at_least else ''}{m.margin_s * 1e3:.3g} ms (rho {m.rho[last]:.3g} "
            "there" + ("" if m.at_least else f", {m.rho[-1]:.3g} one plant step more") + ")")


def margin_line(margins: DelayMargins) -> str:
    """One line: both margins (or why there is none).

    Parameters
    ----------
    margins : DelayMargins
        The margins.

    Returns
    -------
    str
        One line: the margins without and with compensation, or why there is none.
    """
    w, c = margins.without, margins.with_compensation
    if w.margin_s is None and c.margin_s is None and w.reason == c.reason:
        return f"delay margin of {', '.join(margins.robots)}: none, {w.reason}"
    return (f"delay margin of {', '.join(margins.robots)}: {_text(w)} without compensation, "
            f"{_text(c)} with it (prediction horizon {c.horizon})")
