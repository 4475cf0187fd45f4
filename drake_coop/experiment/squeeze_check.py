"""Before a ``contact`` run: every arm's commanded squeeze and the object's load within its
torque limits along the whole path (:mod:`drake_coop.control.squeeze_limits`).

Per robot and control tick: the reference ``(q_d, q̇_d, q̈_d, λ_d, held)``
(:func:`~drake_coop.experiment.references.reference_samples`: with ``object_model.squeeze:
friction`` its ``λ_d`` is the friction squeeze), on the ticks where the object is held, the arm's load ``f_i`` of the object's true
mass along the desired acceleration (:func:`~drake_coop.control.object.load_distribution`:
what the arms must carry whatever the controllers know), the contact point at the pad's surface
(:attr:`~drake_coop.experiment.plan.RobotPlan.contact_offset`) and the limits: the robot's
``actuators.torque_limits``, else the effort limits of its simulated URDF as Drake reads them.
A tick whose torque is beyond them raises
:class:`~drake_coop.scenario.schema.ScenarioError` with one line naming the robot, the time, the
joint and the squeezes the limits allow there (``drake-coop run`` exits 2, nothing is built).
"""

from __future__ import annotations

from typing import Iterator, NamedTuple

import numpy as np

from drake_coop.experiment.plan import RobotPlan, RunPlan
from drake_coop.scenario.schema import ScenarioError

__all__ = ["check_squeeze_limits", "required_torques", "torque_limits"]


def torque_limits(robot: RobotPlan) -> np.ndarray:
    """One robot's ``τ_max``: ``actuators.torque_limits``, else its simulated URDF's effort
    limits (Drake's reading; ``inf`` where none).

    Parameters
    ----------
    robot : RobotPlan
        The robot's plan (its entry and resolved arm).

    Returns
    -------
    numpy.ndarray
        ``τ_max`` (n,), N·m; ``inf`` where none is known.
    """
    from drake_coop.control.arm_plant import make_arm_controller_plant
    from drake_coop.control.squeeze_limits import effort_limits

    if robot.robot.actuators.torque_limits is not None:
        return np.asarray(robot.robot.actuators.torque_limits, dtype=float)
    arm = robot.arm
    return effort_limits(make_arm_controller_plant(arm.urdf_path, arm.base_frame))


class _PathTorques(NamedTuple):
    """One robot's torques along its held ticks (k of them), as the module's check reads them."""

    t: np.ndarray            #: the held ticks' times (k,), s
    tau0: np.ndarray         #: the torque carrying the load without a squeeze (k, n), N·m
    c: np.ndarray            #: the torque per newton of squeeze (k, n), N·m/N
    lam: np.ndarray          #: the commanded squeeze λ_d (k,), N
    limits: np.ndarray       #: τ_max (n,), N·m (:func:`torque_limits`)
    name: str                #: the robot's name
    label: str               #: ``robots[i] (name)``, for a refusal's line
    joints: list[str] | None  #: the arm's joint names, None when they do not match n


def _path_torques(plan: RunPlan, every_robot: bool = False) -> Iterator[_PathTorques]:
    """Per robot with finite limits (``every_robot``: every robot), its torques on the held
    ticks (nothing outside ``contact`` mode)."""
    scenario = plan.scenario
    if scenario.plant.object_mode != "contact":
        return
    from drake_coop.control.object import load_distribution
    from drake_coop.control.squeeze_limits import squeeze_torques
    from drake_coop.experiment.object_blocks import acceleration_samples
    from drake_coop.experiment.plan import grasp_object
    from drake_coop.plant.arms import arm_model

    obj = grasp_object(scenario, float(scenario.plant.object_mass))   # the true object
    for i, resolved in enumerate(plan.robots):
        robot = resolved.robot
        limits = torque_limits(resolved)
        if not every_robot and not np.isfinite(limits).any():
            continue
        t, r = resolved.samples
        arm = resolved.arm
        layout = resolved.layout
        n = layout.n
        q, qd, qdd = (layout.column(r, row) for row in ("q_d", "qdot_d", "qddot_d"))
        held = layout.column(r, "held")[:, 0]
        lam = layout.column(r, "lambda_d")[:, 0] * held
        xdd = acceleration_samples(resolved, t)
        nu = obj.grasp_normals[i]
        offset = resolved.contact_offset
        model = arm_model(arm, arm.urdf_path)
        # The load is affine in the acceleration (G⁺ w, w = [m (a − g); 0]): from 4 solves.
        f0 = load_distribution(obj, np.zeros(3))[i]
        L = np.column_stack([load_distribution(obj, e)[i] - f0 for e in np.eye(3)])
        loads = f0[None, :] + xdd @ L.T
        # Only the held ticks carry a load and a squeeze (elsewhere the arm moves alone).
        ticks = np.flatnonzero(held > 0.5)
        tau0 = np.empty((ticks.size, n))
        c = np.empty((ticks.size, n))
        for row, k in enumerate(ticks):
            tau0[row], c[row] = squeeze_torques(model, q[k], qd[k], qdd[k], loads[k], nu,
                                                offset)
        joints = [model.plant.get_joint(j).name() for j in model.plant.GetJointIndices()
                  if model.plant.get_joint(j).num_velocities() == 1]
        yield _PathTorques(t[ticks], tau0, c, lam[ticks], limits, robot.name,
                           f"robots[{i}] ({robot.name})", joints if len(joints) == n else None)


def check_squeeze_limits(plan: RunPlan) -> None:
    """Refuse a grasp the arms cannot hold within their torque limits (see the module).

    Only in ``contact`` mode (the other modes hold the object by constraints, not friction).
    The references are the plan's (:attr:`~drake_coop.experiment.plan.RobotPlan.samples`,
    computed once, to the run's end).

    Parameters
    ----------
    plan : RunPlan
        The run's plan.

    Raises
    ------
    ScenarioError
        ``robots[i] (name): at t = ... s the squeeze ... N with the object's load needs ...
        at <joint>, beyond its torque limit ...; they allow ... N there``.
    """
    from drake_coop.control.squeeze_limits import check_squeeze_path

    for p in _path_torques(plan):
        try:
            check_squeeze_path(p.t, p.tau0, p.c, p.lam, p.limits, p.label, p.joints)
        except ValueError as exc:
            raise ScenarioError(str(exc)) from None


def required_torques(plan: RunPlan) -> dict[str, list[float]]:
    """Per robot, the largest ``|τ_0 + c λ_d|`` per joint over the held ticks: the torque the
    module's check needs within the limits (N·m; ``contact`` mode only, else empty), whatever
    the robot's limits.

    Parameters
    ----------
    plan : RunPlan
        The run's plan.

    Returns
    -------
    dict
        Robot name -> its needed torque per joint (n,), N·m.
    """
    out = {}
    for p in _path_torques(plan, every_robot=True):
        tau = np.abs(p.tau0 + p.c * p.lam[:, None])
        out[p.name] = (tau.max(axis=0) if tau.size else np.zeros(p.tau0.shape[1])).tolist()
    return out
