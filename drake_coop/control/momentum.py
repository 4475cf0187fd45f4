r"""The generalized-momentum observer of the external joint torque, a force source at ``h``.

From the model (1), ``H q̈ + C q̇ + D q̇ + g = τ + τ_ext`` with ``τ_ext = J_φᵀ λ``, and
``Ḣ = C + Cᵀ``, the generalized momentum ``p = H(q) q̇`` obeys

.. math::
    \dot p = \tau - \beta(q, \dot q) + \tau_{ext}, \qquad
    \beta = g(q) + D\dot q - C^T(q, \dot q)\dot q ,

which needs no acceleration. The observer (De Luca & Mattone 2005; Haddadin, De Luca,
Albu-Schäffer, IEEE T-RO 2017) integrates the known part and feeds back the residual

.. math::
    r(t) = K_O\Big(p(t) - p(0) - \int_0^t (\tau - \beta + r)\,ds\Big), \qquad
    \dot r = K_O(\tau_{ext} - r),

a first-order filter of the external torque with the gain ``K_O`` (1/s). Sampled at ``h``
(forward Euler, as the paper's observers): with the state ``σ`` (``σ(0) = p(0)``),

.. math::
    r(k) = K_O\big(\hat H(q_k)\hat{\dot q}_k - \sigma(k)\big), \qquad
    \sigma(k+1) = \sigma(k) + h\big(\tau(k) - \hat\beta(q_k, \hat{\dot q}_k) + r(k)\big),

so that for a constant ``τ_ext`` on an arm at rest ``r(k) = (1 − (1 − h K_O)^k) τ_ext``
(stable and monotone for ``0 < h K_O ≤ 1``). ``τ(k)`` is the *commanded* torque (what a
controller knows), ``q̇̂`` the robot's velocity source (the observer's ``d/dt q̂`` (15)), and
``Ĥ, Ĉ, D̂, ĝ`` the controller's model: a model error, unknown friction or a torque
saturation appears in ``r`` as external torque. ``Ĉᵀ q̇`` is ``Ḣ q̇ − C q̇`` with ``Ḣ`` the
exact directional derivative of ``H`` along ``q̇`` (AutoDiff).

The contact force then follows as the other force sources deliver it:
``λ̂ = J⁺ᵀ r = (J_φ J_φᵀ)⁻¹ J_φ r`` while the object is held (0 in free motion), feeding (13)
and the integral (6) ``ΔF̃(k+1) = ΔF̃(k) + h (λ̂(k) − λ_d(k))`` (reset to 0 when not held).
"""

from __future__ import annotations

import numpy as np
from pydrake.autodiffutils import ExtractGradient, InitializeAutoDiff
from pydrake.common.value import AbstractValue
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    ValueProducer,
)

from drake_coop.control.anti_windup import (
    back_calculation,
    back_calculation_gains,
    check_limits,
    clipped,
    force_integral_step,
)
from drake_coop.control.interfaces import ForceSource
from drake_coop.control.arm_model import ArmModel
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.params import check_momentum_gain, check_period
from drake_coop.control.timing import Clock, on_clock


def momentum_estimate(p: np.ndarray, sigma: np.ndarray, gain: float, J: np.ndarray | None,
                      m: int) -> tuple[np.ndarray, np.ndarray]:
    """The sampled observer's output at tick ``k``: ``r = K_O (p − σ)`` and
    ``λ̂ = (J_φ J_φᵀ)⁻¹ J_φ r`` while held (module docstring).

    Parameters
    ----------
    p : numpy.ndarray
        The model's momentum ``Ĥ(q_k) q̇̂_k`` (n,), kg·m²/s.
    sigma : numpy.ndarray
        The state ``σ(k)`` (n,).
    gain : float
        ``K_O`` (1/s).
    J : numpy.ndarray or None
        ``J_φ(q_k)`` (m, n) while the object is held; None when it is not.
    m : int
        The number of constraints (``λ̂`` is ``m`` zeros when not held).

    Returns
    -------
    r, lambda_hat : numpy.ndarray
        The external joint torque estimate (n,), N·m, and the contact force (m,), N.
    """
    r = gain * (p - sigma)
    lam = np.linalg.solve(J @ J.T, J @ r) if J is not None else np.zeros(m)
    return r, lam


def momentum_step(sigma: np.ndarray, DF: np.ndarray, tau: np.ndarray, beta: np.ndarray,
                  r: np.ndarray, lam: np.ndarray, lambda_d: np.ndarray, held: bool,
                  h: float, frozen: bool = False, correction: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """One forward-Euler tick of the observer's state and of the integral (6):
    ``σ(k+1) = σ(k) + h (τ(k) − β̂ + r(k))``, ``ΔF̃(k+1) = ΔF̃(k) + h (λ̂ − λ_d)`` while held,
    else 0 (held at ``ΔF̃(k)`` when ``frozen``: :mod:`~drake_coop.control.anti_windup`).

    Parameters
    ----------
    sigma, DF : numpy.ndarray
        ``σ(k)`` (n,) and ``ΔF̃(k)`` (m,).
    tau : numpy.ndarray
        The torque integrated at tick ``k`` (n,), N·m.
    beta : numpy.ndarray
        ``β̂(q_k, q̇̂_k)`` (n,), N·m.
    r, lam : numpy.ndarray
        :func:`momentum_estimate`'s output of tick ``k``.
    lambda_d : numpy.ndarray
        The desired contact force (m,), N.
    held : bool
        Whether the object is held at tick ``k``.
    h : float
        The sampling time (s).
    frozen : bool
        An actuator is clipped at tick ``k`` and anti-windup is on: ``ΔF̃`` is not
        integrated (:func:`~drake_coop.control.anti_windup.force_integral_step`).
    correction : numpy.ndarray or None
        The back-calculation term of tick ``k`` (m,), N
        (:func:`~drake_coop.control.anti_windup.back_calculation`); None: none.

    Returns
    -------
    sigma_next, DF_next : numpy.ndarray
        ``σ(k+1)`` and ``ΔF̃(k+1)``.
    """
    sigma_next = sigma + h * (tau - beta + r)
    return sigma_next, force_integral_step(DF, lam - lambda_d, held, h, frozen, correction)


class MomentumObserver(ForceSource):
    """Generalized-momentum observer of one robot (module docstring).

    .. pydrake_system::

        name: MomentumObserver
        input_ports:
        - q
        - qdot_hat
        - tau
        - reference
        output_ports:
        - tau_ext_hat
        - O_F_ext_hat
        - lambda_hat
        - Delta_F_tilde

    Parameters
    ----------
    model : ArmModel
        The controller's model of the arm.
    layout : ReferenceLayout
        The robot's reference layout (``n`` joints, ``m`` constraints).
    period : float
        Sampling time ``h`` (s).
    gain : float
        ``K_O`` (1/s), ``0 < h K_O ≤ 1``.
    torque_limits : array_like, shape (n,), optional
        The actuators' torque limits (N·m, > 0). Given, the observer integrates the torque
        actually applied, ``clip(τ, −τ_max, τ_max)`` (what Drake's ``Saturation`` in front of
        the plant passes), instead of the commanded ``τ``: a saturated command is then not
        read as external torque. None (the default): the commanded torque.
    anti_windup_limits : array_like, shape (n,), optional
        The arm's torque limits for the anti-windup of (6) (opt-in,
        :mod:`~drake_coop.control.anti_windup`): ``ΔF̃`` is not integrated at a tick whose
        commanded ``τ`` exceeds them at some joint. None (the default): the paper's (6).
    anti_windup_gain : float, optional
        With ``anti_windup_limits``: back-calculation instead of conditional integration,
        at this tracking rate ``K_aw`` (1/s, ``0 < h K_aw ≤ 1``;
        :func:`~drake_coop.control.anti_windup.back_calculation`). None: conditional.
    force_gain : float, optional
        ``k_F`` of (13) (1/s, > 0), which back-calculation's ``P = (J_φᵀ)⁺ / k_F`` needs
        (required with ``anti_windup_gain``).
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.

    Input ports
    -----------
    q : n-vector
        The encoder reading ``q(k)``.
    qdot_hat : n-vector
        The velocity estimate of tick ``k``.
    tau : n-vector
        The commanded torque ``τ(k)`` (read by the update only: no algebraic loop); clipped
        at ``torque_limits`` when given; compared with ``anti_windup_limits`` when given.
    reference : (3n + m + 1)-vector
        ``[q_d, q̇_d, q̈_d, λ_d, held]``.

    Output ports
    ------------
    tau_ext_hat : n-vector
        ``r(k)``, the estimated external joint torque (libfranka's ``tau_ext_hat_filtered``).
    O_F_ext_hat : 3-vector
        The estimated external force on the end effector in the palm frame ``O``,
        ``(J_xᵀ)⁺ r`` (libfranka's ``O_F_ext_hat_K``, force part).
    lambda_hat : m-vector
        ``λ̂(k) = J⁺ᵀ r(k)`` while held, else 0.
    Delta_F_tilde : m-vector
        ``ΔF̃(k)`` (state only).
    """

    def __init__(self, model: ArmModel, layout: ReferenceLayout, period: float, gain: float,
                 torque_limits=None, anti_windup_limits=None,
                 clock: Clock | None = None, anti_windup_gain: float | None = None,
                 force_gain: float | None = None):
        super().__init__()
        self._model = model
        self._layout = layout = ReferenceLayout.check(layout)
        self._h = period = check_period(period)
        self._gain = check_momentum_gain(gain, period)
        self._limits = None
        if torque_limits is not None:
            limits = np.asarray(torque_limits, dtype=float)
            if (limits.shape != (layout.n,) or not np.all(np.isfinite(limits))
                    or np.any(limits <= 0)):
                raise ValueError(f"torque_limits: {layout.n} finite torques > 0 are required "
                                 f"(got {np.shape(torque_limits)})")
            self._limits = limits
        self._windup_limits = (None if anti_windup_limits is None
                               else check_limits(anti_windup_limits, layout.n))
        self._back = back_calculation_gains(self._windup_limits, anti_windup_gain, force_gain,
                                            period)
        n, m = layout.n, layout.m
        self._n, self._m = n, m
        self._q = self.DeclareVectorInputPort("q", n)
        self._v = self.DeclareVectorInputPort("qdot_hat", n)
        self._tau = self.DeclareVectorInputPort("tau", n)
        self._reference = self.DeclareVectorInputPort("reference", layout.size)
        self._sigma = self.DeclareDiscreteState(n)
        self._DF = self.DeclareDiscreteState(m)
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, period), self._update)
        self.DeclareForcedDiscreteUpdateEvent(self._update)   # one tick in a unit test
        inputs = {self.xd_ticket(), self._q.ticket(), self._v.ticket(),
                  self._reference.ticket()}
        self._estimate = self.DeclareCacheEntry(
            "r, lambda_hat, F_hat",
            ValueProducer(allocate=AbstractValue.Make((np.zeros(n), np.zeros(m), np.zeros(3),
                                                       np.zeros(n), False)).Clone,
                          calc=self._calc_estimate), inputs)
        deps = {self._estimate.ticket()}
        self.DeclareVectorOutputPort("tau_ext_hat", n, self._calc_tau_ext,
                                     prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("O_F_ext_hat", 3, self._calc_force,
                                     prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("lambda_hat", m, self._calc_lambda_hat,
                                     prerequisites_of_calc=deps)
        self.DeclareStateOutputPort("Delta_F_tilde", self._DF)

    @property
    def gain(self) -> float:
        """``K_O`` (1/s)."""
        return self._gain

    def get_q_input_port(self):
        return self._q

    def get_qdot_hat_input_port(self):
        return self._v

    def get_tau_input_port(self):
        return self._tau

    def get_tau_ext_hat_output_port(self):
        return self.GetOutputPort("tau_ext_hat")

    def get_O_F_ext_hat_output_port(self):
        return self.GetOutputPort("O_F_ext_hat")

    def set_initial_state(self, context: Context, q0: np.ndarray,
                          v0: np.ndarray | None = None) -> None:
        """``σ(0) = Ĥ(q_0) v_0`` (zero momentum at rest by default) and ``ΔF̃(0) = 0``.

        Parameters
        ----------
        context : Context
            This system's context.
        q0 : numpy.ndarray
            The initial joint positions (n,), rad.
        v0 : numpy.ndarray or None
            The initial joint velocities (n,), rad/s; None for rest.
        """
        v0 = np.zeros(self._n) if v0 is None else np.asarray(v0, float)
        context.SetDiscreteState(self._sigma, self._model.H(q0) @ v0)
        context.SetDiscreteState(self._DF, np.zeros(self._m))

    def applied_torque(self, tau: np.ndarray) -> np.ndarray:
        """The torque the observer integrates: ``τ`` clipped at ``torque_limits`` if given.

        Parameters
        ----------
        tau : numpy.ndarray
            The commanded torque (n,), N·m.

        Returns
        -------
        numpy.ndarray
            The torque integrated (n,), N·m.
        """
        if self._limits is None:
            return tau
        return np.clip(tau, -self._limits, self._limits)

    # ------------------------------------------------------------------ the model's terms
    def momentum(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``p = Ĥ(q) v``.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        v : numpy.ndarray
            Joint velocities (n,), rad/s.
        """
        return self._model.H(q) @ v

    def beta(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``β = ĝ(q) + D̂ v − Ĉ(q, v)ᵀ v`` with ``Ĉᵀ v = Ḣ v − C v``.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        v : numpy.ndarray
            Joint velocities (n,), rad/s.
        """
        model = self._model
        q_ad = InitializeAutoDiff(np.asarray(q, float), np.asarray(v, float).reshape(-1, 1))
        model.plant_ad.SetPositions(model.context_ad, q_ad.reshape(-1))
        H_ad = model.plant_ad.CalcMassMatrix(model.context_ad)
        grad = ExtractGradient(H_ad.reshape(-1, 1))
        Hdot = (grad.reshape(self._n, self._n) if grad.size == self._n ** 2
                else np.zeros((self._n, self._n)))
        CTv = Hdot @ v - model.Cv(q, v)
        beta = model.g(q) + model.D @ v - CTv
        if getattr(model, "coulomb", None) is not None:     # the model's Coulomb friction
            beta = beta + model.friction_torque(v)
        return beta

    def _translational_jacobian(self, q: np.ndarray) -> np.ndarray:
        model = self._model
        model.H(q)   # positions into the model's context
        world = model.plant.world_frame()
        return model.plant.CalcJacobianTranslationalVelocity(
            model.context, JacobianWrtVariable.kV, model.ee_frame, np.zeros(3), world, world)

    # ------------------------------------------------------------------ outputs, update
    def _calc_estimate(self, context: Context, value: AbstractValue) -> None:
        q = self._q.Eval(context)
        v = self._v.Eval(context)
        sigma = context.get_discrete_state(self._sigma).value()
        ref = self._layout.unpack(self._reference.Eval(context))
        r, lam = momentum_estimate(self.momentum(q, v), sigma, self._gain,
                                   self._model.J_phi(q) if ref.held else None, self._m)
        F = np.linalg.lstsq(self._translational_jacobian(q).T, r, rcond=None)[0]
        value.set_value((r, lam, F, ref.lambda_d.copy(), bool(ref.held)))

    def _calc_tau_ext(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._estimate.Eval(context)[0])

    def _calc_force(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._estimate.Eval(context)[2])

    def _calc_lambda_hat(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._estimate.Eval(context)[1])

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        r, lam, _, lambda_d, held = self._estimate.Eval(context)
        q = self._q.Eval(context)
        v = self._v.Eval(context)
        sigma = context.get_discrete_state(self._sigma).value()
        commanded = self._tau.Eval(context)
        DF = context.get_discrete_state(self._DF).value()
        correction = None
        if self._back is not None and held:
            correction = back_calculation(commanded, self._windup_limits, self._model.J_phi(q),
                                          *self._back)
        sigma, DF = momentum_step(sigma, DF, self.applied_torque(commanded), self.beta(q, v),
                                  r, lam, lambda_d, held, self._h,
                                  self._back is None and clipped(commanded,
                                                                 self._windup_limits),
                                  correction)
        discrete_state.set_value(self._sigma, sigma)
        discrete_state.set_value(self._DF, DF)
