"""The object-aware blocks of a run (``object_model:`` of a scenario), built from the library's
:mod:`drake_coop.control.object`: one entry, :func:`add_object_layer`, called once by
:func:`~drake_coop.experiment.diagram.build_experiment` between the arms' control blocks and
their actuators.

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
get, each arm's mass share, contact offset and stiffness are the run's plan's
(:class:`~drake_coop.experiment.plan.ObjectPlan`, :class:`~drake_coop.experiment.plan.RobotPlan`):
the grasp points are the robots' contact points, the inward normals their constraint normals
reversed, the centre of mass their midpoint (the shipped boxes are uniform).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import Adder, ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_coop.control.couple import face_distance, squeeze_couple
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object import (
    CompressedReference,
    LoadFeedforward,
    MassEstimator,
    ObjectStateEstimator,
)
from drake_coop.experiment.plan import RobotPlan, RunPlan
from drake_coop.scenario.task_path import cartesian_reference


#: The mass estimator updates every this many control ticks.
ESTIMATOR_TICKS = 5


@dataclass
class ObjectBlocks:
    """One robot's object-aware systems (None where the mode has none).

    Attributes
    ----------
    feedforward : LoadFeedforward
        The load's feed-forward torque.
    tau_sum : Adder
        The controller's torque plus the feed-forward.
    tau : OutputPort
        The summed torque, to the actuators (n,), N·m.
    mass_share : OutputPort
        The arm's mass share (1,), kg.
    estimator : MassEstimator or None
        The mass estimator (``estimated``).
    acceleration_d : OutputPort or None
        The object's desired acceleration (3,), m/s².
    """

    feedforward: LoadFeedforward
    tau_sum: Adder
    tau: OutputPort
    mass_share: OutputPort
    estimator: MassEstimator | None = None
    acceleration_d: OutputPort | None = None


@dataclass
class ArmSignals:
    """What the object layer reads of one arm's part of the diagram.

    ``q``: the encoders' joint positions; ``reference``: the planned reference (the arm's
    ``TrajectorySource``, rows of :class:`~drake_coop.control.finger.ReferenceLayout`);
    ``control``: the arm's control block (its ``tau``, ``qdot_o`` and ``qddot_r_hat`` outputs).
    The planned reference as a trajectory is the plan's
    (:attr:`~drake_coop.experiment.plan.RobotPlan.reference`).

    Attributes
    ----------
    q : OutputPort
        The encoders' joint positions (n,), rad.
    reference : OutputPort
        The planned reference (rows of ``ReferenceLayout``).
    control : Diagram
        The arm's control block.
    """

    q: OutputPort
    reference: OutputPort
    control: object


@dataclass
class ObjectLayer:
    """The object layer's outputs, one entry per arm: ``references[i]`` feeds arm i's control
    block (and its log), ``taus[i]`` its actuators; ``blocks[i]`` its object-aware systems
    (None without an object model); ``shared`` the one ``object_state_estimator``
    (``object_model.shared``), else None.

    Attributes
    ----------
    references : list of OutputPort
        Each arm's reference for its control block and its log.
    taus : list of OutputPort
        Each arm's torque to its actuators (n,), N·m.
    blocks : list of ObjectBlocks or None
        Each arm's object-aware systems.
    shared : ObjectStateEstimator or None
        The shared object-state block.
    """

    references: list[OutputPort]
    taus: list[OutputPort]
    blocks: list[ObjectBlocks | None]
    shared: ObjectStateEstimator | None = None


def acceleration_samples(robot: RobotPlan, t: np.ndarray) -> np.ndarray:
    """The object's desired acceleration along the robot's path (N, 3): the pad's ``ẍ_d``
    (the path translates the object).

    Parameters
    ----------
    robot : RobotPlan
        The robot's section of the plan.
    t : numpy.ndarray
        The times (N,), s.

    Returns
    -------
    numpy.ndarray
        ``ẍ_d`` (N, 3), m/s².
    """
    return cartesian_reference(robot.task, robot.robot, t)[2]


def couple_samples(plan: RunPlan, index: int, t: np.ndarray) -> np.ndarray:
    """Robot ``index``'s part ``f_c,i`` of the squeeze's couple at the times ``t`` (K, 3):
    :func:`~drake_coop.control.couple.squeeze_couple` on the two pads' centres
    along their references (forward kinematics of both ``q_d``, fixed before the run), the
    arm's own ``λ_d`` and the lever between the faces the pads touch
    (:func:`~drake_coop.control.couple.face_distance`: the pads' radii and their
    compressions ``δ(λ_d)``; the centres' distance in ``rigid`` mode); zero while not held.

    Parameters
    ----------
    plan : RunPlan
        The run's plan (both arms' kinematics, contact offsets, stiffnesses and reference
        trajectories, :attr:`~drake_coop.experiment.plan.RobotPlan.reference`).
    index : int
        The robot's index.
    t : numpy.ndarray
        The times (K,), s.

    Returns
    -------
    numpy.ndarray
        ``f_c,i`` (K, 3), N.
    """
    t = np.asarray(t, dtype=float)
    centres, lam, held, rho, delta = [], [], [], [], []
    for robot in plan.robots:
        r = np.asarray(robot.reference.vector_values(t)).T
        layout = robot.layout
        held.append(layout.column(r, "held")[:, 0])
        centres.append(robot.arm.kinematics.fk(layout.column(r, "q_d")))
        lam.append(layout.column(r, "lambda_d")[:, 0] * held[-1])
        offset = robot.contact_offset
        rho.append(0.0 if offset is None else float(np.linalg.norm(offset)))
        stiffness = robot.stiffness
        delta.append(np.zeros_like(t) if stiffness is None or offset is None
                     else stiffness.compression(lam[-1]))
    E = np.stack(centres, axis=1)
    normal = -np.asarray(plan.scenario.robots[0].normals[0], dtype=float)
    w = face_distance(E, normal, rho, np.stack(delta, axis=1))
    f = squeeze_couple(E, normal, lam[index], w)[:, index, :]
    return f * held[index][:, None]


def add_object_blocks(b: DiagramBuilder, robot: RobotPlan, period: float, q: OutputPort,
                      reference: OutputPort, control, t_samples: np.ndarray,
                      couple: np.ndarray | None = None,
                      estimator_period: float | None = None) -> ObjectBlocks:
    """Add the robot's feedforward (and, when ``estimated``, its mass estimator); return
    the summed torque port to connect to the actuators. ``robot``: its section of the run's
    plan (controller's model, mass share, contact offset, the object's friction);
    ``couple``: the arm's part of the squeeze's couple at ``t_samples``
    (:func:`couple_samples`), fed to both; ``estimator_period``: the mass estimator's period
    (default ``ESTIMATOR_TICKS`` periods; the diagram passes it checked once for all arms).

    Parameters
    ----------
    b : DiagramBuilder
        The experiment's builder.
    robot : RobotPlan
        The robot's section of the plan.
    period : float
        The control period, s.
    q : OutputPort
        The encoders' reading (n,), rad.
    reference : OutputPort
        The robot's reference.
    control : Diagram
        The robot's control block (its ``tau``, ``qdot_o`` and ``qddot_r_hat`` outputs).
    t_samples : numpy.ndarray
        The ticks' times (K,), s.
    couple : numpy.ndarray or None
        The arm's part of the squeeze's couple (K, 3), N.
    estimator_period : float or None
        The mass estimator's period, s.

    Returns
    -------
    ObjectBlocks
        The feedforward (and estimator) added and the torque they feed.
    """
    om = robot.object_settings
    name, model = robot.name, robot.controller_model
    a = acceleration_samples(robot, t_samples)
    acc = b.AddNamedSystem(f"{name}_acceleration_d", TrajectorySource(
        PiecewisePolynomial.FirstOrderHold(t_samples, a.T)))
    share0 = robot.mass_share
    r = robot.contact_offset
    # A grasp held by friction (contact mode) passes the object at most μ λ_d across the
    # normal: the feedforward follows the squeeze in (LoadFeedforward's friction limit), with
    # the grasp's margin (μ λ_d / margin): the squeeze lags λ_d while it ramps up at the
    # grasp, and a feedforward at the cone's edge of λ_d slid the pads up the box by 0.35 mm.
    friction = None
    if robot.object_mode == "contact":
        friction = robot.object.mu / om.margin
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
    if robot.object.estimated:
        # Every ESTIMATOR_TICKS ticks, with the forgetting per tick of the scenario (ρ^N per
        # update): the same horizon in seconds at a fifth of the cost.
        if estimator_period is None:
            estimator_period = ESTIMATOR_TICKS * period
        estimator = b.AddNamedSystem(f"{name}_mass_estimator", MassEstimator(
            model, estimator_period, prior=share0,
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


def add_object_state_estimator(b: DiagramBuilder, plan: RunPlan,
                               layouts: list[ReferenceLayout], period: float
                               ) -> ObjectStateEstimator:
    """The shared ``object_state_estimator``: the plan's grasp
    (:class:`~drake_coop.experiment.plan.ObjectPlan`: grasp points and normals, ``mu``),
    ``margin``, ``squeeze_min``, the grasp window and ramp of
    :func:`~drake_coop.experiment.squeeze.friction_squeeze`, ``squeeze_rate`` and each robot's
    force weights. Its inputs (mass shares, ``a_d``) are connected by
    :func:`connect_object_state_estimator`, the references by the caller.

    Parameters
    ----------
    b : DiagramBuilder
        The experiment's builder.
    plan : RunPlan
        The run's plan.
    layouts : list of ReferenceLayout
        Each robot's reference layout.
    period : float
        The control period, s.
    """
    scenario = plan.scenario
    om, task = scenario.object_model, scenario.task
    obj = plan.object
    return b.AddNamedSystem("object_state_estimator", ObjectStateEstimator(
        obj.model.grasp_points, obj.model.grasp_normals, layouts, period, obj.mu, om.margin,
        grasp_window=(task.t_grasp, task.t_release), ramp=1.0, rate=om.squeeze_rate,
        lambda_min=om.squeeze_min,
        force_weights=[r.force_weights for r in scenario.robots]))


def connect_object_state_estimator(b: DiagramBuilder, estimator: ObjectStateEstimator,
                                   blocks: list[ObjectBlocks], acceleration: OutputPort) -> None:
    """Every arm's mass share and the object's desired acceleration into the shared block.

    Parameters
    ----------
    b : DiagramBuilder
        The experiment's builder.
    estimator : ObjectStateEstimator
        The shared block.
    blocks : list of ObjectBlocks
        Each arm's object blocks.
    acceleration : OutputPort
        The object's desired acceleration (3,), m/s².
    """
    for i, blk in enumerate(blocks):
        b.Connect(blk.mass_share, estimator.get_mass_share_input_port(i))
    b.Connect(acceleration, estimator.get_acceleration_d_input_port())


def add_object_layer(b: DiagramBuilder, plan: RunPlan, period: float,
                     arms: list[ArmSignals], estimator_period: float | None = None
                     ) -> ObjectLayer:
    """Every object-aware block of a run, between the arms' control blocks and actuators.

    Without an object model (``object_model.mode: none``, the paper's diagram) nothing is
    added: each arm's planned reference feeds its control block and the block's ``tau`` its
    actuators. Otherwise, per robot, the load feedforward ``τ_ff`` (and, ``estimated``, the
    mass estimator) of :func:`add_object_blocks`, its torque summed with the controller's;
    with ``object_model.shared`` first the one ``object_state_estimator``
    (:func:`add_object_state_estimator`) through which the planned references pass (their
    ``λ_d`` replaced by the squeeze chosen online), each non-redundant compliant arm's
    :class:`~drake_coop.control.object.CompressedReference` after it (the contact's
    compression ``δ(λ_d)`` of the online ``λ_d`` in ``q_d``), and every arm's mass share and the
    object's ``a_d`` connected into it (:func:`connect_object_state_estimator`).

    Parameters
    ----------
    b : DiagramBuilder
        The experiment's builder.
    plan : RunPlan
        The run's plan: its object section (:class:`~drake_coop.experiment.plan.ObjectPlan`),
        each robot's section (:class:`~drake_coop.experiment.plan.RobotPlan`: controller's
        model, stiffness, control point, mass share) and whether the couple is used.
    period : float
        The control period ``h`` (s), already checked against the plant step.
    arms : list of ArmSignals
        Each robot's ports, in the plan's order.
    estimator_period : float, optional
        The mass estimator's period (s), checked once for all arms by the caller; default
        :data:`ESTIMATOR_TICKS` periods.

    Returns
    -------
    ObjectLayer
        Each arm's reference and torque ports, its blocks and the shared block.
    """
    references = [arm.reference for arm in arms]
    taus = [arm.control.GetOutputPort("tau") for arm in arms]
    if plan.object is None:
        return ObjectLayer(references=references, taus=taus, blocks=[None] * len(arms))
    shared = None
    if plan.shared:
        shared = add_object_state_estimator(
            b, plan, [ReferenceLayout(r.controller_model.n, r.controller_model.m)
                      for r in plan.robots], period)
    blocks = []
    for i, (arm, robot) in enumerate(zip(arms, plan.robots)):
        reference = arm.reference
        if shared is not None:
            b.Connect(reference, shared.get_reference_input_port(i))
            reference = shared.get_reference_output_port(i)
            if robot.stiffness is not None and not getattr(robot.arm.kinematics,
                                                           "redundant", False):
                point = robot.control_point
                press = b.AddNamedSystem(f"{robot.name}_compressed_reference",
                                         CompressedReference(
                    robot.controller_model, robot.stiffness,
                    -np.asarray(robot.robot.normals[0], dtype=float),
                    point_offset=None if point is None else point.offset))
                b.Connect(reference, press.get_reference_input_port())
                reference = press.get_compressed_reference_output_port()
        references[i] = reference
        t_ref = np.asarray(robot.reference.get_segment_times())
        # The squeeze's couple from both arms' references (fixed before the run).
        couple = couple_samples(plan, i, t_ref) if plan.uses_couple else None
        blk = add_object_blocks(b, robot, period, arm.q, reference, arm.control, t_ref,
                                couple, estimator_period=estimator_period)
        taus[i] = blk.tau
        blocks.append(blk)
    if shared is not None:
        connect_object_state_estimator(b, shared, blocks, blocks[0].acceleration_d)
    return ObjectLayer(references=references, taus=taus, blocks=blocks, shared=shared)
