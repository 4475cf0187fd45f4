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
    InputPort,
    State,
)

from drake_coop.control.timing import Clock, on_clock
from drake_coop.control.interfaces import ForceSource, VelocitySource
from drake_coop.control.finger import (
    FingerLaw,
    observer_acceleration,
    observer_qdot_hat,
    observer_qdot_o,
)
from drake_coop.control.params import check_count, check_period, check_positive


class VelocityObserver(VelocitySource):
    r"""Model-based joint-velocity observer (15)–(16) of one robot.

    .. pydrake_system::

        name: VelocityObserver
        input_ports:
        - q
        - qddot_r_hat
        output_ports:
        - q_hat
        - qdot_hat
        - qdot_o

    State ``q̂`` (group 0, n) and ``q̇̂_o`` (group 1, n). With ``z = q − q̂``:

    .. math::
        \frac{d}{dt}\hat q = \dot{\hat q}_o + \Lambda z + k_d z \qquad (15)

        \frac{d}{dt}\dot{\hat q}_o = \ddot{\hat q}_r + k_d \Lambda z \qquad (16)

    discretized as ``x(k+1) = x(k) + h f(x(k), q(k), q̈̂_r(k))`` by a periodic discrete update
    every ``h`` (offset 0); the same update is declared as a forced discrete update, so
    ``CalcForcedDiscreteVariableUpdate`` takes one step ``k → k + 1`` in a unit test.

    Initial state: unless :meth:`set_initial_state` was called on the context, an
    initialization event (run by ``Simulator.Initialize``) sets ``q̂(0) = q(0)``, the first
    measured ``q``, and ``q̇̂_o(0) = 0``: the observer never starts from ``q̂ = 0`` by
    omission (with the paper's gains that start squeezed 111 N for 24 N desired). A default
    context that is never initialized holds ``q̂ = 0``, ``q̇̂_o = 0``.

    Cost: each of ``d/dt q̂`` and ``q̇_o`` is computed once per tick (Drake caches an output
    port's value until ``q`` or the state change; the update reads the cached ``d/dt q̂``);
    ``q_hat`` is a state output port (no Python call). The same outputs from C++ gains, or the
    whole observer as a C++ ``LinearSystem``, were measured and ran no faster: every added
    system costs at every plant step (``docs/benchmark.md``).

    It needs nothing of the controller but ``q̈̂_r`` (an input): use it under any controller
    that provides one (its own reference acceleration; zero gives a plain second-order
    observer).

    Parameters
    ----------
    n : int
        Number of joints.
    Lambda : float
        ``k`` of ``Λ = k I`` (1/s), > 0: the gain of ``z`` in (15) and (8).
    k_d : float
        The observer gain ``k_d`` of (15)–(16) (1/s), > 0.
    period : float
        Sampling time ``h`` (s).
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.

    Raises
    ------
    TypeError, ValueError
        Naming ``n``, ``Lambda``, ``k_d`` or ``period``.

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

    def __init__(self, n: int, Lambda: float, k_d: float, period: float, clock: Clock | None = None):
        super().__init__()
        n = check_count(n, "n")
        Lambda = check_positive(Lambda, "Lambda")
        k_d = check_positive(k_d, "k_d")
        self._h = check_period(period)
        self._Lambda_plus_k_d = Lambda + k_d
        self._k_d = k_d
        self._k_d_Lambda = k_d * Lambda
        n = int(n)
        self._n = n
        self._q = self.DeclareVectorInputPort("q", n)
        self._qddot_r = self.DeclareVectorInputPort("qddot_r_hat", n)
        self._q_hat_state = self.DeclareDiscreteState(n)
        self._qdot_hat_o_state = self.DeclareDiscreteState(n)
        # Whether the context holds an initial state given by the user (set_initial_state) or
        # already taken from q: then the initialization event leaves it alone.
        self._given = self.DeclareAbstractState(AbstractValue.Make(False))
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, period), self._update_observer)
        self.DeclareForcedDiscreteUpdateEvent(self._update_observer)
        self.DeclareInitializationUnrestrictedUpdateEvent(self._initialize_from_q)
        # The outputs depend on q and the state only (not on time or q̈̂_r): Drake caches each
        # and recomputes it once per tick, when q or the state changed.
        depends_on_q = {self.xd_ticket(), self._q.ticket()}
        self._q_hat_out = self.DeclareStateOutputPort("q_hat", self._q_hat_state)
        self._qdot_hat_out = self.DeclareVectorOutputPort(
            "qdot_hat", n, self._calc_qdot_hat, prerequisites_of_calc=depends_on_q)
        self._qdot_o_out = self.DeclareVectorOutputPort(
            "qdot_o", n, self._calc_qdot_o, prerequisites_of_calc=depends_on_q)

    # ------------------------------------------------------------------ ports
    def get_qddot_r_hat_input_port(self) -> InputPort:
        """``q̈̂_r`` of (11) from the controller."""
        return self._qddot_r

    # ------------------------------------------------------------------ state
    def set_initial_state(self, context: Context, q_hat: np.ndarray,
                          qdot_hat_o: np.ndarray | None = None) -> None:
        """``q̂(0)`` and ``q̇̂_o(0)`` (default zero) in this system's context; the
        initialization event then keeps them.

        Parameters
        ----------
        context : Context
            This system's context.
        q_hat : numpy.ndarray
            ``q̂(0)`` (n,), rad.
        qdot_hat_o : numpy.ndarray or None
            ``q̇̂_o(0)`` (n,), rad/s; None for zero.
        """
        context.SetDiscreteState(self._q_hat_state, q_hat)
        context.SetDiscreteState(self._qdot_hat_o_state,
                                 np.zeros(self._n) if qdot_hat_o is None else qdot_hat_o)
        context.SetAbstractState(self._given, True)

    def _initialize_from_q(self, context: Context, state: State) -> None:
        """At ``Simulator.Initialize``: ``q̂ = q``, ``q̇̂_o = 0`` unless already given."""
        if context.get_abstract_state(self._given).get_value():
            return
        xd = state.get_mutable_discrete_state()
        xd.set_value(self._q_hat_state, self._q.Eval(context))
        xd.set_value(self._qdot_hat_o_state, np.zeros(self._n))
        state.get_mutable_abstract_state(self._given).set_value(True)

    def _split(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        return (context.get_discrete_state(self._q_hat_state).value(),
                context.get_discrete_state(self._qdot_hat_o_state).value())

    def _calc_qdot_hat(self, context: Context, output: BasicVector) -> None:
        """``d/dt q̂ = q̇̂_o + (Λ + k_d) z`` of (15)."""
        output.SetFromVector(observer_qdot_hat(self._q.Eval(context), *self._split(context),
                                               self._Lambda_plus_k_d))

    def _calc_qdot_o(self, context: Context, output: BasicVector) -> None:
        """``q̇_o = q̇̂_o + k_d z`` of (8)."""
        output.SetFromVector(observer_qdot_o(self._q.Eval(context), *self._split(context),
                                             self._k_d))

    def _update_observer(self, context: Context, discrete_state: DiscreteValues) -> None:
        q = self._q.Eval(context)
        q_hat, qdot_hat_o = self._split(context)
        qdot_hat = self._qdot_hat_out.Eval(context)
        qddot_hat_o = observer_acceleration(q, q_hat, self._qddot_r.Eval(context),
                                            self._k_d_Lambda)
        discrete_state.set_value(self._q_hat_state, q_hat + self._h * qdot_hat)
        discrete_state.set_value(self._qdot_hat_o_state, qdot_hat_o + self._h * qddot_hat_o)


class ForceObserver(ForceSource):
    r"""Contact-force observer (22) of one robot, with the force integral ΔF̃ (6) as state.

    .. pydrake_system::

        name: ForceObserver
        input_ports:
        - q
        - q_hat
        - qdot_o
        - reference
        output_ports:
        - lambda_hat
        - Delta_F_tilde

    .. math::
        \hat\lambda = \frac{1}{1+\zeta}\Big[J^{+T}(q) K_R(\dot q_o - \dot q_r)
                        - k_F \Delta\tilde F\Big] + \lambda_d \qquad (22)

    (22) is (21) with the controller (13) substituted and solved for ``λ̂``: it needs no torque,
    so observer and controller form no algebraic loop. ``ΔF̃(k+1) = ΔF̃(k) + h (λ̂(k) − λ_d(k))``
    while the object is held; before the grasp and after the release ``λ̂ = 0`` and ``ΔF̃`` is
    reset to 0 (the integral (6) starts at the grasp). ``ΔF̃(0) = 0``. The update is periodic
    (every ``h``, offset 0) and also declared as a forced discrete update.

    Parameters
    ----------
    law : FingerLaw
        The robot's law (model, gains, ``n``, ``m``).
    period : float
        Sampling time ``h`` (s), > 0.
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.

    Input ports
    -----------
    q, q_hat, qdot_o : n-vectors
        Measured positions and the velocity observer's outputs.
    reference : (3n + m + 1)-vector
        ``[q_d, q̇_d, q̈_d, λ_d, held]`` (:class:`~drake_coop.control.reference_layout.ReferenceLayout`).

    Output ports
    ------------
    lambda_hat : m-vector
        ``λ̂(k)`` (depends on the inputs of tick k).
    Delta_F_tilde : m-vector
        ``ΔF̃(k)`` (state only).
    """

    def __init__(self, law: FingerLaw, period: float, clock: Clock | None = None):
        super().__init__()
        check_period(period)
        self._law = law
        self._h = period
        n, m = law.n, law.m
        self._layout = law.layout
        self._lambda_d_rows = law.layout.slices()["lambda_d"]
        self._zero_m = np.zeros(m)
        self._q = self.DeclareVectorInputPort("q", n)
        self._q_hat = self.DeclareVectorInputPort("q_hat", n)
        self._qdot_o = self.DeclareVectorInputPort("qdot_o", n)
        self._reference = self.DeclareVectorInputPort("reference", law.layout.size)
        self._state = self.DeclareDiscreteState(m)
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, period), self._update_integral)
        self.DeclareForcedDiscreteUpdateEvent(self._update_integral)
        # λ̂(k) is computed once per tick: the update reads the output port, whose value
        # Drake caches (it depends on this system's state and inputs only).
        self._lambda_hat_out = self.DeclareVectorOutputPort(
            "lambda_hat", m, self._calc_lambda_hat,
            prerequisites_of_calc={self.xd_ticket(), self.all_input_ports_ticket()})
        self._Delta_F_out = self.DeclareStateOutputPort("Delta_F_tilde", self._state)

    def get_q_input_port(self) -> InputPort:
        """Measured joint positions ``q``."""
        return self._q

    def get_q_hat_input_port(self) -> InputPort:
        """The velocity observer's ``q̂``."""
        return self._q_hat

    def get_qdot_o_input_port(self) -> InputPort:
        """The velocity observer's ``q̇_o``."""
        return self._qdot_o

    def _calc_lambda_hat(self, context: Context, output: BasicVector) -> None:
        """``λ̂(k)`` of (22) from the inputs and ``ΔF̃(k)``."""
        ref = self._layout.unpack(self._reference.Eval(context))
        DF = context.get_discrete_state(self._state).value()
        output.SetFromVector(self._law.force_estimate(
            self._q.Eval(context), self._q_hat.Eval(context), self._qdot_o.Eval(context), ref,
            DF))

    def _update_integral(self, context: Context, discrete_state: DiscreteValues) -> None:
        r = self._reference.Eval(context)
        if self._layout.held(r):
            DF = context.get_discrete_state(self._state).value()
            new = DF + self._h * (self._lambda_hat_out.Eval(context) - r[self._lambda_d_rows])
        else:
            new = self._zero_m
        discrete_state.set_value(self._state, new)

