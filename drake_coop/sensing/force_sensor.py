"""A wrist force/torque sensor's measurement of the squeeze λ: low-pass, bias, noise, sampled.

.. math::
    y(k) = y(k-1) + \\alpha\\,(\\lambda(t_k^-) - y(k-1)), \\qquad
    \\lambda_s(k) = y(k) + b + v_k,

with ``α = 1 − exp(−2π f_c h)`` (:func:`~drake_coop.sensing.sampling.lowpass_alpha`;
``α = 1`` without a cutoff), ``b`` the bias and ``v_k`` seeded white Gaussian noise.

Sampling instant: the reading of tick ``k`` is the contact force of the plant's last step
before the tick, ``[t_k − Δt, t_k)`` (``Δt`` the plant's step), taken under the torque
``τ(k − 1)`` — the latest force that exists at ``t_k``. (The plant's live force port *at*
``t_k`` belongs to the step ``[t_k, t_k + Δt)`` and depends on ``τ(k)``, which is what the
controller is about to compute.)

How that step is read: the plant's ports are live, so at any time in ``(t_k − 2Δt, t_k − Δt]``
before the plant's update at ``t_k − Δt`` they return the force of the step ``[t_k − Δt, t_k)``
(the plant's state and its held actuation do not change in between). The update is declared
at ``t_k − 3Δt/2``, the middle of the step before, and not at ``t_k − Δt``: Drake computes a
periodic event's time as ``offset + k h``, which rounds differently from the plant's
``j Δt`` on some ticks, and an event one rounding *after* the plant's update at ``t_k − Δt``
reads the step ``[t_k, t_k + Δt)`` under the old torque ``τ(k − 1)`` — a step that never
happens (the fault of an earlier version: 23 of 2 000 ticks of ``scenarios/realistic.yaml``, up to
0.58 N). Half a plant step from every plant update, no rounding can move the read across
one. When ``h = Δt`` there is no step in between: the update is at the previous tick
``t_{k−1}`` (offset 0, on the plant's own grid), where the live port is the step
``[t_{k−1}, t_k)`` under ``τ(k − 1)``.

Without a second solve (``planes`` and ``rigid`` modes, ``h ≥ 2Δt``): reading the plant's
live port between two plant updates makes the plant solve that step once for the read and
once more for its own update (a change of time invalidates the solve). There,
:func:`add_ft_sensor` feeds the model the ground truth's ``lambda_last_step``
(:class:`~drake_coop.plant.wrist.WristDynamics`: the step before the tick, from the plant
state held at ``t_k − 3Δt/2`` and the state the plant's update at ``t_k − Δt`` produced), read
at ``t_k − Δt/2``, also half a plant step from every update: the same values without the
second solve. An ideal model (no filter, bias or noise) is then a C++ ``ZeroOrderHold`` of that
port: ``λ_s(k)`` is ``λ`` of the step itself.

The output is state only, so a controller reading it forms no algebraic loop; it holds
``λ_s(k)`` from the read to the next one.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    Context,
    DiagramBuilder,
    DiscreteValues,
    LeafSystem,
    OutputPort,
)
from pydrake.systems.primitives import ZeroOrderHold

from drake_coop.scenario.schema import ForceSensorModel
from drake_coop.sensing.sampling import FORCE_SENSOR_STREAM, lowpass_alpha, white_noise


class FTSensor(LeafSystem):
    """The F/T sensor model of one arm (``robotN_ft_sensor``).

    State ``[y, λ_s]``: the low-pass state and the held reading.

    Parameters
    ----------
    period : float
        Sampling time ``h`` (s).
    plant_step : float
        The plant's step ``Δt`` (s), a divisor of ``h``: the sensor reads the force of the
        step ``[t_k − Δt, t_k)``, at ``t_k − 3Δt/2`` (at ``t_{k−1}`` when ``h = Δt``).
    settings : drake_coop.scenario.ForceSensorModel
        Noise, bias, cutoff and seed.
    robot_index : int
        Index of the robot (noise stream).
    m : int
        Constraint rows: ``λ`` has one component per outward normal (the same model on each).
    read_lead : float, optional
        Time from the read to the tick it serves. Default: ``3Δt/2`` (``h`` when ``h = Δt``),
        for a live input; ``Δt/2`` for the ground truth's ``lambda_last_step``
        (:func:`add_ft_sensor`).

    Input ports
    -----------
    lambda_true : m-vector
        The ground-truth ``λ`` of the step ``[t_k − Δt, t_k)`` at the read
        (``robotN_force_sensor``'s ``lambda_meas``, or ``wrist_dynamics``'s
        ``robotN_lambda_last_step``).

    Output ports
    ------------
    lambda_sensor : m-vector
        ``λ_s(k)`` (state only).
    """

    def __init__(self, period: float, plant_step: float,
                 settings: ForceSensorModel | None = None, robot_index: int = 0, m: int = 1,
                 read_lead: float | None = None):
        super().__init__()
        s = settings or ForceSensorModel()
        self._h = period
        self._dt = plant_step
        self._alpha = lowpass_alpha(s.cutoff_hz, period)
        self._bias = float(s.bias)
        self._std = float(s.noise_std)
        self._seed = int(s.seed)
        self._robot = int(robot_index)
        self._m = int(m)
        self._input = self.DeclareVectorInputPort("lambda_true", m)
        self._y = self.DeclareDiscreteState(np.zeros(m))                 # low-pass state
        self._reading = self.DeclareDiscreteState(np.full(m, self._bias))  # held reading
        # Time from the read to the tick it serves (see the module's docstring).
        steps = int(round(period / plant_step))
        if read_lead is None:
            read_lead = 1.5 * plant_step if steps >= 2 else period
        self._lead = float(read_lead)
        self.DeclarePeriodicDiscreteUpdateEvent(period, period - self._lead,
                                                self._update_reading)
        self.DeclareStateOutputPort("lambda_sensor", self._reading)

    @property
    def read_lead(self) -> float:
        """Time from the read to the tick it serves: ``3Δt/2`` (``h`` when ``h = Δt``) for a
        live input, ``Δt/2`` for ``lambda_last_step``."""
        return self._lead

    @property
    def alpha(self) -> float:
        """The low-pass gain ``α``."""
        return self._alpha

    def _update_reading(self, context: Context, discrete_state: DiscreteValues) -> None:
        k = int(round((context.get_time() + self._lead) / self._h))   # the tick being served
        y_prev = context.get_discrete_state(self._y).CopyToVector()
        y = y_prev + self._alpha * (self._input.Eval(context) - y_prev)
        noise = white_noise(self._seed, self._robot, FORCE_SENSOR_STREAM, k, self._std, self._m)
        discrete_state.set_value(self._y, y)
        discrete_state.set_value(self._reading, y + self._bias + noise)


def _is_ideal(settings: ForceSensorModel | None) -> bool:
    """No filter, no bias, no noise: ``λ_s(k)`` is the ground truth of the step before ``t_k``."""
    s = settings or ForceSensorModel()
    return s.cutoff_hz is None and s.bias == 0.0 and s.noise_std == 0.0


def add_ft_sensor(builder: DiagramBuilder, name: str, period: float, plant_step: float,
                  settings: ForceSensorModel | None, robot_index: int, m: int,
                  lambda_live: OutputPort, lambda_last_step: OutputPort | None = None
                  ) -> tuple[LeafSystem, OutputPort]:
    """``<name>_ft_sensor`` wired to the ground truth; returns it and its ``lambda_sensor``.

    With ``lambda_last_step`` (the ground truth's step before the tick, see the module's
    docstring) the model reads it at ``t_k − Δt/2``; an ideal model is then a C++
    ``ZeroOrderHold`` (period ``h``, offset ``h − Δt/2``, initial value 0: no Python at all).
    Otherwise an :class:`FTSensor` reads the live ``lambda_live`` at ``t_k − 3Δt/2``.
    """
    if lambda_last_step is not None:
        if _is_ideal(settings):
            ft = builder.AddNamedSystem(f"{name}_ft_sensor",
                                        ZeroOrderHold(period, m, period - 0.5 * plant_step))
            builder.Connect(lambda_last_step, ft.get_input_port())
            return ft, ft.get_output_port()
        ft = builder.AddNamedSystem(f"{name}_ft_sensor",
                                    FTSensor(period, plant_step, settings, robot_index, m,
                                             read_lead=0.5 * plant_step))
        builder.Connect(lambda_last_step, ft.GetInputPort("lambda_true"))
    else:
        ft = builder.AddNamedSystem(f"{name}_ft_sensor",
                                    FTSensor(period, plant_step, settings, robot_index, m))
        builder.Connect(lambda_live, ft.GetInputPort("lambda_true"))
    return ft, ft.GetOutputPort("lambda_sensor")
