"""The decentralized position/force controller (13) of one robot as a Drake LeafSystem.

.. math::
    \\tau = H(q)\\ddot{\\hat q}_r + C(q,\\dot q_r)\\dot q_r + D\\dot q_r + g(q)
            - K_R(\\dot q_o - \\dot q_r)
            - J_\\varphi^T(q)\\big(\\lambda_d - k_F\\Delta\\tilde F - \\zeta\\Delta\\tilde\\lambda\\big)

with ``q̇_r`` of (4), ``q̈̂_r`` of (11) and the exact directional derivatives ``Q̂̇``, ``Ĵ⁺̇``
of (7) along ``q̇_o``; in free motion (before the grasp, after the release) the same law with
``Q = I``, ``J_φ = 0``, ``J⁺ = 0``.

Sampling (zero-order hold, no computation delay): the torque of tick ``k`` is computed from
``q(k)`` and the observers' tick-``k`` outputs and applied on ``[t_k, t_{k+1})``. Drake runs the
plant's own step at ``t_k`` at the same time as the controller's update, so the ``tau`` output
computes ``τ(k)`` directly from the inputs when evaluated at a tick that has not been latched
yet, and returns the latched value otherwise; the periodic update latches ``τ(k)`` (state
``[τ, k]``). The plant's state output does not depend on its actuation input, so this makes no
algebraic loop.
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
from drake_coop.scenario.timing import tick_of


class Controller(LeafSystem):
    """Controller (13) of one robot, reading measured joint positions only.

    Input ports
    -----------
    q : n-vector
        Measured joint positions ``q(k)``.
    q_hat, qdot_hat, qdot_o : n-vectors
        The velocity observer's ``q̂``, ``d/dt q̂`` (15) and ``q̇_o`` (8).
    lambda_hat : m-vector
        The force observer's ``λ̂`` (22).
    Delta_F_tilde : m-vector
        The force observer's integral ``ΔF̃`` (6).
    reference : (3n + m + 1)-vector
        ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:class:`~drake_coop.control.finger.ReferenceLayout`).

    Output ports
    ------------
    tau : n-vector
        Joint torques ``τ(k)``, held over the sampling interval.
    qddot_r_hat : n-vector
        ``q̈̂_r(k)`` of (11), for the velocity observer's update (16) at the same tick.
    """

    def __init__(self, law: FingerLaw, period: float, tau0: np.ndarray | None = None):
        super().__init__()
        self._law = law
        self._h = period
        n = law.n
        self._n = n
        self._q = self.DeclareVectorInputPort("q", n)
        self._q_hat = self.DeclareVectorInputPort("q_hat", n)
        self._qdot_hat = self.DeclareVectorInputPort("qdot_hat", n)
        self._qdot_o = self.DeclareVectorInputPort("qdot_o", n)
        self._layout = law.layout
        self._lambda_hat = self.DeclareVectorInputPort("lambda_hat", law.m)
        self._Delta_F = self.DeclareVectorInputPort("Delta_F_tilde", law.m)
        self._reference = self.DeclareVectorInputPort("reference", law.layout.size)
        # Latched [τ(k), k]; k = -1 means nothing latched yet.
        initial = np.concatenate([np.zeros(n) if tau0 is None else tau0, [-1.0]])
        self._state = self.DeclareDiscreteState(initial)
        self._terms = self.DeclareCacheEntry(
            "control terms of (13)",
            ValueProducer(allocate=AbstractValue.Make(dict()).Clone, calc=self._calc_terms),
            {self.all_sources_ticket()})
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_latch)
        self.DeclareVectorOutputPort("tau", n, self._calc_tau)
        self.DeclareVectorOutputPort("qddot_r_hat", n, self._calc_qddot_r_hat)

    # ------------------------------------------------------------------ helpers
    def tick_of(self, context: Context) -> int | None:
        """The tick index if the context's time is a sampling instant, else None."""
        return tick_of(context.get_time(), self._h)

    def _calc_terms(self, context: Context, value: AbstractValue) -> None:
        ref = self._layout.unpack(self._reference.Eval(context))
        terms = self._law.control(
            self._q.Eval(context), self._q_hat.Eval(context), self._qdot_hat.Eval(context),
            self._qdot_o.Eval(context), self._lambda_hat.Eval(context),
            self._Delta_F.Eval(context), ref)
        value.set_value(terms)

    def terms(self, context: Context) -> dict[str, np.ndarray]:
        """``tau``, ``qdot_r``, ``qddot_r_hat``, ``Delta_lambda_tilde`` from the current inputs."""
        return self._terms.Eval(context)

    # ------------------------------------------------------------------ outputs
    def _calc_tau(self, context: Context, output: BasicVector) -> None:
        # Called at every plant step: the test of "a tick not latched yet" is inlined
        # (tick_of's arithmetic) to keep the held case to three framework calls.
        t = context.get_time()
        k = round(t / self._h)
        x = context.get_discrete_state(self._state).value()
        if x[-1] != k and abs(t - k * self._h) <= 1e-9 * max(1.0, t):
            output.SetFromVector(self.terms(context)["tau"])   # τ(k), not latched yet
        else:
            output.SetFromVector(x[: self._n])                  # held τ(k)

    def _calc_qddot_r_hat(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self.terms(context)["qddot_r_hat"])

    # ------------------------------------------------------------------ update
    def _update_latch(self, context: Context, discrete_state: DiscreteValues) -> None:
        k = self.tick_of(context)
        tau = self.terms(context)["tau"]
        discrete_state.set_value(self._state, np.concatenate([tau, [float(k)]]))
