"""What ``drake-coop gains`` checks of the task beyond the map at home and the held start.

:func:`check_task` runs three checks on a scenario with its gains and returns one
:class:`TaskCheck` each:

``map``
    ρ of the one-period map (:func:`~drake_coop.stability.period_map.analyse`) at postures
    sampled along the task: ``free`` at the pre-grasp, ``held`` at the lift's middle and at
    :data:`CIRCLE_SAMPLES` points of the circle (its start, a quarter, half and three
    quarters), each with the reference frozen there (:func:`~drake_coop.stability.operating.
    operating_point`), on the map's copy of the scenario (:func:`map_copy`). Fails when one
    is not below 1, naming the posture.
``torque``
    Every robot's torque along the whole reference within its limits (``actuators.
    torque_limits``, else the URDF's effort limits as Drake reads them): in ``contact`` mode
    :func:`~drake_coop.experiment.squeeze_check.check_squeeze_limits` (the squeeze and the
    object's load at the pad's surface, what ``run`` refuses), in the other modes the law's
    feedforward ``H q̈_d + C q̇_d + g − J_φᵀ λ_d`` on the reference (:func:`torque_path`).
``grasp``
    ``contact`` mode only: the grasp's own closed-loop dynamics, the ``contact`` loop frozen at
    postures of the task and, where one grows, followed along the task's moving reference
    (:func:`~drake_coop.stability.grasp_dynamics.check_grasp_dynamics`): fails when a
    disturbance of the grasp grows there beyond its bar or the followed loop tilts the box past
    its guard. The ideal modes have no such mode. The
    squeeze's static buckling ratio (:func:`~drake_coop.stability.grasp.check_grasp_buckling`)
    is recorded beside it, not checked: it does not separate held from lost grasps.

Each failing check's message is one line: which check, which posture or tick, the value
against its bar and what to change.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from drake_coop.scenario.schema import Scenario

__all__ = ["CIRCLE_SAMPLES", "TaskCheck", "TaskReport", "check_task", "map_copy",
           "map_points", "torque_path"]

#: Fractions of the circle at which the held map is computed.
CIRCLE_SAMPLES = (0.0, 0.25, 0.5, 0.75)


@dataclass
class TaskCheck:
    """One check of :func:`check_task`.

    Attributes
    ----------
    name : str
        ``map``, ``torque`` or ``grasp``.
    passes : bool
        Its verdict.
    message : str
        One line: what was found (and on failure what to change).
    values : dict
        Its numbers (the map's ρ per posture, the grasp's worst ratio, ...).
    """

    name: str
    passes: bool
    message: str
    values: dict = field(default_factory=dict)


@dataclass
class TaskReport:
    """Every check of :func:`check_task`.

    Attributes
    ----------
    checks : list of TaskCheck
        In the order run.
    """

    checks: list[TaskCheck] = field(default_factory=list)

    @property
    def passes(self) -> bool:
        """Whether every check passes."""
        return all(c.passes for c in self.checks)

    @property
    def refusal(self) -> str:
        """The first failing check's message ('' when all pass)."""
        return next((c.message for c in self.checks if not c.passes), "")


def map_copy(scenario: Scenario) -> tuple[Scenario, str]:
    """The scenario the map is computed on: itself, or a copy in ``planes`` mode (for a
    ``contact`` scenario) and without its object model (``object_model.mode: none``).

    The gains are the paper's loop's, (13)–(16) and (22). An object model adds blocks outside
    it, and an ``estimated`` one a parameter estimate that does not move while nothing excites
    it (its mass estimator updates only while the object is held): an eigenvalue 1 of the map
    at the free point whatever the gains, so every gain would be refused.

    Parameters
    ----------
    scenario : Scenario
        The scenario.

    Returns
    -------
    scenario : Scenario
        The scenario the map is computed on.
    mode : str
        Its object mode.
    """
    if scenario.plant.object_mode != "contact" and scenario.object_model.mode == "none":
        return scenario, scenario.plant.object_mode
    import copy

    from drake_coop.scenario.schema import ObjectModelSettings

    s = copy.deepcopy(scenario)
    if s.plant.object_mode == "contact":
        s.plant.object_mode = "planes"
    s.object_model = ObjectModelSettings()          # mode none, the schema's defaults
    return s, s.plant.object_mode


def map_points(task) -> list[tuple[str, str, float]]:
    """The map's postures along the task: ``(label, point, t_star)``.

    Parameters
    ----------
    task : Task
        The scenario's task.

    Returns
    -------
    list of tuple
        ``free`` at the pre-grasp, ``held`` at the lift's middle and along the circle.
    """
    circle = task.t_circle_end - task.t_circle_start
    points = [("pre-grasp", "free", task.t_pregrasp),
              ("lift", "held", 0.5 * (task.t_grasp + task.t_circle_start))]
    points += [(f"circle {int(round(100 * f))} %", "held", task.t_circle_start + f * circle)
               for f in CIRCLE_SAMPLES]
    return points


def _check_map(scenario, epsilon: float, progress) -> TaskCheck:
    from drake_coop.stability.operating import operating_point
    from drake_coop.stability.period_map import analyse

    target, mode = map_copy(scenario)
    rho = {}
    for label, point, t_star in map_points(scenario.task):
        start = time.perf_counter()
        report = analyse(operating_point(target, point, t_star).map, epsilon=epsilon)
        value = float(report.rho) if report.residual <= 1e-6 else math.inf
        rho[f"{point} at {label} (t = {t_star:.2f} s)"] = value
        progress(f"  {point} at {label}, t = {t_star:.2f} s: rho = {value:.6g} "
                 f"({time.perf_counter() - start:.1f} s)")
    worst = max(rho, key=rho.get)
    if rho[worst] < 1.0:
        return TaskCheck("map", True, f"map along the task ({mode}): rho < 1 at "
                                      f"{len(rho)} postures, largest {rho[worst]:.6g} ({worst})",
                         {"rho": rho})
    return TaskCheck("map", False, f"map along the task ({mode}): rho = {rho[worst]:.6g} >= 1 "
                                   f"{worst}: the loop is unstable there; lower K_R of the arm "
                                   "(the gains' kappa) or move the task away from that posture "
                                   "(base_xyz, contact_xy, circle)", {"rho": rho})


def torque_path(scenario, plan=None) -> None:
    """Refuse a reference whose feedforward ``H(q_d) q̈_d + C q̇_d + g(q_d) − J_φᵀ λ_d`` is
    beyond a joint's torque limit at some tick (the ideal modes; ``contact`` has
    :func:`~drake_coop.experiment.squeeze_check.check_squeeze_limits`).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    plan : RunPlan or None
        The run's plan; None plans it here.

    Raises
    ------
    ScenarioError
        ``robots[i] (name): at t = ... s joint ... needs ... N·m, beyond its limit ...``.
    """
    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.squeeze_check import torque_limits
    from drake_coop.plant.arms import arm_model
    from drake_coop.scenario.schema import ScenarioError

    plan = plan or plan_run(scenario)
    for i, resolved in enumerate(plan.robots):
        robot = resolved.robot
        limits = torque_limits(resolved)
        if not np.isfinite(limits).any():
            continue
        t, r = resolved.samples
        arm = resolved.arm
        layout = resolved.layout
        q, qd, qdd = (layout.column(r, row) for row in ("q_d", "qdot_d", "qddot_d"))
        lam = layout.column(r, "lambda_d") * layout.column(r, "held")
        model = arm_model(arm, arm.urdf_path)
        for k in range(len(t)):
            tau = model.inverse_dynamics_terms(q[k], qd[k], qdd[k]) - model.J_phi(q[k]).T @ lam[k]
            over = np.abs(tau) > limits * (1 + 1e-9)
            if over.any():
                j = int(np.argmax(np.abs(tau) / limits))
                raise ScenarioError(
                    f"robots[{i}] ({robot.name}): at t = {t[k]:.2f} s joint {j + 1} needs "
                    f"{abs(tau[j]):.4g} N·m, beyond its torque limit {limits[j]:.4g} N·m; slow "
                    "the task, lower the squeeze (task.force_mean, force_amplitude) or move "
                    "the arm (base_xyz)")


def _check_torque(scenario) -> TaskCheck:
    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.squeeze_check import check_squeeze_limits
    from drake_coop.scenario.schema import ScenarioError

    try:
        if scenario.plant.object_mode == "contact":
            check_squeeze_limits(plan_run(scenario))
        else:
            torque_path(scenario)
    except ScenarioError as exc:
        return TaskCheck("torque", False, f"torque limits: {exc}")
    return TaskCheck("torque", True, "torque limits: the reference's torque is within every "
                                     "joint's limit along the path")


def _check_grasp(scenario) -> TaskCheck:
    from drake_coop.stability.grasp import check_grasp_buckling
    from drake_coop.stability.grasp_dynamics import check_grasp_dynamics

    result = check_grasp_dynamics(scenario)
    values = {"checked": result.checked}
    if result.checked:
        values.update(growth_rate_per_s=result.sigma, amplification=result.amplification,
                      tilt_deg=result.tilt_deg, worst=result.worst,
                      joints=result.joints, pads=result.pads,
                      box_turn_axis=result.box_turn_axis, cpu_seconds=result.cpu_seconds)
        buckling = check_grasp_buckling(scenario)      # the static bound, for the record
        if buckling.checked:
            values.update(buckling_ratio=buckling.worst_ratio, buckling_t=buckling.t,
                          buckling_squeeze_N=buckling.lambda_b)
    return TaskCheck("grasp", result.passes, result.message, values)


def check_task(scenario, epsilon: float = 1e-5, map_check: bool = True,
               progress: Callable[[str], None] = lambda m: None) -> TaskReport:
    """The task's checks of the module docstring, on ``scenario`` with its own gains.

    Parameters
    ----------
    scenario : Scenario
        The validated scenario with the gains to check.
    epsilon : float
        The map's central differences' step.
    map_check : bool
        Run the map along the task (the slowest check; not run once the torque or the grasp
        check has failed: the task is refused by them). The grasp check is not run once the
        torque check has failed.
    progress : Callable[[str], None]
        Receives one line per step.

    Returns
    -------
    TaskReport
        Every task check (postures, torques, grasp) and the refusal, if any.
    """
    report = TaskReport()
    progress("task: torque limits along the path")
    report.checks.append(_check_torque(scenario))
    if scenario.plant.object_mode == "contact" and report.passes:
        progress("task: the grasp's own dynamics (the contact loop frozen along the task)")
        report.checks.append(_check_grasp(scenario))
    if map_check and report.passes:
        progress("task: stability map along the task's postures")
        report.checks.append(_check_map(scenario, epsilon, progress))
    for check in report.checks:
        progress(f"  {check.message}")
    return report
