"""The joint-velocity observer (15)–(16) and the force observer (22) as Drake LeafSystems.

Both run with periodic discrete updates every ``h`` (9 ms in the paper) and read the measured
joint positions ``q`` only. Their updates are forward-Euler steps of the paper's continuous
observers (the paper ran them "in a PC computer" at ``h``; Euler is our reading of that).

Timing: at tick ``k`` every system of a robot reads the same sample ``q(k)`` and the same
observer state; the state outputs (``q_hat``, ``Delta_F_tilde``) hold the values of tick ``k``
until the update at tick ``k`` takes them to ``k + 1``. No signal is one sample old.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
    ValueProducer,
)

from drake_coop.control.finger import FingerLaw


class VelocityObserver(LeafSystem):
    """Model-based joint-velocity observer (15)–(16) of one robot.

    State ``q̂`` (group 0, n) and ``q̇̂_o`` (group 1, n). With ``z = q − q̂``:

    .. math::
        \\frac{d}{dt}\\hat q = \\dot{\\hat q}_o + \\Lambda z + k_d z \\qquad (15)

        \\frac{d}{dt}\\dot{\\hat q}_o = \\ddot{\\hat q}_r + k_d \\Lambda z \\qquad (16)

    discretized as ``x(k+1) = x(k) + h f(x(k), q(k), q̈̂_r(k))``.

    Cost: ``d/dt q̂`` and ``q̇_o`` are computed once per tick into a cache entry that both
    outputs and the update read; ``q_hat`` is a state output port (no Python call).

    Input ports
    -----------
    q : n-vector
        Measured joint positions.
    qddot_r_hat : n-vector
        ``q̈̂_r(k)`` of (11) from the controller, same tick.

    Output ports
    ------------
    q_hat : n-vector
        The estimate ``q̂`` (state only).
    qdot_hat : n-vector
        Its derivative estimate ``d/dt q̂`` (15) (depends on ``q``).
    qdot_o : n-vector
        ``q̇_o = d/dt q̂ − Λ z`` of (8) (depends on ``q``).
    """

    def __init__(self, law: FingerLaw, period: float):
        super().__init__()
        self._law = law
        self._h = period
        n = law.n
        self._n = n
        self._q = self.DeclareVectorInputPort("q", n)
        self._qddot_r = self.DeclareVectorInputPort("qddot_r_hat", n)
        self._q_hat_state = self.DeclareDiscreteState(n)
        self._qdot_hat_o_state = self.DeclareDiscreteState(n)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_observer)
        depends_on_q = {self.xd_ticket(), self._q.ticket()}
        self._signals = self.DeclareCacheEntry(
            "d/dt q_hat (15) and qdot_o (8)",
            ValueProducer(allocate=AbstractValue.Make((np.zeros(n), np.zeros(n))).Clone,
                          calc=self._calc_signals),
            depends_on_q)
        self.DeclareStateOutputPort("q_hat", self._q_hat_state)
        self.DeclareVectorOutputPort("qdot_hat", n, self._calc_qdot_hat,
                                     prerequisites_of_calc={self._signals.ticket()})
        self.DeclareVectorOutputPort("qdot_o", n, self._calc_qdot_o,
                                     prerequisites_of_calc={self._signals.ticket()})

    def set_initial_state(self, context: Context, q_hat: np.ndarray,
                          qdot_hat_o: np.ndarray | None = None) -> None:
        """``q̂(0)`` and ``q̇̂_o(0)`` (default zero) in this system's context."""
        context.SetDiscreteState(self._q_hat_state, q_hat)
        context.SetDiscreteState(self._qdot_hat_o_state,
                                 np.zeros(self._n) if qdot_hat_o is None else qdot_hat_o)

    def _split(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        return (context.get_discrete_state(self._q_hat_state).value(),
                context.get_discrete_state(self._qdot_hat_o_state).value())

    def _calc_signals(self, context: Context, value: AbstractValue) -> None:
        q_hat, qdot_hat_o = self._split(context)
        value.set_value(self._law.observer_derivative(self._q.Eval(context), q_hat, qdot_hat_o))

    def _calc_qdot_hat(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._signals.Eval(context)[0])

    def _calc_qdot_o(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._signals.Eval(context)[1])

    def _update_observer(self, context: Context, discrete_state: DiscreteValues) -> None:
        q = self._q.Eval(context)
        q_hat, qdot_hat_o = self._split(context)
        qdot_hat = self._signals.Eval(context)[0]
        qddot_hat_o = self._law.observer_acceleration(q, q_hat, self._qddot_r.Eval(context))
        discrete_state.set_value(self._q_hat_state, q_hat + self._h * qdot_hat)
        discrete_state.set_value(self._qdot_hat_o_state, qdot_hat_o + self._h * qddot_hat_o)


class ForceObserver(LeafSystem):
    """Contact-force observer (22) of one robot, with the force integral ΔF̃ (6) as state.

    .. math::
        \\hat\\lambda = \\frac{1}{1+\\zeta}\\Big[J^{+T}(q) K_R(\\dot q_o - \\dot q_r)
                        - k_F \\Delta\\tilde F\\Big] + \\lambda_d \\qquad (22)

    (22) is (21) with the controller (13) substituted and solved for ``λ̂``: it needs no torque,
    so observer and controller form no algebraic loop. ``ΔF̃(k+1) = ΔF̃(k) + h (λ̂(k) − λ_d(k))``
    while the object is held; before the grasp and after the release ``λ̂ = 0`` and ``ΔF̃`` is
    reset to 0 (the integral (6) starts at the grasp).

    Input ports
    -----------
    q, q_hat, qdot_o : n-vectors
        Measured positions and the velocity observer's outputs.
    reference : (3n + m + 1)-vector
        ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:class:`~drake_coop.control.finger.ReferenceLayout`).

    Output ports
    ------------
    lambda_hat : m-vector
        ``λ̂(k)`` (depends on the inputs of tick k).
    Delta_F_tilde : m-vector
        ``ΔF̃(k)`` (state only).
    """

    def __init__(self, law: FingerLaw, period: float):
        super().__init__()
        self._law = law
        self._h = period
        n, m = law.n, law.m
        self._layout = law.layout
        self._q = self.DeclareVectorInputPort("q", n)
        self._q_hat = self.DeclareVectorInputPort("q_hat", n)
        self._qdot_o = self.DeclareVectorInputPort("qdot_o", n)
        self._reference = self.DeclareVectorInputPort("reference", law.layout.size)
        self._state = self.DeclareDiscreteState(m)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_integral)
        # λ̂(k) once per tick: the output and the update of ΔF̃ read the same cache entry.
        self._estimate = self.DeclareCacheEntry(
            "lambda_hat (22)",
            ValueProducer(allocate=AbstractValue.Make((np.zeros(m), np.zeros(m), False)).Clone,
                          calc=self._calc_estimate),
            {self.xd_ticket(), self.all_input_ports_ticket()})
        self.DeclareVectorOutputPort("lambda_hat", m, self._calc_lambda_hat,
                                     prerequisites_of_calc={self._estimate.ticket()})
        self.DeclareStateOutputPort("Delta_F_tilde", self._state)

    def _calc_estimate(self, context: Context, value: AbstractValue) -> None:
        """``(λ̂(k), λ_d(k), held)`` from the inputs and ``ΔF̃(k)``."""
        ref = self._layout.unpack(self._reference.Eval(context))
        DF = context.get_discrete_state(self._state).CopyToVector()
        lam = self._law.force_estimate(self._q.Eval(context), self._q_hat.Eval(context),
                                       self._qdot_o.Eval(context), ref, DF)
        value.set_value((lam, ref.lambda_d.copy(), ref.held))

    def _calc_lambda_hat(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._estimate.Eval(context)[0])

    def _update_integral(self, context: Context, discrete_state: DiscreteValues) -> None:
        lam, lambda_d, held = self._estimate.Eval(context)
        DF = context.get_discrete_state(self._state).CopyToVector()
        new = DF + self._h * (lam - lambda_d) if held else np.zeros_like(DF)
        discrete_state.set_value(self._state, new)

