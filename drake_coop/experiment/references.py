"""The references of each robot: joint references through its IK, the reference signal.

The Cartesian paths (28) and the force profile (29) are the scenario's
(:mod:`drake_coop.scenario.task_path`, re-exported here). Joint references come from the arm's
inverse kinematics (closed form for the paper's arms, Drake's otherwise,
:attr:`drake_coop.plant.arms.Arm.kinematics`):
``q_d = IK(x_d)``, ``q̇_d = J⁻¹ ẋ_d``, ``q̈_d = J⁻¹ (ẍ_d − J̇ q̇_d)`` (``J`` the task Jacobian:
position, and orientation held fixed for 6-joint arms). A redundant arm (more joints than task
coordinates, a 7-joint Panda) gets a differential inverse kinematics with a null-space posture
objective, integrated in time (:func:`redundant_joint_reference`). Each constraint row's desired force is
its weight (``robots[i].force_weights``) times (29).

The object is held (constraint active, controller in its constrained form) on the control
ticks ``k`` with ``k_grasp ≤ k < k_release``, ``k_grasp = ⌈t_grasp/h⌉``: integer tick indices,
so the switch never depends on rounding of ``k·h``.
"""

from __future__ import annotations

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from drake_coop.control.finger import ReferenceLayout
from drake_coop.experiment.plan import RunPlan, num_ticks_until, plan_run
from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import Scenario
from drake_coop.scenario.task_path import (
    Segment,
    cartesian_reference,
    first_normal,
    force_reference,
    quintic,
    segments,
    waypoints,
)

#: The task's paths are the scenario's; they are re-exported for the callers of this module.
__all__ = ["Segment", "cartesian_reference", "first_normal", "force_reference", "quintic",
           "segments", "waypoints", "joint_reference", "redundant_joint_reference", "start_posture",
           "reference_samples", "reference_trajectory", "compressed_path"]


def joint_reference(arm: Arm, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q_d``, ``q̇_d``, ``q̈_d`` from a Cartesian reference through the arm's IK (an arm
    with as many joints as task coordinates)."""
    return arm.kinematics.joint_reference(x, xd, xdd)


def start_posture(arm: Arm, task) -> np.ndarray:
    """``q_d(0)``: the reference's posture at ``t = 0`` (the run's rest posture), for either
    kind of arm (the same doubles as the first sample of :func:`reference_samples`)."""
    x, xd, xdd = cartesian_reference(task, arm.robot, [0.0])
    kin = arm.kinematics
    if getattr(kin, "redundant", False):
        return kin.start_posture(x[0], kin.nominal_posture(arm.robot.q_nominal))
    return np.asarray(joint_reference(arm, x, xd, xdd)[0]).reshape(-1)


def redundant_joint_reference(arm: Arm, task, t: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q_d``, ``q̇_d``, ``q̈_d`` of a redundant arm (``n > task_dim``) at the times ``t``:
    the differential inverse kinematics with a null-space posture objective
    (:meth:`~drake_coop.kinematics.drake_arm.DrakeArmKinematics.redundant_reference`, the
    robot's ``q_nominal`` and ``nullspace_gain``).

    Raises
    ------
    ValueError
        A joint leaves its limits along the reference (``validate`` refuses such a scenario
        first, on a coarser grid).
    """
    robot = arm.robot
    kin = arm.kinematics
    q, qd, qdd = kin.redundant_reference(
        t, lambda tt: cartesian_reference(task, robot, tt), robot.q_nominal,
        robot.nullspace_gain)
    outside = (q < kin.q_min) | (q > kin.q_max)
    if outside.any():
        k, j = np.argwhere(outside)[0]
        raise ValueError(f"{robot.name}: joint {kin.joint_names[j]} at {q[k, j]:.4f} rad "
                         f"outside its limits at t = {t[k]:.3f} s along the redundant "
                         "reference (choose q_nominal or nullspace_gain)")
    return q, qd, qdd


def reference_samples(scenario: Scenario, index: int, t_end: float | None = None,
                      plan: RunPlan | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Reference vector of robot ``index`` at every control tick.

    Parameters
    ----------
    t_end : float, optional
        Last time needed (a run stopped early): the samples end at the first tick at or after
        ``min(t_end, task.t_end)``; the ticks before are the same as the full run's.
    plan : RunPlan, optional
        The run's plan when the caller has it (else computed from ``scenario``).

    Returns
    -------
    t : ndarray, shape (K,)
        Tick times ``k h`` (``h`` of the run's plan, :mod:`drake_coop.experiment.plan`).
    r : ndarray, shape (K, 3n + m + 1)
        Rows ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:class:`drake_coop.control.finger.ReferenceLayout`).
    """
    plan = plan or plan_run(scenario)
    h, task, robot = plan.h, scenario.task, scenario.robots[index]
    k_last = num_ticks_until(task.t_end, h)      # the whole task (the plan may be a shorter run)
    if t_end is not None:
        k_last = max(1, min(k_last, num_ticks_until(t_end, h) + 1))
    k = np.arange(k_last + 1)
    t = k * h
    arm = plan.arms[index]
    redundant = getattr(arm.kinematics, "redundant", False)
    if not redundant:
        x, xd, xdd = cartesian_reference(task, robot, t)
    held = ((k >= plan.k_grasp) & (k < plan.k_release)).astype(float)
    profile = force_reference(task, t)
    if scenario.object_model.mode != "none" and scenario.object_model.squeeze == "friction":
        from drake_coop.experiment.object_blocks import friction_squeeze
        profile = friction_squeeze(scenario, t)
    lam = profile[:, None] * np.asarray(robot.force_weights, dtype=float)
    from drake_coop.experiment.object_blocks import contact_stiffness
    stiffness = contact_stiffness(scenario, index)
    if stiffness is not None and not redundant and not scenario.object_model.shared:
        # (object_model.shared: λ_d is chosen during the run, and so is the compression:
        # CompressedReference presses the joint references in online.)
        # A compliant contact: the pad is held where the contact carries λ_d, pressed in by
        # δ(λ_d) along the inward normal, in the joint references too (else the tangent
        # part of (4) sees the compression as a position error: the pad sags).
        x, xd, xdd = compressed_path(stiffness, x, xd, xdd, lam[:, 0] * held, h,
                                     -np.asarray(robot.normals[0], dtype=float))
    if redundant:     # the null-space reference follows the task itself (no compressed path)
        q, qd, qdd = redundant_joint_reference(arm, task, t)
    else:
        q, qd, qdd = joint_reference(arm, x, xd, xdd)
    return t, ReferenceLayout(q.shape[1], arm.m).pack(q, qd, qdd, lam, held)


def compressed_path(stiffness, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray,
                    lam: np.ndarray, h: float, inward: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The path pressed in by the contact's compression: ``x_d + δ(λ_d) n``, ``n`` the unit
    inward normal, with ``δ̇``, ``δ̈`` by central differences on the tick grid ``h``."""
    n = inward / np.linalg.norm(inward)
    delta = stiffness.compression(lam)
    d1 = np.gradient(delta, h) if delta.size > 1 else np.zeros_like(delta)
    d2 = np.gradient(d1, h) if delta.size > 1 else np.zeros_like(delta)
    return (x + delta[:, None] * n, xd + d1[:, None] * n, xdd + d2[:, None] * n)


def reference_trajectory(scenario: Scenario, index: int, t_end: float | None = None,
                         plan: RunPlan | None = None) -> PiecewisePolynomial:
    """The tick samples as a first-order-hold :class:`PiecewisePolynomial`.

    Evaluated at a tick time it returns that tick's sample exactly; the controller and the
    observers only read it at their ticks. ``t_end`` limits it to a shorter run (see
    :func:`reference_samples`).
    """
    t, r = reference_samples(scenario, index, t_end, plan)
    return PiecewisePolynomial.FirstOrderHold(t, r.T)
