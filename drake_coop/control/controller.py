r"""The decentralized position/force controller (13) of one robot as a Drake LeafSystem.

.. math::
    \tau = H(q)\ddot{\hat q}_r + C(q,\dot q_r)\dot q_r + D\dot q_r + g(q)
            - K_R(\dot q_o - \dot q_r)
            - J_\varphi^T(q)\big(\lambda_d - k_F\Delta\tilde F - \zeta\Delta\tilde\lambda\big)

with ``q̇_r`` of (4), ``q̈̂_r`` of (11) and the exact directional derivatives ``Q̂̇``, ``Ĵ⁺̇``
of (7) along ``q̇_o``; in free motion (before the grasp, after the release) the same law with
``Q = I``, ``J_φ = 0``, ``J⁺ = 0``.

Sampling (zero-order hold, no computation delay): the torque of tick ``k`` is computed from
``q(k)`` and the observers' tick-``k`` outputs and applied on :math:`[t_k, t_{k+1})`. A periodic
*unrestricted* update at ``t_k`` latches ``τ(k)`` and ``q̈̂_r(k)`` into state; Drake runs a
time's unrestricted updates before its discrete updates (the plant's step, the observers'
updates), so the plant's step at ``t_k`` already applies ``τ(k)`` and the velocity observer's
update at ``t_k`` reads ``q̈̂_r(k)``. Both outputs are state output ports: no Python call
happens at the plant's steps between two ticks.

What the outputs mean at a tick *before* its events (a simulator stopped by ``AdvanceTo(k h)``,
a logger publishing at ``t_k``): ``tau`` and ``qddot_r_hat`` still hold ``τ(k − 1)`` and
``q̈̂_r(k − 1)``, the values applied on :math:`[t_{k-1}, t_k)`. The values the tick's update
will latch are :meth:`Controller.next_tau` and :meth:`Controller.terms` (the law at the current
inputs). Loggers therefore see ``τ(k)`` at :math:`t_{k+1}`;
:func:`~drake_coop.experiment.simulate.collect_logs` shifts those logs back by one sample.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    Context,
    DiscreteValues,
    InputPort,
    LeafSystem,
    OutputPort,
    State,
)

from drake_coop.control.timing import Clock, on_clock
from drake_coop.control.finger import FingerLaw
from drake_coop.control.params import check_period
from drake_coop.control.timing import tick_of


class Controller(LeafSystem):
    """Controller (13) of one robot, reading measured joint positions only.

    .. pydrake_system::

        name: Controller
        input_ports:
        - q
        - q_hat
        - qdot_hat
        - qdot_o
        - lambda_hat
        - Delta_F_tilde
        - reference
        output_ports:
        - tau
        - qddot_r_hat

    The latch of ``τ(k)``, ``q̈̂_r(k)`` and ``k`` is a periodic unrestricted update (every
    ``h``, offset 0: before the plant's step of the same instant) and is also declared as a
    forced discrete update, so ``CalcForcedDiscreteVariableUpdate`` gives the state the tick
    would latch (its tick index: the context's time as a tick, else the last tick before it).

    Parameters
    ----------
    law : FingerLaw
        The robot's law (model, gains, ``n``, ``m``).
    period : float
        Sampling time ``h`` (s), > 0.
    tau0 : array_like, optional
        The torque held before the first tick (default zero); n entries.
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.

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
        ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:class:`~drake_coop.control.reference_layout.ReferenceLayout`).

    Output ports
    ------------
    tau : n-vector
        Joint torques ``τ(k)``, latched at ``t_k`` and held over :math:`[t_k, t_{k+1})` (state
        only; ``τ(k − 1)`` at ``t_k`` before the tick's update).
    qddot_r_hat : n-vector
        ``q̈̂_r(k)`` of (11), latched with ``τ(k)`` for the velocity observer's update (16) at
        the same tick (state only).
    """

    def __init__(self, law: FingerLaw, period: float, tau0: np.ndarray | None = None, clock: Clock | None = None):
        super().__init__()
        check_period(period)
        self._law = law
        self._h = period
        n = law.n
        self._n = n
        if tau0 is not None and np.shape(tau0) != (n,):
            raise ValueError(f"tau0: {n} torques are required (got shape {np.shape(tau0)})")
        self._q = self.DeclareVectorInputPort("q", n)
        self._q_hat = self.DeclareVectorInputPort("q_hat", n)
        self._qdot_hat = self.DeclareVectorInputPort("qdot_hat", n)
        self._qdot_o = self.DeclareVectorInputPort("qdot_o", n)
        self._layout = law.layout
        self._lambda_hat = self.DeclareVectorInputPort("lambda_hat", law.m)
        self._Delta_F = self.DeclareVectorInputPort("Delta_F_tilde", law.m)
        self._reference = self.DeclareVectorInputPort("reference", law.layout.size)
        # Latched τ(k), q̈̂_r(k) and k (k = -1: nothing latched yet).
        self._tau_state = self.DeclareDiscreteState(np.zeros(n) if tau0 is None
                                                    else np.asarray(tau0, dtype=float))
        self._qddot_state = self.DeclareDiscreteState(np.zeros(n))
        self._tick_state = self.DeclareDiscreteState([-1.0])
        self.DeclarePeriodicUnrestrictedUpdateEvent(*on_clock(clock, period), self._update_latch)
        self.DeclareForcedDiscreteUpdateEvent(self._latch)
        self._tau_out = self.DeclareStateOutputPort("tau", self._tau_state)
        self._qddot_out = self.DeclareStateOutputPort("qddot_r_hat", self._qddot_state)

    # ------------------------------------------------------------------ ports
    def get_q_input_port(self) -> InputPort:
        """Measured joint positions ``q``."""
        return self._q

    def get_q_hat_input_port(self) -> InputPort:
        """The velocity observer's ``q̂``."""
        return self._q_hat

    def get_qdot_hat_input_port(self) -> InputPort:
        """The velocity observer's ``d/dt q̂``."""
        return self._qdot_hat

    def get_qdot_o_input_port(self) -> InputPort:
        """The velocity observer's ``q̇_o``."""
        return self._qdot_o

    def get_lambda_hat_input_port(self) -> InputPort:
        """The force observer's ``λ̂``."""
        return self._lambda_hat

    def get_Delta_F_tilde_input_port(self) -> InputPort:
        """The force observer's ``ΔF̃``."""
        return self._Delta_F

    def get_reference_input_port(self) -> InputPort:
        """The reference ``[q_d, q̇_d, q̈_d, λ_d, held]``."""
        return self._reference

    def get_tau_output_port(self) -> OutputPort:
        """The latched torque ``τ``."""
        return self._tau_out

    def get_qddot_r_hat_output_port(self) -> OutputPort:
        """The latched ``q̈̂_r``."""
        return self._qddot_out

    # ------------------------------------------------------------------ helpers
    def tick_of(self, context: Context) -> int | None:
        """The tick index if the context's time is a sampling instant, else None.

        Parameters
        ----------
        context : Context
            This system's context.

        Returns
        -------
        int or None
            ``k`` with ``t = k h``, or None between ticks.
        """
        return tick_of(context.get_time(), self._h)

    def terms(self, context: Context) -> dict[str, np.ndarray]:
        """``tau``, ``qdot_r``, ``qddot_r_hat``, ``Delta_lambda_tilde`` from the current inputs:
        at a tick, what the tick's update latches.

        Computed on each call (no cache entry: in a simulation the latch is its one caller
        per tick).

        Parameters
        ----------
        context : Context
            This system's context.

        Returns
        -------
        dict of str to numpy.ndarray
            ``tau`` (N·m), ``qdot_r`` (rad/s), ``qddot_r_hat`` (rad/s²), ``Delta_lambda_tilde`` (N).
        """
        return self._law.control(
            self._q.Eval(context), self._q_hat.Eval(context), self._qdot_hat.Eval(context),
            self._qdot_o.Eval(context), self._lambda_hat.Eval(context),
            self._Delta_F.Eval(context), self._layout.unpack(self._reference.Eval(context)))

    def next_tau(self, context: Context) -> np.ndarray:
        """``τ(k)`` of (13) at the current inputs: at tick ``k`` before its events, the torque
        the tick's update latches and the plant then applies on :math:`[t_k, t_{k+1})`.

        Parameters
        ----------
        context : Context
            This system's context.
        """
        return self.terms(context)["tau"]

    def latched_tick(self, context: Context) -> int:
        """The last tick whose torque was latched (-1 before the first).

        Parameters
        ----------
        context : Context
            This system's context.
        """
        return int(context.get_discrete_state(self._tick_state).value()[0])

    # ------------------------------------------------------------------ update
    def _update_latch(self, context: Context, state: State) -> None:
        self._latch(context, state.get_mutable_discrete_state())

    def _latch(self, context: Context, xd: DiscreteValues) -> None:
        k = self.tick_of(context)
        if k is None:      # a forced update between ticks: the last tick before
            k = int(np.floor(context.get_time() / self._h))
        terms = self.terms(context)
        xd.set_value(self._tau_state, terms["tau"])
        xd.set_value(self._qddot_state, terms["qddot_r_hat"])
        xd.set_value(self._tick_state, [float(k)])
