"""The whole experiment as one Drake Diagram: the paper's block diagram, per robot.

::

    robotN_reference ─┐                  ┌──────────── robotN_control (Diagram) ────────────┐
    (TrajectorySource)├─ reference ─────▶│ robotN_velocity_observer (15)-(16)               │
                      │                  │ robotN_force_observer (22)                        │──tau─▶ plant
    plant ─state─▶ robotN_encoders ─ q ─▶│ robotN_controller (13)                            │
      │            (Encoders, or a C++   └───────────────────────────────────────────────────┘
      │             Demultiplexer when ideal)    tau ─▶ robotN_actuators (Saturation) ─▶ plant
      │                     (robotN_latency between them with a computation delay or jitter)
      ├─ live ground truth (force_source: sensor on a robot in planes or rigid mode; none
      │  mode): state, acceleration, actuation ─▶ wrist_dynamics ─▶ robotN_force_sensor
      │  (none: reaction forces, body poses ─▶ wrist_kinematics)
      │                                   └─ λ ─▶ robotN_ft_sensor (sensor model, logged)
      ├─ contact mode, offline: contact results ─▶ pad_forces ─▶ pad_forces_hold (C++, every
      │  plant step) ─▶ pad_forces_log; F_meas, lambda_meas and lambda_sensor sorted into
      │  ticks after the run (force_source: sensor: hold ─▶ robotN_lambda_last_step ─▶
      │  robotN_ft_sensor)
      └─ otherwise, offline: [state, actuation, acceleration] ─▶ ground_truth_hold_tick
         (t_k), [state, actuation] ─▶ ground_truth_hold_before_tick (t_k − 3Δt/2) (C++
         ZeroOrderHolds) ─▶ ground_truth_log; F_meas, lambda_meas and lambda_sensor computed
         after the run (drake_coop.plant.ground_truth); wrist_forces_at_tick gives F_meas
         during the run to a reader that asks (the Meshcat arrows)
    every logged signal of a robot ─▶ robotN_log_signals (Multiplexer) ─▶ robotN_log

Timing at a tick ``t_k``: the controller latches ``τ(k)`` by an unrestricted update (before
every discrete update, so the plant's step at ``t_k`` applies it); the observers, the
encoders and the ground truth's latch (or the offline ground truth's tick hold) then update
from the same context as the plant's step.
Loggers publish before the tick's updates (see
:func:`~drake_coop.experiment.simulate.collect_logs` for the alignment).

The encoders pass on (quantized, noisy, delayed) joint positions only: with the paper's
observers the control block never sees a velocity or a force. The alternatives of
:mod:`drake_coop.control.sources` replace the observers inside the block: ``measured`` also reads the
plant's state (true velocities), ``sensor`` the F/T sensor model's λ. Each control block is a
sub-Diagram whose inputs are ``q`` and ``reference`` (plus ``state`` / ``lambda_sensor`` for
those alternatives) and whose outputs are ``tau`` and the sources' signals (for logging),
added by the public :func:`~drake_coop.control.block.AddCooperativeController` as in a user's
own diagram (one path).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, OutputPort
from pydrake.systems.primitives import (
    Demultiplexer,
    LogVectorOutput,
    Multiplexer,
    Saturation,
    TrajectorySource,
    VectorLogSink,
    ZeroOrderHold,
)

from drake_coop.control.block import AddCooperativeController
from drake_coop.control.controller import Controller
from drake_coop.control.finger import FingerLaw
from drake_coop.control.object import ObjectStateEstimator
from drake_coop.control.interfaces import ForceSource, VelocitySource
from drake_coop.control.params import checked_period
from drake_coop.control.registry import source
from drake_coop.experiment.object_blocks import (
    ESTIMATOR_TICKS,
    ArmSignals,
    ObjectBlocks,
    add_object_layer,
)
from drake_coop.plant.cooperative import (
    CoopPlant,
    build_plant,
)
from drake_coop.plant.ground_truth import (
    GroundTruthLog,
    PadForceLog,
    add_ground_truth,
    add_pad_force_log,
)
from drake_coop.plant.wrist import ForceSensor, add_force_sensors
from drake_coop.scenario.schema import Scenario
from drake_coop.experiment.plan import RunPlan
from drake_coop.sensing.actuators import add_actuators
from drake_coop.sensing.encoders import Encoders
from drake_coop.sensing.force_sensor import FTModel, FTSensor, add_ft_sensor
from drake_coop.sensing.latency import ActuationDelay


#: The signals each robot logs, in the order of its ``<robot>_log_signals`` Multiplexer's
#: inputs (:class:`RobotLog`); with the offline ground truth, those of
#: :data:`GROUND_TRUTH_KEYS` are left out (computed after the run).
LOG_KEYS = ("q", "q_hat", "reference", "lambda_hat", "Delta_F_tilde", "tau", "tau_cmd",
            "F_meas", "lambda_meas", "lambda_sensor", "qdot_hat", "state")
#: In ``contact`` mode each robot's log also holds ``object_state``, the box's plant state
#: ``[quaternion w x y z, position, ω, v]`` (13).
#: The logged signals the offline ground truth computes after the run
#: (:meth:`~drake_coop.plant.ground_truth.GroundTruthLog.evaluate`).
GROUND_TRUTH_KEYS = ("F_meas", "lambda_meas", "lambda_sensor")
#: The signals a robot logs besides :data:`LOG_KEYS` when the controllers have an object
#: model (``object_model.mode`` known or estimated): the load feedforward ``τ_ff``, the
#: arm's load ``f_i`` and its mass share ``m_i`` (the estimate when estimated).
OBJECT_LOG_KEYS = ("tau_ff", "f_load", "mass_share")


@dataclass
class RobotLog:
    """One robot's logged signals: a C++ :class:`Multiplexer` of every logged port into one
    :class:`VectorLogSink` publishing at every tick (one logger per robot, not one per signal).

    ``slices[key]`` is where a signal sits in the logged vector, ``ports[key]`` its source.

    Attributes
    ----------
    logger : VectorLogSink
        The robot's logger.
    slices : dict of str to slice
        Signal → its rows in the logged vector.
    ports : dict of str to OutputPort
        Signal → its source port.
    """

    logger: VectorLogSink
    slices: dict[str, slice]
    ports: dict[str, OutputPort]

    def raw(self, context: Context) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Sample times ``(K,)`` and each signal's samples ``(width, K)``, as published.

        Parameters
        ----------
        context : Context
            The root context.

        Returns
        -------
        t : numpy.ndarray
            The sample times (K,), s.
        signals : dict of str to numpy.ndarray
            Signal → its samples (width, K).
        """
        log = self.logger.FindLog(context)
        data = log.data()
        return log.sample_times(), {k: data[s] for k, s in self.slices.items()}

    def now(self, context: Context, key: str) -> np.ndarray:
        """The current value of a logged signal's source port.

        Parameters
        ----------
        context : Context
            The root context.
        key : str
            The signal.

        Returns
        -------
        numpy.ndarray
            Its source port's value.
        """
        port = self.ports[key]
        return port.Eval(port.get_system().GetMyContextFromRoot(context))


@dataclass
class RobotSystems:
    """The systems of one robot inside the experiment diagram.

    ``force_sensor`` and ``ft_sensor`` are None with the offline ground truth
    (:attr:`Experiment.ground_truth`): no system computes the wrist force during the run.

    Attributes
    ----------
    name : str
        The robot's name.
    law : FingerLaw
        Its control law (gains, model).
    control : Diagram
        Its control block (:func:`~drake_coop.control.block.AddCooperativeController`).
    velocity_observer : VelocitySource
        Its velocity source.
    force_observer : ForceSource
        Its force source.
    controller : Controller
        Its controller (13).
    force_sensor : ForceSensor or None
        The live ground truth of its wrist force.
    encoders : Encoders or Demultiplexer or None
        Its encoders (a Demultiplexer when ideal).
    ft_sensor : FTSensor or ZeroOrderHold or None
        Its F/T sensor model.
    actuators : Saturation or None
        Its torque limits.
    latency : ActuationDelay or None
        Its computation delay.
    log : RobotLog or None
        Its logger.
    object_blocks : ObjectBlocks or None
        Its object-aware systems.
    """

    name: str
    law: FingerLaw
    control: Diagram
    velocity_observer: VelocitySource
    force_observer: ForceSource
    controller: Controller
    force_sensor: ForceSensor | None
    encoders: Encoders | Demultiplexer | None = None
    ft_sensor: FTSensor | ZeroOrderHold | None = None
    actuators: Saturation | None = None
    latency: ActuationDelay | None = None
    log: RobotLog | None = None
    object_blocks: ObjectBlocks | None = None


@dataclass
class Experiment:
    """A built experiment: the diagram, the plant handles and each robot's systems.

    ``ground_truth`` is the offline ground truth's holds and log (in ``contact`` mode the
    pads' forces, :class:`~drake_coop.plant.ground_truth.PadForceLog`; None on the live path
    or without logging).

    Attributes
    ----------
    plan : RunPlan
        The run's plan the diagram was built from (its scenario is :attr:`scenario`).
    diagram : Diagram
        The built diagram.
    coop : CoopPlant
        The plant and its handles.
    robots : list of RobotSystems
        Each robot's systems.
    ground_truth : GroundTruthLog or PadForceLog or None
        The offline ground truth.
    object_state_estimator : ObjectStateEstimator or None
        The shared object-state block (``object_model.shared``), None without it.
    """

    plan: RunPlan
    diagram: Diagram
    coop: CoopPlant
    robots: list[RobotSystems]
    ground_truth: GroundTruthLog | PadForceLog | None = None
    object_state_estimator: ObjectStateEstimator | None = None

    @property
    def scenario(self) -> Scenario:
        """The run's scenario (the plan's)."""
        return self.plan.scenario

    @property
    def h(self) -> float:
        """The control period on the run's time grid (:attr:`RunPlan.h
        <drake_coop.experiment.plan.RunPlan.h>`)."""
        return self.plan.h

    @property
    def dt(self) -> float:
        """The plant step on the run's time grid."""
        return self.plan.dt


def reads_sensor(robot) -> bool:
    """Whether the robot's force source reads its F/T sensor (``lambda_sensor``: its registry
    entry, :data:`drake_coop.control.registry.SOURCES`; ``force_source: sensor``).

    Parameters
    ----------
    robot : Robot
        The robot's entry.

    Returns
    -------
    bool
        True for a source that reads ``lambda_sensor``.
    """
    return "lambda_sensor" in source("force", robot.force_source).inputs


def is_ideal(settings) -> bool:
    """Whether the encoders pass the exact ``q(t_k)``: no quantization, no noise, no delay.

    Parameters
    ----------
    settings : Encoders
        The robot's encoder settings (:class:`~drake_coop.scenario.schema.Encoders`).
    """
    return (settings.counts_per_rev is None and settings.noise_std == 0.0
            and settings.delay_samples == 0)


def add_encoders(builder: DiagramBuilder, name: str, n: int, period: float, settings,
                 robot_index: int, state):
    """``<name>_encoders``, wired to the arm's plant ``state``; returns it and its ``q`` port.

    Ideal encoders are Drake's :class:`~pydrake.systems.primitives.Demultiplexer` (C++) taking
    ``q`` out of ``[q, q̇]``: what the controller reads at ``t_k`` is the plant's ``q(t_k)``, as
    :class:`~drake_coop.sensing.encoders.Encoders` would give bit for bit, without a Python call.

    Parameters
    ----------
    builder : DiagramBuilder
        The experiment's builder.
    name : str
        The robot's name.
    n : int
        Its joints.
    period : float
        The control period, s.
    settings : Encoders
        Its encoder settings.
    robot_index : int
        Its index (seeds the noise).
    state : OutputPort
        The arm's ``[q, q̇]`` from the plant.

    Returns
    -------
    encoder : LeafSystem
        The encoders' system (a C++ ``Demultiplexer`` when ideal).
    q : OutputPort
        Their reading (n,), rad.
    """
    if is_ideal(settings):
        encoder = builder.AddNamedSystem(f"{name}_encoders", Demultiplexer([n, n]))
        builder.Connect(state, encoder.get_input_port(0))
        return encoder, encoder.get_output_port(0)
    encoder = builder.AddNamedSystem(f"{name}_encoders",
                                     Encoders(n, period, settings, robot_index))
    builder.Connect(state, encoder.GetInputPort("state"))
    return encoder, encoder.GetOutputPort("q")


def uses_live_ground_truth(scenario: Scenario) -> bool:
    """Whether the ground truth must run inside the loop: in ``none`` mode (Newton's law on
    the reaction forces, :class:`~drake_coop.plant.wrist.WristKinematics`), or in the
    ``planes`` and ``rigid`` modes when a robot's controller reads the F/T sensor
    (``force_source: sensor``). Otherwise it is computed after the run from held plant data
    (:mod:`drake_coop.plant.ground_truth`; in ``contact`` mode the pads' contact forces of
    every plant step, :class:`~drake_coop.plant.ground_truth.PadForceLog`, which also feeds a
    controller that reads its sensor).

    Parameters
    ----------
    scenario : Scenario
        The scenario whose object mode and force sources decide.
    """
    mode = scenario.plant.object_mode
    return mode == "none" or (mode != "contact"
                              and any(reads_sensor(r) for r in scenario.robots))


def build_experiment(plan: RunPlan, *, builder: DiagramBuilder | None = None,
                     log: bool = True, before_build=None,
                     live_ground_truth: bool | None = None) -> Experiment:
    """Wire the experiment's Diagram from a run's plan.

    Only wiring: every robot's arm, controller's model, stiffness, control point, object
    model and reference trajectory (:attr:`~drake_coop.experiment.plan.RobotPlan.reference`)
    are the plan's, computed there once; nothing is derived again here.

    Parameters
    ----------
    plan : RunPlan
        The run's plan (:func:`~drake_coop.experiment.plan.plan_run`; with references other
        than the scenario's, :meth:`~drake_coop.experiment.plan.RunPlan.with_references`).
    builder : DiagramBuilder, optional
        Builder to use (e.g. to add a visualizer first).
    log : bool
        Log every signal of :class:`RobotLog`, sampling every control period.
    before_build : callable, optional
        ``before_build(builder, coop)`` called just before ``Build()`` (visualizers). With it,
        the offline ground truth also has ``wrist_forces_at_tick``
        (:class:`~drake_coop.plant.ground_truth.TickForces`), the force during the run for the
        Meshcat arrows.
    live_ground_truth : bool, optional
        Where the ground truth (``F_meas``, ``lambda_meas``) and the F/T sensor model
        (``lambda_sensor``) are computed. True: inside the loop, by
        :func:`~drake_coop.plant.wrist.add_force_sensors` and
        :func:`~drake_coop.sensing.force_sensor.add_ft_sensor` (Python systems latching at every
        tick; in ``contact`` mode Newton's law on the reaction forces). False: after the run,
        from C++ holds of the plant's data logged at every tick
        (:func:`~drake_coop.plant.ground_truth.add_ground_truth`; in ``contact`` mode the pads'
        contact forces of every plant step, :func:`~drake_coop.plant.ground_truth.
        add_pad_force_log`; without ``log`` nothing at all, except what a controller reading
        its F/T sensor needs), allowed only when :func:`uses_live_ground_truth` is False. None
        (default): that function decides. Both give the same logs (to rounding, ~1e-12 N;
        ``contact``: to Newton's law's agreement with the contact results, ~1e-3).

    Returns
    -------
    Experiment
        The Diagram, its plant and each robot's systems.

    Raises
    ------
    TypeError
        ``plan`` is not a :class:`~drake_coop.experiment.plan.RunPlan` (a scenario is planned
        first: ``build_experiment(plan_run(scenario))``).
    ValueError
        ``live_ground_truth=False`` in ``none`` mode, or with a robot's
        ``force_source: sensor`` in the ``planes`` and ``rigid`` modes.
    """
    if not isinstance(plan, RunPlan):
        raise TypeError(f"plan: a RunPlan (plan_run(scenario)) is needed, got "
                        f"{type(plan).__name__}")
    scenario = plan.scenario
    # The period checked once (against the plant's step) for every block of the diagram.
    h, dt = checked_period(plan.h, plan.dt), plan.dt
    estimator_h = (checked_period(ESTIMATOR_TICKS * h)
                   if plan.object is not None and plan.object.estimated else None)
    needs_live = uses_live_ground_truth(scenario)
    if live_ground_truth is None:
        live_ground_truth = needs_live
    elif not live_ground_truth and needs_live:
        raise ValueError("live_ground_truth=False needs planes, rigid or contact mode and, "
                         "outside contact mode, no robot with force_source: sensor")
    b = builder or DiagramBuilder()
    coop = build_plant(b, plan)
    plant = coop.plant
    sensors = add_force_sensors(b, coop, h) if live_ground_truth else [None] * len(coop.arms)
    models = [FTModel.from_settings(r.force_sensor, h, i, arm.arm.m)
              for i, (r, arm) in enumerate(zip(scenario.robots, coop.arms))]
    # contact mode off the loop: the pads' forces of every plant step, held and logged (C++);
    # also the F/T sensor's input of a controller that reads it.
    pads = None
    if (not live_ground_truth and coop.mode == "contact"
            and (log or any(reads_sensor(r) for r in scenario.robots))):
        pads = add_pad_force_log(b, coop, h, models, log=log)
    # First every arm's sensors and control block, then the object layer between the control
    # blocks and the actuators (nothing without an object model), then actuators and logs.
    parts, arms = [], []
    for i, handles in enumerate(coop.arms):
        name = handles.arm.name
        robot = scenario.robots[i]
        model = plan.robots[i].controller_model
        state = plant.get_state_output_port(handles.instance)
        clock = plan.robots[i].clock         # its controller's clock (None: the run's grid)
        # Sensors: plant → encoders → control block; ground truth → F/T sensor model.
        encoder, q_port = add_encoders(b, name, model.n, h, robot.encoders, i, state)
        ft = lambda_sensor = None
        if pads is not None and reads_sensor(robot):
            last_step = pads.add_lambda_last_step(b, i, name)
            ft, lambda_sensor = add_ft_sensor(b, name, h, dt, robot.force_sensor, i, model.m,
                                              last_step, last_step, clock=clock)
        elif live_ground_truth:
            ft, lambda_sensor = add_ft_sensor(b, name, h, dt, robot.force_sensor, i, model.m,
                                              sensors[i].GetOutputPort("lambda_meas"),
                                              sensors[i].lambda_last_step, clock=clock)
        # The control block, through the public API (the same path as a user's diagram): the
        # encoders' q in; the F/T reading for classical force feedback; tau left to the
        # actuators below. The measured-velocity baseline reads the plant's state.
        block = AddCooperativeController(
            b, plant, handles.instance, gains=robot.gains, period=h, controller_model=model,
            velocity_source=robot.velocity_source, force_source=robot.force_source,
            difference_cutoff_hz=robot.difference_cutoff_hz,
            q=q_port,
            lambda_sensor=lambda_sensor if reads_sensor(robot) else None,
            connect_actuation=False,
            contact_stiffness=plan.robots[i].stiffness,
            prediction_horizon=robot.timing.prediction_horizon,
            anti_windup_limits=robot.actuators.torque_limits if robot.anti_windup else None,
            anti_windup_gain=robot.anti_windup_gain, name=name, clock=clock)
        ref = b.AddNamedSystem(f"{name}_reference", TrajectorySource(plan.robots[i].reference))
        parts.append((name, robot, state, encoder, q_port, ft, lambda_sensor, block))
        arms.append(ArmSignals(q=q_port, reference=ref.get_output_port(), control=block.system))
    # The object-aware blocks (object_model: known / estimated; with shared: true the one
    # object_state_estimator between the arms): none in the paper's diagram.
    layer = add_object_layer(b, plan, h, arms, estimator_period=estimator_h)
    robots = []
    actuation = []           # each arm's actuation input (for the offline ground truth)
    for i, (name, robot, state, encoder, q_port, ft, lambda_sensor, block) in enumerate(parts):
        n = plan.robots[i].controller_model.n
        law, control = block.law, block.system
        vel, force, ctrl = block.velocity_source, block.force_source, block.controller
        reference, tau_port, objects = layer.references[i], layer.taus[i], layer.blocks[i]
        b.Connect(reference, block.reference_input)
        # Actuators: control block → saturation (+ joint friction) → plant.
        actuators, applied = add_actuators(b, name, n, robot.actuators.torque_limits,
                                           robot.model_error.coulomb_friction, state)
        # Computation delay / jitter: a block of its own, only when enabled, so
        # that the paper's diagram is unchanged at the defaults.
        latency = None
        timing = robot.timing
        if timing.computation_delay > 0.0 or timing.jitter != "none":
            latency = b.AddNamedSystem(f"{name}_latency", ActuationDelay(n, h, dt, timing, i))
            b.Connect(tau_port, latency.get_tau_cmd_input_port())
            b.Connect(latency.get_tau_output_port(), actuators.get_input_port())
        else:
            b.Connect(tau_port, actuators.get_input_port())
        b.Connect(applied, plant.get_actuation_input_port(coop.arms[i].instance))
        actuation.append(applied)
        rs = RobotSystems(name=name, law=law, control=control, velocity_observer=vel,
                          force_observer=force, controller=ctrl, force_sensor=sensors[i],
                          encoders=encoder, ft_sensor=ft, actuators=actuators, latency=latency,
                          object_blocks=objects)
        if log:
            sources = {
                "q": q_port,
                "q_hat": control.GetOutputPort("q_hat"),
                "reference": reference,
                "lambda_hat": control.GetOutputPort("lambda_hat"),
                "Delta_F_tilde": control.GetOutputPort("Delta_F_tilde"),
                "tau": actuators.get_output_port(),
                "tau_cmd": control.GetOutputPort("tau"),
                "F_meas": sensors[i].F_step if live_ground_truth else None,
                "lambda_meas": sensors[i].lambda_step if live_ground_truth else None,
                "lambda_sensor": lambda_sensor,      # None: computed after the run
                "qdot_hat": control.GetOutputPort("qdot_hat"),
                "state": state,
            }
            assert tuple(sources) == LOG_KEYS
            if objects is not None:
                sources.update(zip(OBJECT_LOG_KEYS, (
                    objects.feedforward.get_tau_ff_output_port(),
                    objects.feedforward.get_f_load_output_port(), objects.mass_share)))
            if coop.grasp is not None:          # contact mode: the box's state too
                sources["object_state"] = plant.get_state_output_port(
                    coop.grasp.box.model_instance())
            # The signals computed after the run have no port.
            sources = {k: port for k, port in sources.items() if port is not None}
            sizes = [port.size() for port in sources.values()]
            mux = b.AddNamedSystem(f"{name}_log_signals", Multiplexer(sizes))
            for j, port in enumerate(sources.values()):
                b.Connect(port, mux.get_input_port(j))
            logger = LogVectorOutput(mux.get_output_port(0), b, publish_period=h)
            logger.set_name(f"{name}_log")
            starts = np.cumsum([0] + sizes)
            rs.log = RobotLog(logger, {k: slice(int(starts[j]), int(starts[j + 1]))
                                       for j, k in enumerate(sources)}, dict(sources))
        robots.append(rs)
    ground_truth = pads if log else None
    if not live_ground_truth and log and coop.mode != "contact":
        ground_truth = add_ground_truth(
            b, coop, h, models, actuation,
            tick_forces=before_build is not None)    # for visualizers' readers
    if before_build is not None:
        before_build(b, coop)
    diagram = b.Build()
    diagram.set_name("drake_coop_experiment")
    return Experiment(plan=plan, diagram=diagram, coop=coop, robots=robots,
                      ground_truth=ground_truth, object_state_estimator=layer.shared)
