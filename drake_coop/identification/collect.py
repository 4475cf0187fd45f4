"""The identification experiment: the scenario's true arm alone, driven along the excitation.

The simulated arm is the truth of the scenario (its URDF, base pose, payload, Coulomb
friction, encoders and torque limits, the plant's discrete step), without the object and
without the other robots. A joint-space tracking law (:class:`JointTracker`) drives it along
the excitation; the experiment records only what a real controller has: the encoder reading
``q_m(k)`` and the *commanded* torque ``τ(k)``, at the control period ``h``. The true state is
recorded too, for tests and diagnostics only; the estimate never reads it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiagramBuilder,
    DiscreteValues,
    LeafSystem,
)
from pydrake.systems.primitives import LogVectorOutput

from drake_coop.control.arm_model import ArmModel
from drake_coop.identification.excitation import FourierExcitation
from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import Scenario
from drake_coop.control.timing import tick_of
from drake_coop.experiment.ticks import time_grid
from drake_coop.sensing.actuators import add_actuators
from drake_coop.sensing.encoders import Encoders
from drake_coop.plant.model_error import add_payload


class JointTracker(LeafSystem):
    r"""Joint-space tracking for the identification experiment, at ``h``.

    .. math::
        \tau(k) = \hat H(q_d)\ddot q_d + \hat C(q_d,\dot q_d)\dot q_d + \hat D\dot q_d
                   + \hat g(q_d) + K_p (q_d - q_m(k)) + K_v\big(\dot q_d
                   - (q_m(k) - q_m(k-1))/h\big)

    with the nominal model ``Ĥ, Ĉ, D̂, ĝ`` and the reference ``q_d`` of tick ``k``: a
    feedforward plus PD on the encoder and its backward difference. Sampling as
    :class:`~drake_coop.control.controller.Controller`: the torque of tick ``k`` is computed
    from ``q_m(k)`` and held on :math:`[t_k, t_{k+1})` (state ``[τ(k), q_m(k), k]``).

    .. pydrake_system::

        name: JointTracker
        input_ports:
        - q
        output_ports:
        - tau

    Parameters
    ----------
    model : ArmModel
        The nominal model of the feedforward.
    excitation : FourierExcitation
        The reference ``q_d(t)``.
    period : float
        The control period ``h``, s.
    kp, kv : numpy.ndarray
        The PD gains ``K_p`` (N·m/rad) and ``K_v`` (N·m·s/rad), one per joint.

    Input ports
    -----------
    q : n-vector
        The encoder reading.

    Output ports
    ------------
    tau : n-vector
        The commanded torque ``τ(k)``.
    """

    def __init__(self, model: ArmModel, excitation: FourierExcitation, period: float,
                 kp: np.ndarray, kv: np.ndarray):
        super().__init__()
        self._model = model
        self._excitation = excitation
        self._h = period
        self._kp = np.asarray(kp, float)
        self._kv = np.asarray(kv, float)
        n = model.n
        self._n = n
        self._q = self.DeclareVectorInputPort("q", n)
        q0 = excitation.q0
        self._state = self.DeclareDiscreteState(np.concatenate([np.zeros(n), q0, [-1.0]]))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_latch)
        self.DeclareVectorOutputPort("tau", n, self._calc_tau)

    def get_q_input_port(self):
        return self._q

    def get_tau_output_port(self):
        return self.GetOutputPort("tau")

    def _law(self, context: Context, k: int) -> np.ndarray:
        x = context.get_discrete_state(self._state).value()
        return tracking_law(self._model, self._excitation, self._h, self._kp, self._kv, k,
                            self._q.Eval(context), x[self._n: 2 * self._n])

    def _calc_tau(self, context: Context, output: BasicVector) -> None:
        k = tick_of(context.get_time(), self._h)
        x = context.get_discrete_state(self._state).value()
        if k is not None and x[-1] != k:
            output.SetFromVector(self._law(context, k))
        else:
            output.SetFromVector(x[: self._n])

    def _update_latch(self, context: Context, discrete_state: DiscreteValues) -> None:
        k = tick_of(context.get_time(), self._h)
        discrete_state.set_value(self._state, np.concatenate(
            [self._law(context, k), self._q.Eval(context), [float(k)]]))


def tracking_law(model: ArmModel, excitation: FourierExcitation, h: float, kp: np.ndarray,
                 kv: np.ndarray, k: int, q: np.ndarray, q_prev: np.ndarray) -> np.ndarray:
    """:class:`JointTracker`'s torque ``τ(k)`` on floats: the one law of the simulated
    experiment and of the excitation driven over the wire
    (:mod:`~drake_coop.robot.wire_identify`).

    Parameters
    ----------
    model : ArmModel
        The nominal model of the feedforward.
    excitation : FourierExcitation
        The reference ``q_d(t)``.
    h : float
        The control period, s.
    kp, kv : numpy.ndarray
        The PD gains (n,), N·m/rad and N·m·s/rad.
    k : int
        The tick.
    q : numpy.ndarray
        The reading of tick ``k`` (n,), rad.
    q_prev : numpy.ndarray
        The reading of tick ``k − 1`` (n,), rad (the first reading at ``k = 0``).

    Returns
    -------
    numpy.ndarray
        ``τ(k)`` (n,), N·m.
    """
    qd, vd, ad = (y[0] for y in excitation.evaluate(k * h))
    v = (np.asarray(q, float) - np.asarray(q_prev, float)) / h
    return model.inverse_dynamics_terms(qd, vd, ad) + kp * (qd - q) + kv * (vd - v)


@dataclass
class ExcitationData:
    """What the identification experiment recorded, at ``h``.

    Attributes
    ----------
    t : ndarray (N,)
        Tick times ``t_k = k h``.
    q : ndarray (N, n)
        Encoder readings ``q_m(k)``.
    tau : ndarray (N, n)
        Commanded torques ``τ(k)`` (held on :math:`[t_k, t_{k+1})`).
    h : float
        The control period, s.
    torque_limits : ndarray (n,)
        The actuators' limits (``inf`` without): samples at a limit are not used.
    q_true, v_true : ndarray (N, n)
        The simulated truth (tests only).
    """

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    h: float
    torque_limits: np.ndarray
    q_true: np.ndarray
    v_true: np.ndarray


def tracking_gains(model: ArmModel, q0: np.ndarray, bandwidth: float = 20.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """PD gains from the nominal model's effective joint inertias at ``q0``:
    ``K_p = J_j ω²``, ``K_v = 2 J_j ω`` (critically damped, ``ω = bandwidth`` rad/s, well below
    ``π/h``), ``J_j = 1/(H⁻¹)_jj`` the inertia joint ``j`` sees with the others free.

    ``J_j`` rather than ``H_jj``: on an arm whose inertia matrix is strongly coupled (the
    Panda's light wrist under its heavy shoulder) the diagonal overstates what a joint moves,
    and gains from ``H_jj`` made the sampled PD loop oscillate (commanded torques of 10³ N·m,
    a torque prediction error of 170 % on the Panda); on a weakly coupled arm the two are
    close (``J_j ≤ H_jj``).

    Parameters
    ----------
    model : ArmModel
        The nominal model.
    q0 : numpy.ndarray
        The posture the inertias are taken at (n,), rad.
    bandwidth : float
        ``ω``, rad/s.

    Returns
    -------
    kp, kv : numpy.ndarray
        ``K_p`` (N·m/rad) and ``K_v`` (N·m·s/rad), (n,).
    """
    J = 1.0 / np.diag(np.linalg.inv(model.H(q0)))
    return J * bandwidth ** 2, 2.0 * J * bandwidth


def simulate_excitation(scenario: Scenario, robot_index: int, excitation: FourierExcitation,
                        nominal: ArmModel) -> ExcitationData:
    """Run the identification experiment of one robot (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The scenario whose robot ``robot_index`` is the truth (URDF, pose, payload, friction,
        encoders, torque limits; ``plant.time_step``, ``control_period``).
    excitation : FourierExcitation
        The joint trajectory to track.
    nominal : ArmModel
        The model the tracking law's feedforward uses (the user's nominal model).
    robot_index : int
        The robot's index (0-based).

    Returns
    -------
    ExcitationData
        The recorded experiment.
    """
    robot = scenario.robots[robot_index]
    arm = Arm(robot, scenario.task)
    h, dt = time_grid(scenario)
    b = DiagramBuilder()
    plant, _ = AddMultibodyPlant(MultibodyPlantConfig(
        time_step=dt, discrete_contact_approximation="sap"), b)
    plant.SetUseSampledOutputPorts(False)
    (instance,) = Parser(plant).AddModels(str(arm.urdf_path))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(arm.base_frame, instance),
                     RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base))
    add_payload(plant, instance, robot.model_error.payload_mass, robot.sensor_joint)
    plant.Finalize()
    n = plant.num_positions()
    state = plant.get_state_output_port(instance)
    encoders = b.AddNamedSystem("encoders", Encoders(n, h, robot.encoders, robot_index))
    b.Connect(state, encoders.GetInputPort("state"))
    kp, kv = tracking_gains(nominal, excitation.q0)
    tracker = b.AddNamedSystem("tracker", JointTracker(nominal, excitation, h, kp, kv))
    b.Connect(encoders.GetOutputPort("q"), tracker.get_q_input_port())
    saturation, applied = add_actuators(b, robot.name, n, robot.actuators.torque_limits,
                                        robot.model_error.coulomb_friction, state)
    b.Connect(tracker.get_tau_output_port(), saturation.get_input_port())
    b.Connect(applied, plant.get_actuation_input_port(instance))
    logs = {"q": LogVectorOutput(encoders.GetOutputPort("q"), b, publish_period=h),
            "tau": LogVectorOutput(tracker.get_tau_output_port(), b, publish_period=h),
            "state": LogVectorOutput(state, b, publish_period=h)}
    diagram = b.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(context), instance, excitation.q0)
    encoders.set_initial_state(encoders.GetMyMutableContextFromRoot(context), excitation.q0)
    simulator.Initialize()
    simulator.AdvanceTo(excitation.duration)
    out = {k: log.FindLog(context) for k, log in logs.items()}
    N = int(round(excitation.duration / h)) + 1
    t = out["q"].sample_times()[:N]
    x = out["state"].data().T[:N]
    limits = (np.full(n, np.inf) if robot.actuators.torque_limits is None
              else np.asarray(robot.actuators.torque_limits, float))
    return ExcitationData(t=t, q=out["q"].data().T[:N], tau=out["tau"].data().T[:N], h=h,
                          torque_limits=limits, q_true=x[:, :n], v_true=x[:, n:])
