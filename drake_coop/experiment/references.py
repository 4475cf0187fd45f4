"""The references of each robot: joint references through its IK, the reference signal.

The Cartesian paths (28) and the force profile (29) are the scenario's
(:mod:`drake_coop.scenario.task_path`). Joint references come from the arm's
inverse kinematics (closed form for the paper's arms, Drake's otherwise,
:attr:`drake_coop.plant.arms.Arm.kinematics`):
``q_d = IK(x_d)``, ``q̇_d = J⁻¹ ẋ_d``, ``q̈_d = J⁻¹ (ẍ_d − J̇ q̇_d)`` (``J`` the task Jacobian:
position, and orientation held fixed for 6-joint arms). A redundant arm (more joints than task
coordinates, a 7-joint Panda) gets a differential inverse kinematics with a null-space posture
objective, integrated in time (:func:`redundant_joint_reference`). Each constraint row's desired force is
its weight (``robots[i].force_weights``) times the run plan's squeeze
(:meth:`~drake_coop.experiment.plan.RunPlan.squeeze`: (29), or with
``object_model.squeeze: friction`` the least squeeze that holds the object).

With an object model held by friction, each arm follows what it can hold of its pad
(:attr:`~drake_coop.experiment.plan.RobotPlan.pad_point_control`): ``pose`` (a 6-D task, square
or redundant: the path pressed in by the contact's compression, :func:`compressed_path`,
:func:`pressed_path`), ``contact`` (a 3-joint arm: the pad's material point across the normal,
:func:`contact_point_reference`, closed form or Drake's kinematics) or ``centre``.

The object is held (constraint active, controller in its constrained form) on the control
ticks ``k`` with ``k_grasp ≤ k < k_release``, ``k_grasp = ⌈t_grasp/h⌉``: integer tick indices,
so the switch never depends on rounding of ``k·h``.
"""

from __future__ import annotations

import numpy as np

from drake_coop.experiment.ticks import num_ticks_until
from drake_coop.kinematics.pose_task import pad_control, point_kinematics
from drake_coop.plant.arms import Arm
from drake_coop.control.deprecation import moved
from drake_coop.scenario.task_path import cartesian_reference

#: The task's paths are the scenario's (:mod:`drake_coop.scenario.task_path` defines them;
#: found here until the removal date of :mod:`drake_coop.control.deprecation`).
_MOVED = dict.fromkeys(("Segment", "first_normal", "force_reference",
                        "quintic", "segments", "waypoints"), "drake_coop.scenario.task_path")

__all__ = ["joint_reference", "redundant_joint_reference", "start_posture",
           "reference_samples", "compressed_path",
           "contact_point_reference", "followed_point", "rolling_correction", "pressed_path"]


def joint_reference(arm: Arm, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q_d``, ``q̇_d``, ``q̈_d`` from a Cartesian reference through the arm's IK (an arm
    with as many joints as task coordinates).

    Parameters
    ----------
    arm : Arm
        The arm.
    x, xd, xdd : numpy.ndarray
        The Cartesian reference (K, 3): m, m/s, m/s².

    Returns
    -------
    q_d, qdot_d, qddot_d : numpy.ndarray
        (K, n): rad, rad/s, rad/s².
    """
    return arm.kinematics.joint_reference(x, xd, xdd)


def start_posture(arm: Arm, task, point=None) -> np.ndarray:
    """``q_d(0)``: the reference's posture at ``t = 0`` (the run's rest posture), for either
    kind of arm (the same doubles as the first sample of :func:`reference_samples`);
    ``point`` (:class:`~drake_coop.experiment.plan.ControlPoint`) when the arm
    controls its pad's material contact point.

    Parameters
    ----------
    arm : Arm
        The arm.
    task : Task
        The task.
    point : ControlPoint or None
        The controlled material point; None for the pad's centre.
    """
    x, xd, xdd = cartesian_reference(task, arm.robot, [0.0])
    kin = arm.kinematics
    if getattr(kin, "redundant", False):
        return kin.start_posture(x[0], kin.nominal_posture(arm.robot.q_nominal))
    if point is not None and pad_control(kin) == "contact":
        return np.asarray(contact_point_reference(kin, point, x, xd, xdd)[0]).reshape(-1)
    return np.asarray(joint_reference(arm, x, xd, xdd)[0]).reshape(-1)


def redundant_joint_reference(arm: Arm, task, t: np.ndarray, path=None
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q_d``, ``q̇_d``, ``q̈_d`` of a redundant arm (``n > task_dim``) at the times ``t``:
    the differential inverse kinematics with a null-space posture objective
    (:meth:`~drake_coop.kinematics.drake_arm.DrakeArmKinematics.redundant_reference`, the
    robot's ``q_nominal`` and ``nullspace_gain``) along ``path(times) -> (x, ẋ, ẍ)``
    (default: the task's path of the robot, :func:`cartesian_reference`).

    Parameters
    ----------
    arm : Arm
        The arm.
    task : Task
        The task.
    t : numpy.ndarray
        The times (K,), s.
    path : Callable or None
        ``path(times) -> (x, ẋ, ẍ)``; None for the task's.

    Returns
    -------
    q_d, qdot_d, qddot_d : numpy.ndarray
        (K, n): rad, rad/s, rad/s².

    Raises
    ------
    ValueError
        A joint leaves its limits along the reference (``validate`` refuses such a scenario
        first, on a coarser grid).
    """
    robot = arm.robot
    kin = arm.kinematics
    q, qd, qdd = kin.redundant_reference(
        t, path or (lambda tt: cartesian_reference(task, robot, tt)), robot.q_nominal,
        robot.nullspace_gain)
    outside = (q < kin.q_min) | (q > kin.q_max)
    if outside.any():
        k, j = np.argwhere(outside)[0]
        raise ValueError(f"{robot.name}: joint {kin.joint_names[j]} at {q[k, j]:.4f} rad "
                         f"outside its limits at t = {t[k]:.3f} s along the redundant "
                         "reference (choose q_nominal or nullspace_gain)")
    return q, qd, qdd


def reference_samples(robot: "RobotPlan") -> tuple[np.ndarray, np.ndarray]:
    """The reference vector of one robot at every control tick of its run, computed.

    :attr:`RobotPlan.samples <drake_coop.experiment.plan.RobotPlan.samples>` calls this once
    per plan and keeps the result; read that (or :attr:`~drake_coop.experiment.plan.RobotPlan.
    reference`, the trajectory) rather than computing again.

    Parameters
    ----------
    robot : RobotPlan
        The robot's plan (its arm, ``λ_d``, control point and contact stiffness; the run's
        ``h``, grasp ticks and ``t_end``: the samples end at the first tick at or after
        ``min(t_end, task.t_end)``, and the ticks before are the same as the whole task's).

    Returns
    -------
    t : ndarray, shape (K,)
        Tick times ``k h``.
    r : ndarray, shape (K, 3n + m + 1)
        Rows ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:attr:`~drake_coop.experiment.plan.RobotPlan.
        layout`).
    """
    plan = robot.run
    resolved, index = robot, robot.index
    h, task, robot = plan.h, plan.scenario.task, robot.robot
    k_last = num_ticks_until(task.t_end, h)      # the whole task (the plan may be a shorter run)
    k_last = max(1, min(k_last, num_ticks_until(plan.t_end, h) + 1))
    k = np.arange(k_last + 1)
    t = k * h
    arm = plan.arms[index]
    redundant = getattr(arm.kinematics, "redundant", False)
    x, xd, xdd = cartesian_reference(task, robot, t)
    held = ((k >= plan.k_grasp) & (k < plan.k_release)).astype(float)
    lam = resolved.lambda_d(t)
    point = resolved.control_point
    stiffness = resolved.stiffness
    inward = -np.asarray(robot.normals[0], dtype=float)
    path = None
    if stiffness is not None and not plan.shared:
        # (object_model.shared: λ_d is chosen during the run, and so is the compression:
        # CompressedReference presses the joint references in online.)
        # A compliant contact: the pad is held where the contact carries λ_d, pressed in by
        # δ(λ_d) along the inward normal, in the joint references too (else the tangent
        # part of (4) sees the compression as a position error: the pad sags).
        x, xd, xdd = compressed_path(stiffness, x, xd, xdd, lam[:, 0] * held, h, inward)
        if redundant:      # the same pressed path between the ticks, for the integration
            t_on, t_off = plan.k_grasp * h, plan.k_release * h

            def path(times):
                times = np.asarray(times, dtype=float)
                return pressed_path(stiffness, lambda tt: cartesian_reference(task, robot, tt),
                                    lambda tt: resolved.lambda_d(tt)[:, 0]
                                    * ((tt >= t_on - 1e-9) & (tt < t_off - 1e-9)),
                                    times, h, inward)
    if redundant:      # the null-space reference (the pose task holds the pad's orientation)
        q, qd, qdd = redundant_joint_reference(arm, task, t, path)
    elif point is not None and resolved.pad_point_control == "contact":
        # The pad's material contact point across the normal (a 3-joint arm's pad rolls).
        q, qd, qdd = contact_point_reference(arm.kinematics, point, x, xd, xdd)
        if stiffness is not None:
            # The pad pressed in by δ rolls on the face about its material point at ρ − δ
            # from the centre, not ρ: the path across the normal corrected by ∫ δ ω × n.
            c = rolling_correction(arm.kinematics, point, q, qd,
                                   stiffness.compression(lam[:, 0] * held), h)
            q, qd, qdd = contact_point_reference(arm.kinematics, point, x + c[0], xd + c[1],
                                                 xdd + c[2])
    else:      # the centre's path (with the pose held: the material point's too)
        q, qd, qdd = joint_reference(arm, x, xd, xdd)
    return t, resolved.layout.pack(q, qd, qdd, lam, held)


def contact_point_reference(kinematics, point, x: np.ndarray, xd: np.ndarray,
                            xdd: np.ndarray, tolerance: float = 1e-13
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q_d``, ``q̇_d``, ``q̈_d`` that put the pad's material contact point ``P`` on the
    path ``x`` across the normal and the pad's centre ``E`` on it along the normal.

    The point followed is ``y(q) = T P(q) + n nᵀ E(q)``, ``T = I − n nᵀ`` (``n`` the unit
    normal, ``point.normal``; ``P = E + R(q) o``, ``o`` = ``point.offset``): across the normal
    the box, stuck to the pad by friction, follows the material point even when the pad
    rolls on its face (the centre moves ``ρ Δα`` against the box when the pad turns by
    ``Δα``); along the normal the pad's compression, and the line of its normal force, are
    the centre's (a sphere's normal force passes through its centre), so the constraint (2)
    and its force stay the centre's, ``φ = N (E − c)``. ``P``'s desired path is the
    centre's plus ``ρ n`` (``point.shift``, along the normal): across the normal the two
    are the same, so ``y``'s desired path is ``x`` itself (the centre's, compressed).

    ``q`` by Newton's method from ``P``'s closed-form inverse kinematics at ``x + ρ n``
    (exact when the pad has not turned since the grasp), to ``tolerance`` (m); then
    ``q̇_d = J_y⁻¹ ẋ_d``, ``q̈_d = J_y⁻¹ (ẍ_d − J̇_y q̇_d)`` with
    ``J_y = T J_P + n nᵀ J_E`` (and ``J̇_y`` likewise).

    Parameters
    ----------
    kinematics : CrsKinematics
        The arm's kinematics of its pad's centre (``with_offset`` gives ``P``'s).
    point : ControlPoint
        :attr:`~drake_coop.experiment.plan.RobotPlan.control_point`.
    x, xd, xdd : ndarray, shape (K, 3)
        The centre's desired path (compressed, :func:`compressed_path`).
    tolerance : float
        Newton's tolerance, m.

    Returns
    -------
    q_d, qdot_d, qddot_d : numpy.ndarray
        (K, 3): rad, rad/s, rad/s².

    Raises
    ------
    ValueError
        Newton's method does not reach ``tolerance`` (a posture out of reach).
    """
    n = np.asarray(point.normal, dtype=float)
    Pn = np.outer(n, n)
    T = np.eye(3) - Pn
    kin_p = point_kinematics(kinematics, point.offset)
    kinematics = point_kinematics(kinematics)
    x = np.atleast_2d(x)
    q = kin_p.ik(x + point.shift)

    def jacobian(q):
        return T @ kin_p.jacobian(q) + Pn @ kinematics.jacobian(q)

    for _ in range(20):          # each sample on its own (the same doubles alone or in a batch)
        residual = _followed(kinematics, kin_p, Pn, q) - x
        active = np.abs(residual).max(axis=1) > tolerance
        if not active.any():
            break
        q[active] -= np.linalg.solve(jacobian(q[active]), residual[active][..., None])[..., 0]
    else:
        raise ValueError(f"{kinematics.name}: the contact point's reference did not converge "
                         f"({np.abs(residual).max():.3g} m)")
    J = jacobian(q)
    qd = np.linalg.solve(J, np.atleast_2d(xd)[..., None])[..., 0]
    Jd = T @ kin_p.jacobian_dot(q, qd) + Pn @ kinematics.jacobian_dot(q, qd)
    qdd = np.linalg.solve(J, (np.atleast_2d(xdd) - (Jd @ qd[..., None])[..., 0])[..., None])[..., 0]
    return q, qd, qdd


def rolling_correction(kinematics, point, q: np.ndarray, qd: np.ndarray, delta: np.ndarray,
                       h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The correction ``c(t)`` of the path across the normal for a pad pressed in by ``δ``.

    A pad pressed ``δ`` into the box carries it by its material point *on the box's face*,
    ``ρ − δ`` from its centre along the inward normal ``n``, not by the point at ``ρ`` (the
    undeformed surface, :func:`contact_point_reference`'s ``P``): the face's no-slip velocity
    is ``T (Ė + (ρ − δ) ω × n) = T (Ṗ − δ ω × n)`` (to first order in the pad's turn since
    the grasp; ``T = I − n nᵀ``, ``ω`` the pad's angular velocity), so the box moves with
    ``T P − c``,

    .. math:: c(t) = T \int_0^t \delta(s)\, \omega(s) \times n \, ds

    and the path of ``T P`` is ``x + c`` (``ċ``, ``c̈`` with it). ``ω`` along the reference
    ``q``, ``q̇`` (:func:`contact_point_reference` without the correction; the correction
    changes ``ω`` by a second-order amount), ``δ`` the compression ``δ(λ_d)`` of each tick.

    Parameters
    ----------
    kinematics : CrsKinematics
        The arm's kinematics of its pad's centre.
    point : ControlPoint
        The controlled material point.
    q, qd : numpy.ndarray
        The reference (K, 3): rad, rad/s.
    delta : numpy.ndarray
        The compression per tick (K,), m.
    h : float
        The tick grid's step, s.

    Returns
    -------
    c, c_dot, c_ddot : ndarray, shape (K, 3)
        ``c`` (m), ``ċ`` (m/s), ``c̈`` (m/s²) per tick.
    """
    n = -np.asarray(point.normal, dtype=float)           # inward
    T = np.eye(3) - np.outer(n, n)
    w = point_kinematics(kinematics).angular_velocity(q, qd)
    rate = (np.asarray(delta, dtype=float)[:, None] * np.cross(w, n)) @ T
    c = np.zeros_like(rate)
    if len(rate) > 1:
        c[1:] = np.cumsum(0.5 * (rate[1:] + rate[:-1]) * h, axis=0)
        acc = np.gradient(rate, h, axis=0)
    else:
        acc = np.zeros_like(rate)
    return c, rate, acc


def followed_point(kinematics, point, q: np.ndarray) -> np.ndarray:
    """The point :func:`contact_point_reference` puts on the path, at the postures ``q``
    (..., 3): the pad's material contact point across the normal, its centre along it; the
    pad's centre itself when ``point`` is None.

    Parameters
    ----------
    kinematics : CrsKinematics or DrakeArmKinematics
        The arm's kinematics of its pad's centre.
    point : ControlPoint or None
        The controlled material point.
    q : numpy.ndarray
        Postures (..., n), rad.

    Returns
    -------
    numpy.ndarray
        The point (..., 3), m.
    """
    if point is None:
        return kinematics.fk(q)
    n = np.asarray(point.normal, dtype=float)
    return _followed(point_kinematics(kinematics), point_kinematics(kinematics, point.offset),
                     np.outer(n, n), q)


def _followed(kinematics, kin_p, Pn: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``y(q) = T P(q) + n nᵀ E(q)`` (``Pn = n nᵀ``, ``T = I − Pn``; ``kin_p`` the kinematics
    of ``P``, ``kinematics`` those of ``E``)."""
    return kin_p.fk(q) @ (np.eye(3) - Pn) + kinematics.fk(q) @ Pn


def compressed_path(stiffness, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray,
                    lam: np.ndarray, h: float, inward: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The path pressed in by the contact's compression: ``x_d + δ(λ_d) n``, ``n`` the unit
    inward normal, with ``δ̇``, ``δ̈`` by central differences on the tick grid ``h``.

    Parameters
    ----------
    stiffness : ContactStiffness
        The contact's stiffness (``δ(λ)``).
    x, xd, xdd : numpy.ndarray
        The path (K, 3): m, m/s, m/s².
    lam : numpy.ndarray
        ``λ_d`` per tick (K,), N.
    h : float
        The tick grid's step, s.
    inward : numpy.ndarray
        The inward normal (3,).

    Returns
    -------
    x, xd, xdd : numpy.ndarray
        The pressed path (K, 3): m, m/s, m/s².
    """
    n = inward / np.linalg.norm(inward)
    delta = stiffness.compression(lam)
    d1 = np.gradient(delta, h) if delta.size > 1 else np.zeros_like(delta)
    d2 = np.gradient(d1, h) if delta.size > 1 else np.zeros_like(delta)
    return (x + delta[:, None] * n, xd + d1[:, None] * n, xdd + d2[:, None] * n)


def pressed_path(stiffness, path, lam, times: np.ndarray, h: float, inward: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`compressed_path` at any times: ``x_d + δ(λ_d) n`` with ``δ̇``, ``δ̈`` by central
    differences of step ``h`` (the tick grid's, so that at a tick it is
    :func:`compressed_path`'s first difference); ``path(times) -> (x, ẋ, ẍ)``,
    ``lam(times)`` the squeeze (N).

    Parameters
    ----------
    stiffness : ContactStiffness
        The contact's stiffness.
    path : Callable
        ``path(times) -> (x, ẋ, ẍ)``.
    lam : Callable
        ``lam(times)``, N.
    times : numpy.ndarray
        The times (K,), s.
    h : float
        The differences' step, s.
    inward : numpy.ndarray
        The inward normal (3,).

    Returns
    -------
    x, xd, xdd : numpy.ndarray
        The pressed path (K, 3): m, m/s, m/s².
    """
    n = inward / np.linalg.norm(inward)
    x, xd, xdd = path(times)
    d0, dp, dm = (stiffness.compression(lam(times + s)) for s in (0.0, h, -h))
    d1 = (dp - dm) / (2.0 * h)
    d2 = (dp - 2.0 * d0 + dm) / h ** 2
    return (x + d0[:, None] * n, xd + d1[:, None] * n, xdd + d2[:, None] * n)


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
