r"""Delay compensation: the controller's inputs predicted over a horizon ``p`` with its own model.

A computation (and transport) delay ``d`` puts ``τ(k)`` on the arm at ``t_k + d``; until then
``τ(k−1)`` acts. The paper's controller (13) computes ``τ(k)`` from the state at ``t_k``, so its
feedback lags by ``d``, and the loop's delay margin is a few milliseconds (``docs/stability.md``).
:class:`DelayPredictor` sits between the velocity source (and the encoders' ``q``) and the
controller (13) and force observer (22): it advances what they read over a horizon ``p`` with
the controller's own arm model, driven by the torque that is actually on the arm,

.. math::
    a = H(q)^{-1}\big(\tau(k-1) + J_\varphi^T(q)\hat\lambda(k-1)
        - C(q,\dot{\hat q})\dot{\hat q} - D\dot{\hat q} - g(q)\big)

    q_p = q + p\,\dot{\hat q} + \tfrac{p^2}{2} a, \qquad
    \hat q_p = \hat q + p\,\dot{\hat q} + \tfrac{p^2}{2} a, \qquad
    \dot{\hat q}_p = \dot{\hat q} + p\,a, \qquad \dot q_{o,p} = \dot q_o + p\,a,

(``z = q − q̂`` is left as it is: the whole estimate is shifted by the predicted motion), and
feeds the velocity observer (16), which runs on the measured ``q`` in real time, the
acceleration as it acts over the coming period: ``τ(k−1)``'s for the first ``p``, the new
``q̈̂_r(k)`` for the rest,

.. math::
    \ddot{\hat q}_{r,\mathrm{fed}} = \frac{p}{h}\,a + \Big(1 - \frac{p}{h}\Big)\ddot{\hat q}_r(k).

``λ̂(k−1)`` is the force source's estimate of the previous tick (zero in free motion): in the
held phase the constraint force carries the arm's load, and a prediction without it would
accelerate the arm by ``H⁻¹ J_φᵀ λ`` (a velocity bias of ``p H⁻¹ J_φᵀ λ``).

The horizon is a design choice, not the delay: with the paper's gains at ``h`` = 9 ms the
stability map (``docs/stability.md``, "Delay compensation", on the continuous-arm basis) shows a
fixed horizon of 3 ms keeping the loop stable from 0 to 8 ms of delay with the exact model and
from 0 to 6 ms with models 30 % light or heavy, without knowing the delay.

With no predictor in the diagram (the default) nothing of the paper's block changes.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, InputPort, LeafSystem

from drake_coop.control.timing import Clock, on_clock
from drake_coop.control.finger import FingerLaw
from drake_coop.control.params import check_period

__all__ = ["DelayPredictor", "check_horizon"]


def check_horizon(horizon: float, period: float, name: str = "prediction_horizon") -> float:
    """``0 < horizon <= period`` (``ValueError`` naming ``name``).

    Parameters
    ----------
    horizon : float
        The prediction horizon ``p`` (s).
    period : float
        The control period ``h`` (s).
    name : str
        The argument or field named in the error.
    """
    if isinstance(horizon, bool) or not isinstance(horizon, (int, float)) \
            or not np.isfinite(horizon) or not 0.0 < horizon <= period * (1 + 1e-9):
        raise ValueError(f"{name}: a prediction horizon in (0, control period = {period:g} s] "
                         f"is required, got {horizon!r}")
    return float(horizon)


class DelayPredictor(LeafSystem):
    """Predicts the controller's and the force observer's inputs over a horizon ``p``.

    .. pydrake_system::

        name: DelayPredictor
        input_ports:
        - q
        - q_hat
        - qdot_hat
        - qdot_o
        - qddot_r_hat
        - tau
        - lambda_hat
        output_ports:
        - q_p
        - q_hat_p
        - qdot_hat_p
        - qdot_o_p
        - qddot_fed
        - acceleration

    State: ``τ`` (group 0, n), ``λ̂`` (group 1, m) latched at every tick by a periodic discrete
    update (offset 0) from the ``tau`` and ``lambda_hat`` inputs, i.e. ``τ(k)``, ``λ̂(k)`` after
    the controller's latch at ``t_k``: at :math:`t_{k+1}` they are the torque still on the arm and
    the last force estimate. Group 2 is 1 once something was latched; before that ``a = 0``.

    Parameters
    ----------
    law : FingerLaw
        The robot's law (its model gives ``H``, ``C``, ``D``, ``g``, ``J_φ``).
    period : float
        The control period ``h`` (s).
    horizon : float
        The prediction horizon ``p`` (s), ``0 < p <= h``.
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.

    Input ports
    -----------
    q : n-vector
        Measured positions ``q(k)``.
    q_hat, qdot_hat, qdot_o : n-vectors
        The velocity source's outputs at ``t_k``.
    qddot_r_hat : n-vector
        The controller's latched ``q̈̂_r(k)``.
    tau : n-vector
        The controller's latched torque.
    lambda_hat : m-vector
        The force source's ``λ̂``.

    Output ports
    ------------
    q_p, q_hat_p, qdot_hat_p, qdot_o_p : n-vectors
        The predicted inputs of (13) and (22).
    qddot_fed : n-vector
        The acceleration fed to the velocity observer (16).
    acceleration : n-vector
        The model's ``a`` above.
    """

    def __init__(self, law: FingerLaw, period: float, horizon: float, clock: Clock | None = None):
        super().__init__()
        h = check_period(period)
        self._p = check_horizon(horizon, h)
        self._w = self._p / h
        self._law = law
        self._model = law.model
        n, m = law.n, law.m
        self._n, self._m = n, m
        self._q = self.DeclareVectorInputPort("q", n)
        self._q_hat = self.DeclareVectorInputPort("q_hat", n)
        self._qdot_hat = self.DeclareVectorInputPort("qdot_hat", n)
        self._qdot_o = self.DeclareVectorInputPort("qdot_o", n)
        self._qddot_r = self.DeclareVectorInputPort("qddot_r_hat", n)
        self._tau = self.DeclareVectorInputPort("tau", n)
        self._lambda = self.DeclareVectorInputPort("lambda_hat", m)
        self._tau_state = self.DeclareDiscreteState(n)
        self._lambda_state = self.DeclareDiscreteState(m)
        self._valid_state = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, h), self._latch)
        self.DeclareForcedDiscreteUpdateEvent(self._latch)
        xd = self.xd_ticket()
        acc_deps = {xd, self._q.ticket(), self._qdot_hat.ticket()}
        self._a_out = self.DeclareVectorOutputPort("acceleration", n, self._calc_a,
                                                   prerequisites_of_calc=acc_deps)
        pos = acc_deps | {self._q_hat.ticket()}
        self.DeclareVectorOutputPort("q_p", n, self._calc_q_p, prerequisites_of_calc=acc_deps)
        self.DeclareVectorOutputPort("q_hat_p", n, self._calc_q_hat_p, prerequisites_of_calc=pos)
        self.DeclareVectorOutputPort("qdot_hat_p", n, self._calc_qdot_hat_p,
                                     prerequisites_of_calc=acc_deps)
        self.DeclareVectorOutputPort("qdot_o_p", n, self._calc_qdot_o_p,
                                     prerequisites_of_calc=acc_deps | {self._qdot_o.ticket()})
        self.DeclareVectorOutputPort("qddot_fed", n, self._calc_fed,
                                     prerequisites_of_calc=acc_deps | {self._qddot_r.ticket()})

    @property
    def horizon(self) -> float:
        """The prediction horizon ``p`` (s)."""
        return self._p

    def get_tau_input_port(self) -> InputPort:
        return self._tau

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                     lambda_hat: np.ndarray) -> np.ndarray:
        """``a = H⁻¹(τ + J_φᵀ λ̂ − C v − D v − g)`` on the controller's model.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        v : numpy.ndarray
            Joint velocities (n,), rad/s.
        tau : numpy.ndarray
            The applied torque (n,), N·m.
        lambda_hat : numpy.ndarray
            The force estimate ``λ̂`` (m,), N.
        """
        model = self._model
        rhs = np.asarray(tau, dtype=float) - model.inverse_dynamics_terms(q, v, np.zeros(self._n))
        if np.any(lambda_hat):
            rhs = rhs + model.J_phi(q).T @ np.asarray(lambda_hat, dtype=float)
        return np.linalg.solve(model.H(q), rhs)

    def _calc_a(self, context: Context, output: BasicVector) -> None:
        if context.get_discrete_state(self._valid_state).value()[0] < 0.5:
            output.SetFromVector(np.zeros(self._n))
            return
        output.SetFromVector(self.acceleration(
            self._q.Eval(context), self._qdot_hat.Eval(context),
            context.get_discrete_state(self._tau_state).value(),
            context.get_discrete_state(self._lambda_state).value()))

    def _shift(self, context: Context) -> np.ndarray:
        p = self._p
        return p * self._qdot_hat.Eval(context) + 0.5 * p * p * self._a_out.Eval(context)

    def _calc_q_p(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._q.Eval(context) + self._shift(context))

    def _calc_q_hat_p(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._q_hat.Eval(context) + self._shift(context))

    def _calc_qdot_hat_p(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._qdot_hat.Eval(context) + self._p * self._a_out.Eval(context))

    def _calc_qdot_o_p(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._qdot_o.Eval(context) + self._p * self._a_out.Eval(context))

    def _calc_fed(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._w * self._a_out.Eval(context)
                             + (1.0 - self._w) * self._qddot_r.Eval(context))

    def _latch(self, context: Context, xd: DiscreteValues) -> None:
        xd.set_value(self._tau_state, self._tau.Eval(context))
        xd.set_value(self._lambda_state, self._lambda.Eval(context))
        xd.set_value(self._valid_state, [1.0])
