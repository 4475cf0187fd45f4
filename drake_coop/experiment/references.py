"""References of Section IV: Cartesian paths (28), joint references, force profile (29).

Every phase moves the end-effector point along a Cartesian path, rest to rest, with the
quintic time scaling ``σ(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` (zero velocity and acceleration at both
ends), so that the whole reference is C² in time:

====================  =====================================  ======================================
phase                 time                                   path of robot i
====================  =====================================  ======================================
free (approach)       ``[0, t_pregrasp]``                    home → pre-grasp (straight line)
free (approach)       ``[t_pregrasp, t_grasp]``              pre-grasp → grasp, along the normal
lift                  ``[t_grasp, t_circle_start]``          grasp → circle start, 0.1 m up
circle (28)           ``[t_circle_start, t_circle_end]``     ``y = R sin θ``, ``z = z_top − R + R cos θ``
put-down              ``[t_circle_end, t_release]``          circle start → grasp
return                ``[t_release, t_release + Δ]``         grasp → pre-grasp
return                ``[t_release + Δ, t_end]``             pre-grasp → home
====================  =====================================  ======================================

with ``θ(t) = 2π σ((t − t_i)/(t_f − t_i))`` on the circle (``θ̇ = θ̈ = 0`` at ``t_i``, ``t_f``),
drawn in the plane of ``task.circle_axes = [u, v]`` (the paper: y and z):
``x = c − R v + R sin θ u + R cos θ v`` from its start point ``c``; ``Δ = t_grasp − t_pregrasp``,
the grasp point ``(contact_xy, z_top − lift)`` and the pre-grasp point moved out along the
object's first outward normal by ``pregrasp_distance``.

Joint references come from the arm's inverse kinematics (closed form for the paper's arms,
Drake's otherwise, :attr:`drake_coop.plant.arms.Arm.kinematics`):
``q_d = IK(x_d)``, ``q̇_d = J⁻¹ ẋ_d``, ``q̈_d = J⁻¹ (ẍ_d − J̇ q̇_d)`` (``J`` the task Jacobian:
position, and orientation held fixed for 6-joint arms).

The desired squeeze force (29), ``f(t)``, times each constraint row's weight
(``robots[i].force_weights``, the paper: one row of weight 1): ``f_mean (t − t_grasp)/(t_circle_start − t_grasp)`` on the
lift, ``f_mean + f_amp sin(ω (t − t_circle_start))`` on the circle and
``f_mean (1 − (t − t_circle_end)/(t_release − t_circle_end))`` on the put-down; zero otherwise.
With the paper's numbers this is ``16(t − 15)/5``, ``32 + 18 sin(3π(t − 25)/40)`` and
``32 − 16(t − 65)/5``.

The object is held (constraint active, controller in its constrained form) on the control
ticks ``k`` with ``k_grasp ≤ k < k_release``, ``k_grasp = ⌈t_grasp/h⌉``: integer tick indices,
so the switch never depends on rounding of ``k·h``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from drake_coop.control.finger import ReferenceLayout
from drake_coop.experiment.plan import num_ticks_until, plan_run
from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import Robot, Scenario, ScenarioError, Task


def quintic(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic time scaling σ(τ) and its first two derivatives, τ clipped to [0, 1]."""
    tau = np.clip(tau, 0.0, 1.0)
    s = tau ** 3 * (10 - 15 * tau + 6 * tau ** 2)
    ds = 30 * tau ** 2 * (1 - tau) ** 2
    dds = 60 * tau * (1 - tau) * (1 - 2 * tau)
    return s, ds, dds


def first_normal(robot: Robot) -> np.ndarray:
    """The object's first outward unit normal at the robot's contact (the squeeze direction)."""
    n = np.asarray(robot.normals[0], dtype=float)
    return n / np.linalg.norm(n)


def waypoints(task: Task, robot: Robot) -> dict[str, np.ndarray]:
    """Home, pre-grasp, grasp and circle-start points of one robot (palm frame, m)."""
    z_top = task.circle_top_z
    x, y = (float(v) for v in robot.contact_xy)
    grasp = np.array([x, y, z_top - task.lift_height])
    return {
        "home": np.asarray(robot.home, dtype=float),
        "pregrasp": grasp + task.pregrasp_distance * first_normal(robot),
        "grasp": grasp,
        "circle_start": np.array([x, y, z_top]),
    }


@dataclass(frozen=True)
class Segment:
    """A rest-to-rest straight line from ``a`` to ``b`` during ``[t0, t1]``."""

    t0: float
    t1: float
    a: np.ndarray
    b: np.ndarray


def segments(task: Task, robot: Robot) -> list[Segment]:
    """The straight-line segments of the path (the circle is handled apart)."""
    w = waypoints(task, robot)
    back = task.t_release + (task.t_grasp - task.t_pregrasp)
    return [
        Segment(0.0, task.t_pregrasp, w["home"], w["pregrasp"]),
        Segment(task.t_pregrasp, task.t_grasp, w["pregrasp"], w["grasp"]),
        Segment(task.t_grasp, task.t_circle_start, w["grasp"], w["circle_start"]),
        Segment(task.t_circle_end, task.t_release, w["circle_start"], w["grasp"]),
        Segment(task.t_release, back, w["grasp"], w["pregrasp"]),
        Segment(back, task.t_end, w["pregrasp"], w["home"]),
    ]


def cartesian_reference(task: Task, robot: Robot, t: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Desired end-effector position, velocity and acceleration at times ``t``.

    Returns
    -------
    x_d, xdot_d, xddot_d : ndarray, shape (N, 3)
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    x = np.zeros((t.size, 3))
    xd = np.zeros_like(x)
    xdd = np.zeros_like(x)
    w = waypoints(task, robot)
    x[:] = w["home"]
    for seg in segments(task, robot):
        T = seg.t1 - seg.t0
        sel = t >= seg.t0
        s, ds, dds = quintic((t[sel] - seg.t0) / T)
        d = seg.b - seg.a
        x[sel] = seg.a + s[:, None] * d
        xd[sel] = (ds / T)[:, None] * d
        xdd[sel] = (dds / T ** 2)[:, None] * d
    # The circle (28) overrides [t_circle_start, t_circle_end).
    T = task.t_circle_end - task.t_circle_start
    sel = (t >= task.t_circle_start) & (t < task.t_circle_end)
    s, ds, dds = quintic((t[sel] - task.t_circle_start) / T)
    th, thd, thdd = 2 * np.pi * s, 2 * np.pi * ds / T, 2 * np.pi * dds / T ** 2
    R = task.circle_radius
    u, v = (np.asarray(a, dtype=float) for a in task.circle_axes)
    centre = w["circle_start"] - R * v
    # Written per axis so that the paper's u = e_y, v = e_z give its very doubles (28).
    x[sel] = centre + (R * np.sin(th))[:, None] * u + (R * np.cos(th))[:, None] * v
    xd[sel] = ((R * np.cos(th) * thd)[:, None] * u + (-R * np.sin(th) * thd)[:, None] * v)
    xdd[sel] = ((-R * np.sin(th) * thd ** 2 + R * np.cos(th) * thdd)[:, None] * u
                + (-R * np.cos(th) * thd ** 2 - R * np.sin(th) * thdd)[:, None] * v)
    return x, xd, xdd


def force_reference(task: Task, t: np.ndarray) -> np.ndarray:
    """Desired squeeze force λ_d of (29) (N) at times ``t``."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    f = np.zeros_like(t)
    up = (t >= task.t_grasp) & (t < task.t_circle_start)
    f[up] = task.force_mean * (t[up] - task.t_grasp) / (task.t_circle_start - task.t_grasp)
    circle = (t >= task.t_circle_start) & (t < task.t_circle_end)
    f[circle] = task.force_mean + task.force_amplitude * np.sin(
        task.force_omega * (t[circle] - task.t_circle_start))
    down = (t >= task.t_circle_end) & (t <= task.t_release)
    f[down] = task.force_mean * (1.0 - (t[down] - task.t_circle_end)
                                 / (task.t_release - task.t_circle_end))
    return f


def joint_reference(arm: Arm, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q_d``, ``q̇_d``, ``q̈_d`` from a Cartesian reference through the arm's IK."""
    return arm.kinematics.joint_reference(x, xd, xdd)


def reference_samples(scenario: Scenario, index: int, t_end: float | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Reference vector of robot ``index`` at every control tick.

    Parameters
    ----------
    t_end : float, optional
        Last time needed (a run stopped early): the samples end at the first tick at or after
        ``min(t_end, task.t_end)``; the ticks before are the same as the full run's.

    Returns
    -------
    t : ndarray, shape (K,)
        Tick times ``k h`` (``h`` of the run's plan, :mod:`drake_coop.experiment.plan`).
    r : ndarray, shape (K, 3n + m + 1)
        Rows ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:class:`drake_coop.control.finger.ReferenceLayout`).
    """
    plan = plan_run(scenario)
    h, task, robot = plan.h, scenario.task, scenario.robots[index]
    k_last = plan.k_end
    if t_end is not None:
        k_last = max(1, min(k_last, num_ticks_until(t_end, h) + 1))
    k = np.arange(k_last + 1)
    t = k * h
    x, xd, xdd = cartesian_reference(task, robot, t)
    arm = plan.arms[index]
    q, qd, qdd = joint_reference(arm, x, xd, xdd)
    held = ((k >= plan.k_grasp) & (k < plan.k_release)).astype(float)
    lam = force_reference(task, t)[:, None] * np.asarray(robot.force_weights, dtype=float)
    return t, ReferenceLayout(q.shape[1], arm.m).pack(q, qd, qdd, lam, held)


def reference_trajectory(scenario: Scenario, index: int, t_end: float | None = None
                         ) -> PiecewisePolynomial:
    """The tick samples as a first-order-hold :class:`PiecewisePolynomial`.

    Evaluated at a tick time it returns that tick's sample exactly; the controller and the
    observers only read it at their ticks. ``t_end`` limits it to a shorter run (see
    :func:`reference_samples`).
    """
    t, r = reference_samples(scenario, index, t_end)
    return PiecewisePolynomial.FirstOrderHold(t, r.T)


def _fields_to_check(i: int) -> str:
    return (f"check robots[{i}].model, home, base_xyz, base_yaw_deg, contact_xy and "
            "task.circle_top_z, circle_radius, lift_height, pregrasp_distance")


def check_reachable(scenario: Scenario) -> None:
    """Raise :class:`ScenarioError` if a target of the task is out of an arm's reach.

    Every Cartesian target (sampled every 0.05 s) must be reachable with the joints within
    their limits, away from singular postures (Assumption 1), see the arm's
    ``kinematics.check_path``.
    """
    task = scenario.task
    t = np.arange(0.0, task.t_end + 1e-9, 0.05)
    for i, robot in enumerate(scenario.robots):
        arm = Arm(robot, task)
        x, _, _ = cartesian_reference(task, robot, t)
        problem = arm.kinematics.check_path(x, t)
        if problem:
            problem = problem.removeprefix(f"{robot.name}: ")
            raise ScenarioError(f"robots[{i}] ({robot.name}): {problem}; {_fields_to_check(i)}")
