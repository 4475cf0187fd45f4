"""The identification experiment driven over the wire: each arm's excitation sent as torque
commands through its driver's LCM messages, and what the wire carried recorded
(:mod:`~drake_coop.identification.recording`).

Before the first command, for every arm (:func:`preflight`; a refusal is one line, and no
command is sent):

* its status: a valid one has arrived (:func:`~drake_coop.robot.status.check_panda_status`),
  the arm is at rest (every joint's ``joint_velocity`` under :data:`REST_SPEED`) and inside
  the URDF's position limits;
* the excitation, designed about that reading (:func:`~drake_coop.identification.setup.
  design_for`), keeps inside the URDF's position and velocity limits and the driver's
  torque limits (the nominal model's torque, :meth:`~drake_coop.identification.excitation.
  ExcitationLimits.violation` with no margin);
* no contact between the arms, or with the stand, object or floor, along all the arms'
  planned motions at once (:func:`~drake_coop.identification.clearance.first_contact`,
  Drake's geometry queries).

Each tick ``k`` (:func:`drive`): the clock brings the driver to ``t_k`` (:class:`Lockstep`, an
in-process simulated driver stepped by the loop; :class:`WallClock`, a driver in another
process, on the wall clock); each arm's newest status is read; the tracking law of the
simulated experiment (:func:`~drake_coop.identification.collect.tracking_law`) gives ``τ(k)``;
the arm's :class:`~drake_coop.control.watchdog.Watchdog` checks the tick (the status's age and
bytes, the joint range, the jumps against the URDF's velocity limits, the torque limits) —
a trip sends every arm its safe command and stops the experiment, one line saying why; the
command is encoded, published and recorded as it was sent. At the end every arm gets its
safe command. A lockstep driver of another process plugs in as a clock with the same two
methods (:class:`WallClock`'s).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from drake_coop.identification.collect import tracking_gains, tracking_law
from drake_coop.identification.recording import WireRecording
from drake_coop.identification.setup import IdentifyInputError, design_for, identification_setup

__all__ = ["REST_SPEED", "Lockstep", "WallClock", "WireRefusal", "drive", "preflight"]

#: An arm is at rest when every joint's reported speed is below this, rad/s.
REST_SPEED = 0.01


class WireRefusal(ValueError):
    """The experiment refused before the first command, or stopped by a watchdog (one line)."""


def _drain(lcm) -> None:
    while lcm.HandleSubscriptions(0) > 0:
        pass


class WallClock:
    """A driver in another process, on the wall clock: :meth:`advance` pumps LCM until
    ``t0 + t`` (``t0``: :meth:`start` plus ``lead``).

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    lead : float
        The wait before tick 0, s.
    """

    lockstep = False

    def __init__(self, lcm, lead: float = 0.05):
        self.lcm = lcm
        self.lead = float(lead)
        self.t0 = math.nan

    def start(self) -> None:
        """Tick 0 is ``lead`` seconds from now."""
        self.t0 = time.perf_counter() + self.lead

    def advance(self, t: float) -> None:
        """Pump LCM until the wall clock reaches ``t0 + t``.

        Parameters
        ----------
        t : float
            The tick's time from the start, s.
        """
        from drake_coop.robot.pacing import pump_until

        pump_until(self.lcm, self.t0 + t)

    def after_command(self) -> None:
        """Deliver what is already there (nothing to step)."""
        self.lcm.HandleSubscriptions(0)


class Lockstep:
    """The scenario's arms simulated behind their drivers' messages in this process, stepped by
    the loop: :meth:`advance` runs the driver to ``t`` (its statuses published at its cycle)
    and delivers the messages; :meth:`after_command` delivers the tick's commands.

    The driver holds each arm's newest command (torque mode, ``lcmt_panda_command``) through
    the actuators of the scenario's truth — saturation at the torque limits and Coulomb
    friction (:func:`~drake_coop.sensing.actuators.add_actuators`) — on the cooperative
    plant (:func:`~drake_coop.plant.cooperative.build_plant`, arms at rest at ``q_d(0)``) and
    publishes ``lcmt_panda_status`` every driver cycle; no ``LcmInterfaceSystem``: messages
    move only when the loop pumps.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its truth).
    lcm : DrakeLcm
        The in-process LCM (``memq://``).
    specs : list of DriverSpec
        The arms' drivers.
    """

    lockstep = True

    def __init__(self, scenario, lcm, specs):
        from pydrake.manipulation import (
            PandaCommandReceiver,
            PandaControlMode,
            PandaStatusSender,
        )
        from pydrake.systems.analysis import Simulator
        from pydrake.systems.framework import DiagramBuilder
        from pydrake.systems.lcm import LcmPublisherSystem, LcmSubscriberSystem
        from pydrake.systems.primitives import Demultiplexer

        from drake import lcmt_panda_command, lcmt_panda_status
        from drake_coop.experiment.plan import plan_run
        from drake_coop.experiment.simulate import rest_posture
        from drake_coop.plant.cooperative import build_plant, initialize_plant_context
        from drake_coop.sensing.actuators import add_actuators

        self.lcm = lcm
        self._publishers = []
        b = DiagramBuilder()
        plan = plan_run(scenario)
        coop = build_plant(b, plan)
        plant = coop.plant
        for handles, robot, spec in zip(coop.arms, scenario.robots, specs):
            name, n = robot.name, spec.n
            state = b.AddNamedSystem(f"{name}_driver_state", Demultiplexer([n, n]))
            b.Connect(plant.get_state_output_port(handles.instance), state.get_input_port(0))
            sub = b.AddNamedSystem(f"{name}_command_subscriber", LcmSubscriberSystem.Make(
                spec.command_channel, lcmt_panda_command, lcm, use_cpp_serializer=True))
            receiver = b.AddNamedSystem(f"{name}_command_receiver",
                                        PandaCommandReceiver(n, PandaControlMode.kTorque))
            b.Connect(sub.get_output_port(), receiver.get_message_input_port())
            b.Connect(state.get_output_port(0), receiver.get_position_measured_input_port())
            limits = robot.actuators.torque_limits
            if limits is None and spec.torque_limits is not None:
                limits = list(spec.torque_limits)
            saturation, applied = add_actuators(b, name, n, limits,
                                                robot.model_error.coulomb_friction,
                                                plant.get_state_output_port(handles.instance))
            b.Connect(receiver.get_commanded_torque_output_port(), saturation.get_input_port())
            b.Connect(applied, plant.get_actuation_input_port(handles.instance))
            sender = b.AddNamedSystem(f"{name}_status_sender", PandaStatusSender(n))
            b.Connect(state.get_output_port(0), sender.get_position_measured_input_port())
            b.Connect(state.get_output_port(0), sender.get_position_commanded_input_port())
            b.Connect(state.get_output_port(1), sender.get_velocity_measured_input_port())
            b.Connect(receiver.get_commanded_torque_output_port(),
                      sender.get_torque_commanded_input_port())
            b.Connect(saturation.get_output_port(), sender.get_torque_measured_input_port())
            pub = b.AddNamedSystem(f"{name}_status_publisher", LcmPublisherSystem.Make(
                spec.status_channel, lcmt_panda_status, lcm, publish_period=spec.period,
                use_cpp_serializer=True))
            b.Connect(sender.get_output_port(), pub.get_input_port())
            self._publishers.append(pub)
        self.diagram = b.Build()
        self.simulator = Simulator(self.diagram)
        context = self.simulator.get_mutable_context()
        rest, z = rest_posture(plan)
        initialize_plant_context(coop, plant.GetMyMutableContextFromRoot(context), rest, z)
        self.coop = coop
        self.simulator.Initialize()

    def start(self) -> None:
        """Brakes on until the first command: every arm's status at rest published now (the
        plant does not move before the loop's first :meth:`advance`)."""
        context = self.simulator.get_context()
        for pub in self._publishers:
            pub.ForcedPublish(pub.GetMyContextFromRoot(context))
        _drain(self.lcm)

    def advance(self, t: float) -> None:
        """Run the driver to ``t`` and deliver its statuses.

        Parameters
        ----------
        t : float
            The tick's time, s.
        """
        if t > self.simulator.get_context().get_time():
            self.simulator.AdvanceTo(t)
        _drain(self.lcm)

    def after_command(self) -> None:
        """Deliver the tick's commands to the driver."""
        _drain(self.lcm)


@dataclass
class _Arm:
    index: int
    spec: object
    setup: object
    excitation: object = None
    kp: np.ndarray = None
    kv: np.ndarray = None
    watchdog: object = None
    context: object = None
    q: np.ndarray = None
    status: tuple = (math.nan, 0.0, 0.0)


def _with_limits(spec, setup):
    """The driver's torque limits, else the URDF's effort limits (as ``serve`` resolves
    them); refused when neither gives a finite limit for every joint."""
    from dataclasses import replace

    if spec.torque_limits is not None:
        return spec
    plant = setup.structure.plant
    effort = {plant.get_joint_actuator(a).joint().name(): plant.get_joint_actuator(a)
              .effort_limit() for a in plant.GetJointActuatorIndices()}
    limits = np.array([effort.get(j, np.inf) for j in setup.structure.joints])
    if not np.all(np.isfinite(limits)):
        raise WireRefusal(f"robots[{setup.index}].driver.torque_limits: required, the arm's "
                          "URDF gives no effort limit for every joint; no command sent")
    return replace(spec, torque_limits=limits)


def _read(data: bytes, n: int):
    from drake import lcmt_panda_status
    from drake_coop.robot.status import check_panda_status

    q, stamp, fault, value = check_panda_status(data, n)
    try:
        v = np.asarray(lcmt_panda_status.decode(data).joint_velocity, float)
    except Exception:
        v = np.full(n, math.nan)
    return q, stamp, fault, value, v


def preflight(scenario, arms: list[_Arm], first: dict[int, bytes], duration: float,
              seed: int, radius: float | None = None) -> None:
    """The checks of the module's docstring, before the first command; designs each arm's
    excitation about its reading.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    arms : list of _Arm
        The arms to excite (their ``excitation``, gains and reading are set here).
    first : dict of int to bytes
        Each arm's newest status.
    duration : float
        The excitation's length, s.
    seed : int
        Seeds the excitations.
    radius : float or None
        The links' capsules' radius (m) of the clearance check; None for
        :data:`~drake_coop.identification.clearance.LINK_RADIUS`.

    Raises
    ------
    WireRefusal
        One line naming the arm and what is wrong.
    """
    from drake_coop.control.watchdog import STATUS_OK
    from drake_coop.identification.clearance import first_contact

    readings = {}
    for arm in arms:
        name, ch = scenario.robots[arm.index].name, arm.spec.status_channel
        where = f"robots[{arm.index}] ({name})"
        data = first.get(arm.index)
        if data is None:
            raise WireRefusal(f"{where}: no status on {ch}; no command sent")
        q, stamp, fault, value, v = _read(data, arm.spec.n)
        if fault != STATUS_OK:
            raise WireRefusal(f"{where}: the status on {ch} is not valid (fault {fault:.0f}, "
                              f"value {value:g}); no command sent")
        if not np.all(np.abs(v) < REST_SPEED):
            raise WireRefusal(f"{where}: the arm is moving ({np.max(np.abs(v)):.3g} rad/s on "
                              f"{ch}, at rest below {REST_SPEED:g}); no command sent")
        lo, hi = arm.setup.arm.q_min, arm.setup.arm.q_max
        if np.any(q < lo) or np.any(q > hi):
            j = int(np.argmax(np.maximum(lo - q, q - hi)))
            raise WireRefusal(f"{where}: joint {j + 1} reads {q[j]:.4g} rad, outside the URDF's "
                              f"limits [{lo[j]:.4g}, {hi[j]:.4g}]; no command sent")
        try:
            arm.excitation = design_for(arm.setup, duration, seed, q0=q, name=name)
        except IdentifyInputError as exc:
            raise WireRefusal(f"{exc} about its reading on {ch}; no command sent") from None
        limits = arm.setup.limits
        if arm.spec.torque_limits is not None:
            limits.torque_limits = np.minimum(limits.torque_limits, arm.spec.torque_limits)
        t = np.linspace(0.0, duration, 400)
        qe, ve, ae = arm.excitation.evaluate(t)
        limits.margin, limits.torque_fraction = 0.0, 1.0
        use = limits.violation(qe, ve, arm.setup.nominal_torque(qe, ve, ae))
        if use > 1.0:
            raise WireRefusal(f"{where}: the excitation leaves the URDF's or the driver's "
                              f"limits (use {use:.3g} of them); no command sent")
        arm.q = q
        arm.status = (stamp, float(fault), value)
        readings[arm.index] = q
    for arm in arms:                      # the torque on the arm would be unknown
        if arm.spec.gravity == "robot_adds":
            raise WireRefusal(
                f"robots[{arm.index}].driver.gravity: robot_adds leaves the torque on the arm "
                "unknown to identification (the robot adds its own g(q)); identify with "
                "driver_subtracts (the driver removes the robot's compensation) or none; "
                "no command sent")
    postures = []
    for i, robot in enumerate(scenario.robots):
        if i in readings:
            postures.append(readings[i])
        elif i in first:                  # an arm not excited: where its status says
            from drake import lcmt_panda_status

            postures.append(np.asarray(lcmt_panda_status.decode(first[i]).joint_position,
                                       float))
        else:
            from drake_coop.experiment.plan import plan_run
            from drake_coop.experiment.simulate import rest_posture

            postures.append(rest_posture(plan_run(scenario))[0][i])
    from drake_coop.identification.clearance import LINK_RADIUS

    contact = first_contact(scenario, {a.index: (lambda t, e=a.excitation: e.evaluate(t)[0])
                                       for a in arms}, postures, duration,
                            radius=LINK_RADIUS if radius is None else radius)
    if contact is not None:
        raise WireRefusal(f"the excitation would bring {contact}; no command sent")


def drive(scenario, robots: list[int], lcm, clock, *, duration: float = 10.0, seed: int = 0,
          specs=None, status_wait: float = 5.0,
          clearance_radius: float | None = None) -> list[WireRecording]:
    """Drive each robot's excitation over the wire and record it (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The scenario (its arms, drivers, nominal models).
    robots : list of int
        The arms to excite (0-based), all at once.
    lcm : DrakeLcm
        The LCM connection (the drivers').
    clock : Lockstep or WallClock
        Brings the drivers to each tick.
    duration : float
        The excitation's length, s.
    seed : int
        Seeds the excitations.
    specs : list of DriverSpec or None
        The drivers (default: the scenario's).
    status_wait : float
        The longest wait for every arm's first status, s (simulated in lockstep).
    clearance_radius : float or None
        The links' capsules' radius of the clearance check, m (None: the default).

    Returns
    -------
    list of WireRecording
        What the wire carried, one recording per excited robot.

    Raises
    ------
    WireRefusal
        A refusal before the first command, or a watchdog's trip (one line).
    """
    from drake_coop.control.watchdog import STATUS_OK, Watchdog
    from drake_coop.experiment.ticks import time_grid
    from drake_coop.robot.driver_spec import driver_specs, safe_command_message
    from drake_coop.scenario.model_check import check_models

    h, _ = time_grid(scenario)
    specs = specs if specs is not None else driver_specs(scenario, check_models(scenario))
    setups = {i: identification_setup(scenario, i) for i in robots}
    arms = [_Arm(index=i, spec=_with_limits(specs[i], setups[i]), setup=setups[i])
            for i in robots]
    newest: dict[int, bytes] = {}
    arrival: dict[int, float] = {}

    def handler(i):
        def handle(data: bytes) -> None:
            newest[i] = bytes(data)
            arrival[i] = time.perf_counter()
        return handle

    for i, spec in enumerate(specs):
        lcm.Subscribe(spec.status_channel, handler(i))
    clock.start()
    waited = 0.0
    while not all(a.index in newest for a in arms) and waited < status_wait:
        waited += 0.01
        if clock.lockstep:
            clock.advance(waited)
        else:
            lcm.HandleSubscriptions(10)
    preflight(scenario, arms, newest, duration, seed, clearance_radius)
    guards = scenario.guards
    for arm in arms:
        plant = arm.setup.structure.plant
        velocity = np.array([plant.GetJointByName(j).velocity_upper_limits()[0]
                             for j in arm.setup.structure.joints])
        velocity = np.where(np.isfinite(velocity) & (velocity > 0), velocity, np.inf)
        margin = math.radians(guards.joint_limit_margin_deg)
        arm.kp, arm.kv = tracking_gains(arm.setup.nominal, arm.excitation.q0)
        arm.watchdog = Watchdog(
            arm.spec.n, arm.setup.arm.m, h, max_status_age=arm.spec.max_status_age,
            q_min=arm.setup.arm.q_min - margin, q_max=arm.setup.arm.q_max + margin,
            max_force=guards.max_force, torque_limits=arm.spec.torque_limits,
            velocity_limits=velocity, safe_command=arm.spec.safe_command,
            hold_torque=arm.setup.nominal.g, periodic=False)
        arm.context = arm.watchdog.CreateDefaultContext()
        arm.watchdog.set_initial_state(arm.context, arm.q)
    steps = int(round(duration / h)) + 1
    rows = {a.index: {k: [] for k in ("t", "q", "tau", "status_utime", "command_utime",
                                      "arrival_s")} for a in arms}
    last_utime = 0
    reason = ""
    offset = waited if clock.lockstep else 0.0     # the driver's time at tick 0
    if not clock.lockstep:
        clock.start()
    for k in range(steps):
        t = k * h
        clock.advance(t + offset)
        for arm in arms:
            data = newest.get(arm.index)
            q, stamp, fault, value, _ = _read(data, arm.spec.n)
            q_prev = arm.q
            if fault == STATUS_OK:
                arm.q = q
            arm.status = (stamp, float(fault), value)
            tau = tracking_law(arm.setup.nominal, arm.excitation, h, arm.kp, arm.kv, k,
                               arm.q, q_prev)
            if arm.watchdog.tick(arm.context, t, arm.status, arm.q.tolist(),
                                 [0.0] * arm.setup.arm.m, tau.tolist()):
                reason = (f"{scenario.robots[arm.index].name}: watchdog at t = {t:.3f} s: "
                          f"{arm.watchdog.reason(arm.context)} on {arm.spec.status_channel}")
                break
            sent = arm.watchdog.get_tau_latched_output_port().Eval(arm.context)
            last_utime = max(last_utime + 1, int(time.time() * 1e6))
            message = safe_command_message(arm.spec, sent, last_utime)
            lcm.Publish(arm.spec.command_channel, message.encode())
            r = rows[arm.index]
            r["t"].append(t)
            r["q"].append(arm.q.copy())
            r["tau"].append(np.asarray(message.joint_torque, float))
            r["status_utime"].append(int(round(stamp * 1e6)) if math.isfinite(stamp) else -1)
            r["command_utime"].append(last_utime)
            r["arrival_s"].append(math.nan if clock.lockstep else arrival[arm.index]
                                  - clock.t0)
        if reason:
            break
        clock.after_command()
    for arm in arms:                  # the safe command last, in every case
        q = arm.watchdog.last_good_position(arm.context)
        tau = (np.zeros(arm.spec.n) if arm.spec.safe_command == "zero_torque"
               else arm.setup.nominal.g(q))
        last_utime = max(last_utime + 1, int(time.time() * 1e6))
        lcm.Publish(arm.spec.command_channel,
                    safe_command_message(arm.spec, tau, last_utime).encode())
    clock.after_command()
    if reason:
        raise WireRefusal(reason + "; safe command sent")
    out = []
    for arm in arms:
        r = rows[arm.index]
        limits = (np.full(arm.spec.n, np.inf) if arm.spec.torque_limits is None
                  else np.asarray(arm.spec.torque_limits, float))
        out.append(WireRecording(
            robot=scenario.robots[arm.index].name, index=arm.index, excitation=arm.excitation,
            t=np.asarray(r["t"]), q=np.asarray(r["q"]), tau=np.asarray(r["tau"]),
            status_utime=np.asarray(r["status_utime"], dtype=np.int64),
            command_utime=np.asarray(r["command_utime"], dtype=np.int64),
            arrival_s=np.asarray(r["arrival_s"], float), h=h, torque_limits=limits,
            source="wire", channels=[arm.spec.status_channel, arm.spec.command_channel]))
    return out
