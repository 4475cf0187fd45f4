"""Ground-truth wrist force of every arm: what the object exerts on each end effector.

Newton's law for the bodies a wrist sensor carries (the sensor body and the pad, welded after
the flange) gives ``F_obj = Σ_b m_b (a_b − g) − F_weld``, where ``F_weld`` is the reaction force
the last link exerts on the sensor body through the arm's ``sensor_joint`` (Drake reports it on
the child body, in the joint's child frame; SAP constraint impulses are included). The plant's
output ports are live: at time t the values belong to the plant step that starts at t.

Where it runs: in the ``planes`` and ``rigid`` modes the force follows from each arm's own
equations of motion for one plant step (:mod:`drake_coop.plant.wrist_dynamics`: the equation
:class:`~drake_coop.plant.wrist_dynamics.ArmForces` and the system that serves it live,
:class:`~drake_coop.plant.wrist_dynamics.WristDynamics`). When nothing in the control loop
reads it (no robot with ``force_source: sensor``), the experiment computes it *after* the run
from plant data held by C++ blocks (:mod:`drake_coop.plant.ground_truth`): no system of this
module is then in the diagram. In ``contact`` mode the force is the pad's contact
force, held and logged at every plant step and sorted into ticks after the run
(:class:`~drake_coop.plant.ground_truth.PadForceLog`). The systems below are the live path: a
controller that reads the F/T sensor in the ``planes`` and ``rigid`` modes, the ``none``
mode, or ``build_experiment(..., live_ground_truth=True)`` (in ``contact`` mode: Newton's law
on the reaction forces).

Two kinds of systems, so that the cost per tick grows linearly with the number of arms:

* one :class:`WristKinematics` (``wrist_kinematics``) reads the plant's per-body ports once
  (their Python conversion is what costs: it grows with the plant's size) and hands each arm
  only what its sensor needs, as a vector;
* one :class:`ForceSensor` per arm (``<robot>_force_sensor``) turns that vector into the force
  and its components along the object's outward normals.

Logged force of a tick (``F_step``, ``lambda_step``): with a control period, the ground truth
(:class:`~drake_coop.plant.wrist_dynamics.WristDynamics` once for all arms, or each
:class:`ForceSensor` on the reaction forces) latches at every tick ``t_k`` the force of the plant step actually taken from ``t_k``: its discrete
update runs after the controller's unrestricted update (so under ``τ(k)``) and after a grasp
switch made between two ``AdvanceTo`` calls (so a grasp or release tick logs the step of the
new form), from the same context as the plant's own update (the step's solve is shared). A
logger publishing at :math:`t_{k+1}` sees it; :func:`~drake_coop.experiment.simulate.collect_logs`
shifts it back to the row of ``t_k``. The live ports (``F_meas``, ``lambda_meas``) at a tick
before its events would read the state of ``t_k`` under ``τ(k − 1)``: a step that is not
taken.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import (
    Context,
    DiagramBuilder,
    LeafSystem,
    OutputPort,
    ValueProducer,
)
from pydrake.systems.primitives import Multiplexer, ZeroOrderHold

from drake_coop.plant.cooperative import ArmHandles, CoopPlant
from drake_coop.control.deprecation import moved
from drake_coop.plant.wrist_dynamics import WristDynamics

#: Names this module no longer holds (found here until the removal date of
#: :mod:`drake_coop.control.deprecation`).
_MOVED = {"ArmForces": "drake_coop.plant.wrist_dynamics"}


def _wrist_size(handles: ArmHandles) -> int:
    """``F_weld`` (3) and, per carried body, ``R_WB p_BoBcm``, ``ω``, ``α``, ``a_Bo`` (12)."""
    return 3 + 12 * len(handles.sensor_bodies)


class WristKinematics(LeafSystem):
    """What every arm's wrist sensor needs from the plant, from one read of its ports.

    Parameters
    ----------
    plant : MultibodyPlant
        The finalized plant.
    arms : list of ArmHandles
        The arms.

    Input ports
    -----------
    reaction_forces, body_poses, body_spatial_velocities, body_spatial_accelerations
        The plant's ports of the same names.

    Output ports
    ------------
    <robot>_wrist : (3 + 12 k)-vector, one per arm
        ``F_weld`` in the palm frame, then for each of the ``k`` bodies the sensor carries:
        its centre of mass offset ``R_WB p_BoBcm_B``, ``ω_WB``, ``α_WB`` and the acceleration of
        its origin ``a_WBo`` (palm frame).
    """

    def __init__(self, plant: MultibodyPlant, arms: list[ArmHandles]):
        super().__init__()
        self._arms = [(int(h.sensor_weld.index()), int(h.sensor_weld.child_body().index()),
                       h.sensor_weld.frame_on_child().GetFixedPoseInBodyFrame().rotation(),
                       [(int(b.index()), b.default_com()) for b in h.sensor_bodies])
                      for h in arms]
        self._reaction = self.DeclareAbstractInputPort(
            "reaction_forces", plant.get_reaction_forces_output_port().Allocate())
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", plant.get_body_poses_output_port().Allocate())
        self._velocities = self.DeclareAbstractInputPort(
            "body_spatial_velocities", plant.get_body_spatial_velocities_output_port().Allocate())
        self._accelerations = self.DeclareAbstractInputPort(
            "body_spatial_accelerations",
            plant.get_body_spatial_accelerations_output_port().Allocate())
        self._signals = self.DeclareCacheEntry(
            "wrist signals of every arm",
            ValueProducer(allocate=AbstractValue.Make([np.zeros(0)]).Clone,
                          calc=self._calc_signals),
            {self.all_input_ports_ticket()})
        for i, h in enumerate(arms):
            self.DeclareVectorOutputPort(
                f"{h.arm.name}_wrist", _wrist_size(h),
                lambda context, output, i=i: output.SetFromVector(
                    self._signals.Eval(context)[i]),
                prerequisites_of_calc={self._signals.ticket()})

    def _calc_signals(self, context: Context, value: AbstractValue) -> None:
        reactions = self._reaction.Eval(context)
        poses = self._poses.Eval(context)
        velocities = self._velocities.Eval(context)
        accelerations = self._accelerations.Eval(context)
        out = []
        for weld, child, R_BJc, bodies in self._arms:
            R_WJc = poses[child].rotation().multiply(R_BJc)
            parts = [R_WJc.multiply(reactions[weld].translational())]
            for index, p_BoBcm_B in bodies:
                A = accelerations[index]
                parts += [poses[index].rotation().multiply(p_BoBcm_B),
                          velocities[index].rotational(), A.rotational(), A.translational()]
            out.append(np.concatenate(parts))
        value.set_value(out)


class ForceSensor(LeafSystem):
    """Ground-truth wrist force of one arm (see the module's docstring).

    Parameters
    ----------
    plant : MultibodyPlant
        The finalized plant.
    handles : ArmHandles
        The arm.
    period : float or None
        The control period ``h``, s; None for no latched outputs.
    direct : bool
        Whether the input is :class:`WristDynamics`'s force (else :class:`WristKinematics`'s).

    Input ports
    -----------
    wrist : (3 + 12 k)-vector
        This arm's output of :class:`WristKinematics`.

    Output ports
    ------------
    F_meas : 3-vector
        Force of the object on the end effector, palm frame (N), live: the plant step that
        starts at the context's state and inputs.
    lambda_meas : m-vector
        ``N_i F_meas``, ``N_i`` the object's outward normals (rows): positive when squeezing (N).
    F_step, lambda_step : 3- and m-vectors
        With a ``period`` and the :class:`WristKinematics` input: ``[F_meas, lambda_meas]`` of
        the step taken from the last tick, latched at that tick (state only; see the module's
        docstring). With the :class:`WristDynamics` input they are that system's ports (the
        attributes :attr:`F_step`, :attr:`lambda_step` give them in both cases).
    """

    def __init__(self, plant: MultibodyPlant, handles: ArmHandles, period: float | None = None,
                 direct: bool = False):
        super().__init__()
        self._masses = [b.default_mass() for b in handles.sensor_bodies]
        self._g_list = plant.gravity_field().gravity_vector().tolist()
        self._N = handles.arm.N
        self._direct = direct      # the input is the force itself (WristDynamics)
        #: ``λ`` of the plant step before each tick, read in ``(t_k − Δt, t_k]`` without a
        #: second solve (a :class:`WristDynamics` port), or None; set by
        #: :func:`add_force_sensors`.
        self.lambda_last_step: OutputPort | None = None
        self._wrist = self.DeclareVectorInputPort("wrist", 3 if direct else _wrist_size(handles))
        self._force_cache = self.DeclareCacheEntry(
            "measured force", ValueProducer(allocate=AbstractValue.Make(np.zeros(3)).Clone,
                                            calc=self._calc_force_cache),
            {self.all_input_ports_ticket()})
        self.DeclareVectorOutputPort("F_meas", 3, self._calc_force)
        self.DeclareVectorOutputPort("lambda_meas", handles.arm.m, self._calc_lambda)
        #: The latched ``F_step`` and ``lambda_step`` ports (with a ``period``, else None): this
        #: system's own, or with ``direct``, :class:`WristDynamics`'s ``<robot>_F_step`` and
        #: ``<robot>_lambda_step`` (one latch for all arms; set by :func:`add_force_sensors`).
        self.F_step: OutputPort | None = None
        self.lambda_step: OutputPort | None = None
        if period is not None and not direct:
            self._F_step = self.DeclareDiscreteState(3)
            self._lambda_step = self.DeclareDiscreteState(handles.arm.m)
            self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_step)
            self.F_step = self.DeclareStateOutputPort("F_step", self._F_step)
            self.lambda_step = self.DeclareStateOutputPort("lambda_step", self._lambda_step)

    def force(self, context: Context) -> np.ndarray:
        """The measured force vector (palm frame).

        Parameters
        ----------
        context : Context
            This system's context.
        """
        return self._force_cache.Eval(context)

    def _calc_force_cache(self, context: Context, value: AbstractValue) -> None:
        value.set_value(self._compute_force(context))

    def _compute_force(self, context: Context) -> np.ndarray:
        """``F_obj = Σ_b m_b (a_b − g) − F_weld`` with ``a_b = a_Bo + α × p + ω × (ω × p)``.

        Scalar arithmetic on Python floats (a 3-vector per NumPy call costs more than the
        math), in the operation order of the vector formula. With ``direct``, the input is
        already the force (:class:`WristDynamics`).
        """
        w = self._wrist.Eval(context)
        if self._direct:
            return w.copy()
        values = w.tolist()
        gx, gy, gz = self._g_list
        fx = fy = fz = 0.0
        for k, mass in enumerate(self._masses):
            (px, py, pz, wx, wy, wz, ax, ay, az,
             tx, ty, tz) = values[3 + 12 * k: 15 + 12 * k]
            cx, cy, cz = wy * pz - wz * py, wz * px - wx * pz, wx * py - wy * px   # ω × p
            fx += mass * ((tx + (ay * pz - az * py) + (wy * cz - wz * cy)) - gx)
            fy += mass * ((ty + (az * px - ax * pz) + (wz * cx - wx * cz)) - gy)
            fz += mass * ((tz + (ax * py - ay * px) + (wx * cy - wy * cx)) - gz)
        return np.array([fx, fy, fz]) - w[0:3]

    def _update_step(self, context: Context, discrete_state) -> None:
        F = self.force(context)
        discrete_state.set_value(self._F_step, F)
        discrete_state.set_value(self._lambda_step, self._N @ F)

    def _calc_force(self, context: Context, output) -> None:
        output.SetFromVector(self.force(context))

    def _calc_lambda(self, context: Context, output) -> None:
        output.SetFromVector(self._N @ self.force(context))


def add_force_sensors(builder: DiagramBuilder, coop: CoopPlant, period: float | None = None
                      ) -> list[ForceSensor]:
    """The ground truth wired to the plant: ``wrist_dynamics`` (:class:`WristDynamics`) in the
    ``planes`` and ``rigid`` modes, ``wrist_kinematics`` (:class:`WristKinematics`, Newton's
    law from the reaction forces: other contacts may touch an arm) in ``contact`` mode, and one
    :class:`ForceSensor` per arm (``<robot>_force_sensor``); with a control ``period``, each
    latches the force of every tick's step (``F_step``, ``lambda_step``).

    With ``wrist_dynamics`` and a ``period`` of at least two plant steps, a C++
    ``ZeroOrderHold`` (``wrist_dynamics_hold``, period ``h``, offset ``h − 3Δt/2``) holds the
    plant's ``[state, net_actuation]`` of the step before each tick, and each sensor's
    :attr:`ForceSensor.lambda_last_step` is the ``<robot>_lambda_last_step`` port of
    :class:`WristDynamics` (the F/T sensor models read it at ``t_k − Δt/2``); otherwise it is
    ``None`` (the models read the live ``lambda_meas`` at ``t_k − 3Δt/2``).

    (In ``contact`` mode an experiment takes its ground truth from the pads' contact
    forces instead, off the loop: :func:`~drake_coop.plant.ground_truth.add_pad_force_log`.)

    Parameters
    ----------
    builder : DiagramBuilder
        The experiment's builder (the plant is in it).
    coop : CoopPlant
        The plant.
    period : float or None
        The control period ``h``, s.
    """
    plant = coop.plant
    direct = coop.mode in ("planes", "rigid")
    last_step = {}
    if direct:
        wrist = builder.AddNamedSystem(
            "wrist_dynamics", WristDynamics(plant, coop.arms, plant.time_step(), period))
        names = ("state", "generalized_acceleration", "net_actuation")
        ports = (plant.get_state_output_port(), plant.get_generalized_acceleration_output_port(),
                 plant.get_net_actuation_output_port())
        for name, port in zip(names, ports):
            builder.Connect(port, wrist.GetInputPort(name))
        if wrist.HasInputPort("held"):
            sizes = [plant.num_multibody_states(), plant.num_actuators()]
            mux = builder.AddNamedSystem("wrist_dynamics_held_signals", Multiplexer(sizes))
            builder.Connect(plant.get_state_output_port(), mux.get_input_port(0))
            builder.Connect(plant.get_net_actuation_output_port(), mux.get_input_port(1))
            dt = plant.time_step()
            hold = builder.AddNamedSystem(
                "wrist_dynamics_hold", ZeroOrderHold(period, sum(sizes), period - 1.5 * dt))
            builder.Connect(mux.get_output_port(0), hold.get_input_port())
            builder.Connect(hold.get_output_port(), wrist.GetInputPort("held"))
            last_step = {h.arm.name: wrist.GetOutputPort(f"{h.arm.name}_lambda_last_step")
                         for h in coop.arms}
    else:
        wrist = builder.AddNamedSystem("wrist_kinematics", WristKinematics(plant, coop.arms))
        for name in ("reaction_forces", "body_poses", "body_spatial_velocities",
                     "body_spatial_accelerations"):
            builder.Connect(plant.GetOutputPort(name), wrist.GetInputPort(name))
    sensors = []
    for h in coop.arms:
        sensor = builder.AddNamedSystem(f"{h.arm.name}_force_sensor",
                                        ForceSensor(plant, h, period, direct))
        builder.Connect(wrist.GetOutputPort(f"{h.arm.name}_wrist"), sensor.GetInputPort("wrist"))
        sensor.lambda_last_step = last_step.get(h.arm.name)
        if direct and period is not None:
            sensor.F_step = wrist.GetOutputPort(f"{h.arm.name}_F_step")
            sensor.lambda_step = wrist.GetOutputPort(f"{h.arm.name}_lambda_step")
        sensors.append(sensor)
    return sensors


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
