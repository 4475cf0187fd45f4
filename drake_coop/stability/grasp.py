r"""The squeeze's buckling of a two-pad grasp: the largest squeeze the arms' position loops hold.

Two spherical pads press a free object between them with the squeeze ``λ``. A sphere's contact
force passes through its centre and the object takes no other load worth the name, so the
object is a *two-force member*: the force between the pads is along the line joining their
centres (length ``L``). Moving the pads across that line by ``δ_1``, ``δ_2`` turns it by
``(δ_2 − δ_1)/L``, and the squeeze's part across it, ``λ (δ_2 − δ_1)/L`` on pad 1 and the
opposite on pad 2, pushes the pads further the way they went: a negative (geometric)
stiffness

.. math::
    K_g = -\frac{\lambda}{L}\begin{bmatrix} I & -I \\ -I & I \end{bmatrix}

on the pads' displacements across the line (2 × 2 blocks, the plane normal to it). Each arm's
position loop resists with its pad's stiffness across the line,

.. math::
    K_{\perp,i} = \big(P\, J_x(q_i)\, (K_{R,i}\Lambda_i)^{-1} J_x(q_i)^\top P^\top\big)^{-1},

``K_R Λ`` the static joint stiffness of the law (13) (``τ = −K_R (q̇̂ − q̇_r)``, ``q̇_r =
q̇_d − Λ (q̂ − q_d)`` at rest), ``J_x`` the pad centre's translational Jacobian (the pad's
rotation free: a sphere passes no moment) and ``P`` the 2 × 3 basis of the plane normal to
the line. The held grasp is statically stable iff ``blkdiag(K_⊥,1, K_⊥,2) + K_g`` is positive
definite, i.e. iff ``λ`` is below

.. math::
    \lambda_b = 1 \big/ \rho\big(K^{-1/2} G K^{-1/2}\big), \qquad
    K = \operatorname{blkdiag}(K_{\perp,1}, K_{\perp,2}),\ G = \frac{1}{L}\begin{bmatrix} I & -I \\ -I & I \end{bmatrix}

(for two equal arms ``λ_b = K_⊥ L / 2`` along the softer direction). Above it the grasp
*buckles*: the pads slide across the line in opposite directions, the object turns about the
axis normal to the line and to that direction, the pads leave their path and the squeeze falls
— whatever the force observer, the object model or the object's mass (the mode is the
squeeze's, not the load's). The ideal ``planes`` and ``rigid`` modes have no such mode (the
constraint planes do not turn), so neither the stability map nor a ``planes`` run shows it.

This is a quasi-static bound (the loop's damping only sets how fast a buckled grasp drifts).
It does not predict, on its own, which grasps hold: measured on the lab-arms guide's pairs
(``docs/results/every_arm.json``, each run through the whole circle past ``gains``), the worst
``λ_d / λ_b`` of grasps that held was about 0.05 (UR5s), 0.46 (Pandas), 0.48 (UR10s), 0.99 (UR5 +
Z1), 1.29 (Jaco2s at the friction squeeze) and 2.26 (xArm7s), and of grasps that were lost
0.85 (UR3s: the pads began to sway vertically in opposite directions, joints 2–4 of both
arms growing at about 3 1/s without oscillating, 2.4 s into the circle at ``λ_d ≈ 42 N = 0.70
λ_b``), 1.94 (Z1s) and 5.5 (Jaco2s). No threshold on the ratio separates the two sets; every
threshold in (1.29, 1.94] misclassifies the fewest, two (the xArm7s refused though they carry,
the UR3s passed though they lose the box). The bound leaves out the pads' hydroelastic
patches (a sphere pressed into a face resists the box's rotation), the box's inertia, the
object model's feedforward and the force loop's and observers' reaction to a tilted box (which
of these decides was not isolated). So
``drake-coop gains`` no longer refuses on it: its grasp check is the ``contact`` loop's
own dynamics (:mod:`drake_coop.stability.grasp_dynamics`: frozen postures, and the moving
reference followed where one grows), which gets every one of them right, and the ratio is
recorded beside it. :func:`check_grasp_buckling`
(``λ_d ≤`` :data:`GRASP_MARGIN` ``× λ_b`` at every held tick, an empirical factor in that
interval) and :func:`buckling_squeeze` (``λ_b`` per posture) remain for that record and for
diagnosis. Two robots with one contact row each only
(the grasp of a box between two pads); other grasps are not checked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["GRASP_MARGIN", "GraspBuckling", "buckling_squeeze", "check_grasp_buckling",
           "pad_stiffness"]

#: ``λ_d ≤ GRASP_MARGIN × λ_b`` at every held tick: a threshold among those that misclassify
#: the fewest measured grasps (the module docstring), not derived.
GRASP_MARGIN = 1.75


def _plane_basis(u: np.ndarray) -> np.ndarray:
    """A 2 × 3 orthonormal basis of the plane normal to the unit vector ``u``."""
    return np.linalg.svd(np.eye(3) - np.outer(u, u))[0][:, :2].T


def pad_stiffness(J_x: np.ndarray, joint_stiffness: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The pad's stiffness in the plane spanned by the rows of ``P``, the rest of the pad's
    motion free: ``(P J_x K_q⁻¹ J_xᵀ Pᵀ)⁻¹``.

    Parameters
    ----------
    J_x : numpy.ndarray
        The pad centre's translational Jacobian (3, n), m/rad.
    joint_stiffness : numpy.ndarray
        ``K_q`` per joint (n,), N·m/rad (``K_R Λ``).
    P : numpy.ndarray
        The plane's basis (k, 3), orthonormal rows.

    Returns
    -------
    numpy.ndarray
        (k, k), N/m.
    """
    compliance = P @ J_x @ np.diag(1.0 / np.asarray(joint_stiffness, dtype=float)) @ J_x.T @ P.T
    return np.linalg.inv(compliance)


def buckling_squeeze(K1: np.ndarray, K2: np.ndarray, distance: float
                     ) -> tuple[float, np.ndarray]:
    """``λ_b`` of the module docstring: the squeeze at which the two pads' grasp buckles.

    Parameters
    ----------
    K1, K2 : numpy.ndarray
        Each pad's stiffness across the line between the pads (k, k), N/m, in one basis.
    distance : float
        ``L``, the distance between the pads' centres, m.

    Returns
    -------
    lambda_b : float
        The buckling squeeze, N.
    mode : numpy.ndarray
        The buckling mode (2k,): pad 1's then pad 2's displacement in the basis (unit norm).
    """
    k = K1.shape[0]
    K = np.zeros((2 * k, 2 * k))
    K[:k, :k], K[k:, k:] = 0.5 * (K1 + K1.T), 0.5 * (K2 + K2.T)
    G = np.block([[np.eye(k), -np.eye(k)], [-np.eye(k), np.eye(k)]]) / distance
    w, V = np.linalg.eigh(K)
    root_inv = V @ np.diag(1.0 / np.sqrt(w)) @ V.T
    mu, modes = np.linalg.eigh(root_inv @ G @ root_inv)
    mode = root_inv @ modes[:, -1]
    return float(1.0 / mu[-1]), mode / np.linalg.norm(mode)


@dataclass
class GraspBuckling:
    """The grasp's buckling check along the task.

    Attributes
    ----------
    checked : bool
        False when the scenario's grasp is not two pads (nothing was checked).
    passes : bool
        ``λ_d ≤ GRASP_MARGIN · λ_b`` at every held tick (True when not checked).
    worst_ratio : float
        The largest ``λ_d / λ_b`` (dimensionless).
    t : float
        Its time, s.
    phase : str
        Its phase (``lift``, ``circle``, ...).
    squeeze : float
        ``λ_d`` there, N.
    lambda_b : float
        ``λ_b`` there, N.
    min_lambda_b : float
        The smallest ``λ_b`` over the held ticks, N.
    stiffness : list of float
        The two pads' softest stiffness across the line there, N/m.
    distance : float
        ``L`` there, m.
    joints : dict of str to list of str
        Per robot, the joints that give the buckling mode most of its compliance.
    message : str
        One line: what was found and, on failure, what to change.
    """

    checked: bool
    passes: bool = True
    worst_ratio: float = 0.0
    t: float = float("nan")
    phase: str = ""
    squeeze: float = 0.0
    lambda_b: float = float("inf")
    min_lambda_b: float = float("inf")
    stiffness: list = None
    distance: float = float("nan")
    joints: dict = None
    message: str = ""


def _phase(task, t: float) -> str:
    for name, end in (("free", task.t_grasp), ("lift", task.t_circle_start),
                      ("circle", task.t_circle_end), ("put-down", task.t_release)):
        if t < end:
            return name
    return "return"


def _soft_joints(J_x, Kq, P, direction, names, count: int = 3) -> list[str]:
    """The joints whose compliance makes up most of the pad's motion along ``direction``
    (in ``P``'s basis) under a unit force there."""
    f = P.T @ direction
    share = (J_x.T @ f) ** 2 / Kq
    order = np.argsort(share)[::-1][:count]
    return [names[j] for j in order if share[j] > 0.05 * share.sum()]


def check_grasp_buckling(scenario, plan=None, step: float = 0.1,
                         margin: float = GRASP_MARGIN,
                         t_end: float | None = None) -> GraspBuckling:
    """:func:`buckling_squeeze` along the held ticks of ``scenario`` (every ``step`` s) at its
    robots' gains and reference: ``λ_d ≤ margin × λ_b``.

    Parameters
    ----------
    scenario : Scenario
        The scenario with the gains to check (any object mode: the grasp is the ``contact``
        mode's; in ``planes`` mode it tells what a real box between the pads would do).
    plan : RunPlan or None
        The run's plan; None plans it here.
    step : float
        The sampling of the held path, s.
    margin : float
        The largest ``λ_d / λ_b`` allowed.
    t_end : float or None
        Check the held ticks before ``t_end`` (s) only; None: all of them.

    Returns
    -------
    GraspBuckling
        The worst tick and the verdict (``checked`` False unless two robots with one contact
        row each).
    """
    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.arms import arm_model

    if len(scenario.robots) != 2 or any(len(r.normals) != 1 for r in scenario.robots):
        return GraspBuckling(False, message="grasp buckling: not checked (two robots with one "
                                            "contact row each only)")
    plan = plan or plan_run(scenario)
    rows, models, names = [], [], []
    for resolved in plan.robots:
        t, r = resolved.samples
        arm = resolved.arm
        layout = resolved.layout
        stride = max(1, int(round(step / plan.h)))
        held = layout.column(r, "held")[:, 0] > 0.5
        lam = layout.column(r, "lambda_d")[:, 0]
        rows.append((t[::stride], layout.column(r, "q_d")[::stride], held[::stride],
                     lam[::stride]))
        model = arm_model(arm, arm.urdf_path)
        models.append(model)
        names.append([model.plant.get_joint(j).name() for j in model.plant.GetJointIndices()
                      if model.plant.get_joint(j).num_velocities() == 1])
    Kq = [np.asarray(r.gains.K_R, dtype=float) * float(r.gains.Lambda)
          for r in scenario.robots]
    t = rows[0][0]
    held = rows[0][2] & rows[1][2] & (t < (math.inf if t_end is None else t_end))
    out = GraspBuckling(True)
    worst = None
    for k in np.flatnonzero(held):
        q = [rows[0][1][k], rows[1][1][k]]
        x = [models[i].ee_position(q[i]) for i in range(2)]
        distance = float(np.linalg.norm(x[1] - x[0]))
        P = _plane_basis((x[1] - x[0]) / distance)
        J = [models[i].J_x(q[i]) for i in range(2)]
        K = [pad_stiffness(J[i], Kq[i], P) for i in range(2)]
        lambda_b, mode = buckling_squeeze(K[0], K[1], distance)
        lam = max(rows[0][3][k], rows[1][3][k])
        out.min_lambda_b = min(out.min_lambda_b, lambda_b)
        ratio = lam / lambda_b
        if worst is None or ratio > worst[0]:
            worst = (ratio, k, lam, lambda_b, distance, K, J, P, mode)
    if worst is None:
        return GraspBuckling(False, message="grasp buckling: not checked (no held tick)")
    ratio, k, lam, lambda_b, distance, K, J, P, mode = worst
    out.worst_ratio, out.t, out.squeeze, out.lambda_b = float(ratio), float(t[k]), float(lam), \
        float(lambda_b)
    out.phase = _phase(scenario.task, out.t)
    out.distance = distance
    out.stiffness = [float(np.linalg.eigvalsh(0.5 * (Ki + Ki.T))[0]) for Ki in K]
    out.joints = {}
    for i, robot in enumerate(scenario.robots):
        part = mode[2 * i: 2 * i + 2]
        direction = part / np.linalg.norm(part) if np.linalg.norm(part) > 0 else part
        out.joints[robot.name] = _soft_joints(J[i], Kq[i], P, direction, names[i])
    out.passes = bool(ratio <= margin)
    where = (f"at t = {out.t:.2f} s ({out.phase}) the squeeze lambda_d = {lam:.3g} N against "
             f"lambda_b = {lambda_b:.3g} N (pads {distance:.3g} m apart, stiffness across "
             f"their line {out.stiffness[0]:.4g} / {out.stiffness[1]:.4g} N/m)")
    if out.passes:
        out.message = (f"grasp buckling: passes, worst {where}, ratio {ratio:.3g} <= "
                       f"{margin:g}")
    else:
        soft = "; ".join(f"{name}: {', '.join(js)}" for name, js in out.joints.items())
        lower = ("the friction squeeze is the least that holds the box: a lighter box or a "
                 "higher friction, plant.object_mass, plant.friction"
                 if (scenario.object_model.mode != "none"
                     and scenario.object_model.squeeze == "friction") else
                 "task.force_mean, force_amplitude; object_model.squeeze: friction")
        out.message = (f"grasp buckling: the squeeze buckles the grasp {where}, ratio "
                       f"{ratio:.3g} > {margin:g}: keep the squeeze below "
                       f"{out.min_lambda_b * margin:.3g} N ({lower}), widen "
                       f"the grasp or stiffen the arms across it (K_R x Lambda of {soft})")
    return out
