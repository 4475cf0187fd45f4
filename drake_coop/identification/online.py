r"""Online identification while the task runs: recursive least squares on the momentum form
of the arm's regressor, feeding a generalized-momentum force estimate with its parameters.

The arm's dynamics are linear in its parameters ``θ`` (:mod:`~drake_coop.identification.regressor`):
``τ = Y(q, q̇, q̈) θ``. Written for the generalized momentum ``p = H q̇`` (as the momentum
observer of :mod:`drake_coop.control.momentum`) they need no acceleration:

.. math::
    p = Y_p(q, \dot q)\,\theta, \quad Y_p = Y(q, 0, \dot q) - Y(q, 0, 0), \qquad
    \dot p = \tau - \beta + J_\varphi^T\lambda, \quad
    \beta = Y_\beta(q, \dot q)\,\theta, \quad
    Y_\beta = Y(q, \dot q, 0) - \dot Y_p ,

with ``Ẏ_p q̇``-part ``Ḣ q̇`` taken by a central difference of ``Y_p`` along ``q̇`` (``Ḣ = C +
Cᵀ`` makes ``β = g + D q̇ + f_c − Cᵀ q̇ = Y(q, q̇, 0)θ − Ḣ q̇``). Over one tick ``h`` (forward
Euler, as the observers):

.. math::
    \big(Y_p(k) - Y_p(k-1) + h\,Y_\beta(k-1)\big)\,\theta = h\,\tau(k-1) + h\,J_\varphi^T\lambda ,

with ``Y_p(k) = Y_p(q_k, v_k)`` at the central difference of the encoder,
``v(k) = (q(k+1) − q(k−1)) / 2h``: the rows lag the tick by one (the row from ``k − 2`` to
``k − 1`` is built at tick ``k``). Not the velocity estimate ``q̇̂``: its error biases the rows
(with the exact model as the prior, the batch solution of 10 s of task rows moved the
contact direction's share of the model away from the truth by 0.10 N with ``q̇̂`` and by
0.011 N with the central difference; in the loop the estimate went from 0.03 to 0.13 N of
squeeze error with ``q̇̂``). It is not better everywhere: fed the log of a run whose loop
ran on a 30 % heavy model (a rough motion, 24 N of force error), the difference's rows left
1.3 N of that contact-direction error where ``q̇̂``'s left 0.13 N (measured with the friction
held at zero; with the friction's prior floor 1.9 N, the friction columns taking part of the
rough motion's row error) (``tests/identification/test_online.py``); in the loop the block
smooths its own motion.
Encoder noise enters the difference amplified by ``1/(√2 h)`` (not measured here).

While the object is held ``λ`` is unknown: the rows are projected onto the complement of
``J_φᵀ``'s range, ``Π = I − J_φᵀ(J_φJ_φᵀ)⁻¹J_φ`` (the contact force drops out; on the ideal
constraint exactly). Each tick's (projected) rows ``Φ``, ``y`` update ``θ̂`` by recursive least
squares, i.e. the Kalman filter of a constant ``θ`` with the rows' noise variance
``R = (h σ_τ)²`` and a forgetting factor ``μ``:
``K = PΦᵀ(μR I + ΦPΦᵀ)⁻¹``, ``θ̂ ← θ̂ + K(y − Φθ̂)``, ``P ← (P − KΦP)/μ``, with ``trace P`` held
at most its initial value (no wind-up in the directions the motion does not excite).
The prior is the controller's model ``θ_0`` with ``P_0 = diag((r|θ_0| + ε)²)``, each
joint's Coulomb friction's standard deviation at least ``coulomb_prior`` (0 by default: a model
without friction has ``f_c0 = 0``, and ``r|θ_0|`` alone holds the friction at zero, so where the
truth has friction the data move the inertial parameters to explain it instead — on the
reference table's Coulomb column they did: link masses off by up to 0.6 kg, the squeeze error
1.8 N; the batch identification's floor, 0.5 N·m, frees it, at a cost where there is no
friction: see the parameter). With ``μ = 1``
(the default) ``θ̂`` after any tick is exactly the batch MAP estimate of the same rows,
``argmin ‖Φθ − y‖²/R + (θ − θ_0)ᵀP_0⁻¹(θ − θ_0)``. ``R`` matters: the rows are a torque
times ``h`` (about 10⁻² N·m·s), so with ``R = 1`` the prior outweighs the data by orders of
magnitude, and the estimate stays near the prior in all but the strongest directions (on
the ±30 % model draws of the compressed task, the contact direction's share of the model
error over the circle stayed at about 2.3 N where the same rows' batch solution had 0.1 N).

**Excitation condition.** ``θ̂`` converges in the directions spanned by the rows (over the
forgetting window, about ``1/(1 − μ)`` ticks, when ``μ < 1``): the identifiable combinations
of :func:`~drake_coop.identification.regressor.identifiable_basis` that the motion excites;
the others stay at the prior. On the paper's arm, 10 s of the compressed task (free motion,
approach, lift, circle; the contact projected out while held) span 15 of the 39 parameters'
directions, the rows' singular values falling from 1 to about 2·10⁻³ of the largest; the
squeeze needs the contact direction's share of ``Y θ``, which the free motion before the
grasp excites (measured, ``tests/identification/test_online.py``). A tick updates only when
the arm moves (``‖q̇̂‖ ≥ v_min``): at rest the rows carry only noise and the Coulomb column's
sign.

**Feeding the controller.** The squeeze error under a model error comes mostly from the
control law's model, not from the force estimate (with the F/T sensor in the loop the ±30 %
model's squeeze error stays at several newtons): given the controller's model, the block
writes ``θ̂`` into it after each update (:func:`apply_parameters`), Coulomb friction included
when ``coulomb_prior > 0`` (the model's ``F_c tanh(q̇ / v_c)`` with the regressor's ``v_c``), so
the control law and the velocity observer run on the refined parameters too.

The force estimate is the momentum observer's, with the model ``Y θ̂``:
``r(k) = K_O(Y_p(k)θ̂ − σ(k))``, ``σ(k+1) = σ(k) + h(τ(k) − Y_β(k)θ̂ + r(k))``,
``λ̂ = (J_φJ_φᵀ)⁻¹J_φ r`` while held, and the integral (6)
``ΔF̃(k+1) = ΔF̃(k) + h(λ̂ − λ_d)`` (reset in free motion).

**Replay.** :func:`replay` feeds a recorded run (a robot's logged encoder, velocity estimate,
torque and desired force) through a block tick by tick, open loop: what the block would
have identified and estimated on that motion, without simulating the arm.
"""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    EventStatus,
    ValueProducer,
)

from drake_coop.control.timing import Clock, on_clock
from drake_coop.control.interfaces import ForceSource
from drake_coop.control.momentum import momentum_estimate, momentum_step
from drake_coop.control.params import check_momentum_gain, check_period
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.identification.regressor import (ArmStructure, Regressor,
                                                 spatial_inertia_from_theta)

__all__ = ["OnlineIdentification", "apply_parameters", "momentum_rows", "replay"]

#: Step of the central difference along ``q̇`` (s): ``q ± ε q̇``.
DIFFERENCE_STEP = 1e-4


def momentum_rows(regressor: Regressor, q: np.ndarray, v: np.ndarray,
                  eps: float = DIFFERENCE_STEP) -> tuple[np.ndarray, np.ndarray]:
    """``Y_p(q, v)`` and ``Y_β(q, v)`` (module docstring), each ``(n, p)``.

    Parameters
    ----------
    regressor : Regressor
        The arm's regressor.
    q : numpy.ndarray
        Joint positions (n,), rad.
    v : numpy.ndarray
        Joint velocities (n,), rad/s.
    eps : float
        The central difference's step, s.

    Returns
    -------
    Y_p, Y_beta : numpy.ndarray
        ``p = Y_p θ`` (kg·m²/s) and ``β = Y_β θ`` (N·m).
    """
    q, v = np.asarray(q, float), np.asarray(v, float)
    n, z = q.size, np.zeros(q.size)
    Q = np.array([q, q, q, q + eps * v, q - eps * v, q + eps * v, q - eps * v])
    V = np.array([z, z, v, z, z, z, z])
    A = np.array([v, z, z, v, v, z, z])
    Y = regressor.matrix(Q, V, A).reshape(7, n, -1)
    Y_p = Y[0] - Y[1]
    Hdot_v = ((Y[3] - Y[5]) - (Y[4] - Y[6])) / (2.0 * eps)
    return Y_p, Y[2] - Hdot_v


def apply_parameters(model, structure: ArmStructure, theta: np.ndarray,
                     coulomb_velocity: float | None = None) -> None:
    """Write ``θ`` into a controller's model: each composite link's ten parameters as its
    body's spatial inertia (the bodies welded to it carry none), each joint's reflected rotor
    inertia and viscous damping, and, given ``coulomb_velocity``, each joint's Coulomb
    friction (the model's ``coulomb``, compensated by its control law and observers as
    ``F_c tanh(q̇ / v_c)``).

    The model's dynamics (``H``, ``C q̇``, ``g``, ``D``, :meth:`inverse_dynamics_terms`) are
    then those of ``θ`` (with the regressor's friction column when ``coulomb_velocity`` is the
    regressor's); its kinematics do not change.

    Parameters
    ----------
    model : ArmModel
        The controller's model (:class:`~drake_coop.control.arm_model.ArmModel`): its own
        plant's context is changed.
    structure : ArmStructure
        The parameter layout (the same arm: body and joint names of ``model.plant``).
    theta : numpy.ndarray
        The parameters (p,). Negative damping and negative Coulomb friction are written as 0
        (Drake refuses the one, :class:`~drake_coop.control.arm_model.ArmModel` the other).
    coulomb_velocity : float or None
        ``v_c`` (rad/s, > 0) of the written friction: the regressor's
        (:attr:`~drake_coop.identification.regressor.Regressor.coulomb_velocity`). None (the
        default): the model's Coulomb friction is left as it is.
    """
    plant, context = model.plant, model.context
    for i, link in enumerate(structure.links):
        for name in structure.members[link]:
            if plant.HasBodyNamed(name):
                plant.GetBodyByName(name).SetSpatialInertiaInBodyFrame(
                    context, spatial_inertia_from_theta(
                        theta[10 * i:10 * i + 10] if name == link else np.zeros(10)))
    rotor = theta[structure.joint_slice("rotor_inertia")]
    damping = np.maximum(theta[structure.joint_slice("viscous")], 0.0)
    for a in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(a)
        k = structure.joints.index(actuator.joint().name())
        actuator.SetRotorInertia(context, rotor[k] / actuator.default_gear_ratio() ** 2)
    for k, joint in enumerate(structure.joints):
        plant.GetJointByName(joint).SetDamping(context, float(damping[k]))
    model.D = np.diag(damping)
    if coulomb_velocity is not None:
        if not (np.isfinite(coulomb_velocity) and coulomb_velocity > 0.0):
            raise ValueError(f"coulomb_velocity: must be a finite number > 0 (rad/s), got "
                             f"{coulomb_velocity}")
        model.coulomb = np.maximum(theta[structure.joint_slice("coulomb")], 0.0)
        model.coulomb_velocity = float(coulomb_velocity)


class OnlineIdentification(ForceSource):
    """Recursive identification of the arm's parameters and the force estimate they give
    (module docstring), a force source at ``h``.

    .. pydrake_system::

        name: OnlineIdentification
        input_ports:
        - q
        - qdot_hat
        - tau
        - reference
        output_ports:
        - theta_hat
        - lambda_hat
        - Delta_F_tilde

    Parameters
    ----------
    regressor : Regressor
        The arm's regressor (its parameter layout ``p``).
    theta0 : array_like, shape (p,)
        The prior: the controller's model's parameters.
    J_phi : callable
        ``J_phi(q)`` -> ``(m, n)``: the constraint Jacobian (the controller's model's).
    layout : ReferenceLayout
        The robot's reference layout.
    period : float
        ``h`` (s).
    gain : float
        ``K_O`` (1/s), ``0 < h K_O ≤ 1``.
    forgetting : float
        ``μ`` in (0, 1]; 1 (the default): no forgetting, the batch estimate of every row
        so far. Below 1 old rows fade (0.998, a 5 s window, gave a contact-direction error
        within 40 % of the default's on a ±30 % draw's 10 s log), for parameters that change during the run.
    prior_relative : float
        ``r``: the prior's relative standard deviation (> 0). The default 1 lets the data
        move a parameter by its own size. With ``σ_τ`` weighing the rows the data dominate
        the excited directions whatever ``r`` (0.3 gave the same contact-direction error
        within a few per cent on the ±30 % draws).
    v_min : float
        Least ``‖q̇̂‖`` (rad/s) at which a tick updates ``θ̂``.
    torque_noise : float
        ``σ_τ`` (N·m, > 0): the standard deviation of a row's equation error as a torque
        (encoder and velocity-estimate error, the forward-Euler step, unmodelled effects);
        the rows' noise variance is ``(h σ_τ)²`` (a row is a torque times ``h``). It weighs
        the data against the prior: the update is the Kalman filter of ``θ`` (with
        ``μ = 1`` exactly the batch least squares with the prior, ``σ_τ⁻²``-weighted rows).
        The default, 0.03 N·m, is of the size of the rows' equation error with the exact
        parameters on the compressed task (0.02–0.35 N·m measured, mostly the velocity's
        error); 0.01 and 0.1 gave the same contact-direction error within 10 %.
    model : ArmModel or None
        The controller's model (:class:`~drake_coop.control.arm_model.ArmModel`, the one its
        control law (13) and velocity observer evaluate). Given, each update that changes
        ``θ̂`` writes it into the model (:func:`apply_parameters`), and so do
        :meth:`set_initial_state` and ``Simulator.Initialize`` (an initialization publish of
        the context's ``θ̂``: a new run of the diagram starts from its own ``θ̂(0)``, not from
        the last run's); evaluating the force estimate writes nothing. The control law runs
        on the refined parameters from the next tick on. This changes an object outside the
        Drake context: two simulations of one diagram must not run at once.
        None (the default): only this block's force estimate uses ``θ̂``.
    clock : Clock or None
        The clock its periodic update ticks on (:class:`~drake_coop.control.timing.Clock`,
        e.g. a controller's computer's); ``h`` stays the period of its equations. None
        (default): the run's grid.
    coulomb_prior : float
        The prior's standard deviation of each joint's Coulomb friction at least (N·m,
        ``≥ 0``): ``max(r|f_c0|, coulomb_prior)``; when > 0 the identified friction is also
        written into ``model`` (its control law and velocity observer compensate it as
        ``F_c tanh(q̇ / v_c)``, the regressor's ``v_c``). 0 (the default): the prior
        ``r|θ_0|`` alone, the model's friction left as it is. A model without friction
        (``f_c0 = 0``) then holds the friction at zero, and where the truth has friction the
        data move the inertial parameters instead: on the reference table's Coulomb column
        the online row's squeeze error is 1.8 N, against 0.26 N with the batch
        identification's floor, 0.5 N·m
        (:data:`~drake_coop.identification.estimate.PRIOR_FLOORS`).
        The floor has a cost where the truth has no friction: on the ±30 % model draws the
        free friction takes part of the model error (11 of 20 draws worse, up to 0.22 N of
        squeeze error against 0.05 N). 0.1 N·m did better on the draws tried (closed loop,
        paired, not the table's 20): the four ±30 % draws that had got worst back to
        0.004–0.023 N (0.15–0.22 N with 0.5), five Coulomb draws equal or lower (0.05–0.50 N
        against 0.06–0.50 N). The reference-table page gives the numbers.

    Input ports
    -----------
    q, qdot_hat, tau : n-vectors
        Encoder reading, velocity estimate, commanded torque of the tick.
    reference : (3n + m + 1)-vector

    Output ports
    ------------
    theta_hat : p-vector
        ``θ̂(k)``.
    lambda_hat : m-vector
    Delta_F_tilde : m-vector
    """

    def __init__(self, regressor: Regressor, theta0, J_phi: Callable, layout: ReferenceLayout,
                 period: float, gain: float, forgetting: float = 1.0,
                 prior_relative: float = 1.0, v_min: float = 0.01,
                 torque_noise: float = 0.03, model=None, clock: Clock | None = None,
                 coulomb_prior: float = 0.0):
        super().__init__()
        self._regressor = regressor
        self._layout = layout = ReferenceLayout.check(layout)
        self._h = period = check_period(period)
        self._gain = check_momentum_gain(gain, period)
        theta0 = np.asarray(theta0, float)
        p = regressor.structure.num_parameters
        if theta0.shape != (p,) or not np.all(np.isfinite(theta0)):
            raise ValueError(f"theta0: {p} finite parameters are required, got shape "
                             f"{theta0.shape}")
        if not 0.0 < forgetting <= 1.0:
            raise ValueError(f"forgetting: must be in (0, 1], got {forgetting}")
        if not prior_relative > 0.0:
            raise ValueError(f"prior_relative: must be > 0, got {prior_relative}")
        if not (np.isfinite(torque_noise) and torque_noise > 0.0):
            raise ValueError(f"torque_noise: must be a finite number > 0 (N·m), got "
                             f"{torque_noise}")
        if not (np.isfinite(coulomb_prior) and coulomb_prior >= 0.0):
            raise ValueError(f"coulomb_prior: must be a finite number >= 0 (N·m), got "
                             f"{coulomb_prior}")
        self._J_phi, self._mu, self._v_min = J_phi, float(forgetting), float(v_min)
        self._R = (period * float(torque_noise)) ** 2
        self._model = model
        self._written = b""      # the parameters last written into the model
        n, m = layout.n, layout.m
        self._n, self._m, self._p = n, m, p
        scale = prior_relative * np.abs(theta0) + 1e-5 * max(np.abs(theta0).max(), 1.0)
        coulomb = regressor.structure.joint_slice("coulomb")
        scale[coulomb] = np.maximum(scale[coulomb], coulomb_prior)
        self._free_friction = coulomb_prior > 0.0
        self._P0 = np.diag(scale ** 2)
        self._trace0 = float(np.trace(self._P0))
        self._theta0 = theta0
        self._q = self.DeclareVectorInputPort("q", n)
        self._v = self.DeclareVectorInputPort("qdot_hat", n)
        self._tau = self.DeclareVectorInputPort("tau", n)
        self._reference = self.DeclareVectorInputPort("reference", layout.size)
        self._theta = self.DeclareDiscreteState(theta0)
        self._P = self.DeclareDiscreteState(self._P0.reshape(-1))
        self._sigma = self.DeclareDiscreteState(n)
        self._DF = self.DeclareDiscreteState(m)
        # the previous tick's  -Y_p + h Y_beta  (n p), h tau (n), its projector (n n), valid
        self._prev = self.DeclareDiscreteState(n * p + n + n * n + 1)
        # q(k-1), q(k-2), tau(k-1), held(k-1), ticks seen (at most 2)
        self._history = self.DeclareDiscreteState(3 * n + 2)
        self.DeclarePeriodicDiscreteUpdateEvent(*on_clock(clock, period), self._update)
        self.DeclareForcedDiscreteUpdateEvent(self._update)
        # A new run of the diagram starts the model from its own θ̂(0); later only the
        # update changes θ̂ and writes it.
        self.DeclareInitializationPublishEvent(self._write_initial)
        # The tick's rows and estimate, computed once for the output and the update; they
        # do not read the torque (read by the update only: no algebraic loop with (13)).
        self._cache = self.DeclareCacheEntry(
            "rows and estimate", ValueProducer(
                allocate=AbstractValue.Make(()).Clone, calc=self._calc_estimate),
            {self.xd_ticket(), self._q.ticket(), self._v.ticket(), self._reference.ticket()})
        self.DeclareStateOutputPort("theta_hat", self._theta)
        self.DeclareVectorOutputPort("lambda_hat", m, self._calc_lambda_hat,
                                     prerequisites_of_calc={self._cache.ticket()})
        self.DeclareStateOutputPort("Delta_F_tilde", self._DF)

    def set_initial_state(self, context: Context, q0: np.ndarray,
                          v0: np.ndarray | None = None) -> None:
        """``θ̂ = θ_0``, ``P = P_0``, ``σ(0) = Y_p(q_0, v_0)θ_0``, no previous tick.

        Parameters
        ----------
        context : Context
            This system's context.
        q0 : numpy.ndarray
            Initial joint positions (n,), rad.
        v0 : numpy.ndarray or None
            Initial joint velocities (n,), rad/s; None for rest.
        """
        v0 = np.zeros(self._n) if v0 is None else np.asarray(v0, float)
        context.SetDiscreteState(self._theta, self._theta0)
        context.SetDiscreteState(self._P, self._P0.reshape(-1))
        Y_p, _ = momentum_rows(self._regressor, q0, v0)
        context.SetDiscreteState(self._sigma, Y_p @ self._theta0)
        context.SetDiscreteState(self._DF, np.zeros(self._m))
        context.SetDiscreteState(self._prev, np.zeros(self._prev_size))
        context.SetDiscreteState(self._history, np.zeros(3 * self._n + 2))
        self._write(self._theta0)

    @property
    def _prev_size(self) -> int:
        return self._n * self._p + self._n + self._n * self._n + 1

    def _estimate(self, context: Context):
        return self._cache.Eval(context)

    def _calc_estimate(self, context: Context, value: AbstractValue) -> None:
        value.set_value(self._compute(context))

    def _compute(self, context: Context):
        q, v = self._q.Eval(context), self._v.Eval(context)
        theta = context.get_discrete_state(self._theta).value()
        Y_p, Y_b = momentum_rows(self._regressor, q, v)
        ref = self._layout.unpack(self._reference.Eval(context))
        J = self._J_phi(q)
        r, lam = momentum_estimate(Y_p @ theta, context.get_discrete_state(self._sigma).value(),
                                   self._gain, J if ref.held else None, self._m)
        return q, v, theta, Y_p, Y_b, r, lam, ref, J

    def _calc_lambda_hat(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._estimate(context)[6])

    def _write_initial(self, context: Context) -> EventStatus:
        """At ``Simulator.Initialize``: the context's ``θ̂`` into the controller's model."""
        self._write(context.get_discrete_state(self._theta).value())
        return EventStatus.Succeeded()

    def _write(self, theta: np.ndarray) -> None:
        """``θ`` into the controller's model, if one was given and it holds other values."""
        if self._model is not None and theta.tobytes() != self._written:
            if self._free_friction:     # the identified friction written too
                apply_parameters(self._model, self._regressor.structure, theta,
                                 self._regressor.coulomb_velocity)
            else:
                apply_parameters(self._model, self._regressor.structure, theta)
            self._written = theta.tobytes()

    def _rls(self, theta: np.ndarray, P: np.ndarray, Phi: np.ndarray, y: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """One recursive least-squares step (module docstring) with the rows ``Φ``, ``y``."""
        S = self._mu * self._R * np.eye(self._n) + Phi @ P @ Phi.T
        K = np.linalg.solve(S, Phi @ P).T
        theta = theta + K @ (y - Phi @ theta)
        P = (P - K @ Phi @ P) / self._mu
        P = 0.5 * (P + P.T)
        trace = float(np.trace(P))
        if trace > self._trace0:
            P *= self._trace0 / trace
        return theta, P

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        q, v, theta, Y_p, Y_b, r, lam, ref, J = self._estimate(context)
        n, p, h = self._n, self._p, self._h
        tau = self._tau.Eval(context)
        prev = context.get_discrete_state(self._prev).value()
        P = context.get_discrete_state(self._P).value().reshape(p, p)
        history = context.get_discrete_state(self._history).value()
        q1, q2, tau1 = history[:n], history[n:2 * n], history[2 * n:3 * n]
        held1, seen = history[-2] > 0.5, int(history[-1])
        if seen >= 2:
            # the row of the tick from k-2 to k-1, with the central difference at k-1
            v1 = (q - q2) / (2.0 * h)
            Y_p1, Y_b1 = momentum_rows(self._regressor, q1, v1)
            if prev[-1] > 0.5 and np.linalg.norm(v1) >= self._v_min:
                A = prev[:n * p].reshape(n, p)
                b = prev[n * p:n * p + n]
                Pi = prev[n * p + n:-1].reshape(n, n)
                theta, P = self._rls(theta, P, Pi @ (Y_p1 + A), Pi @ b)
                self._write(theta)
            J1 = self._J_phi(q1)
            Pi1 = (np.eye(n) - J1.T @ np.linalg.solve(J1 @ J1.T, J1)) if held1 else np.eye(n)
            discrete_state.set_value(self._prev, np.concatenate(
                [(-Y_p1 + h * Y_b1).reshape(-1), h * tau1, Pi1.reshape(-1), [1.0]]))
        discrete_state.set_value(self._history, np.concatenate(
            [q, q1, tau, [float(ref.held), min(seen + 1, 2)]]))
        discrete_state.set_value(self._theta, theta)
        discrete_state.set_value(self._P, P.reshape(-1))
        sigma, DF = momentum_step(context.get_discrete_state(self._sigma).value(),
                                  context.get_discrete_state(self._DF).value(), tau,
                                  Y_b @ theta, r, lam, ref.lambda_d, ref.held, h)
        discrete_state.set_value(self._sigma, sigma)
        discrete_state.set_value(self._DF, DF)


#: The keys :func:`replay` reads from a log.
REPLAY_KEYS = ("q", "qdot_hat", "tau", "lambda_d")


def replay(block: OnlineIdentification, log: Mapping[str, np.ndarray]
           ) -> tuple[np.ndarray, np.ndarray]:
    """Feed a recorded run through ``block`` tick by tick, open loop: the block's estimate
    and parameters on a logged motion, without simulating the arm.

    Sample ``k`` of the log is tick ``k`` (the log's rows one period ``h`` apart, as the
    experiment's logs are): the inputs are fixed to it, ``λ̂(k)`` is read, then the block's
    update runs (the periodic update of a simulation, forced). It starts from
    :meth:`OnlineIdentification.set_initial_state` at ``q(0)``, at rest. The reference the
    block reads is the log's ``λ_d``, the object held where it is nonzero (the task's
    reference is zero in free motion); its desired motion is not read by the block.

    Parameters
    ----------
    block : OnlineIdentification
        The block (its prior, gains, options). Given a controller's model it writes ``θ̂`` into
        it at the start and after each update, as in a simulation.
    log : mapping of str to numpy.ndarray
        A robot's log (:func:`~drake_coop.experiment.simulate.simulate`'s ``logs[robot]``):
        ``q`` (K, n) rad (the encoder), ``qdot_hat`` (K, n) rad/s (the velocity estimate),
        ``tau`` (K, n) N·m (the commanded torque), ``lambda_d`` (K,) or (K, m) N (the desired
        contact force); other keys are not read. K ≥ 1 samples, all finite.

    Returns
    -------
    theta_hat : numpy.ndarray
        ``θ̂`` after the last tick (p,).
    lambda_hat : numpy.ndarray
        The force estimate ``λ̂(k)`` at every tick (K, m), N.

    Raises
    ------
    TypeError
        ``block`` is not an :class:`OnlineIdentification`.
    ValueError
        A key missing, an array of another shape than the block's ``n`` and ``m`` and the
        log's ``K``, or a value not finite.
    """
    if not isinstance(block, OnlineIdentification):
        raise TypeError(f"block: must be an OnlineIdentification, got {type(block).__name__}")
    n, m = block._n, block._m
    missing = [key for key in REPLAY_KEYS if key not in log]
    if missing:
        raise ValueError(f"log: missing {', '.join(missing)} (needs {', '.join(REPLAY_KEYS)})")
    data = {}
    for key in REPLAY_KEYS:
        try:
            data[key] = np.asarray(log[key], float)
        except (TypeError, ValueError):
            raise ValueError(f"log: {key} must be an array of numbers") from None
        if not np.all(np.isfinite(data[key])):
            raise ValueError(f"log: {key} must be finite")
    K = len(data["q"]) if data["q"].ndim == 2 else 0
    for key in ("q", "qdot_hat", "tau"):
        if K < 1 or data[key].shape != (K, n):
            raise ValueError(f"log: {key} must be (K, {n}) with K >= 1 the samples of q, got "
                             f"{data[key].shape}")
    allowed = [(K, m)] + ([(K,)] if m == 1 else [])
    if data["lambda_d"].shape not in allowed:
        raise ValueError(f"log: lambda_d must be {' or '.join(map(str, allowed))}, got "
                         f"{data['lambda_d'].shape}")
    lam_d = data["lambda_d"].reshape(K, m)
    context = block.CreateDefaultContext()
    block.set_initial_state(context, data["q"][0])
    zero = np.zeros((K, n))
    reference = block._layout.pack(zero, zero, zero, lam_d, np.any(lam_d != 0, axis=1))
    ports = [block.get_input_port(i) for i in range(4)]
    lam_hat = np.zeros((K, m))
    values = block.AllocateDiscreteVariables()
    for k in range(K):
        for port, value in zip(ports, (data["q"][k], data["qdot_hat"][k], data["tau"][k],
                                       reference[k])):
            port.FixValue(context, value)
        lam_hat[k] = block.GetOutputPort("lambda_hat").Eval(context)
        block.CalcForcedDiscreteVariableUpdate(context, values)
        context.SetDiscreteState(values)
    return context.get_discrete_state(block._theta).value().copy(), lam_hat
