"""The experiment split at the robot's cable: the controller side and a simulated driver,
joined only by the driver's LCM messages.

Controller side (:func:`add_controller_side`), per arm::

    status channel ─▶ LcmSubscriberSystem ─▶ CheckedStatusReceiver ─ position_measured, status
                     (the raw bytes)           (robot/status.py)                  ─▶ Watchdog
    Watchdog ─ q_checked ─▶ AddCooperativeController(q, connect_actuation=False) ─ tau ─▶ Watchdog
    reference ─▶ AddCooperativeController
    Watchdog ─ tau_safe ─▶ PandaCommandSender (torque mode) ─▶ LcmPublisherSystem ─▶ command channel

The control blocks read the driver's measured position only, never its velocity or torque
(the paper's premise: no tachometer, no force sensor). The status's bytes are checked before
anything reaches the controller (:mod:`drake_coop.robot.status`: type, size, joint count,
finite positions); the watchdog clips every torque to the scenario's torque limits, else the
URDF's effort limits, and checks each reading's jump against the URDF's velocity limits. The
command is published once per tick, :data:`COMMAND_OFFSET` after ``t_k`` (after the tick's
updates): before the first valid status, and once tripped, it is the safe command.

Simulated driver (:func:`add_driver_side`), per arm, on the scenario's cooperative plant::

    command channel ─▶ LcmSubscriberSystem ─▶ PandaCommandReceiver ─ torque ─▶ CommandHold ─▶ plant
    plant ─ [q, v] ─▶ PandaStatusSender ─▶ LcmPublisherSystem (every driver cycle) ─▶ status channel

:class:`CommandHold` applies the newest command as a real driver does: held until the next
one, clipped to the driver's torque limits, zero torque when it is older than
``command_timeout`` or before the first one, never a non-finite value.

Timing in one Diagram on one ``DrakeLcm("memq://")`` (the messages are pumped by
``LcmInterfaceSystem`` when the Simulator asks for its next event): the status published at
``t`` reaches the controller after that instant's updates, so the tick at ``t_k`` reads the
status of the driver cycle before (``q(t_k − 1 ms)`` at 1 kHz), and the command of ``t_k``
is applied from the driver's next cycle, ``t_k + 1 ms``: the cable costs one driver cycle each
way.

Each arm's driver (:class:`~drake_coop.robot.driver_spec.DriverSpec`, resolved from the
scenario by :func:`~drake_coop.robot.driver_spec.driver_specs`) and the messages' helpers are
in :mod:`drake_coop.robot.driver_spec` (their names are also importable from here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcm
from pydrake.manipulation import (
    PandaCommandReceiver,
    PandaCommandSender,
    PandaControlMode,
    PandaStatusSender,
)
from pydrake.systems.framework import (
    Context,
    DiagramBuilder,
    LeafSystem,
    OutputPort,
    State,
    TriggerType,
)
from pydrake.systems.lcm import LcmInterfaceSystem, LcmPublisherSystem, LcmSubscriberSystem
from pydrake.systems.primitives import Demultiplexer, PassThrough, TrajectorySource

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.control.block import AddCooperativeController, ControllerHandles
from drake_coop.control.watchdog import Watchdog
from drake_coop.control.params import checked_period
from drake_coop.experiment.object_blocks import ESTIMATOR_TICKS, add_object_blocks, couple_samples
from drake_coop.experiment.plan import RunPlan, time_grid
from drake_coop.experiment.references import reference_trajectory
from drake_coop.plant.cooperative import CoopPlant, build_plant
from drake_coop.plant.model_error import controller_arm_model
from drake_coop.robot.driver_spec import (  # noqa: F401 (re-exported)
    DriverSpec,
    SharedPandaCommand,
    driver_specs,
    safe_command_message,
    shared_message_type,
)
from drake_coop.robot.status import CheckedStatusReceiver, RawMessage
from drake_coop.scenario.schema import Scenario, ScenarioError

#: The command of tick ``k`` is published at ``t_k + COMMAND_OFFSET`` (simulated time): after
#: the tick's updates, off the driver's 1 ms grid.
COMMAND_OFFSET = 1e-4


class CommandHold(LeafSystem):
    """What a torque-mode driver applies: the newest command, held, limited, timed out.

    .. pydrake_system::

        name: CommandHold
        input_ports:
        - tau_commanded
        - command
        output_ports:
        - tau_applied

    At every driver cycle ``t`` (a periodic unrestricted update, so the plant's step at ``t``
    applies it), with ``t_c`` the cycle at which the newest command (its ``utime``) was first
    seen::

        tau_applied = clip(τ_cmd, −τ_max, τ_max)   if a command arrived and t − t_c <= T_out
                      0                            otherwise (and where τ_cmd is not finite)

    Parameters
    ----------
    n : int
        Joints.
    period : float
        The driver's cycle (s).
    timeout : float
        ``T_out`` (s).
    torque_limits : array_like, optional
        ``τ_max`` (N·m); default none.
    offset : float
        The first cycle's time (the driver clock's phase, s); default 0.
    """

    def __init__(self, n: int, period: float, timeout: float, torque_limits=None,
                 offset: float = 0.0):
        super().__init__()
        self._n = n
        self._timeout = float(timeout)
        self._tau_max = (np.full(n, np.inf) if torque_limits is None
                         else np.asarray(torque_limits, dtype=float))
        self._tau = self.DeclareVectorInputPort("tau_commanded", n)
        self._msg = self.DeclareAbstractInputPort("command",
                                                  AbstractValue.Make(lcmt_panda_command()))
        self._applied = self.DeclareDiscreteState(n)
        self._seen = self.DeclareDiscreteState(np.array([0.0, -math.inf]))   # utime, t_c
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, offset, self._update)
        self.DeclareStateOutputPort("tau_applied", self._applied)

    def _update(self, context: Context, state: State) -> None:
        t = context.get_time()
        utime = float(self._msg.Eval(context).utime)
        last, t_c = context.get_discrete_state(self._seen).get_value()
        if utime != last and utime != 0.0:
            last, t_c = utime, t
        state.get_mutable_discrete_state(self._seen).SetFromVector([last, t_c])
        tau = np.zeros(self._n)
        if t - t_c <= self._timeout * (1 + 1e-9):
            tau = np.asarray(self._tau.Eval(context), dtype=float)
            if tau.size != self._n:          # an empty or malformed command: nothing applied
                tau = np.zeros(self._n)
            tau = np.clip(np.where(np.isfinite(tau), tau, 0.0), -self._tau_max, self._tau_max)
        state.get_mutable_discrete_state(self._applied).SetFromVector(tau)


@dataclass
class ArmController:
    """One arm's controller-side systems.

    Attributes
    ----------
    spec : DriverSpec
        Its driver.
    block : ControllerHandles
        Its control block.
    watchdog : Watchdog
        Its watchdog.
    status_subscriber : LcmSubscriberSystem or None
        The status subscriber (None with ``status_input="loop"``).
    status_receiver : CheckedStatusReceiver or None
        The status decoder (None with ``status_input="loop"``).
    command_sender : PandaCommandSender
        The command encoder.
    command_publisher : LcmPublisherSystem
        The command publisher.
    hold_torque : object
        The ``hold`` safe command's torque: the controller model's gravity ``g(q)`` (a
        callable of the last good position).
    position_input : PassThrough or None
        The checked reading's entry with ``status_input="loop"``.
    tau : OutputPort or None
        The torque the watchdog checks and latches: the control block's ``tau``, plus the
        load feedforward's ``τ_ff`` with an object model.
    """

    spec: DriverSpec
    block: ControllerHandles
    watchdog: Watchdog
    status_subscriber: LcmSubscriberSystem | None
    status_receiver: CheckedStatusReceiver | None
    command_sender: PandaCommandSender
    command_publisher: LcmPublisherSystem
    hold_torque: object = None
    #: ``status_input="loop"``: the C++ pass-through whose input the caller sets to the
    #: checked reading (it feeds the watchdog's ``q`` and the control blocks' ``q``).
    position_input: PassThrough | None = None
    #: The torque the watchdog checks and latches (the control block's ``tau``, plus the
    #: load feedforward with an object model).
    tau: OutputPort | None = None


@dataclass
class ArmDriver:
    """One arm's simulated-driver systems.

    Attributes
    ----------
    spec : DriverSpec
        Its driver.
    command_subscriber : LcmSubscriberSystem
        The command subscriber.
    command_receiver : PandaCommandReceiver
        The command decoder.
    hold : CommandHold
        The command's hold (zero torque past ``command_timeout``).
    status_sender : PandaStatusSender
        The status encoder.
    status_publisher : LcmPublisherSystem
        The status publisher (every driver cycle).
    """

    spec: DriverSpec
    command_subscriber: LcmSubscriberSystem
    command_receiver: PandaCommandReceiver
    hold: CommandHold
    status_sender: PandaStatusSender
    status_publisher: LcmPublisherSystem


@dataclass
class ControllerSide:
    """The controller side's systems in a builder (``model_plant``: the plant the control
    blocks take their models and checks from; it is not part of the Diagram).

    Attributes
    ----------
    arms : list of ArmController
        One per arm.
    model_plant : CoopPlant
        The plant the blocks' models come from.
    keep : list
        Objects kept alive with the systems.
    """

    arms: list[ArmController]
    model_plant: CoopPlant
    keep: list = field(default_factory=list, repr=False)


@dataclass
class DriverSide:
    """The simulated driver's plant and per-arm systems in a builder.

    Attributes
    ----------
    coop : CoopPlant
        The plant.
    arms : list of ArmDriver
        One per arm.
    """

    coop: CoopPlant
    arms: list[ArmDriver]


def add_lcm_interface(builder: DiagramBuilder, lcm: DrakeLcm) -> LcmInterfaceSystem:
    """The one ``LcmInterfaceSystem`` that pumps ``lcm``'s messages inside the Simulator's
    steps; add it first.

    Without it, messages reach the subscriber systems when the caller pumps
    (``lcm.HandleSubscriptions``) between ``AdvanceTo`` calls, as ``drake-coop serve`` does.
    Plain Python handlers (``lcm.Subscribe``) must not be pumped inside ``AdvanceTo``: drake
    1.58 releases the GIL there and such a handler crashes the process (drake 1.51 does not).

    Parameters
    ----------
    builder : DiagramBuilder
        The builder.
    lcm : DrakeLcm
        The LCM connection.
    """
    return builder.AddNamedSystem("lcm_interface", LcmInterfaceSystem(lcm))


def urdf_limits(plant, instance) -> tuple[np.ndarray, np.ndarray]:
    """``(effort, velocity)``: the URDF's limits of a model instance's joints, read through
    the plant (its joint actuators' effort limits, in the order of the instance's velocities;
    ``inf`` where none is given).

    Parameters
    ----------
    plant : MultibodyPlant
        A finalized plant.
    instance : ModelInstanceIndex
        The arm's model instance.

    Returns
    -------
    effort : numpy.ndarray
        N·m (N for a prismatic joint), (n,).
    velocity : numpy.ndarray
        rad/s (m/s), (n,).
    """
    effort = plant.GetVelocitiesFromArray(
        instance, plant.MakeActuationMatrix() @ plant.GetEffortUpperLimits())
    velocity = plant.GetVelocitiesFromArray(instance, plant.GetVelocityUpperLimits())
    return np.asarray(effort, dtype=float), np.asarray(velocity, dtype=float)


def add_controller_side(builder: DiagramBuilder, scenario: Scenario, lcm: DrakeLcm,
                        plan: RunPlan, specs: list[DriverSpec] | None = None, *,
                        status_input: str = "subscriber",
                        robots: list[str] | None = None) -> ControllerSide:
    """Add each arm's control block, watchdog and LCM status/command systems to ``builder``.

    ``status_input="subscriber"``: each arm's status arrives through an
    ``LcmSubscriberSystem`` (pumped by an ``LcmInterfaceSystem`` or by the caller) and a
    :class:`CheckedStatusReceiver`, the blocks read the watchdog's ``q_checked``, and the
    command is published periodically, :data:`COMMAND_OFFSET` after each tick.
    ``"loop"``: no subscriber and no receiver system; the caller reads each status's bytes
    (:func:`~drake_coop.robot.status.check_panda_status`, as
    :class:`~drake_coop.robot.serve_loop.ServeLoop` does) and fixes the checked reading on
    ``position_input`` (a C++ ``PassThrough`` feeding the blocks' ``q``) before the tick; the
    watchdog has no event (``Watchdog(..., periodic=False)``): the caller runs its checks
    after the tick's step (:meth:`~drake_coop.control.watchdog.Watchdog.tick`, on the
    status's floats, ``λ̂(k)`` and ``τ(k)``) and publishes the command itself
    (``ForcedPublish`` of the ``command_publisher``, which has no periodic event): no Python
    event for the status or the watchdog in the Simulator's step.

    ``robots``: the names of the arms to add (default all; ``serve --robot``), in the
    scenario's order.

    Either way the command carries the watchdog's ``tau_latched`` (its ``tau_safe`` latched at
    the tick: no Python call to publish it).

    The control blocks are the public
    :func:`~drake_coop.control.block.AddCooperativeController` with ``q`` from the driver's
    ``position_measured`` and ``connect_actuation=False``; their models come from a plant
    built from the scenario in a builder of its own (never simulated), and so do the
    watchdog's limits: each arm's ``spec.torque_limits`` (in the returned
    :class:`ArmController`) is the driver's or the actuators' torque limits, else the URDF's
    effort limits (:func:`urdf_limits`), and its velocity limits the URDF's.

    Parameters
    ----------
    builder : DiagramBuilder
        The controller's builder.
    scenario : Scenario
        The scenario.
    lcm : DrakeLcm
        The LCM connection.
    plan : RunPlan
        The run's plan.
    specs : list of DriverSpec or None
        The drivers; None resolves them here.
    status_input : str
        ``subscriber`` or ``loop``.
    robots : list of str or None
        The arms to add; None for all.

    Returns
    -------
    ControllerSide
        The systems added.

    Raises
    ------
    ScenarioError
        An arm with no finite torque limit anywhere (``robots[i].driver.torque_limits``).
    """
    model_builder = DiagramBuilder()
    coop = build_plant(model_builder, scenario, plan.dt)
    joints = [coop.plant.num_positions(a.instance) for a in coop.arms]
    specs = specs if specs is not None else driver_specs(scenario, joints)
    if status_input not in ("subscriber", "loop"):
        raise ValueError(f"status_input: 'subscriber' or 'loop' (got {status_input!r})")
    guards = scenario.guards
    margin = math.radians(guards.joint_limit_margin_deg)
    if plan.shared:
        raise ScenarioError("object_model.shared: the shared object-state block needs every "
                            "arm's reading in one diagram; not served over the cable")
    # The object model's blocks (object_model: known / estimated), as in the simulated
    # diagram: each arm's load feedforward (and mass estimator) on its own reading.
    trajectories = [reference_trajectory(scenario, i, plan.t_end, plan)
                    for i in range(len(coop.arms))]
    estimator_h = (checked_period(ESTIMATOR_TICKS * plan.h)
                   if scenario.object_model.mode == "estimated" else None)
    arms = []
    for i, (handles, robot, spec) in enumerate(zip(coop.arms, scenario.robots, specs)):
        if robots is not None and robot.name not in robots:
            continue
        resolved = plan.robots[i]
        name, n = robot.name, spec.n
        receiver = status_sub = position = None
        if status_input == "loop":
            position = builder.AddNamedSystem(f"{name}_position", PassThrough(n))
        else:
            receiver = builder.AddNamedSystem(f"{name}_status_receiver",
                                              CheckedStatusReceiver(n))
            status_sub = builder.AddNamedSystem(
                f"{name}_status_subscriber",
                LcmSubscriberSystem.Make(spec.status_channel, RawMessage, lcm))
            builder.Connect(status_sub.get_output_port(), receiver.get_message_input_port())
        model = controller_arm_model(handles.arm, robot.model_error)
        arm = handles.arm
        effort, velocity = urdf_limits(coop.plant, handles.instance)
        limits = spec.torque_limits if spec.torque_limits is not None else effort
        if not np.all(np.isfinite(limits)):
            raise ScenarioError(f"robots[{i}].driver.torque_limits: required, the arm's URDF "
                                "gives no effort limit for every joint")
        spec = replace(spec, torque_limits=np.asarray(limits, dtype=float))
        watchdog = builder.AddNamedSystem(f"{name}_watchdog", Watchdog(
            n, arm.m, plan.h, max_status_age=spec.max_status_age,
            q_min=arm.q_min - margin, q_max=arm.q_max + margin, max_force=guards.max_force,
            torque_limits=spec.torque_limits, velocity_limits=velocity,
            safe_command=spec.safe_command, hold_torque=model.g,
            periodic=status_input != "loop"))
        if position is not None:
            builder.Connect(position.get_output_port(), watchdog.get_q_input_port())
            q = position.get_output_port()
        else:
            builder.Connect(receiver.get_position_measured_output_port(),
                            watchdog.get_q_input_port())
            builder.Connect(receiver.get_status_output_port(), watchdog.get_status_input_port())
            q = watchdog.get_q_checked_output_port()
        block = AddCooperativeController(
            builder, coop.plant, handles.instance, gains=robot.gains, period=plan.h,
            controller_model=model, velocity_source=robot.velocity_source,
            force_source=robot.force_source, difference_cutoff_hz=robot.difference_cutoff_hz,
            prediction_horizon=robot.timing.prediction_horizon,
            contact_stiffness=resolved.stiffness,
            q=q, connect_actuation=False, name=name)
        ref = builder.AddNamedSystem(f"{name}_reference", TrajectorySource(trajectories[i]))
        builder.Connect(ref.get_output_port(), block.reference_input)
        tau = block.tau_output
        if plan.object is not None:
            t_ref = np.asarray(trajectories[i].get_segment_times())
            couple = (couple_samples(plan, i, trajectories, t_ref) if plan.uses_couple
                      else None)
            tau = add_object_blocks(builder, resolved, plan.h, q, ref.get_output_port(),
                                    block.system, t_ref, couple,
                                    estimator_period=estimator_h).tau
        builder.Connect(tau, watchdog.get_tau_input_port())
        builder.Connect(block.lambda_hat_output, watchdog.get_lambda_hat_input_port())
        sender = builder.AddNamedSystem(f"{name}_command_sender",
                                        PandaCommandSender(n, PandaControlMode.kTorque))
        builder.Connect(watchdog.get_tau_latched_output_port(), sender.get_torque_input_port())
        if position is not None:
            publisher = LcmPublisherSystem.Make(
                spec.command_channel, lcmt_panda_command, lcm, use_cpp_serializer=True,
                publish_triggers={TriggerType.kForced})
        else:
            publisher = LcmPublisherSystem.Make(
                spec.command_channel, lcmt_panda_command, lcm, publish_period=plan.h,
                publish_offset=COMMAND_OFFSET, use_cpp_serializer=True)
        publisher = builder.AddNamedSystem(f"{name}_command_publisher", publisher)
        builder.Connect(sender.get_output_port(), publisher.get_input_port())
        arms.append(ArmController(spec=spec, block=block, watchdog=watchdog,
                                  status_subscriber=status_sub,
                                  status_receiver=receiver, command_sender=sender,
                                  command_publisher=publisher, hold_torque=model.g,
                                  position_input=position, tau=tau))
    return ControllerSide(arms=arms, model_plant=coop, keep=[model_builder])


def add_driver_side(builder: DiagramBuilder, scenario: Scenario, lcm: DrakeLcm,
                    specs: list[DriverSpec] | None = None) -> DriverSide:
    """Add the scenario's cooperative plant (on the run's time grid) and each arm's simulated
    driver to ``builder``.

    Parameters
    ----------
    builder : DiagramBuilder
        The driver's builder.
    scenario : Scenario
        The scenario.
    lcm : DrakeLcm
        The LCM connection.
    specs : list of DriverSpec or None
        The drivers; None resolves them here.

    Returns
    -------
    DriverSide
        The systems added.
    """
    coop = build_plant(builder, scenario, time_grid(scenario)[1])
    plant = coop.plant
    joints = [plant.num_positions(a.instance) for a in coop.arms]
    specs = specs if specs is not None else driver_specs(scenario, joints)
    arms = []
    for handles, robot, spec in zip(coop.arms, scenario.robots, specs):
        name, n = robot.name, spec.n
        state = builder.AddNamedSystem(f"{name}_driver_state", Demultiplexer([n, n]))
        builder.Connect(plant.get_state_output_port(handles.instance), state.get_input_port(0))
        cmd_sub = builder.AddNamedSystem(f"{name}_command_subscriber", LcmSubscriberSystem.Make(
            spec.command_channel, lcmt_panda_command, lcm, use_cpp_serializer=True))
        cmd_stamp = builder.AddNamedSystem(f"{name}_command_stamp_subscriber",
                                           LcmSubscriberSystem.Make(spec.command_channel,
                                                                    SharedPandaCommand, lcm))
        receiver = builder.AddNamedSystem(f"{name}_command_receiver",
                                          PandaCommandReceiver(n, PandaControlMode.kTorque))
        builder.Connect(cmd_sub.get_output_port(), receiver.get_message_input_port())
        builder.Connect(state.get_output_port(0), receiver.get_position_measured_input_port())
        # The driver's own clock (phase and drift); the plant still reads the held torque and
        # gives its state on its own step grid, so both act to within one plant step.
        cycle = spec.period * (1.0 + spec.clock_drift)
        hold = builder.AddNamedSystem(f"{name}_command_hold", CommandHold(
            n, cycle, spec.command_timeout, spec.torque_limits, offset=spec.clock_phase))
        builder.Connect(receiver.get_commanded_torque_output_port(), hold.get_input_port(0))
        builder.Connect(cmd_stamp.get_output_port(), hold.get_input_port(1))
        builder.Connect(hold.get_output_port(0), plant.get_actuation_input_port(handles.instance))
        sender = builder.AddNamedSystem(f"{name}_status_sender", PandaStatusSender(n))
        builder.Connect(state.get_output_port(0), sender.get_position_measured_input_port())
        builder.Connect(state.get_output_port(0), sender.get_position_commanded_input_port())
        builder.Connect(state.get_output_port(1), sender.get_velocity_measured_input_port())
        builder.Connect(receiver.get_commanded_torque_output_port(),
                        sender.get_torque_commanded_input_port())
        builder.Connect(hold.get_output_port(0), sender.get_torque_measured_input_port())
        publisher = builder.AddNamedSystem(f"{name}_status_publisher", LcmPublisherSystem.Make(
            spec.status_channel, lcmt_panda_status, lcm, publish_period=cycle,
            publish_offset=spec.clock_phase, use_cpp_serializer=True))
        builder.Connect(sender.get_output_port(), publisher.get_input_port())
        arms.append(ArmDriver(spec=spec, command_subscriber=cmd_sub, command_receiver=receiver,
                              hold=hold,
                              status_sender=sender, status_publisher=publisher))
    return DriverSide(coop=coop, arms=arms)
