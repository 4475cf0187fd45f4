"""Alternatives to the paper's observers, with the same output ports (a control block swaps them).

Velocity sources (outputs ``q_hat``, ``qdot_hat``, ``qdot_o``, as
:class:`~drake_coop.control.observers.VelocityObserver`):

* :class:`MeasuredVelocity` — the true joint velocities (a baseline: a perfect tachometer);
* :class:`DifferenceVelocity` — the backward difference of the encoder signal at ``h``,
  optionally low-passed: the numerical differentiation that the paper's references [7]–[10]
  compare against.

Both set ``q̂ = q`` (the encoder reading), so ``z = 0`` and ``d/dt q̂ = q̇_o`` = the velocity
estimate.

Force sources (outputs ``lambda_hat``, ``Delta_F_tilde``, as
:class:`~drake_coop.control.observers.ForceObserver`):

* :class:`SensedForce` — classical force feedback: the F/T sensor's ``λ_s`` used in place of
  ``λ̂`` in (13) and in the integral (6);
* :class:`NoForceEstimate` — no force information: ``λ̂ := λ_d`` and ``ΔF̃ ≡ 0``, the implicit
  force control of reference [9] that relies on the constraint alone.

As for the observers, ``λ̂ = 0`` and ``ΔF̃ = 0`` in free motion.
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

from drake_coop.control.anti_windup import (
    back_calculation,
    back_calculation_gains,
    check_limits,
    clipped,
    force_integral_step,
)
from drake_coop.control.interfaces import ForceSource, VelocitySource
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.params import check_count, check_optional_positive, check_period
from drake_coop.control.timing import Clock, lowpass_alpha, on_clock


class MeasuredVelocity(VelocitySource):
    """Baseline for comparisons, *not* the paper's scheme: the true joint velocities.

    .. pydrake_system::

        name: MeasuredVelocity
        input_ports:
        - state
        - q
        output_ports:
        - q_hat
        - qdot_hat
        - qdot_o

    ``q̂ = q`` (the encoder reading), ``d/dt q̂ = q̇_o = q̇`` from the plant's state, so that
    ``z = 0``. With ideal encoders a run with it isolates what the velocity observer costs.

    Input ports
    -----------
    state : 2n-vector
        The arm's ``[q, q̇]`` from the plant (only ``q̇`` is read when ``q`` is connected).
    q : n-vector, optional
        The encoder reading; when not connected ``q̂`` is the plant's ``q``.

    Output ports
    ------------
    q_hat, qdot_hat, qdot_o : n-vectors

    Parameters
    ----------
    n : int
        Joints (> 0). Stateless: no update, nothing to initialize.
    """

    def __init__(self, n: int):
        super().__init__()
        self._n = n = check_count(n, "n")
        self._state = self.DeclareVectorInputPort("state", 2 * n)
        self._q = self.DeclareVectorInputPort("q", n)
        self._q_hat_out = self.DeclareVectorOutputPort("q_hat", n, self._calc_q)
        self._qdot_hat_out = self.DeclareVectorOutputPort("qdot_hat", n, self._calc_v)
        self._qdot_o_out = self.DeclareVectorOutputPort("qdot_o", n, self._calc_v)

    def get_state_input_port(self) -> InputPort:
        """The arm's ``[q, q̇]``."""
        return self._state

    def set_initial_state(self, context: Context, q_hat: np.ndarray,
                          qdot_hat_o: np.ndarray | None = None) -> None:
        """Nothing to initialize (stateless); kept for the same interface as the observer.

        Parameters
        ----------
        context : Context
            This system's context.
        q_hat : numpy.ndarray
            Ignored (n,), rad.
        qdot_hat_o : numpy.ndarray or None
            Ignored.
        """

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        if self._q.HasValue(context):
            output.SetFromVector(self._q.Eval(context))
        else:
            output.SetFromVector(self._state.Eval(context)[: self._n])

    def _calc_v(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._state.Eval(context)[self._n:])


class DifferenceVelocity(VelocitySource):
    r"""Backward difference of the encoder signal, with an optional first-order low-pass.

    .. pydrake_system::

        name: DifferenceVelocity
        input_ports:
        - q
        output_ports:
        - q_hat
        - qdot_hat
        - qdot_o

    .. math::
        u(k) = \frac{q(k) - q(k-1)}{h}, \qquad
        \dot{\hat q}(k) = \dot{\hat q}(k-1) + \alpha\,(u(k) - \dot{\hat q}(k-1))

    with ``α = 1 − exp(−2π f_c h)`` (``α = 1``, the raw difference, without a cutoff). State
    ``[q(k−1), q̇̂(k−1)]``; at tick ``k`` the outputs use the current input ``q(k)`` (no sample
    of delay beyond the difference's own); the update stores ``q(k)`` and ``q̇̂(k)``.
    Initially ``q(−1) = q(0)`` and ``q̇̂(−1) = 0``: unless :meth:`set_initial_state` was
    called, an initialization event (``Simulator.Initialize``) takes ``q(−1)`` from the first
    measured ``q``. The update is periodic (every ``h``, offset 0) and also forced.

    Parameters
    ----------
    n : int
        Joints.
    period : float
        Sampling time ``h`` (s), > 0.
    cutoff_hz : float, optional
        Low-pass cutoff ``f_c`` (Hz), > 0; none: the raw difference.
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.

    Input ports
    -----------
    q : n-vector
        Encoder reading.

    Output ports
    ------------
    q_hat : n-vector
        ``q(k)``.
    qdot_hat, qdot_o : n-vectors
        ``q̇̂(k)``.
    """

    def __init__(self, n: int, period: float, cutoff_hz: float | None = None, clock: Clock | None = None):
        super().__init__()
        self._n = n = check_count(n, "n")
        self._h = period = check_period(period)
        cutoff_hz = check_optional_positive(cutoff_hz, "cutoff_hz")
        self._alpha = lowpass_alpha(cutoff_hz, period)
        self._q = self.DeclareVectorInputPort("q", n)
        self._state = self.DeclareDiscreteState(2 * n)
        self._given = self.DeclareAbstractState(AbstractValue.Make(False))
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, period), self._update_difference)
        self.DeclareForcedDiscreteUpdateEvent(self._update_difference)
        self.DeclareInitializationUnrestrictedUpdateEvent(self._initialize_from_q)
        self._q_hat_out = self.DeclareVectorOutputPort(
            "q_hat", n, self._calc_q_hat, prerequisites_of_calc={self._q.ticket()})
        self._qdot_hat_out = self.DeclareVectorOutputPort("qdot_hat", n, self._calc_velocity)
        self._qdot_o_out = self.DeclareVectorOutputPort("qdot_o", n, self._calc_velocity)

    @property
    def alpha(self) -> float:
        """The low-pass gain ``α``."""
        return self._alpha

    def set_initial_state(self, context: Context, q_hat: np.ndarray,
                          qdot_hat_o: np.ndarray | None = None) -> None:
        """``q(−1) = q_hat`` (the initial reading) and ``q̇̂(−1)`` (default zero).

        Parameters
        ----------
        context : Context
            This system's context.
        q_hat : numpy.ndarray
            The initial reading ``q(−1)`` (n,), rad.
        qdot_hat_o : numpy.ndarray or None
            ``q̇̂(−1)`` (n,), rad/s; None for zero.
        """
        v = np.zeros(self._n) if qdot_hat_o is None else qdot_hat_o
        context.SetDiscreteState(self._state, np.concatenate([q_hat, v]))
        context.SetAbstractState(self._given, True)

    def _initialize_from_q(self, context: Context, state: State) -> None:
        """At ``Simulator.Initialize``: ``q(−1) = q``, ``q̇̂(−1) = 0`` unless already given."""
        if context.get_abstract_state(self._given).get_value():
            return
        state.get_mutable_discrete_state().set_value(
            self._state, np.concatenate([self._q.Eval(context), np.zeros(self._n)]))
        state.get_mutable_abstract_state(self._given).set_value(True)

    def _velocity(self, context: Context) -> np.ndarray:
        x = context.get_discrete_state(self._state).value()
        q_prev, v_prev = x[: self._n], x[self._n:]
        u = (self._q.Eval(context) - q_prev) / self._h
        return v_prev + self._alpha * (u - v_prev)

    def _calc_q_hat(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._q.Eval(context))

    def _calc_velocity(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._velocity(context))

    def _update_difference(self, context: Context, discrete_state: DiscreteValues) -> None:
        discrete_state.set_value(self._state, np.concatenate(
            [self._q.Eval(context), self._velocity(context)]))


class SensedForce(ForceSource):
    """Classical force feedback: the sensor's ``λ_s`` in place of ``λ̂`` in (13) and (6).

    .. pydrake_system::

        name: SensedForce
        input_ports:
        - lambda_sensor
        - reference
        output_ports:
        - lambda_hat
        - Delta_F_tilde

    ``λ̂(k) = λ_s(k)`` while held (0 in free motion) and
    ``ΔF̃(k+1) = ΔF̃(k) + h (λ_s(k) − λ_d(k))`` while held, reset to 0 otherwise (as the force
    observer's integral). The update is periodic (every ``h``, offset 0) and also forced.

    Parameters
    ----------
    period : float
        Sampling time ``h`` (s).
    layout : ReferenceLayout
        The robot's reference layout (``n`` joints, ``m`` constraints).
    anti_windup_limits : array_like, shape (n,), optional
        The arm's torque limits for the anti-windup of (6) (opt-in,
        :mod:`~drake_coop.control.anti_windup`): the system then has an input ``tau`` (the
        commanded torque) and does not integrate ``ΔF̃`` at a tick whose ``τ`` exceeds them
        at some joint. None (the default): the paper's (6), no ``tau`` input.
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.
    anti_windup_gain : float, optional
        With ``anti_windup_limits``: back-calculation instead of conditional integration at
        this tracking rate ``K_aw`` (1/s, ``0 < h K_aw ≤ 1``;
        :func:`~drake_coop.control.anti_windup.back_calculation`); the system then also
        reads ``q``. None: conditional.
    model : ArmModel, optional
        The arm's model, for ``J_φ(q)`` (required with ``anti_windup_gain``).
    force_gain : float, optional
        ``k_F`` of (13), 1/s (required with ``anti_windup_gain``).

    Input ports
    -----------
    lambda_sensor : m-vector
        The F/T sensor model's reading.
    reference : (3n + m + 1)-vector
        ``[q_d, q̇_d, q̈_d, λ_d, held]``.
    tau : n-vector
        With ``anti_windup_limits`` only: the commanded torque ``τ(k)`` (read by the update
        only).
    q : n-vector
        With ``anti_windup_gain`` only: the encoder reading ``q(k)`` (read by the update
        only).

    Output ports
    ------------
    lambda_hat : m-vector
    Delta_F_tilde : m-vector
        State only.
    """

    def __init__(self, period: float, layout: ReferenceLayout, anti_windup_limits=None,
                 clock: Clock | None = None, anti_windup_gain: float | None = None,
                 model=None, force_gain: float | None = None):
        super().__init__()
        self._h = period = check_period(period)
        self._layout = layout = ReferenceLayout.check(layout)
        m = layout.m
        self._zero = np.zeros(m)
        self._lambda = self.DeclareVectorInputPort("lambda_sensor", m)
        self._reference = self.DeclareVectorInputPort("reference", layout.size)
        self._windup_limits = self._tau = None
        if anti_windup_limits is not None:
            self._windup_limits = check_limits(anti_windup_limits, layout.n)
            self._tau = self.DeclareVectorInputPort("tau", layout.n)
        self._back = back_calculation_gains(self._windup_limits, anti_windup_gain, force_gain,
                                            period)
        self._model = self._q = None
        if self._back is not None:
            if model is None or not callable(getattr(model, "J_phi", None)):
                raise ValueError(f"model: an arm model with J_phi is required with "
                                 f"anti_windup_gain (got {model!r})")
            self._model = model
            self._q = self.DeclareVectorInputPort("q", layout.n)
        self._state = self.DeclareDiscreteState(m)
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, period), self._update_integral)
        self.DeclareForcedDiscreteUpdateEvent(self._update_integral)
        self._lambda_hat_out = self.DeclareVectorOutputPort("lambda_hat", m,
                                                            self._calc_lambda_hat)
        self._Delta_F_out = self.DeclareVectorOutputPort(
            "Delta_F_tilde", m, self._calc_Delta_F_tilde, prerequisites_of_calc={self.xd_ticket()})

    def get_lambda_sensor_input_port(self) -> InputPort:
        """The sensor's reading ``λ_s``."""
        return self._lambda

    def set_initial_state(self, context: Context, Delta_F_tilde: np.ndarray | None = None
                          ) -> None:
        """``ΔF̃(0)`` (default zero).

        Parameters
        ----------
        context : Context
            This system's context.
        Delta_F_tilde : numpy.ndarray or None
            ``ΔF̃(0)`` (m,), N·s; None for zero.
        """
        context.SetDiscreteState(self._state, self._zero if Delta_F_tilde is None
                                 else Delta_F_tilde)

    def _lambda_hat(self, context: Context):
        ref = self._layout.unpack(self._reference.Eval(context))
        return (self._lambda.Eval(context) if ref.held else self._zero), ref

    def _calc_lambda_hat(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._lambda_hat(context)[0])

    def _calc_Delta_F_tilde(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).value())

    def _update_integral(self, context: Context, discrete_state: DiscreteValues) -> None:
        lam, ref = self._lambda_hat(context)
        DF = context.get_discrete_state(self._state).CopyToVector()
        frozen, correction = False, None
        if self._back is not None and ref.held:
            correction = back_calculation(self._tau.Eval(context), self._windup_limits,
                                          self._model.J_phi(self._q.Eval(context)), *self._back)
        elif self._back is None and self._tau is not None:
            frozen = clipped(self._tau.Eval(context), self._windup_limits)
        discrete_state.set_value(self._state, force_integral_step(
            DF, lam - ref.lambda_d, ref.held, self._h, frozen, correction))


class NoForceEstimate(ForceSource):
    """No force information (implicit force control, reference [9]): ``λ̂ := λ_d``, ``ΔF̃ ≡ 0``.

    .. pydrake_system::

        name: NoForceEstimate
        input_ports:
        - reference
        output_ports:
        - lambda_hat
        - Delta_F_tilde

    Then ``Δλ̃ = 0`` and (13) applies the feedforward ``J_φᵀ λ_d``; the force error is left to
    the constraint and the position loop. ``λ̂ = 0`` in free motion.

    Parameters
    ----------
    layout : ReferenceLayout
        The robot's reference layout (``n`` joints, ``m`` constraints).

    Input ports
    -----------
    reference : (3n + m + 1)-vector

    Output ports
    ------------
    lambda_hat : m-vector
        ``λ_d`` while held, else 0.
    Delta_F_tilde : m-vector
        Always 0.
    """

    def __init__(self, layout: ReferenceLayout):
        super().__init__()
        self._layout = layout = ReferenceLayout.check(layout)
        self._zero = np.zeros(layout.m)
        self._reference = self.DeclareVectorInputPort("reference", layout.size)
        self._lambda_hat_out = self.DeclareVectorOutputPort("lambda_hat", layout.m,
                                                            self._calc_lambda_hat)
        self._Delta_F_out = self.DeclareVectorOutputPort(
            "Delta_F_tilde", layout.m, self._calc_Delta_F_tilde,
            prerequisites_of_calc={self.nothing_ticket()})

    def _calc_lambda_hat(self, context: Context, output: BasicVector) -> None:
        ref = self._layout.unpack(self._reference.Eval(context))
        output.SetFromVector(ref.lambda_d if ref.held else self._zero)

    def _calc_Delta_F_tilde(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._zero)

