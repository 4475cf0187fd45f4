"""The whole experiment as one Drake Diagram: the paper's block diagram, per robot.

::

    robotN_reference ─┐                  ┌──────────── robotN_control (Diagram) ────────────┐
    (TrajectorySource)├─ reference ─────▶│ robotN_velocity_observer (15)-(16)               │
                      │                  │ robotN_force_observer (22)                        │──tau─▶ plant
    plant ─state─▶ robotN_encoders ─ q ─▶│ robotN_controller (13)                            │
      │            (MatrixGain [I 0])    └───────────────────────────────────────────────────┘
      └─ reaction forces, body poses ─▶ robotN_force_sensor (ground truth, logged only)

The encoders pass on the joint positions only: the control block never sees a velocity or a
force. Each control block is a sub-Diagram whose inputs are ``q`` and ``reference`` and whose
outputs are ``tau`` and the observers' signals (for logging).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, MatrixGain, TrajectorySource, VectorLogSink

from drake_coop.arm_model import ArmModel
from drake_coop.controller import Controller
from drake_coop.finger import FingerLaw
from drake_coop.observers import ForceObserver, MeasuredVelocity, VelocityObserver
from drake_coop.plant import CoopPlant, ForceSensor, add_force_sensors, build_plant
from drake_coop.references import reference_trajectory
from drake_coop.scenario import Scenario, aligned_periods

@dataclass
class RobotSystems:
    """The systems of one robot inside the experiment diagram."""

    name: str
    law: FingerLaw
    control: Diagram
    velocity_observer: VelocityObserver | MeasuredVelocity
    force_observer: ForceObserver
    controller: Controller
    force_sensor: ForceSensor
    loggers: dict[str, VectorLogSink] = field(default_factory=dict)


@dataclass
class Experiment:
    """A built experiment: the diagram, the plant handles and each robot's systems."""

    scenario: Scenario
    diagram: Diagram
    coop: CoopPlant
    robots: list[RobotSystems]


def build_control_block(name: str, law: FingerLaw, period: float,
                        velocity_source: str = "observer"
                        ) -> tuple[Diagram, VelocityObserver | MeasuredVelocity, ForceObserver,
                                   Controller]:
    """One robot's observers and controller, wired as in the paper, as a sub-Diagram.

    Exported inputs: ``q``, ``reference`` (and ``state`` for the ``measured`` baseline).
    Exported outputs: ``tau``, ``q_hat``, ``qdot_hat``, ``qdot_o``, ``lambda_hat``,
    ``Delta_F_tilde``, ``qddot_r_hat``.
    """
    b = DiagramBuilder()
    if velocity_source == "measured":
        vel = b.AddNamedSystem(f"{name}_measured_velocity", MeasuredVelocity(law.n))
    else:
        vel = b.AddNamedSystem(f"{name}_velocity_observer", VelocityObserver(law, period))
    force = b.AddNamedSystem(f"{name}_force_observer", ForceObserver(law, period))
    ctrl = b.AddNamedSystem(f"{name}_controller", Controller(law, period))
    for port in ("q_hat", "qdot_hat", "qdot_o"):
        b.Connect(vel.GetOutputPort(port), ctrl.GetInputPort(port))
    b.Connect(vel.GetOutputPort("q_hat"), force.GetInputPort("q_hat"))
    b.Connect(vel.GetOutputPort("qdot_o"), force.GetInputPort("qdot_o"))
    b.Connect(force.GetOutputPort("lambda_hat"), ctrl.GetInputPort("lambda_hat"))
    b.Connect(force.GetOutputPort("Delta_F_tilde"), ctrl.GetInputPort("Delta_F_tilde"))
    if velocity_source == "measured":
        b.ExportInput(vel.GetInputPort("state"), "state")
        b.ExportInput(force.GetInputPort("q"), "q")
    else:
        b.Connect(ctrl.GetOutputPort("qddot_r_hat"), vel.GetInputPort("qddot_r_hat"))
        b.ExportInput(vel.GetInputPort("q"), "q")
        b.ConnectInput("q", force.GetInputPort("q"))
    b.ConnectInput("q", ctrl.GetInputPort("q"))
    b.ExportInput(ctrl.GetInputPort("reference"), "reference")
    b.ConnectInput("reference", force.GetInputPort("reference"))
    b.ExportOutput(ctrl.GetOutputPort("tau"), "tau")
    for port in ("q_hat", "qdot_hat", "qdot_o"):
        b.ExportOutput(vel.GetOutputPort(port), port)
    b.ExportOutput(force.GetOutputPort("lambda_hat"), "lambda_hat")
    b.ExportOutput(force.GetOutputPort("Delta_F_tilde"), "Delta_F_tilde")
    b.ExportOutput(ctrl.GetOutputPort("qddot_r_hat"), "qddot_r_hat")
    diagram = b.Build()
    diagram.set_name(f"{name}_control")
    return diagram, vel, force, ctrl


def build_experiment(scenario: Scenario, *, builder: DiagramBuilder | None = None,
                     log: bool = True, before_build=None, references=None) -> Experiment:
    """Build the experiment's Diagram from a scenario.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario.
    builder : DiagramBuilder, optional
        Builder to use (e.g. to add a visualizer first).
    log : bool
        Add a :class:`VectorLogSink` per logged signal, sampling every control period.
    before_build : callable, optional
        ``before_build(builder, coop)`` called just before ``Build()`` (visualizers).
    references : list of Trajectory, optional
        One 11-row reference trajectory per robot instead of the scenario's (studies and
        tests, e.g. a constant posture for Theorem 1).
    """
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    b = builder or DiagramBuilder()
    coop = build_plant(b, scenario)
    plant = coop.plant
    sensors = add_force_sensors(b, coop)
    robots = []
    for i, handles in enumerate(coop.arms):
        name = handles.arm.name
        law = FingerLaw(ArmModel(handles.arm), scenario.robots[i].gains)
        velocity_source = scenario.robots[i].velocity_source
        control, vel, force, ctrl = build_control_block(name, law, h, velocity_source)
        b.AddSystem(control)
        trajectory = (reference_trajectory(scenario, i) if references is None
                      else references[i])
        ref = b.AddNamedSystem(f"{name}_reference", TrajectorySource(trajectory))
        n = law.n
        encoder = b.AddNamedSystem(
            f"{name}_encoders", MatrixGain(np.hstack([np.eye(n), np.zeros((n, n))])))
        b.Connect(plant.get_state_output_port(handles.instance), encoder.get_input_port())
        b.Connect(encoder.get_output_port(), control.GetInputPort("q"))
        if velocity_source == "measured":   # the comparison baseline, not the paper's scheme
            b.Connect(plant.get_state_output_port(handles.instance),
                      control.GetInputPort("state"))
        b.Connect(ref.get_output_port(), control.GetInputPort("reference"))
        b.Connect(control.GetOutputPort("tau"), plant.get_actuation_input_port(handles.instance))
        rs = RobotSystems(name=name, law=law, control=control, velocity_observer=vel,
                          force_observer=force, controller=ctrl, force_sensor=sensors[i])
        if log:
            sources = {
                "q": encoder.get_output_port(),
                "q_hat": control.GetOutputPort("q_hat"),
                "reference": ref.get_output_port(),
                "lambda_hat": control.GetOutputPort("lambda_hat"),
                "Delta_F_tilde": control.GetOutputPort("Delta_F_tilde"),
                "tau": control.GetOutputPort("tau"),
                "F_meas": sensors[i].GetOutputPort("F_meas"),
                "lambda_meas": sensors[i].GetOutputPort("lambda_meas"),
            }
            for key, port in sources.items():
                logger = LogVectorOutput(port, b, publish_period=h)
                logger.set_name(f"{name}_log_{key}")
                rs.loggers[key] = logger
        robots.append(rs)
    if before_build is not None:
        before_build(b, coop)
    diagram = b.Build()
    diagram.set_name("drake_coop_experiment")
    return Experiment(scenario=scenario, diagram=diagram, coop=coop, robots=robots)
