r"""A wrist force/torque sensor's measurement of the squeeze λ: low-pass, bias, noise, sampled.

.. math::
    y(k) = y(k-1) + \alpha\,(\lambda(t_k^-) - y(k-1)), \qquad
    \lambda_s(k) = y(k) + b + v_k,

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
:math:`t_{k-1}` (offset 0, on the plant's own grid), where the live port is the step
:math:`[t_{k-1}, t_k)` under ``τ(k − 1)``.

Without a second solve (``planes`` and ``rigid`` modes, ``h ≥ 2Δt``): reading the plant's
live port between two plant updates makes the plant solve that step once for the read and
once more for its own update (a change of time invalidates the solve). There,
:func:`add_ft_sensor` feeds the model the ground truth's ``lambda_last_step``
(:class:`~drake_coop.plant.wrist_dynamics.WristDynamics`: the step before the tick, from the plant
state held at ``t_k − 3Δt/2`` and the state the plant's update at ``t_k − Δt`` produced), read
at ``t_k − Δt/2``, also half a plant step from every update: the same values without the
second solve. An ideal model (no filter, bias or noise) is then a C++ ``ZeroOrderHold`` of that
port: ``λ_s(k)`` is ``λ`` of the step itself.

The output is state only, so a controller reading it forms no algebraic loop; it holds
``λ_s(k)`` from the read to the next one.

Offline: when no controller reads the sensor (no robot with ``force_source: sensor``) in the
``planes`` and ``rigid`` modes, no sensor system is built at all: the experiment logs the
plant data of the step before every tick with C++ holds and
:class:`~drake_coop.plant.ground_truth.GroundTruthLog` applies :meth:`FTModel.readings` to
``λ`` of those steps after the run, the same recursion, noise and tick numbering as the live
:class:`FTSensor` (which steps the same :class:`FTModel`). In ``contact`` mode likewise
(:class:`~drake_coop.plant.ground_truth.PadForceLog`: the pads' forces of every plant step);
there a robot that reads its sensor gets a live model fed by ``λ`` of the held step.
"""

from __future__ import annotations

from dataclasses import dataclass

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
from drake_coop.sensing.sampling import FORCE_SENSOR_STREAM, white_noise
from drake_coop.control.timing import Clock, lowpass_alpha, on_clock


@dataclass(frozen=True)
class FTModel:
    """The sensor model's equations of one arm, without a system: the one implementation
    that both :class:`FTSensor` (live, one :meth:`step` per tick) and the offline ground truth
    (:meth:`readings` over a whole run,
    :class:`~drake_coop.plant.ground_truth.GroundTruthLog`) evaluate.

    Attributes
    ----------
    alpha : float
        Low-pass gain ``α`` (1 without a cutoff).
    bias, noise_std : float
        ``b`` and the standard deviation of ``v_k`` (N).
    seed, robot, m : int
        Noise seed, robot index (noise stream) and the number of components of ``λ``.
    """

    alpha: float
    bias: float
    noise_std: float
    seed: int
    robot: int
    m: int

    @classmethod
    def from_settings(cls, settings: ForceSensorModel | None, period: float,
                      robot_index: int, m: int) -> FTModel:
        """The model of a scenario's ``force_sensor`` settings at the sampling time ``h``.

        Parameters
        ----------
        settings : ForceSensorModel or None
            The scenario's settings; None for an ideal sensor.
        period : float
            The sampling time ``h``, s.
        robot_index : int
            The robot's index (seeds its noise).
        m : int
            The number of constraints (the reading's size).
        """
        s = settings or ForceSensorModel()
        return cls(alpha=lowpass_alpha(s.cutoff_hz, period), bias=float(s.bias),
                   noise_std=float(s.noise_std), seed=int(s.seed), robot=int(robot_index),
                   m=int(m))

    @property
    def ideal(self) -> bool:
        """No filter, no bias, no noise: ``λ_s(k)`` is the true ``λ`` itself (bit for bit, as
        the C++ hold of :func:`add_ft_sensor` gives it)."""
        return self.alpha == 1.0 and self.bias == 0.0 and self.noise_std == 0.0

    def initial_reading(self) -> np.ndarray:
        """``λ_s(0)``: the reading before any read (``y(0) = 0``): the bias.
        """
        return np.full(self.m, self.bias)

    def step(self, y_prev: np.ndarray, lambda_true: np.ndarray, k: int
             ) -> tuple[np.ndarray, np.ndarray]:
        """``y(k) = y(k−1) + α (λ − y(k−1))`` and the reading ``y(k) + b + v_k`` of tick ``k``
        (``y(k) = λ`` exactly when ``α = 1``).

        Parameters
        ----------
        y_prev : numpy.ndarray
            ``y(k−1)`` (m,), N.
        lambda_true : numpy.ndarray
            The true ``λ`` of the step before tick ``k`` (m,), N.
        k : int
            The tick index (seeds the noise).

        Returns
        -------
        y : numpy.ndarray
            ``y(k)`` (m,), N.
        reading : numpy.ndarray
            The reading (m,), N.
        """
        y = (np.array(lambda_true, dtype=float) if self.alpha == 1.0
             else y_prev + self.alpha * (lambda_true - y_prev))
        noise = white_noise(self.seed, self.robot, FORCE_SENSOR_STREAM, k, self.noise_std,
                            self.m)
        return y, y + self.bias + noise

    def readings(self, lambdas: np.ndarray) -> np.ndarray:
        """The readings ``λ_s(0), …, λ_s(K−1)`` of a run, from ``lambdas[k]``, the true ``λ``
        of the plant step before tick ``k`` (row 0 unused: no step precedes ``t_0``), by
        :meth:`step` from ``y(0) = 0``; an ideal model's readings are ``λ`` itself (the C++
        hold's initial value 0 at tick 0).

        Parameters
        ----------
        lambdas : numpy.ndarray
            The true ``λ`` per tick (K, m), N.

        Returns
        -------
        numpy.ndarray
            The readings (K, m), N.
        """
        lambdas = np.asarray(lambdas, dtype=float).reshape(-1, self.m)
        out = np.empty_like(lambdas)
        if out.shape[0] == 0:
            return out
        if self.ideal:          # the C++ hold: λ itself, 0 before its first sample
            out[1:] = lambdas[1:]
            out[0] = 0.0
            return out
        out[0] = self.initial_reading()
        y = np.zeros(self.m)
        for k in range(1, lambdas.shape[0]):
            y, out[k] = self.step(y, lambdas[k], k)
        return out


class FTSensor(LeafSystem):
    """The F/T sensor model of one arm (``robotN_ft_sensor``).

    State ``[y, λ_s]``: the low-pass state and the held reading.

    Parameters
    ----------
    period : float
        Sampling time ``h`` (s).
    plant_step : float
        The plant's step ``Δt`` (s), a divisor of ``h``: the sensor reads the force of the
        step ``[t_k − Δt, t_k)``, at ``t_k − 3Δt/2`` (at :math:`t_{k-1}` when ``h = Δt``).
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
    clock : Clock or None
        The clock its reads tick on (:class:`~drake_coop.control.timing.Clock`: the arm's
        controller's); the read serving the clock's tick ``k h`` at its ``k h − lead``. None
        (default): the run's grid.

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
                 read_lead: float | None = None, clock: Clock | None = None):
        super().__init__()
        self._h = period
        self._dt = plant_step
        self._model = FTModel.from_settings(settings, period, robot_index, m)
        self._input = self.DeclareVectorInputPort("lambda_true", m)
        self._y = self.DeclareDiscreteState(np.zeros(m))                          # low-pass state
        self._reading = self.DeclareDiscreteState(self._model.initial_reading())  # held reading
        # Time from the read to the tick it serves (see the module's docstring).
        steps = int(round(period / plant_step))
        if read_lead is None:
            read_lead = 1.5 * plant_step if steps >= 2 else period
        self._lead = float(read_lead)
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, period, period - self._lead),
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
        return self._model.alpha

    @property
    def model(self) -> FTModel:
        """The model's equations (shared with the offline path, :meth:`FTModel.readings`)."""
        return self._model

    def _update_reading(self, context: Context, discrete_state: DiscreteValues) -> None:
        k = int(round((context.get_time() + self._lead) / self._h))   # the tick being served
        y, reading = self._model.step(context.get_discrete_state(self._y).CopyToVector(),
                                      self._input.Eval(context), k)
        discrete_state.set_value(self._y, y)
        discrete_state.set_value(self._reading, reading)


def _hold(clock: Clock | None, period: float, m: int, plant_step: float):
    """``ZeroOrderHold``'s ``(period, size, offset)``: offset ``h − Δt/2`` on ``clock``."""
    held_period, offset = on_clock(clock, period, period - 0.5 * plant_step)
    return held_period, m, offset


def add_ft_sensor(builder: DiagramBuilder, name: str, period: float, plant_step: float,
                  settings: ForceSensorModel | None, robot_index: int, m: int,
                  lambda_live: OutputPort, lambda_last_step: OutputPort | None = None,
                  clock: Clock | None = None) -> tuple[LeafSystem, OutputPort]:
    """``<name>_ft_sensor`` wired to the ground truth; returns it and its ``lambda_sensor``.

    With ``lambda_last_step`` (the ground truth's step before the tick, see the module's
    docstring) the model reads it at ``t_k − Δt/2``; an ideal model is then a C++
    ``ZeroOrderHold`` (period ``h``, offset ``h − Δt/2``, initial value 0: no Python at all).
    Otherwise an :class:`FTSensor` reads the live ``lambda_live`` at ``t_k − 3Δt/2``.

    Parameters
    ----------
    builder : DiagramBuilder
        The experiment's builder.
    name : str
        The robot's name (the system's prefix).
    period : float
        The control period ``h``, s.
    plant_step : float
        The plant's step ``Δt``, s.
    settings : ForceSensorModel or None
        The scenario's settings; None for an ideal sensor.
    robot_index : int
        The robot's index (seeds its noise).
    m : int
        The number of constraints.
    lambda_live : OutputPort
        The ground truth's live ``λ`` (m,), N.
    lambda_last_step : OutputPort or None
        The ground truth's ``λ`` of the step before the tick, if any.
    clock : Clock or None
        The arm's controller's clock (:class:`~drake_coop.control.timing.Clock`): the model
        (the ``ZeroOrderHold`` too) samples on it. None (default): the run's grid.

    Returns
    -------
    system : LeafSystem
        The sensor model's system, added to ``builder``.
    lambda_sensor : OutputPort
        Its reading (m,), N.
    """
    if lambda_last_step is not None:
        if FTModel.from_settings(settings, period, robot_index, m).ideal:
            ft = builder.AddNamedSystem(f"{name}_ft_sensor",
                                        ZeroOrderHold(*_hold(clock, period, m, plant_step)))
            builder.Connect(lambda_last_step, ft.get_input_port())
            return ft, ft.get_output_port()
        ft = builder.AddNamedSystem(f"{name}_ft_sensor",
                                    FTSensor(period, plant_step, settings, robot_index, m,
                                             read_lead=0.5 * plant_step, clock=clock))
        builder.Connect(lambda_last_step, ft.GetInputPort("lambda_true"))
    else:
        ft = builder.AddNamedSystem(f"{name}_ft_sensor",
                                    FTSensor(period, plant_step, settings, robot_index, m,
                                             clock=clock))
        builder.Connect(lambda_live, ft.GetInputPort("lambda_true"))
    return ft, ft.GetOutputPort("lambda_sensor")
