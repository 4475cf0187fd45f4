"""A wrist force/torque sensor's measurement of the squeeze λ: low-pass, bias, noise, sampled.

.. math::
    y(k) = y(k-1) + \\alpha\\,(\\lambda(t_k^-) - y(k-1)), \\qquad
    \\lambda_s(k) = y(k) + b + v_k,

with ``α = 1 − exp(−2π f_c h)`` (:func:`~drake_coop.sensing.sampling.lowpass_alpha`;
``α = 1`` without a cutoff), ``b`` the bias and ``v_k`` seeded white Gaussian noise.

Sampling instant ``t_k^-``: the sensor is read during the plant's last step before the tick,
``t_k − Δt`` (``Δt`` the plant's step), i.e. it measures the contact force of
``[t_k − Δt, t_k)`` under the torque ``τ(k − 1)`` — the latest force that exists at ``t_k``.
(The plant's live force port *at* ``t_k`` belongs to the step ``[t_k, t_k + Δt)`` and depends on
``τ(k)``, which is what the controller is about to compute.) The output is state only, so a
controller reading it forms no algebraic loop; it holds ``λ_s(k)`` from ``t_k − Δt`` to
``t_{k+1} − Δt``.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

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
        The plant's step ``Δt`` (s), a divisor of ``h``: the sensor is read at ``t_k − Δt``.
    settings : drake_coop.scenario.ForceSensorModel
        Noise, bias, cutoff and seed.
    robot_index : int
        Index of the robot (noise stream).
    m : int
        Constraint rows: ``λ`` has one component per outward normal (the same model on each).

    Input ports
    -----------
    lambda_true : m-vector
        The ground-truth ``λ`` (``robotN_force_sensor``'s ``lambda_meas``).

    Output ports
    ------------
    lambda_sensor : m-vector
        ``λ_s(k)`` (state only).
    """

    def __init__(self, period: float, plant_step: float,
                 settings: ForceSensorModel | None = None, robot_index: int = 0, m: int = 1):
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
        self.DeclarePeriodicDiscreteUpdateEvent(period, period - plant_step, self._update_reading)
        self.DeclareStateOutputPort("lambda_sensor", self._reading)

    @property
    def alpha(self) -> float:
        """The low-pass gain ``α``."""
        return self._alpha

    def _update_reading(self, context: Context, discrete_state: DiscreteValues) -> None:
        k = int(round((context.get_time() + self._dt) / self._h))   # the tick being served
        y_prev = context.get_discrete_state(self._y).CopyToVector()
        y = y_prev + self._alpha * (self._input.Eval(context) - y_prev)
        noise = white_noise(self._seed, self._robot, FORCE_SENSOR_STREAM, k, self._std, self._m)
        discrete_state.set_value(self._y, y)
        discrete_state.set_value(self._reading, y + self._bias + noise)
