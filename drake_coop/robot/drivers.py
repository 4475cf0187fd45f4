"""The experiment split at the robot's cable: the controller side and a simulated driver,
joined only by the driver's LCM messages.

Controller side (:func:`add_controller_side`), per arm::

    status channel ─▶ LcmSubscriberSystem ─▶ CheckedStatusReceiver ─ position_measured, status
                     (the raw bytes)           (robot/status.py)                  ─▶ Watchdog
    Watchdog ─ q_checked ─▶ AddCooperativeController(q, connect_actuation=False) ─ tau ─▶ Watchdog
    reference ─▶ AddCooperativeController
    Watchdog ─ tau_latched ─▶ WireCommand (τ − g(q) for a robot that adds g; utime in the
                              driver's time base) ─▶ LcmPublisherSystem ─▶ command channel

The control blocks read the driver's measured position only, never its velocity or torque
(the paper's premise: no tachometer, no force sensor). The status's bytes are checked before
anything reaches the controller (:mod:`drake_coop.robot.status`: type, size, joint count,
finite positions); the watchdog clips every torque to the scenario's torque limits, else the
URDF's effort limits, and checks each reading's jump against the URDF's velocity limits. The
command is published once per tick, :data:`COMMAND_OFFSET` after ``t_k`` (after the tick's
updates): before the first valid status, and once tripped, it is the safe command.

Simulated driver (:func:`add_driver_side`), per arm, on the scenario's cooperative plant::

    command channel ─▶ LcmSubscriberSystem ─▶ TorqueDriver ─ tau_applied ─▶ plant
    plant ─ [q, v] ─▶ TorqueDriver ─▶ status channel (published every driver cycle)

:class:`~drake_coop.robot.torque_driver.TorqueDriver` applies the newest command as a real
driver does, by the arm's conventions: held until the next one or its expiry by ``utime``
against the driver's clock, the robot's ``g(q)`` added where the robot adds it, gravity
compensation and damping before the arm's own first command and after an expiry.

Timing in one Diagram on one ``DrakeLcm("memq://")`` (the messages are pumped by
``LcmInterfaceSystem`` when the Simulator asks for its next event, and latched by the
subscriber in a zero-length step at that instant, after the updates already due there): the
driver publishes the status of its cycle at ``t`` a µs ahead
(:data:`~drake_coop.robot.torque_driver.STATUS_LEAD`, stamped ``t``), so it is latched before
the tick at ``t_k`` and holds the state before the plant's update at ``t_k`` however ``k h``,
the cycle's ``c·1 ms`` and the plant's ``j Δt`` round; the tick at ``t_k`` reads ``q(t_k)``,
and the command of ``t_k`` is
applied from the driver's next cycle, ``t_k + 1 ms``: the cable costs one driver cycle
(checked: the lockstep run over two processes, which feeds each tick the status of its own
cycle, gives the same doubles, :mod:`drake_coop.robot.lockstep`).

Each arm's driver (:class:`~drake_coop.robot.driver_spec.DriverSpec`, resolved from the
scenario by :func:`~drake_coop.robot.driver_spec.driver_specs`) and the messages' helpers are
in :mod:`drake_coop.robot.driver_spec` (their names are also importable from here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.lcm import DrakeLcm
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import DiagramBuilder, OutputPort, TriggerType
from pydrake.systems.lcm import LcmInterfaceSystem, LcmPublisherSystem, LcmSubscriberSystem
from pydrake.systems.primitives import PassThrough, TrajectorySource

from drake import lcmt_panda_command
from drake_coop.control.block import AddCooperativeController, ControllerHandles
from drake_coop.control.deprecation import moved
from drake_coop.control.watchdog import Watchdog
from drake_coop.control.params import checked_period
from drake_coop.experiment.object_blocks import ESTIMATOR_TICKS, add_object_blocks, couple_samples
from drake_coop.experiment.plan import RunPlan
from drake_coop.plant.cooperative import CoopPlant, build_plant
from drake_coop.plant.model_error import controller_arm_model
from drake_coop.robot.driver_spec import DriverSpec, SharedPandaCommand, driver_specs
from drake_coop.robot.status import CheckedStatusReceiver, RawMessage
from drake_coop.robot.torque_driver import FRANKA_LOW_PASS_HZ, DriverClock, TorqueDriver
from drake_coop.robot.wire import WireCommand
from drake_coop.scenario.schema import ScenarioError

#: Names this module no longer holds (found here until the removal date of
#: :mod:`drake_coop.control.deprecation`).
_MOVED = dict.fromkeys(("safe_command_message", "shared_message_type"),
                       "drake_coop.robot.driver_spec")

#: The command of tick ``k`` is published at ``t_k + COMMAND_OFFSET`` (simulated time): after
#: the tick's updates, off the driver's 1 ms grid.
COMMAND_OFFSET = 1e-4


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
    command_sender : WireCommand
        The command encoder (the wire's torque and stamp).
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
    command_sender: WireCommand
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
    driver : TorqueDriver
        The driver: the torque on the arm, the status.
    """

    spec: DriverSpec
    command_subscriber: LcmSubscriberSystem
    driver: TorqueDriver


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
    clock : DriverClock
        The drivers' clock.
    keep : list
        Objects kept alive with the systems (the arms' models).
    """

    coop: CoopPlant
    arms: list[ArmDriver]
    clock: DriverClock | None = None
    keep: list = field(default_factory=list, repr=False)

    def fault(self, context) -> str:
        """The first emulated driver's stop (one line), or ``''``.

        Parameters
        ----------
        context : Context
            The root context.

        Returns
        -------
        str
            The reason, or ``''``.
        """
        for arm in self.arms:
            reason = arm.driver.fault(arm.driver.GetMyContextFromRoot(context))
            if reason:
                return reason
        return ""


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


def add_controller_side(builder: DiagramBuilder, plan: RunPlan, lcm: DrakeLcm,
                        specs: list[DriverSpec] | None = None, *,
                        status_input: str = "subscriber",
                        robots: list[str] | None = None,
                        clock: DriverClock | None = None) -> ControllerSide:
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
    the tick) as the driver reads it (:class:`~drake_coop.robot.wire.WireCommand`: minus the
    controller model's ``g(q)`` for a robot that adds gravity itself; stamped by ``clock``
    in the driver's time base, the Diagram's time for ``time_base: run``).

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
    plan : RunPlan
        The run's plan (its scenario, resolved arms and references).
    lcm : DrakeLcm
        The LCM connection.
    specs : list of DriverSpec or None
        The drivers; None resolves them here.
    status_input : str
        ``subscriber`` or ``loop``.
    robots : list of str or None
        The arms to add; None for all.
    clock : DriverClock or None
        The command's stamp for ``time_base: epoch`` (default: the wall clock).

    Returns
    -------
    ControllerSide
        Each served arm's systems (control block, watchdog, LCM) and the models' plant.

    Raises
    ------
    ScenarioError
        An arm with no finite torque limit anywhere (``robots[i].driver.torque_limits``).
    """
    scenario = plan.scenario
    model_builder = DiagramBuilder()
    coop = build_plant(model_builder, plan)
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
    trajectories = [resolved.reference for resolved in plan.robots]
    estimator_h = (checked_period(ESTIMATOR_TICKS * plan.h)
                   if plan.object is not None and plan.object.estimated else None)
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
            anti_windup_limits=spec.torque_limits if robot.anti_windup else None,
            anti_windup_gain=robot.anti_windup_gain,
            contact_stiffness=resolved.stiffness,
            q=q, connect_actuation=False, name=name)
        ref = builder.AddNamedSystem(f"{name}_reference", TrajectorySource(trajectories[i]))
        builder.Connect(ref.get_output_port(), block.reference_input)
        tau = block.tau_output
        if plan.object is not None:
            t_ref = np.asarray(trajectories[i].get_segment_times())
            couple = (couple_samples(plan, i, t_ref) if plan.uses_couple
                      else None)
            tau = add_object_blocks(builder, resolved, plan.h, q, ref.get_output_port(),
                                    block.system, t_ref, couple,
                                    estimator_period=estimator_h).tau
        builder.Connect(tau, watchdog.get_tau_input_port())
        builder.Connect(block.lambda_hat_output, watchdog.get_lambda_hat_input_port())
        stamp = None
        if spec.time_base == "epoch":
            stamp = (clock if clock is not None else DriverClock("epoch", wall=True)).utime
        sender = builder.AddNamedSystem(f"{name}_command_sender",
                                        WireCommand(spec, model.g, stamp))
        builder.Connect(watchdog.get_tau_latched_output_port(), sender.get_input_port(0))
        builder.Connect(q, sender.get_input_port(1))
        builder.Connect(watchdog.get_tripped_output_port(), sender.get_input_port(2))
        if position is not None:
            publisher = LcmPublisherSystem.Make(
                spec.command_channel, lcmt_panda_command, lcm,
                publish_triggers={TriggerType.kForced})
        else:
            publisher = LcmPublisherSystem.Make(
                spec.command_channel, lcmt_panda_command, lcm, publish_period=plan.h,
                publish_offset=COMMAND_OFFSET)
        publisher = builder.AddNamedSystem(f"{name}_command_publisher", publisher)
        builder.Connect(sender.get_output_port(), publisher.get_input_port())
        arms.append(ArmController(spec=spec, block=block, watchdog=watchdog,
                                  status_subscriber=status_sub,
                                  status_receiver=receiver, command_sender=sender,
                                  command_publisher=publisher, hold_torque=model.g,
                                  position_input=position, tau=tau))
    return ControllerSide(arms=arms, model_plant=coop, keep=[model_builder])


def add_driver_side(builder: DiagramBuilder, plan: RunPlan, lcm: DrakeLcm,
                    specs: list[DriverSpec] | None = None, *, clock: DriverClock | None = None,
                    emulate: str | None = None,
                    low_pass_hz: float = FRANKA_LOW_PASS_HZ) -> DriverSide:
    """Add the scenario's cooperative plant (on the run's time grid) and each arm's simulated
    driver to ``builder``.

    Parameters
    ----------
    builder : DiagramBuilder
        The driver's builder.
    plan : RunPlan
        The run's plan (its scenario, plant step and resolved arms).
    lcm : DrakeLcm
        The LCM connection.
    specs : list of DriverSpec or None
        The drivers; None resolves them here.
    clock : DriverClock or None
        The drivers' clock (default: a simulated epoch clock from this second).
    emulate : str or None
        ``drake-franka-driver``: emulate that driver
        (:class:`~drake_coop.robot.torque_driver.TorqueDriver`); None: the plain simulated
        driver.
    low_pass_hz : float
        The emulation's torque cutoff, Hz (drake-franka-driver's ``--low_pass_freq``).

    Returns
    -------
    DriverSide
        The plant and each arm's simulated driver on it.

    Raises
    ------
    ValueError
        ``emulate`` with an arm of other than 7 joints (one line naming the robot).
    """
    scenario = plan.scenario
    coop = build_plant(builder, plan)
    plant = coop.plant
    joints = [plant.num_positions(a.instance) for a in coop.arms]
    specs = specs if specs is not None else driver_specs(scenario, joints)
    arms, keep = [], []
    for handles, robot, spec in zip(coop.arms, scenario.robots, specs):
        name, n = robot.name, spec.n
        arm_clock = (clock if clock is not None and spec.time_base == "epoch"
                     else DriverClock(spec.time_base))
        model = controller_arm_model(handles.arm, None)      # the robot's own, exact
        cmd_sub = builder.AddNamedSystem(f"{name}_command_subscriber", LcmSubscriberSystem.Make(
            spec.command_channel, SharedPandaCommand, lcm))
        driver = builder.AddNamedSystem(f"{name}_driver", TorqueDriver(
            spec, arm_clock, lcm, model=model, emulate=emulate, low_pass_hz=low_pass_hz))
        # the robot's g(q): C++ gravity compensation on the arm's own model (kept alive)
        gravity = builder.AddNamedSystem(f"{name}_robot_gravity", InverseDynamics(
            model.plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation))
        keep.append(model)
        state = plant.get_state_output_port(handles.instance)
        builder.Connect(cmd_sub.get_output_port(), driver.get_input_port(0))
        builder.Connect(state, driver.get_input_port(1))
        builder.Connect(state, gravity.get_input_port(0))
        builder.Connect(gravity.get_output_port(0), driver.get_input_port(2))
        builder.Connect(driver.get_output_port(0), plant.get_actuation_input_port(handles.instance))
        arms.append(ArmDriver(spec=spec, command_subscriber=cmd_sub, driver=driver))
    return DriverSide(coop=coop, arms=arms, clock=clock, keep=keep)


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
