"""One robot's control block in any Drake diagram: :func:`AddCooperativeController`.

In the style of pydrake's ``AddMultibodyPlantSceneGraph`` and the ``Add*``/``Make*`` helpers of
the ``manipulation`` package: given a user's :class:`~pydrake.systems.framework.DiagramBuilder`,
a finalized :class:`~pydrake.multibody.plant.MultibodyPlant` and one arm's model instance,
:func:`AddCooperativeController` adds the paper's velocity observer (15)–(16), force observer
(22) and controller (13) of that arm as one sub-Diagram, wires its ``q`` input (the plant's
positions through a C++ :class:`~pydrake.systems.primitives.Demultiplexer`, or the user's own
sensor) and its ``tau`` output (to the plant's actuation input of that instance, or left to the
user), and returns a :class:`ControllerHandles`.

The controller's model follows Drake's ``InverseDynamicsController`` idiom: its own single-arm
plant (:func:`MakeArmControllerPlant`, from the arm's model file with its base welded where the
arm's base is in the simulated plant), never the simulated plant's context.

The simulated plant must have *live* output ports (``plant.SetUseSampledOutputPorts(False)``
before ``Finalize()``): with Drake's default sampled ports the plant's step is an unrestricted
update run before the controllers' discrete updates at the same instant, so the observers would
read ``q`` one plant step late; the tracking and force errors are then 2–4× larger.
:func:`AddCooperativeController` refuses such a plant unless told otherwise.
"""

from __future__ import annotations

import warnings
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex
from pydrake.systems.framework import (
    Context,
    Diagram,
    DiagramBuilder,
    InputPort,
    LeafSystem,
    OutputPort,
)
from pydrake.systems.primitives import Demultiplexer

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.arm_plant import make_arm_controller_plant
from drake_coop.control.controller import Controller
from drake_coop.control.delay import DelayPredictor
from drake_coop.control.finger import FingerLaw
from drake_coop.control.registry import EXTERNAL_INPUTS, SOURCES, source
from drake_coop.control.sources import MeasuredVelocity
from drake_coop.control.timing import Clock, on_clock
from drake_coop.control.params import (
    FORCE_SOURCES,
    VELOCITY_SOURCES,
    Gains,
    check_choice,
    check_optional_positive,
    check_period,
)


def _check_sources(velocity_source, force_source, difference_cutoff_hz) -> None:
    """The sources' names, and a cutoff only for ``velocity_source = difference``."""
    check_choice(velocity_source, "velocity_source", VELOCITY_SOURCES)
    check_choice(force_source, "force_source", FORCE_SOURCES)
    check_optional_positive(difference_cutoff_hz, "difference_cutoff_hz")
    if difference_cutoff_hz is not None and velocity_source != "difference":
        raise ValueError("difference_cutoff_hz: only for velocity_source='difference' (got "
                         f"velocity_source={velocity_source!r})")


def build_control_block(name: str, law: FingerLaw, period: float,
                        velocity_source: str = "observer", force_source: str = "observer",
                        difference_cutoff_hz: float | None = None,
                        momentum_torque_limits=None, prediction_horizon: float | None = None,
                        anti_windup_limits=None, clock: Clock | None = None,
                        anti_windup_gain: float | None = None
                        ) -> tuple[Diagram, LeafSystem, LeafSystem, Controller]:
    """One robot's velocity source, force source and controller, wired as in the paper.

    The sources are the paper's observers (``observer``) or the alternatives of
    :mod:`drake_coop.control.sources`, with the same port names, so only the blocks change.
    Most users want :func:`AddCooperativeController`, which also wires the block into a plant.

    The momentum observer's gain ``K_O`` of ``force_source = momentum`` is the law's
    (``Gains.momentum_gain``).

    Parameters
    ----------
    name : str
        Prefix of the systems' names; the Diagram is ``<name>_control``.
    law : FingerLaw
        The robot's law.
    period : float
        Sampling time ``h`` (s), > 0.
    velocity_source, force_source : str
        One of :data:`~drake_coop.scenario.VELOCITY_SOURCES`, :data:`~drake_coop.scenario.FORCE_SOURCES`.
    difference_cutoff_hz : float, optional
        Low-pass cutoff of ``velocity_source = difference``.
    momentum_torque_limits : array_like, optional
        ``force_source = momentum`` only: the actuators' torque limits, so the observer
        integrates the torque actually applied (after saturation) instead of the commanded
        one (opt-in; :class:`~drake_coop.control.momentum.MomentumObserver`).
    prediction_horizon : float, optional
        Delay compensation (opt-in): a :class:`~drake_coop.control.delay.DelayPredictor`
        ``<name>_predictor`` with this horizon (s) between the sources and the controller;
        the force observer (22) reads the predicted values too. None (default): the paper's
        block, unchanged.
    anti_windup_limits : array_like, optional
        Anti-windup of the force integral (6) (opt-in, for the force sources whose registry
        entry declares the ``anti_windup`` option): the arm's torque limits (n,), N·m; the
        force source reads the controller's ``tau`` and holds ``ΔF̃`` at a tick whose
        commanded torque exceeds them (:mod:`~drake_coop.control.anti_windup`). None
        (default): the paper's (6).
    clock : Clock or None
        The controller's own clock (:class:`~drake_coop.control.timing.Clock`, its
        computer's): every system of the block with periodic updates ticks on it, each
        keeping ``h`` in its equations. None (default): the run's grid.
    anti_windup_gain : float, optional
        With ``anti_windup_limits``: back-calculation at this tracking rate ``K_aw`` (1/s,
        ``0 < h K_aw ≤ 1``) instead of conditional integration; the force source then also
        reads ``q`` (:func:`~drake_coop.control.anti_windup.back_calculation`). None
        (default): conditional integration.

    Returns
    -------
    tuple
        ``(diagram, velocity source, force source, controller)``. Exported inputs: ``q``,
        ``reference``; ``state`` for ``velocity_source = measured`` (the true velocities);
        ``lambda_sensor`` for ``force_source = sensor``. Exported outputs: ``tau``, ``q_hat``,
        ``qdot_hat``, ``qdot_o``, ``lambda_hat``, ``Delta_F_tilde``, ``qddot_r_hat``; with
        ``force_source = momentum`` (which reads ``q``, the velocity source's ``qdot_hat`` and
        the commanded ``tau``) also ``tau_ext_hat`` and ``O_F_ext_hat``.
    """
    check_period(period)
    _check_sources(velocity_source, force_source, difference_cutoff_hz)
    if anti_windup_limits is not None and "anti_windup" not in source("force",
                                                                      force_source).options:
        users = " or ".join(repr(s.name) for s in SOURCES if "anti_windup" in s.options)
        raise ValueError(f"anti_windup_limits: only for force_source {users} (got "
                         f"force_source={force_source!r})")
    on_clock(clock, period)                  # a Clock or None, refused by name otherwise
    options = {"difference_cutoff_hz": difference_cutoff_hz,
               "momentum_torque_limits": momentum_torque_limits,
               "anti_windup_limits": anti_windup_limits, "clock": clock,
               "anti_windup_gain": anti_windup_gain}
    specs = (source("velocity", velocity_source), source("force", force_source))
    b = DiagramBuilder()
    vel, force = (b.AddNamedSystem(f"{name}_{spec.suffix}", spec.make(law, period, options))
                  for spec in specs)
    ctrl = b.AddNamedSystem(f"{name}_controller", Controller(law, period, clock=clock))
    # What the controller and the force observer read: the sources' values, or predicted.
    inputs = {port: vel.GetOutputPort(port) for port in ("q_hat", "qdot_hat", "qdot_o")}
    predictor = None
    if prediction_horizon is not None:
        predictor = b.AddNamedSystem(f"{name}_predictor",
                                     DelayPredictor(law, period, prediction_horizon,
                                                    clock=clock))
        for port in ("q_hat", "qdot_hat", "qdot_o"):
            b.Connect(vel.GetOutputPort(port), predictor.GetInputPort(port))
            inputs[port] = predictor.GetOutputPort(f"{port}_p")
        b.Connect(ctrl.get_tau_output_port(), predictor.GetInputPort("tau"))
        b.Connect(ctrl.get_qddot_r_hat_output_port(), predictor.GetInputPort("qddot_r_hat"))
        b.Connect(force.GetOutputPort("lambda_hat"), predictor.GetInputPort("lambda_hat"))
    for port in ("q_hat", "qdot_hat", "qdot_o"):
        b.Connect(inputs[port], ctrl.GetInputPort(port))
    b.Connect(force.GetOutputPort("lambda_hat"), ctrl.get_lambda_hat_input_port())
    b.Connect(force.GetOutputPort("Delta_F_tilde"), ctrl.get_Delta_F_tilde_input_port())
    # Each source's inputs, as its registry entry declares them: a signal of the block, or
    # an input from outside (exported under its name). The block's inputs in the order
    # q, the velocity source's own, reference, the force source's own. With the predictor,
    # the controller and the force observer (22) read the predicted q, q̂, q̇_o, and the
    # velocity observer is fed the predictor's acceleration (DelayPredictor).
    signals = {"q_hat": vel, "qdot_hat": vel, "qdot_o": vel, "qddot_r_hat": ctrl,
               "tau": ctrl}

    def feed(spec, port: str):
        """The output feeding ``port`` of ``spec``'s system; None: the block's input."""
        if predictor is not None:
            if spec.kind == "velocity" and port == "qddot_r_hat":
                return predictor.GetOutputPort("qddot_fed")
            if spec.kind == "force" and spec.name == "observer" and port != "reference":
                return predictor.GetOutputPort(f"{port}_p")
        if port in ("q", "reference"):
            return None
        return signals[port].GetOutputPort(port)

    if predictor is None:
        b.ExportInput(ctrl.get_q_input_port(), "q")
    else:
        b.ExportInput(predictor.GetInputPort("q"), "q")
        b.Connect(predictor.GetOutputPort("q_p"), ctrl.get_q_input_port())
    for spec, system in zip(specs, (vel, force)):
        if spec.kind == "force":
            b.ExportInput(ctrl.get_reference_input_port(), "reference")
        # The registry's inputs, then any a block option added (anti-windup: ``tau``).
        extra = [system.get_input_port(i).get_name() for i in range(system.num_input_ports())]
        for port in spec.inputs + tuple(p for p in extra if p not in spec.inputs):
            if port in EXTERNAL_INPUTS:
                b.ExportInput(system.GetInputPort(port), port)
                continue
            output = feed(spec, port)
            if output is None:
                b.ConnectInput(port, system.GetInputPort(port))
            else:
                b.Connect(output, system.GetInputPort(port))
        for port in spec.outputs:
            b.ExportOutput(system.GetOutputPort(port), port)
    b.ExportOutput(ctrl.get_tau_output_port(), "tau")
    for port in ("q_hat", "qdot_hat", "qdot_o"):
        b.ExportOutput(vel.GetOutputPort(port), port)
    b.ExportOutput(force.GetOutputPort("lambda_hat"), "lambda_hat")
    b.ExportOutput(force.GetOutputPort("Delta_F_tilde"), "Delta_F_tilde")
    b.ExportOutput(ctrl.get_qddot_r_hat_output_port(), "qddot_r_hat")
    diagram = b.Build()
    diagram.set_name(f"{name}_control")
    return diagram, vel, force, ctrl


class GraspWarning(UserWarning):
    """Two controllers of one builder whose pads pass each other: each arm's squeeze (a
    positive ``λ`` pushes its end effector along its inward normal ``−N_1``) would push away
    from the other's contact point, a pull on the object (:func:`AddCooperativeController`)."""


#: Each builder's controllers so far: ``(name, c, −N_1)`` (see :func:`_check_opposed`).
_GRASPS: "weakref.WeakKeyDictionary[DiagramBuilder, list]" = weakref.WeakKeyDictionary()


def _check_opposed(builder: DiagramBuilder, name: str, model: ArmModel) -> None:
    """Warn (:class:`GraspWarning`, one line naming both arms) when this arm's contact point
    ``c_i`` and another controller's ``c_j`` of the same builder are not on each other's
    inward side: a squeeze pushes arm ``i``'s end effector along :math:`ν_i = -N_{i,1}`,
    towards the object, which lies between the pads only if ``(c_j − c_i)·ν_i ≥ 0`` and
    ``(c_i − c_j)·ν_j ≥ 0`` (equal to 0: both pads at one point, a zero-width object)."""
    inward = -np.asarray(model.N[0], dtype=float)
    c = np.asarray(model.c, dtype=float)
    grasps = _GRASPS.setdefault(builder, [])
    for other, c_o, inward_o in grasps:
        gap = c_o - c
        if float(gap @ inward) < 0.0 or float(-gap @ inward_o) < 0.0:
            warnings.warn(GraspWarning(
                f"{name} and {other}: their pads pass each other (each contact point is not on "
                f"the other's inward side along the normals), so a squeeze λ > 0 pulls the "
                f"object apart; check normals and contact_point"), stacklevel=3)
    grasps.append((name, c, inward))


@dataclass
class ControllerHandles:
    """What :func:`AddCooperativeController` added: the block, its systems and its ports.

    Attributes
    ----------
    system : Diagram
        The control block ``<name>_control``.
    law : FingerLaw
        The robot's law (its model, gains, reference layout ``law.layout``).
    velocity_source, force_source, controller : LeafSystem
        The block's three systems.
    reference_input : InputPort
        ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:class:`~drake_coop.control.reference_layout.ReferenceLayout`):
        the one input the user must connect.
    q_input : InputPort
        The measured ``q`` (already connected).
    tau_output : OutputPort
        The torque ``τ(k)``, held over :math:`[t_k, t_{k+1})`.
    q_hat_output, qdot_hat_output, qdot_o_output : OutputPort
        The velocity source's ``q̂``, ``d/dt q̂``, ``q̇_o`` (for logging).
    lambda_hat_output, Delta_F_tilde_output : OutputPort
        The force source's ``λ̂`` and ``ΔF̃`` (for logging).
    plant : MultibodyPlant
        The simulated plant.
    model_instance : ModelInstanceIndex
        The arm in ``plant``.
    lambda_sensor_input : InputPort or None
        The F/T reading of ``force_source = sensor`` (connected when given).
    q_selector : Demultiplexer or None
        The C++ block taking ``q`` out of the plant's ``[q, v]`` (None when the user gave ``q``).
    """

    system: Diagram
    law: FingerLaw
    velocity_source: object
    force_source: object
    controller: Controller
    reference_input: InputPort
    q_input: InputPort
    tau_output: OutputPort
    q_hat_output: OutputPort
    qdot_hat_output: OutputPort
    qdot_o_output: OutputPort
    lambda_hat_output: OutputPort
    Delta_F_tilde_output: OutputPort
    plant: MultibodyPlant
    model_instance: ModelInstanceIndex
    lambda_sensor_input: InputPort | None = None
    q_selector: Demultiplexer | None = None

    def set_initial_state(self, root_context: Context, q_hat: np.ndarray | None = None,
                          qdot_hat_o: np.ndarray | None = None) -> None:
        """Start the velocity source at ``q̂(0) = q_hat`` (default: the arm's positions in
        the plant's context inside ``root_context``) and ``q̇̂_o(0)`` (default 0).

        Optional: without it ``Simulator.Initialize`` starts the observer at the first
        measured ``q``. Call it after setting the plant's positions and before ``Initialize``.

        Parameters
        ----------
        root_context : Context
            The root (whole diagram's) context.
        q_hat : numpy.ndarray or None
            ``q̂(0)`` (n,), rad; None for the plant's positions of the arm.
        qdot_hat_o : numpy.ndarray or None
            ``q̇̂_o(0)`` (n,), rad/s; None for zero.
        """
        if q_hat is None:
            plant_context = self.plant.GetMyContextFromRoot(root_context)
            q_hat = self.plant.GetPositions(plant_context, self.model_instance)
        source = self.velocity_source
        if isinstance(source, MeasuredVelocity):
            return
        source.set_initial_state(source.GetMyMutableContextFromRoot(root_context),
                                 np.asarray(q_hat, dtype=float), qdot_hat_o)


def MakeArmControllerPlant(model_file: str | Path, plant: MultibodyPlant,
                           model_instance: ModelInstanceIndex) -> MultibodyPlant:
    """The controller's own single-arm plant for one arm of ``plant``.

    The arm's model file is parsed into a new continuous plant and the body the arm's model
    instance welds to the world is welded at the same pose (read from ``plant``'s default
    context), so that ``φ``, ``J_φ`` and gravity are expressed in the simulated world frame.

    Parameters
    ----------
    model_file : str or Path
        The arm's URDF/SDFormat (a file or a ``package://`` URL); a perturbed model gives a
        model-error study.
    plant : MultibodyPlant
        The simulated plant (finalized).
    model_instance : ModelInstanceIndex
        The arm in ``plant``; its base must be welded to the world.

    Returns
    -------
    MultibodyPlant
        Finalized, time step 0.
    """
    base = _base_body(plant, model_instance)
    X_WB = plant.EvalBodyPoseInWorld(plant.CreateDefaultContext(), base)
    return make_arm_controller_plant(model_file, base.name(), X_WB)


def _base_body(plant: MultibodyPlant, model_instance: ModelInstanceIndex):
    """The arm's body welded to the world (``ValueError`` naming ``model_instance`` if none)."""
    world = plant.world_body().index()
    for j in plant.GetJointIndices(model_instance):
        joint = plant.get_joint(j)
        if joint.parent_body().index() == world and joint.num_velocities() == 0:
            return joint.child_body()
    raise ValueError(f"model_instance: {plant.GetModelInstanceName(model_instance)!r} has no "
                     "body welded to the world (weld the arm's base before Finalize)")


def AddCooperativeController(
        builder: DiagramBuilder, plant: MultibodyPlant, model_instance: ModelInstanceIndex, *,
        gains: Gains, period: float, controller_model: str | Path | MultibodyPlant | ArmModel,
        ee_frame: str | Frame | None = None, normals=None, contact_point=None,
        velocity_source: str = "observer", force_source: str = "observer",
        difference_cutoff_hz: float | None = None,
        q: OutputPort | None = None,
        lambda_sensor: OutputPort | None = None, connect_actuation: bool = True,
        name: str | None = None, allow_sampled_output_ports: bool = False,
        pinv_damping: float = 0.0, momentum_torque_limits=None, contact_stiffness=None,
        prediction_horizon: float | None = None, anti_windup_limits=None,
        clock: Clock | None = None, anti_windup_gain: float | None = None
) -> ControllerHandles:
    """Add one arm's observers (15)–(16), (22) and controller (13) to ``builder``.

    The identified Coulomb friction is compensated by passing an
    :class:`~drake_coop.control.arm_model.ArmModel` built with ``coulomb=`` as
    ``controller_model``.

    Parameters
    ----------
    builder : DiagramBuilder
        The user's builder, holding ``plant``.
    plant : MultibodyPlant
        The simulated plant, finalized, with live output ports
        (``plant.SetUseSampledOutputPorts(False)`` before ``Finalize()``).
    model_instance : ModelInstanceIndex
        The arm (``n`` positions, ``n`` velocities, ``n`` actuators; base welded to the world).
    gains : Gains
        The law's gains (:class:`~drake_coop.control.Gains`): ``K_R`` has ``n``
        entries, ``xi_matrix`` (if any) is ``m × m`` SPD, ``momentum_gain`` the ``K_O`` of
        ``force_source = "momentum"`` (``0 < h K_O <= 1``); checked here, by name.
    period : float
        Sampling time ``h`` (s), between 1e-5 and 1 s; for a discrete plant a whole multiple
        of its time step (every tick falls on a plant step).
    controller_model : str, Path, MultibodyPlant or ArmModel
        The controller's own model: the arm's model file (built with
        :func:`MakeArmControllerPlant`), a finalized single-arm plant welded as the arm is, or
        an :class:`~drake_coop.control.arm_model.ArmModel` (which carries its own frame,
        normals and contact point: then leave ``ee_frame``, ``normals``, ``contact_point``
        unset).
    ee_frame : str or Frame
        The end-effector frame (its origin is ``x(q)`` of (2)); a name or a frame of ``plant``.
    normals : array_like, shape (m, 3) or (3,)
        The object's outward normals at the contact (``m = 1..3`` independent rows):
        ``φ(q) = N (x(q) − c)``; ``λ > 0`` pushes the end effector outwards (a squeeze).
    contact_point : array_like, shape (3,)
        ``c`` of (2), in the world frame: where the end-effector point ``x(q)`` is when the
        contact *just touches* (zero force). On a rigid surface ``φ = 0`` holds under any
        squeeze. On a compliant one, the contact carries ``λ`` only once pressed in by its
        compression ``δ(λ)``: with ``c`` on the undeformed surface and no
        ``contact_stiffness``, the term ``−β Δp`` of (4) pulls the end effector back out of
        that compression and the squeeze lags ``λ_d`` (the shipped ``contact`` pads, 1.4 mm at
        32 N: 3.1 N RMS behind); a point placed 1 mm inside instead makes the arm push to a
        fixed depth whatever ``λ_d`` asks. Keep ``c`` on the undeformed surface and pass
        ``contact_stiffness``.
    contact_stiffness : ContactStiffness, optional
        The compliant contact's law ``λ = a δᵖ``
        (:class:`~drake_coop.control.object.ContactStiffness`): the law then holds
        ``Δp = φ(q) + δ(λ_d)`` at zero (the reference offset ``p_d = −δ(λ_d)`` of (4)), so the
        pad sits where the contact carries ``λ_d``. ``λ̂`` still estimates the normal force
        through the arm's dynamics (22); on a compliant contact it is the force of the pad's
        pressure patch along the normal, not a position-derived quantity. Default None: the
        paper's ``p_d = 0`` (rigid surface).
    velocity_source : {"observer", "measured", "difference"}
        The paper's observer (default) or a comparison baseline
        (:mod:`drake_coop.control.sources`); ``measured`` reads the plant's velocities.
    force_source : {"observer", "sensor", "none", "momentum"}
        The paper's observer (default), an F/T reading (``lambda_sensor``), none, or the
        generalized-momentum observer.
    difference_cutoff_hz : float, optional
        Low-pass cutoff of ``velocity_source = "difference"``.
    q : OutputPort, optional
        The measured positions (the user's own encoder model); default: the plant's exact
        ``q`` through a C++ ``Demultiplexer``.
    lambda_sensor : OutputPort, optional
        The F/T reading for ``force_source = "sensor"`` (else the input is left to connect).
    connect_actuation : bool
        Connect ``tau`` to ``plant.get_actuation_input_port(model_instance)`` (default); False
        leaves it to the user (actuator models, delays).
    name : str, optional
        Prefix of the systems' names (default: the model instance's name).
    allow_sampled_output_ports : bool
        Accept a plant with sampled output ports (a one-step-late ``q``; not the paper's
        timing).
    pinv_damping : float
        ``μ`` of the damped pseudo-inverse near singular postures (0, the paper's exact
        ``J⁺``, by default; :class:`~drake_coop.control.finger.FingerLaw`).
    momentum_torque_limits : array_like, optional
        ``force_source = "momentum"``: the actuators' torque limits, so the momentum observer
        integrates the applied (saturated) torque (see :func:`build_control_block`).
    prediction_horizon : float, optional
        Delay compensation over this horizon (s, ``0 < p <= period``; see
        :func:`build_control_block`). None (default): off.
    anti_windup_limits : array_like, optional
        ``force_source = "momentum"`` or ``"sensor"``: the arm's torque limits, so the force
        integral (6) is not integrated while the commanded torque exceeds them (opt-in; see
        :func:`build_control_block`). None (default): the paper's (6).
    anti_windup_gain : float, optional
        With ``anti_windup_limits``: back-calculation at this tracking rate (1/s; see
        :func:`build_control_block`). None (default): conditional integration.
    clock : Clock or None
        The controller's own clock (phase and rate against the plant's time,
        :class:`~drake_coop.control.timing.Clock`): the block's periodic updates tick on it
        (see :func:`build_control_block`). None (default): the run's grid.

    Returns
    -------
    ControllerHandles
        The block, its systems and ports, and ``set_initial_state``.

    Raises
    ------
    TypeError
        An argument of the wrong type (a string for a number, a dict for ``gains``), naming it.
    ValueError
        One line naming the argument at fault; also for a second controller on an arm whose
        actuation input is already connected, or a ``name`` already used in ``builder``.

    Warns
    -----
    GraspWarning
        This arm's pad and another controller's of the same ``builder`` pass each other (the
        other's contact point is not on this one's inward side ``−N_1``, or the reverse): a
        squeeze would pull the object apart.
    """
    if not isinstance(builder, DiagramBuilder):
        raise TypeError(f"builder: a DiagramBuilder is required (got {type(builder).__name__})")
    if not isinstance(plant, MultibodyPlant) or not plant.is_finalized():
        raise ValueError("plant: a finalized MultibodyPlant is required (call Finalize() "
                         "before AddCooperativeController)")
    if plant.has_sampled_output_ports() and not allow_sampled_output_ports:
        raise ValueError("plant: its output ports are sampled (Drake's default): call "
                         "plant.SetUseSampledOutputPorts(False) before Finalize() so that "
                         "the observers read q(t_k), or pass allow_sampled_output_ports=True")
    if not isinstance(model_instance, ModelInstanceIndex) or not plant.HasModelInstanceNamed(
            plant.GetModelInstanceName(model_instance)):
        raise ValueError("model_instance: a model instance of plant is required")
    check_period(period, plant.time_step() if plant.time_step() > 0 else None)
    _check_sources(velocity_source, force_source, difference_cutoff_hz)
    for arg, port in (("q", q), ("lambda_sensor", lambda_sensor)):
        if port is not None and not isinstance(port, OutputPort):
            raise TypeError(f"{arg}: an OutputPort is required (got {type(port).__name__})")
    if lambda_sensor is not None and "lambda_sensor" not in source("force", force_source).inputs:
        readers = " or ".join(f"force_source={s.name!r}" for s in SOURCES
                              if s.kind == "force" and "lambda_sensor" in s.inputs)
        raise ValueError(f"lambda_sensor: only for {readers} (got "
                         f"force_source={force_source!r})")
    arm_name = plant.GetModelInstanceName(model_instance)
    name = arm_name if name is None else name
    if not isinstance(name, str) or not name:
        raise TypeError(f"name: a non-empty string is required (got {name!r})")
    if connect_actuation and builder.IsConnectedOrExported(
            plant.get_actuation_input_port(model_instance)):
        raise ValueError(f"model_instance: the arm {arm_name!r} already has its actuation "
                         "input connected (a second controller on one arm?); pass "
                         "connect_actuation=False to wire tau yourself")
    if any(system.get_name() == f"{name}_control" for system in builder.GetSystems()):
        raise ValueError(f"name: {name!r} is already used in this builder (a second "
                         "controller on one arm?); give each controller its own name")

    if isinstance(controller_model, ArmModel):
        if ee_frame is not None or normals is not None or contact_point is not None:
            raise ValueError("controller_model: an ArmModel carries its own ee_frame, normals "
                             "and contact_point; leave those arguments unset")
        model = controller_model
    else:
        if ee_frame is None or normals is None or contact_point is None:
            raise ValueError("ee_frame, normals, contact_point: all three are required "
                             "(the end effector and the constraint (2))")
        if not isinstance(ee_frame, (str, Frame)):
            raise TypeError(f"ee_frame: a frame name or a Frame is required "
                            f"(got {type(ee_frame).__name__})")
        frame_name = ee_frame.name() if isinstance(ee_frame, Frame) else ee_frame
        if not plant.HasFrameNamed(frame_name, model_instance):
            raise ValueError(f"ee_frame: the arm {plant.GetModelInstanceName(model_instance)!r}"
                             f" has no frame named {frame_name!r}")
        if isinstance(controller_model, MultibodyPlant):
            arm_plant = controller_model
        elif isinstance(controller_model, (str, Path)):
            text = str(controller_model)
            if "://" not in text and not Path(text).is_file():
                raise ValueError(f"controller_model: no model file {text!r}")
            try:
                arm_plant = MakeArmControllerPlant(controller_model, plant, model_instance)
            except RuntimeError as exc:            # Drake's parser: one line, naming the file
                raise ValueError(f"controller_model: {text!r} cannot be parsed "
                                 f"({' '.join(str(exc).split())[:200]})") from None
        else:
            raise ValueError("controller_model: a model file, a single-arm MultibodyPlant or "
                             f"an ArmModel is required (got {type(controller_model).__name__})")
        model = ArmModel.from_plant(arm_plant, frame_name, normals, contact_point)
    n = plant.num_positions(model_instance)
    if model.n != n or plant.num_velocities(model_instance) != n:
        raise ValueError(f"controller_model: it has {model.n} joints, the arm "
                         f"{plant.GetModelInstanceName(model_instance)!r} {n} positions and "
                         f"{plant.num_velocities(model_instance)} velocities")
    if connect_actuation and plant.num_actuated_dofs(model_instance) != n:
        raise ValueError(f"model_instance: the arm has {plant.num_actuated_dofs(model_instance)} "
                         f"actuators for {n} joints; actuate every joint or pass "
                         "connect_actuation=False")
    if q is not None and q.size() != n:
        raise ValueError(f"q: an output port of size {n} is required (got {q.size()})")
    if lambda_sensor is not None and lambda_sensor.size() != model.m:
        raise ValueError(f"lambda_sensor: an output port of size m = {model.m} is required "
                         f"(got {lambda_sensor.size()})")
    law = FingerLaw(model, gains, contact_stiffness, pinv_damping=pinv_damping)
    block, vel, force, ctrl = build_control_block(name, law, period, velocity_source,
                                                  force_source, difference_cutoff_hz,
                                                  momentum_torque_limits, prediction_horizon,
                                                  anti_windup_limits,
                                                  clock, anti_windup_gain)
    try:
        selector, lambda_in = _wire(builder, plant, model_instance, block, name, q,
                                    lambda_sensor, connect_actuation)
    except (RuntimeError, SystemExit) as exc:   # Drake's wiring errors, never a SystemExit
        raise ValueError(f"model_instance: wiring the controller of the arm {arm_name!r} "
                         f"failed ({' '.join(str(exc).split())[:200]})") from None
    _check_opposed(builder, name, model)
    return ControllerHandles(
        system=block, law=law, velocity_source=vel, force_source=force, controller=ctrl,
        reference_input=block.GetInputPort("reference"), q_input=block.GetInputPort("q"),
        tau_output=block.GetOutputPort("tau"), q_hat_output=block.GetOutputPort("q_hat"),
        qdot_hat_output=block.GetOutputPort("qdot_hat"),
        qdot_o_output=block.GetOutputPort("qdot_o"),
        lambda_hat_output=block.GetOutputPort("lambda_hat"),
        Delta_F_tilde_output=block.GetOutputPort("Delta_F_tilde"),
        plant=plant, model_instance=model_instance, lambda_sensor_input=lambda_in,
        q_selector=selector)


def _wire(builder, plant, model_instance, block, name, q, lambda_sensor, connect_actuation):
    """Add ``block`` to ``builder`` and connect it to ``plant``; returns the ``q`` selector
    (or None) and the ``lambda_sensor`` input (or None)."""
    n = plant.num_positions(model_instance)
    builder.AddSystem(block)
    state = plant.get_state_output_port(model_instance)
    selector = None
    if q is None:
        selector = builder.AddNamedSystem(f"{name}_q_selector",
                                          Demultiplexer([n, plant.num_velocities(model_instance)]))
        builder.Connect(state, selector.get_input_port(0))
        q = selector.get_output_port(0)
    builder.Connect(q, block.GetInputPort("q"))
    if block.HasInputPort("state"):          # a source reading the plant's velocities
        builder.Connect(state, block.GetInputPort("state"))
    lambda_in = None
    if block.HasInputPort("lambda_sensor"):  # a source reading an F/T sensor
        lambda_in = block.GetInputPort("lambda_sensor")
        if lambda_sensor is not None:
            builder.Connect(lambda_sensor, lambda_in)
    if connect_actuation:
        builder.Connect(block.GetOutputPort("tau"),
                        plant.get_actuation_input_port(model_instance))
    return selector, lambda_in
