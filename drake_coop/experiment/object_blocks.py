"""The object-aware blocks of a run (``object_model:`` of a scenario), built from the library's
:mod:`drake_coop.control.object`.

Per robot, with ``object_model.mode`` ``known`` or ``estimated`` (``none``, the default, adds
nothing: the paper's diagram)::

    robotN_acceleration_d (TrajectorySource: a_d of the shared path) ──┐
    robotN_mass_share (ConstantVectorSource, known) or                 │
    robotN_mass_estimator (MassEstimator, every 5 ticks) ── mass_share ┤
    q, reference ─────────────────────────────────────────────────────┴▶ robotN_load_feedforward
    robotN_control.tau + robotN_load_feedforward.tau_ff ─▶ robotN_tau_sum (Adder) ─▶ actuators

With ``object_model.shared: true`` one more block, between the arms::

    robotN_reference ─▶ object_state_estimator (ObjectStateEstimator) ─▶ reference_out_N ─▶
        robotN_control, robotN_load_feedforward, robotN_mass_estimator (and the log)
    every robotN mass_share, robot1_acceleration_d ─▶ object_state_estimator

It sums the arms' shares into the object's mass and centre of mass and chooses the squeeze
online from that load (rate limited, the same ramps at the grasp and the release), replacing
each planned ``λ_d``: the arms then communicate through it.

Without it, the estimator reads the arm's own ``q``, the control block's ``qdot_o`` and ``qddot_r_hat``
and the summed torque: nothing of the other arm (decentralized). The object model the blocks
get is built from the scenario: the grasp points are the robots' contact points, the inward
normals their constraint normals reversed, the centre of mass their midpoint (the shipped
boxes are uniform).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import Adder, ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.finger import ReferenceLayout
from drake_coop.control.object import (
    ContactStiffness,
    LoadFeedforward,
    MassEstimator,
    ObjectModel,
    ObjectStateEstimator,
    load_distribution,
    mass_shares,
    squeeze_for_grasp,
)
from drake_coop.control.couple import face_distance, squeeze_couple
from drake_coop.scenario.schema import Scenario
from drake_coop.scenario.task_path import cartesian_reference


#: The mass estimator updates every this many control ticks.
ESTIMATOR_TICKS = 5


@dataclass
class ObjectBlocks:
    """One robot's object-aware systems (None where the mode has none)."""

    feedforward: LoadFeedforward
    tau_sum: Adder
    tau: OutputPort
    mass_share: OutputPort
    estimator: MassEstimator | None = None
    acceleration_d: OutputPort | None = None


def object_enabled(scenario: Scenario) -> bool:
    """Whether the controllers get an object model (``object_model.mode`` not ``none``)."""
    return scenario.object_model.mode != "none"


def true_mass(scenario: Scenario) -> float:
    """The simulated object's mass (kg)."""
    return float(scenario.plant.object_mass)


def controller_mass(scenario: Scenario) -> float:
    """The mass the controllers start from: the truth (or ``object_model.mass``) when
    ``known``, ``prior_mass_factor`` times the truth when ``estimated``."""
    om = scenario.object_model
    if om.mode == "estimated":
        return om.prior_mass_factor * true_mass(scenario)
    return float(om.mass) if om.mass is not None else true_mass(scenario)


def scenario_object(scenario: Scenario, mass: float) -> ObjectModel:
    """The object model the controllers get: grasp points at the robots' contact points
    (``contact_xy``, at a common height), inward normals ``−N_i`` (first row), centre of mass
    at the points' midpoint."""
    points = np.array([[r.contact_xy[0], r.contact_xy[1], 0.0] for r in scenario.robots])
    normals = -np.array([np.asarray(r.normals[0], dtype=float) for r in scenario.robots])
    return ObjectModel(mass=mass, com=points.mean(axis=0), grasp_points=points,
                       grasp_normals=normals)


def contact_stiffness(scenario: Scenario, index: int) -> ContactStiffness | None:
    """The compliant-contact model of robot ``index``'s pad (``object_model.contact_stiffness``;
    by default, with an object model in ``contact`` mode, Drake's hydroelastic sphere of
    radius ``r`` pressed on a rigid face, ``λ = π E (δ² − 2δ³/(3r))`` exactly (ContactStiffness's
    ``radius``; ``π E δ²`` to first order in ``δ/r``), from the pad's hydroelastic modulus
    ``E``: ``plant.pad_modulus``, else the arm's model file's); None for a rigid contact."""
    om = scenario.object_model
    if om.contact_stiffness is not None:
        return (ContactStiffness(om.contact_stiffness, om.contact_exponent)
                if om.contact_stiffness > 0 else None)
    if not object_enabled(scenario) or scenario.plant.object_mode != "contact":
        return None
    E = (scenario.plant.pad_modulus if scenario.plant.pad_modulus is not None
         else pad_modulus(scenario.robots[index]))
    # The sphere's exact law (ContactStiffness's radius), a = π E.
    return None if E is None else ContactStiffness(np.pi * E, 2.0,
                                                   radius=pad_radius(scenario.robots[index]))


def pad_modulus(robot) -> float | None:
    """The hydroelastic modulus (Pa) of the end-effector link's collision geometry in the
    robot's model file (``drake:hydroelastic_modulus``), None if it has none."""
    from drake_coop.scenario.resources import model_urdf_path
    text = model_urdf_path(robot).read_text()
    link = re.search(r'<link\s+name="%s"(.*?)</link>' % re.escape(robot.ee_frame), text, re.S)
    if link is None:
        return None
    value = re.search(r'hydroelastic_modulus\s+value="([^"]+)"', link.group(1))
    return None if value is None else float(value.group(1))


def pad_radius(robot) -> float | None:
    """The radius (m) of the end-effector link's spherical collision geometry in the robot's
    model file, None if it has none."""
    from drake_coop.scenario.resources import model_urdf_path
    text = model_urdf_path(robot).read_text()
    link = re.search(r'<link\s+name="%s"(.*?)</link>' % re.escape(robot.ee_frame), text, re.S)
    collision = link and re.search(r"<collision.*?</collision>", link.group(1), re.S)
    sphere = collision and re.search(r'<sphere\s+radius="([^"]+)"', collision.group(0))
    return float(sphere.group(1)) if sphere else None


def pad_point_control(scenario: Scenario, index: int, kinematics=None) -> str:
    """What robot ``index``'s references hold of its pad: ``pose``, ``contact`` or ``centre``.

    The one rule behind ``object_model.control_point``. ``centre`` (the pad's centre E, the
    paper's end-effector point) without an object model, outside the ``contact`` mode, for a
    pad without a spherical collision geometry or with ``control_point: centre``; otherwise
    (``auto`` or ``contact``) what the arm can do,
    :func:`~drake_coop.kinematics.pose_task.pad_control`: ``pose`` on an arm whose task
    holds its pad's orientation (six or more joints and ``ee_rpy_deg``: the material point
    then moves with the centre), ``contact`` on a 3-joint arm (the references follow the
    pad's material contact point across the normal, closed form or Drake's kinematics),
    ``centre`` on a redundant arm with a position-only task (validation refuses
    ``control_point: contact`` there). ``kinematics``: the arm's (default: built from the
    robot's entry).
    """
    from drake_coop.kinematics.pose_task import pad_control
    from drake_coop.scenario.reach import robot_kinematics

    om = scenario.object_model
    robot = scenario.robots[index]
    if (om.control_point == "centre" or om.mode == "none"
            or scenario.plant.object_mode != "contact" or pad_radius(robot) is None):
        return "centre"
    return pad_control(kinematics if kinematics is not None else robot_kinematics(robot))


def controls_contact_point(scenario: Scenario) -> bool:
    """Whether every arm follows its pad's material contact point (:func:`pad_point_control`
    ``pose`` or ``contact``) instead of its pad's centre."""
    return all(pad_point_control(scenario, i) != "centre"
               for i in range(len(scenario.robots)))


@dataclass(frozen=True)
class ControlPoint:
    """Robot ``i``'s pad's material contact point, which its references follow across the
    normal (:func:`~drake_coop.experiment.references.contact_point_reference`).

    Attributes
    ----------
    offset : ndarray, shape (3,)
        The point in the pad's frame, from its centre (the kinematics' ``offset``):
        ``ρ R_WP(q_g)ᵀ n``, ``ρ`` the pad's radius, ``n`` the unit inward normal, ``q_g``
        the posture with the pad's centre at the contact point of the grasp (the point on
        the undeformed surface that touches the box there).
    shift : ndarray, shape (3,)
        ``ρ n`` (world): the point's desired path is the centre's plus this constant vector
        (along the normal, so across it the two paths are the same).
    normal : ndarray, shape (3,)
        The unit outward normal ``N_1`` of the constraint (the squeeze's direction).
    """

    offset: np.ndarray
    shift: np.ndarray
    normal: np.ndarray


def control_point(scenario: Scenario, index: int, arm) -> ControlPoint | None:
    """Robot ``index``'s :class:`ControlPoint` (``arm``: its
    :class:`~drake_coop.plant.arms.Arm`), None when it controls its pad's centre
    (:func:`pad_point_control`).

    The offset is ``ρ R(q_g)ᵀ n``: ``R(q_g)`` the pad's orientation at the posture with its
    centre at the grasp's contact point (the closed-form or Drake's inverse kinematics of a
    3-joint arm), or the orientation ``R_d`` the pose task holds. The two pads' shifts are
    opposite (equal radii, opposite normals): the midpoint of the points' desired paths is
    the midpoint of the centres', the object's desired path.
    """
    kin = arm.kinematics
    kind = pad_point_control(scenario, index, kin)
    if kind == "centre":
        return None
    robot = scenario.robots[index]
    rho = pad_radius(robot)
    n = -np.asarray(robot.normals[0], dtype=float)
    shift = rho * n / np.linalg.norm(n)
    if kind == "pose":
        R_g = np.asarray(kin.R_d.matrix())
    elif hasattr(kin, "pad_rotation"):
        R_g = kin.pad_rotation(kin.ik(arm.c))
    else:
        R_g = kin.rotation(kin.joint_positions(arm.c)[0])
    return ControlPoint(offset=R_g.T @ shift, shift=shift, normal=-n / np.linalg.norm(n))


def contact_offset(scenario: Scenario, index: int) -> np.ndarray | None:
    """Where the object's force acts on robot ``index``'s pad, from its centre E: in
    ``contact`` mode the pad's surface along the inward normal (``ρ n``, ``ρ`` its sphere's
    radius: where the pad touches the box's face whatever the pad's orientation, also when
    the references follow the pad's material contact point, :func:`control_point`); None
    (at E) in ``rigid`` mode, whose ball constraint holds E itself."""
    if scenario.plant.object_mode != "contact":
        return None
    robot = scenario.robots[index]
    rho = pad_radius(robot)
    if rho is None:
        return None
    n = -np.asarray(robot.normals[0], dtype=float)
    return rho * n / np.linalg.norm(n)


def acceleration_samples(scenario: Scenario, index: int, t: np.ndarray) -> np.ndarray:
    """The object's desired acceleration along robot ``index``'s path (N, 3): the pad's
    ``ẍ_d`` (the path translates the object)."""
    return cartesian_reference(scenario.task, scenario.robots[index], t)[2]


def friction_squeeze(scenario: Scenario, t: np.ndarray, ramp: float = 1.0) -> np.ndarray:
    """``object_model.squeeze: friction``: the least squeeze holding the object in every
    friction cone along the desired path (:func:`~drake_coop.control.object.squeeze_for_grasp`
    on the loads of :func:`~drake_coop.control.object.load_distribution`, the controllers'
    mass, ``mu``, ``margin``, ``squeeze_min``), between the grasp and the release, ramped
    linearly over ``ramp`` seconds after the grasp and before the release (N, one per time)."""
    om, task = scenario.object_model, scenario.task
    obj = scenario_object(scenario, controller_mass(scenario))
    mu = om.mu if om.mu is not None else scenario.plant.friction
    t = np.atleast_1d(np.asarray(t, dtype=float))
    xdd = acceleration_samples(scenario, 0, t)
    lam = np.zeros_like(t)
    held = (t >= task.t_grasp) & (t <= task.t_release)
    for k in np.flatnonzero(held):
        loads = load_distribution(obj, xdd[k])
        lam[k] = squeeze_for_grasp(loads, obj.grasp_normals, mu, om.margin,
                                   lambda_min=om.squeeze_min)[0]
    scale = np.clip(np.minimum(t - task.t_grasp, task.t_release - t) / ramp, 0.0, 1.0)
    return lam * scale


def uses_couple(scenario: Scenario) -> bool:
    """Whether the feedforward carries the squeeze's couple (``object_model.couple``: true,
    or null when the arms follow their pads' material contact points, whose centres then
    leave the same height, :func:`controls_contact_point`); two robots only."""
    om = scenario.object_model
    if om.mode == "none" or len(scenario.robots) != 2 or om.couple is False:
        return False
    return om.couple is True or controls_contact_point(scenario)


def couple_samples(scenario: Scenario, index: int, arms, trajectories, t: np.ndarray
                   ) -> np.ndarray:
    """Robot ``index``'s part ``f_c,i`` of the squeeze's couple at the times ``t`` (K, 3):
    :func:`~drake_coop.control.couple.squeeze_couple` on the two pads' centres
    along their references (forward kinematics of both ``q_d``, fixed before the run), the
    arm's own ``λ_d`` and the lever between the faces the pads touch
    (:func:`~drake_coop.control.couple.face_distance`: the pads' radii and their
    compressions ``δ(λ_d)``; the centres' distance in ``rigid`` mode); zero while not held.

    Parameters
    ----------
    arms : sequence of Arm
        Both robots' arms (their kinematics give the centres).
    trajectories : sequence of PiecewisePolynomial
        Both robots' reference trajectories (:func:`~drake_coop.experiment.references.
        reference_trajectory`).
    """
    t = np.asarray(t, dtype=float)
    centres, lam, held, rho, delta = [], [], [], [], []
    for j, (arm, traj) in enumerate(zip(arms, trajectories)):
        r = np.asarray(traj.vector_values(t)).T
        # Rows [q_d, q̇_d, q̈_d, λ_d, held] (ReferenceLayout).
        n = (r.shape[1] - len(scenario.robots[j].normals) - 1) // 3
        centres.append(arm.kinematics.fk(r[:, :n]))
        lam.append(r[:, 3 * n] * r[:, -1])
        held.append(r[:, -1])
        offset = contact_offset(scenario, j)
        rho.append(0.0 if offset is None else float(np.linalg.norm(offset)))
        stiffness = contact_stiffness(scenario, j)
        delta.append(np.zeros_like(t) if stiffness is None or offset is None
                     else stiffness.compression(lam[-1]))
    E = np.stack(centres, axis=1)
    normal = -np.asarray(scenario.robots[0].normals[0], dtype=float)
    w = face_distance(E, normal, rho, np.stack(delta, axis=1))
    f = squeeze_couple(E, normal, lam[index], w)[:, index, :]
    return f * held[index][:, None]


def add_object_blocks(b: DiagramBuilder, scenario: Scenario, index: int, name: str,
                      model: ArmModel, period: float, q: OutputPort, reference: OutputPort,
                      control, t_samples: np.ndarray, couple: np.ndarray | None = None
                      ) -> ObjectBlocks:
    """Add robot ``index``'s feedforward (and, when ``estimated``, its mass estimator); return
    the summed torque port to connect to the actuators. ``couple``: the arm's part of the
    squeeze's couple at ``t_samples`` (:func:`couple_samples`), fed to both."""
    om = scenario.object_model
    a = acceleration_samples(scenario, index, t_samples)
    acc = b.AddNamedSystem(f"{name}_acceleration_d", TrajectorySource(
        PiecewisePolynomial.FirstOrderHold(t_samples, a.T)))
    share0 = float(mass_shares(scenario_object(scenario, controller_mass(scenario)))[index])
    r = contact_offset(scenario, index)
    # A grasp held by friction (contact mode) passes the object at most μ λ_d across the
    # normal: the feedforward follows the squeeze in (LoadFeedforward's friction limit), with
    # the grasp's margin (μ λ_d / margin): the squeeze lags λ_d while it ramps up at the
    # grasp, and a feedforward at the cone's edge of λ_d slid the pads up the box by 0.35 mm.
    friction = None
    if scenario.plant.object_mode == "contact":
        friction = (om.mu if om.mu is not None else scenario.plant.friction) / om.margin
    ff = b.AddNamedSystem(f"{name}_load_feedforward", LoadFeedforward(
        model, period, contact_offset=r, friction=friction, couple=couple is not None))
    f_couple = None
    if couple is not None:
        f_couple = b.AddNamedSystem(f"{name}_f_couple", TrajectorySource(
            PiecewisePolynomial.FirstOrderHold(t_samples, np.asarray(couple).T))
        ).get_output_port()
        b.Connect(f_couple, ff.get_f_couple_input_port())
    tau_sum = b.AddNamedSystem(f"{name}_tau_sum", Adder(2, model.n))
    b.Connect(q, ff.get_q_input_port())
    b.Connect(reference, ff.get_reference_input_port())
    b.Connect(acc.get_output_port(), ff.get_acceleration_d_input_port())
    b.Connect(control.GetOutputPort("tau"), tau_sum.get_input_port(0))
    b.Connect(ff.get_tau_ff_output_port(), tau_sum.get_input_port(1))
    estimator = None
    if om.mode == "estimated":
        # Every ESTIMATOR_TICKS ticks, with the forgetting per tick of the scenario (ρ^N per
        # update): the same horizon in seconds at a fifth of the cost.
        estimator = b.AddNamedSystem(f"{name}_mass_estimator", MassEstimator(
            model, ESTIMATOR_TICKS * period, prior=share0,
            prior_std=om.prior_std_factor * share0,
            forgetting=om.forgetting ** ESTIMATOR_TICKS, contact_offset=r,
            couple=f_couple is not None))
        if f_couple is not None:
            b.Connect(f_couple, estimator.get_f_couple_input_port())
        b.Connect(q, estimator.get_q_input_port())
        b.Connect(control.GetOutputPort("qdot_o"), estimator.get_qdot_o_input_port())
        b.Connect(control.GetOutputPort("qddot_r_hat"),
                  estimator.get_qddot_r_hat_input_port())
        b.Connect(tau_sum.get_output_port(), estimator.get_tau_input_port())
        b.Connect(acc.get_output_port(), estimator.get_acceleration_d_input_port())
        b.Connect(reference, estimator.get_reference_input_port())
        mass = estimator.get_mass_share_output_port()
    else:
        mass = b.AddNamedSystem(f"{name}_mass_share",
                                ConstantVectorSource([share0])).get_output_port()
    b.Connect(mass, ff.get_mass_share_input_port())
    return ObjectBlocks(feedforward=ff, tau_sum=tau_sum, tau=tau_sum.get_output_port(),
                        mass_share=mass, estimator=estimator,
                        acceleration_d=acc.get_output_port())


def shared_enabled(scenario: Scenario) -> bool:
    """Whether the run has the shared object-state block (``object_model.shared``)."""
    return object_enabled(scenario) and bool(scenario.object_model.shared)


def add_object_state_estimator(b: DiagramBuilder, scenario: Scenario,
                               layouts: list[ReferenceLayout], period: float
                               ) -> ObjectStateEstimator:
    """The shared ``object_state_estimator``: the scenario's grasp (:func:`scenario_object`),
    ``mu``, ``margin``, ``squeeze_min``, the grasp window and ramp of
    :func:`friction_squeeze`, ``squeeze_rate`` and each robot's force weights. Its inputs
    (mass shares, ``a_d``) are connected by :func:`connect_object_state_estimator`, the
    references by the caller."""
    om, task = scenario.object_model, scenario.task
    obj = scenario_object(scenario, controller_mass(scenario))
    mu = om.mu if om.mu is not None else scenario.plant.friction
    return b.AddNamedSystem("object_state_estimator", ObjectStateEstimator(
        obj.grasp_points, obj.grasp_normals, layouts, period, mu, om.margin,
        grasp_window=(task.t_grasp, task.t_release), ramp=1.0, rate=om.squeeze_rate,
        lambda_min=om.squeeze_min,
        force_weights=[r.force_weights for r in scenario.robots]))


def connect_object_state_estimator(b: DiagramBuilder, estimator: ObjectStateEstimator,
                                   blocks: list[ObjectBlocks], acceleration: OutputPort) -> None:
    """Every arm's mass share and the object's desired acceleration into the shared block."""
    for i, blk in enumerate(blocks):
        b.Connect(blk.mass_share, estimator.get_mass_share_input_port(i))
    b.Connect(acceleration, estimator.get_acceleration_d_input_port())
