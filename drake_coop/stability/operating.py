"""Operating points of the paper's loop for the one-period map: free at home, held on the circle.

``free``
    Both arms at the home posture ``q_d(0)`` with the reference frozen there (``q̇_d = q̈_d = 0``,
    not held, ``λ_d = 0``): the free-motion loop of Section IV's first and last phases.
``held``
    The object held, the reference frozen at a tick ``t*`` of the circle (default: its start,
    ``task.t_circle_start``, where the circle's time scaling has zero velocity and
    acceleration): ``q_d(t*)``, ``q̇_d = q̈_d = 0``, ``λ_d(t*)``, held. The grasp constraints are
    switched on as the run does it (:meth:`~drake_coop.plant.cooperative.CoopPlant.set_held`).

The map is computed on a *linearizable* copy of the scenario: encoder quantization and every
sensor noise are switched off (a rounding makes the map piecewise constant, noise makes it
depend on the tick) and so is sampling jitter; the deterministic timing — the encoders' delay in
whole samples and the computation delay — is kept.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.trajectories import PiecewisePolynomial

from drake_coop.experiment.diagram import Experiment, build_experiment
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.ticks import time_grid
from drake_coop.experiment.simulate import set_rest_state
from drake_coop.scenario.schema import Scenario, ScenarioError
from drake_coop.stability.period_map import PeriodMap

__all__ = ["POINTS", "OperatingPoint", "linearizable", "operating_point"]

#: The operating points of :func:`operating_point`.
POINTS = ("free", "held")


@dataclass
class OperatingPoint:
    """A built loop at an operating point: the experiment, its map and where it is.

    Attributes
    ----------
    name : str
        ``free`` or ``held``.
    experiment : Experiment
        The built loop.
    map : PeriodMap
        Its one-period map.
    t_star : float
        The time of the operating point, s.
    """

    name: str
    experiment: Experiment
    map: PeriodMap
    t_star: float


def linearizable(scenario: Scenario) -> Scenario:
    """A copy of ``scenario`` without encoder quantization, sensor noise and jitter.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    """
    s = copy.deepcopy(scenario)
    for robot in s.robots:
        robot.encoders.counts_per_rev = None
        robot.encoders.noise_std = 0.0
        robot.force_sensor.noise_std = 0.0
        timing = getattr(robot, "timing", None)
        if timing is not None:
            timing.jitter = "none"
    return s


def _frozen(row: np.ndarray, layout, held: bool) -> PiecewisePolynomial:
    r = np.array(row, dtype=float)
    sl = layout.slices()
    r[sl["qdot_d"]] = 0.0
    r[sl["qddot_d"]] = 0.0
    r[sl["held"]] = 1.0 if held else 0.0
    if not held:
        r[sl["lambda_d"]] = 0.0
    return PiecewisePolynomial.ZeroOrderHold([0.0, 1e6], np.column_stack([r, r]))


def operating_point(scenario: Scenario, point: str = "free", t_star: float | None = None
                    ) -> OperatingPoint:
    """Build the loop at ``point`` (``free`` or ``held``) and its one-period map at ``t_0 = h``.

    The state is the designed equilibrium guess (arms at ``q_d``, at rest, observers at
    ``q̂ = q``, ``q̇̂_o = 0``, ``ΔF̃ = 0``); :func:`~drake_coop.stability.period_map.analyse`
    then solves for the map's fixed point.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    point : str
        ``free`` or ``held``.
    t_star : float or None
        The time of the point, s; None for the point's default.

    Returns
    -------
    OperatingPoint
        The loop and its map.

    Raises
    ------
    ScenarioError
        Unknown ``point``, or ``object_mode: contact`` (a floating box: its quaternion is not
        a vector space the central differences could perturb).
    """
    if point not in POINTS:
        raise ScenarioError(f"point must be one of {', '.join(POINTS)}, got {point!r}")
    scenario = linearizable(scenario)
    if scenario.plant.object_mode == "contact":
        raise ScenarioError("plant.object_mode: the stability map supports planes, rigid and "
                            "none, not contact (a floating box: its quaternion is no vector "
                            "space for central differences, its contacts are not smooth)")
    h = time_grid(scenario)[0]
    if t_star is None:
        t_star = scenario.task.t_circle_start if point == "held" else 0.0
    k_star = int(round(t_star / h))
    held = point == "held"
    # The references only to the point (the plan's samples end at the first tick after it).
    plan = plan_run(scenario, k_star * h + h)
    refs, q_star = [], []
    for robot in plan.robots:
        _, samples = robot.samples
        row = samples[min(k_star, len(samples) - 1)]
        refs.append(_frozen(row, robot.layout, held))
        q_star.append(np.array(robot.layout.column(row[None, :], "q_d")[0]))
    exp = build_experiment(plan.with_references(refs), log=False)
    context = exp.diagram.CreateDefaultContext()
    coop = exp.coop
    set_rest_state(exp, context, q_star, plan.z_grasp)    # (quantization is off: reading = q*)
    if held:
        coop.set_held(coop.plant.GetMyMutableContextFromRoot(context), True)
    # One period of warm-up: the map then starts at t_0 = h, where every sampled system has a
    # previous tick behind it (a latch's "nothing latched yet" start, e.g. the actuation delay
    # applying the very first torque at once, must not be part of every evaluation).
    simulator = Simulator(exp.diagram, context)
    simulator.Initialize()
    simulator.AdvanceTo(h)
    return OperatingPoint(point, exp, PeriodMap(exp.diagram, simulator.get_context(), h),
                          k_star * h)
