r"""Computation delay and sampling jitter of one robot's digital controller, between its torque
command and the actuators.

The controller (13) computes ``τ(k)`` from ``q(t_k)``; a real controller needs time ``d`` to do
so and wakes up late by ``ℓ_k`` on some ticks. Here ``τ(k)`` reaches the actuators at

.. math::
    t_k + D_k, \qquad D_k = d + \ell_k, \qquad 0 \le D_k \le h,

and until then ``τ(k−1)`` stays on. ``ℓ_k = 0`` without jitter; otherwise a seeded draw
(``U(0, s)`` or exponential with mean ``s``, cut at ``h − d``) that depends only on
``(seed, robot, k)``: reproducible, independent across ticks and robots.

Realisation on the plant's step grid (``Δt``, ``h = N Δt``): the plant reads its actuation at
its own steps ``t_k + r Δt`` only, so the switch happens at the first plant step at or after
``t_k + D_k``: at step ``r ≥ s_k = ⌈D_k / Δt⌉`` (to 1e-9 of a step, so that ``d = 2 ms`` on a 1 ms
grid is exactly 2 steps, not 3), ``s_k ≤ N``. The block knows ``r`` from the time of its
context and the tick it latched (a scheduled event at ``t_k + D_k`` would land after the plant
step it should precede on ~15 % of ticks in floating point). ``s_k = N`` puts ``τ(k)`` on from
the next tick until that tick's own switch. The first tick's torque is applied at once (the
controller ran before the experiment started; no torque-free start under gravity).

Jitter here delays the *actuation* of a tick; its sample ``q(t_k)`` is still taken on time (a
hardware-latched encoder read by a late computation). A loop that also *reads* late sees
``q(t_k + ℓ_k)`` instead, an extra error of about ``q̇ ℓ_k`` that this model leaves out.

State ``[k, s_k, τ(k−1), τ(k)]``: the latched tick, its switch step and the two torques.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_coop.scenario.schema import Timing
from drake_coop.control.timing import tick_of

__all__ = ["JITTER_STREAM", "ActuationDelay", "lateness", "switch_step"]

#: Noise stream of the jitter (after the encoders' 0 and the force sensor's 1).
JITTER_STREAM = 2


def lateness(timing: Timing, robot: int, k: int, h: float) -> float:
    """``ℓ_k`` (s) of tick ``k`` (0 without jitter).

    Parameters
    ----------
    timing : Timing
        The scenario's timing settings (jitter, seed).
    robot : int
        The robot's index (seeds its jitter).
    k : int
        The tick index.
    h : float
        The control period, s.
    """
    if timing.jitter == "none":
        return 0.0
    rng = np.random.default_rng([int(timing.seed), int(robot), JITTER_STREAM, int(k)])
    room = max(0.0, h - timing.computation_delay)
    if timing.jitter == "uniform":
        return float(min(room, rng.uniform(0.0, timing.jitter_scale)))
    return float(min(room, rng.exponential(timing.jitter_scale)))


def switch_step(delay: float, dt: float, steps: int) -> int:
    """``s = ⌈delay / Δt⌉`` (to 1e-9 of a step), clipped to ``[0, steps]``.

    Parameters
    ----------
    delay : float
        The delay after the tick, s.
    dt : float
        The plant's step ``Δt``, s.
    steps : int
        The plant steps per tick.
    """
    return int(min(steps, max(0, math.ceil(delay / dt - 1e-9))))


class ActuationDelay(LeafSystem):
    """Applies each tick's torque ``d + ℓ_k`` late, on the plant's step grid
    (``robotN_latency``).

    .. pydrake_system::

        name: ActuationDelay
        input_ports:
        - tau_cmd
        output_ports:
        - tau

    Parameters
    ----------
    n : int
        Joints.
    period, time_step : float
        Control period ``h`` and plant step ``Δt`` (``h = N Δt`` exactly:
        :func:`~drake_coop.control.timing.aligned_periods`).
    timing : drake_coop.scenario.Timing
        Delay, jitter and seed.
    robot_index : int
        Robot (jitter stream).
    """

    def __init__(self, n: int, period: float, time_step: float, timing: Timing,
                 robot_index: int = 0):
        super().__init__()
        self._n = n
        self._h = float(period)
        self._dt = float(time_step)
        self._N = int(round(period / time_step))
        self._timing = timing
        self._robot = int(robot_index)
        self._tau_cmd = self.DeclareVectorInputPort("tau_cmd", n)
        self._state = self.DeclareDiscreteState(np.concatenate([[-1.0, 0.0], np.zeros(2 * n)]))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_latch)
        self.DeclareVectorOutputPort("tau", n, self._calc_tau)

    def get_tau_cmd_input_port(self):
        return self._tau_cmd

    def get_tau_output_port(self):
        return self.get_output_port(0)

    def switch(self, k: int) -> int:
        """``s_k``: the plant step of tick ``k`` from which ``τ(k)`` is applied.

        Parameters
        ----------
        k : int
            The tick index.
        """
        delay = self._timing.computation_delay + lateness(self._timing, self._robot, k, self._h)
        return switch_step(delay, self._dt, self._N)

    def _calc_tau(self, context: Context, output: BasicVector) -> None:
        x = context.get_discrete_state(self._state).value()
        n = self._n
        t = context.get_time()
        k = tick_of(t, self._h)
        if k is not None and x[0] != k:           # tick k, before its latch: r = 0
            first = x[0] < 0                      # no torque before: the first one at once
            output.SetFromVector(self._tau_cmd.Eval(context) if first or self.switch(k) == 0
                                 else x[2 + n:])  # τ(k) now, or τ(k−1) still
            return
        r = round((t - x[0] * self._h) / self._dt)
        output.SetFromVector(x[2:2 + n] if r < x[1] else x[2 + n:])

    def _update_latch(self, context: Context, discrete_state: DiscreteValues) -> None:
        k = tick_of(context.get_time(), self._h)
        x = context.get_discrete_state(self._state).value()
        n = self._n
        discrete_state.set_value(self._state, np.concatenate(
            [[float(k), float(self.switch(k))], x[2 + n:], self._tau_cmd.Eval(context)]))
