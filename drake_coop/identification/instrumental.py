"""Identification for closed-loop data: the iterated instrumental-variable estimate (IDIM-IV).

The excitation runs in closed loop (:class:`~drake_coop.identification.collect.JointTracker`):
the commanded torque ``τ(k)`` contains ``K_p (q_d − q_m(k)) + K_v(…)``, so every disturbance of
the measured motion (encoder quantization, the unmodelled friction's effect on the tracking
error, the filtering of ``q_m``) is in the torque *and* in the regressor
``Y(q_m, q̇, q̈)`` built from the same measurements. Least squares then solves equations whose
error is correlated with their matrix, and is biased (Janot, Vandanjon, Gautier, "A generic
instrumental variable approach for industrial robot identification", IEEE T-CST 2014; BIRDy's
``IDIM-IV``).

**The instruments** are the regressor of a noise-free *simulation* of the closed loop: the arm
with the current estimate ``θ_i`` (:class:`ModelDynamics`), driven by the same tracking law
with the same reference, feedforward and gains (:func:`simulate_tracking`), its positions
sampled at ``h`` and smoothed exactly as the measurements (the same Savitzky–Golay filter):
``Z_i = Y(q_s, q̇_s, q̈_s)`` on the kept samples. ``Z_i`` is correlated with ``Y`` (the two
trajectories differ by the tracking error only) and not with the measurement disturbances
(the simulation never reads them).

**The estimate** solves the instrumental-variable normal equations ``Zᵀ(Yθ − τ) = 0`` in their
least-squares (two-stage) form: with ``U_r`` an orthonormal basis of the identifiable column
space of ``Z`` (column-scaled, relative rank as :func:`~drake_coop.identification.regressor.
identifiable_basis`), it minimizes ``‖U_rᵀ(Yθ − τ)‖²`` — for a square full-rank ``ZᵀY`` the
closed form ``θ = (ZᵀY)⁻¹Zᵀτ`` — under the *same* prior and physical-consistency constraints
as the MAP estimate (:func:`~drake_coop.identification.estimate.physically_consistent_map`:
``A = U_rᵀY``, ``b = U_rᵀτ``). ``σ²`` is the variance of the full residual ``τ − Yθ`` of the
unconstrained IV solution. Iterated (``θ_0`` the MAP estimate, then :math:`θ_{i+1}` from the
instruments of ``θ_i``) until the simulated torques change by less than ``tol`` of their RMS
or ``iterations`` are done.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drake_coop.identification.estimate import (
    Estimate,
    PreparedData,
    estimate_parameters,
    physically_consistent_map,
    smooth_and_differentiate,
)
from drake_coop.identification.regressor import (
    ArmStructure,
    Regressor,
    column_scale,
    condition_number,
    spatial_inertia_from_theta,
    RANK_RTOL,
    base_rank,
)


class ModelDynamics:
    r"""The forward dynamics of the arm with parameters ``θ``.

    .. math::
        (M_\theta(q) + \mathrm{diag}(I_a))\,\ddot q = \tau - C_\theta(q,\dot q)\dot q
            + g_\theta(q) - D\dot q - f_c \tanh(\dot q / v_c)

    from a context of the structure's plant in which each composite body carries its ten
    parameters (all other bodies none) and the rotors none (their reflected inertia ``I_a``,
    ``D`` and ``f_c`` are added here): the dynamics whose inverse is ``Y θ``.

    Parameters
    ----------
    structure : ArmStructure
        The arm's parameter layout.
    theta : ndarray
        Physically consistent parameters (each pseudo-inertia PSD).
    coulomb_velocity : float
        ``v_c`` (rad/s), the regressor's smoothing of ``sign(q̇)``.
    """

    def __init__(self, structure: ArmStructure, theta: np.ndarray,
                 coulomb_velocity: float = 0.02):
        self.structure = s = structure
        theta = np.asarray(theta, float)
        if theta.shape != (s.num_parameters,) or not np.all(np.isfinite(theta)):
            raise ValueError(f"theta: {s.num_parameters} finite parameters are required "
                             f"(got shape {theta.shape})")
        plant = s.plant
        self._plant = plant
        self._context = context = plant.CreateDefaultContext()
        for a in plant.GetJointActuatorIndices():
            plant.get_joint_actuator(a).SetRotorInertia(context, 0.0)
        instance = plant.GetBodyByName(s.links[0]).model_instance()
        zero = spatial_inertia_from_theta(np.zeros(10))
        for b in plant.GetBodyIndices(instance):
            plant.get_body(b).SetSpatialInertiaInBodyFrame(context, zero)
        for i, link in enumerate(s.links):
            plant.GetBodyByName(link).SetSpatialInertiaInBodyFrame(
                context, spatial_inertia_from_theta(theta[10 * i: 10 * i + 10]))
        self.rotor = theta[s.joint_slice("rotor_inertia")]
        self.viscous = theta[s.joint_slice("viscous")]
        self.coulomb = theta[s.joint_slice("coulomb")]
        self.coulomb_velocity = float(coulomb_velocity)

    def terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(M + diag(I_a), C v − g + D v + f_c tanh(v / v_c))`` at ``(q, v)``.

        Parameters
        ----------
        q : numpy.ndarray
            Positions (n,), rad.
        v : numpy.ndarray
            Velocities (n,), rad/s.

        Returns
        -------
        M : numpy.ndarray
            The inertia with the rotors' (n, n), kg·m².
        bias : numpy.ndarray
            The velocity and gravity terms (n,), N·m.
        """
        plant, context = self._plant, self._context
        plant.SetPositions(context, q)
        plant.SetVelocities(context, v)
        M = plant.CalcMassMatrix(context) + np.diag(self.rotor)
        bias = (plant.CalcBiasTerm(context) - plant.CalcGravityGeneralizedForces(context)
                + self.viscous * v + self.coulomb * np.tanh(v / self.coulomb_velocity))
        return M, bias

    def step(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float
             ) -> tuple[np.ndarray, np.ndarray]:
        """One semi-implicit Euler step of ``dt`` (friction linearly implicit, so the steep
        ``tanh`` near rest stays stable): ``(M + dt F'(v)) Δv = dt (τ − bias)``,
        ``q⁺ = q + dt v⁺``.

        Parameters
        ----------
        q : numpy.ndarray
            Positions (n,), rad.
        v : numpy.ndarray
            Velocities (n,), rad/s.
        tau : numpy.ndarray
            The torque (n,), N·m.
        dt : float
            The step, s.

        Returns
        -------
        q_next, v_next : numpy.ndarray
            ``q⁺`` (rad), ``v⁺`` (rad/s).
        """
        M, bias = self.terms(q, v)
        slope = (self.viscous + self.coulomb / self.coulomb_velocity
                 / np.cosh(np.clip(v / self.coulomb_velocity, -300, 300)) ** 2)
        dv = np.linalg.solve(M + dt * np.diag(slope), dt * (tau - bias))
        v = v + dv
        return q + dt * v, v


#: A simulated closed loop whose joint speed passes this (rad/s, or m/s) has diverged.
MAX_LOOP_SPEED = 1e3


class ClosedLoopDiverged(RuntimeError):
    """The closed loop simulated with a parameter estimate diverged (a non-finite state, or a
    joint faster than :data:`MAX_LOOP_SPEED`); raised before the state reaches Drake."""


def simulate_tracking(dynamics: ModelDynamics, q_d: np.ndarray, v_d: np.ndarray,
                      feedforward: np.ndarray, kp: np.ndarray, kv: np.ndarray, h: float,
                      substeps: int, torque_limits: np.ndarray | None = None,
                      encoder_delay: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The identification experiment's closed loop on the model, without any measurement noise.

    The law of :class:`~drake_coop.identification.collect.JointTracker`,
    ``τ(k) = τ_ff(k) + K_p(q_d(k) − q_m(k)) + K_v(q̇_d(k) − (q_m(k) − q_m(k−1))/h)`` with
    :math:`q_m(k) = q(t_{k-d})` (exact positions, ``d = encoder_delay`` samples, the initial
    posture before), held over :math:`[t_k, t_{k+1})`, clipped at ``torque_limits``, integrated with
    ``substeps`` steps of :meth:`ModelDynamics.step` per tick. The arm starts at rest in
    ``q_d(0)``.

    Parameters
    ----------
    q_d, v_d, feedforward : ndarray, shape (N, n)
        The reference and the tracking law's feedforward at the ticks.
    dynamics : ModelDynamics
        The model simulated.
    kp, kv : numpy.ndarray
        The PD gains (n,): N·m/rad, N·m·s/rad.
    h : float
        The control period, s.
    substeps : int
        Integration steps per tick (>= 1).
    torque_limits : numpy.ndarray or None
        ``|τ_j|`` bounds (n,), N·m; None for none.
    encoder_delay : int
        ``d``, ticks.

    Returns
    -------
    Simulated
        Positions and velocities at the ticks, the accelerations just after them (the
        model's exact ``q̈(t_k⁺)`` under the held torque), the commanded and the applied
        (clipped) torques.

    Raises
    ------
    ClosedLoopDiverged
        If the loop diverges (one line: the time and the joint).
    """
    N, n = q_d.shape
    if substeps < 1:
        raise ValueError(f"substeps: an integer >= 1 is required (got {substeps})")
    dt = h / substeps
    q, v = np.array(q_d[0], float), np.zeros(n)
    Q, V, A, T, U = (np.empty((N, n)) for _ in range(5))
    q_m_prev = q.copy()
    lim = np.full(n, np.inf) if torque_limits is None else np.asarray(torque_limits, float)
    for k in range(N):
        Q[k], V[k] = q, v
        q_m = Q[k - encoder_delay] if k >= encoder_delay else Q[0]
        tau = feedforward[k] + kp * (q_d[k] - q_m) + kv * (v_d[k] - (q_m - q_m_prev) / h)
        T[k] = tau
        q_m_prev = q_m
        U[k] = applied = np.clip(tau, -lim, lim)
        M, bias = dynamics.terms(q, v)
        A[k] = np.linalg.solve(M, applied - bias)
        for _ in range(substeps):
            q, v = dynamics.step(q, v, applied, dt)
            speed = np.abs(v)
            if not (np.all(np.isfinite(q)) and np.all(speed <= MAX_LOOP_SPEED)):
                j = int(np.argmax(np.where(np.isfinite(speed), speed, np.inf)))
                raise ClosedLoopDiverged(
                    f"the closed loop simulated with the estimate diverged at t = "
                    f"{(k + 1) * h:.3f} s (joint {j + 1}: speed {speed[j]:.3g}, bound "
                    f"{MAX_LOOP_SPEED:g} rad/s)")
    return Simulated(q=Q, v=V, a=A, tau=T, applied=U)


@dataclass
class Simulated:
    """A simulated closed loop at the ticks (:func:`simulate_tracking`), arrays (N, n).

    Attributes
    ----------
    q, v, a : numpy.ndarray
        Positions (rad), velocities (rad/s), accelerations just after the ticks (rad/s²).
    tau : numpy.ndarray
        The commanded torques, N·m.
    applied : numpy.ndarray
        The applied (clipped) torques, N·m.
    """

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    applied: np.ndarray


def projected_equations(Y: np.ndarray, Z: np.ndarray, tau: np.ndarray,
                        rtol: float = RANK_RTOL) -> tuple[np.ndarray, np.ndarray]:
    """``(U_rᵀ Y, U_rᵀ τ)`` with ``U_r`` the identifiable left singular vectors of ``Z``
    (columns scaled, relative rank ``rtol``): the instrumental-variable equations in
    least-squares form (module docstring).

    Parameters
    ----------
    Y : numpy.ndarray
        The regressor (N n, p).
    Z : numpy.ndarray
        The instruments (N n, p).
    tau : numpy.ndarray
        The torques (N n,), N·m.
    rtol : float
        The relative rank tolerance.

    Returns
    -------
    A : numpy.ndarray
        ``U_rᵀ Y`` (r, p).
    b : numpy.ndarray
        ``U_rᵀ τ`` (r,).
    """
    U, sv, _ = np.linalg.svd(Z / column_scale(Z), full_matrices=False)
    U = U[:, :base_rank(sv, rtol)]
    return U.T @ Y, U.T @ tau


def iv_solution(Y: np.ndarray, Z: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The unconstrained (minimum-norm) instrumental-variable solution, ``(ZᵀY)⁻¹Zᵀτ`` when
    ``ZᵀY`` is square and invertible.

    Parameters
    ----------
    Y : numpy.ndarray
        The regressor (N n, p).
    Z : numpy.ndarray
        The instruments (N n, p).
    tau : numpy.ndarray
        The torques (N n,), N·m.
    """
    A, b = projected_equations(Y, Z, tau)
    scale = column_scale(Y)
    return np.linalg.lstsq(A / scale, b, rcond=1e-8)[0] / scale


@dataclass
class ClosedLoop:
    """What the instruments' simulation needs of the experiment (module docstring).

    Attributes
    ----------
    q_d, v_d, feedforward : ndarray, shape (N, n)
        Reference and feedforward at every recorded tick.
    kp, kv : ndarray (n,)
        The tracking law's gains.
    h : float
        Control period (s).
    substeps : int
        Integration steps per tick.
    torque_limits : ndarray (n,) or None
        ``|τ_j|`` bounds, N·m; None for none.
    encoder_delay : int
        The encoders' delay, ticks.
    window, order : int
        The Savitzky–Golay filter of :func:`~drake_coop.identification.estimate.prepare`.
    """

    q_d: np.ndarray
    v_d: np.ndarray
    feedforward: np.ndarray
    kp: np.ndarray
    kv: np.ndarray
    h: float
    substeps: int
    torque_limits: np.ndarray | None = None
    encoder_delay: int = 0
    window: int = 15
    order: int = 3


def instruments(regressor: Regressor, theta: np.ndarray, loop: ClosedLoop,
                index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Z = Y(q_s, q̇_s, q̈_s)`` of the closed loop simulated with ``θ`` on the ticks
    ``index`` (the measured data's kept samples), and the simulated commanded torques.

    Parameters
    ----------
    regressor : Regressor
        The regressor.
    theta : numpy.ndarray
        The parameters simulated (p,).
    loop : ClosedLoop
        The experiment's closed loop.
    index : numpy.ndarray
        The kept samples' ticks.

    Returns
    -------
    Z : numpy.ndarray
        The instruments (N n, p).
    tau : numpy.ndarray
        The simulated commanded torques (N, n), N·m.
    """
    dyn = ModelDynamics(regressor.structure, theta, regressor.coulomb_velocity)
    sim = simulate_tracking(dyn, loop.q_d, loop.v_d, loop.feedforward, loop.kp,
                                       loop.kv, loop.h, loop.substeps, loop.torque_limits,
                                       loop.encoder_delay)
    q, v, a = smooth_and_differentiate(sim.q, loop.h, loop.window, loop.order)
    rows = np.asarray(index) - loop.window // 2
    return regressor.matrix(q[rows], v[rows], a[rows]), sim.tau


@dataclass
class IVEstimate(Estimate):
    """:class:`~drake_coop.identification.estimate.Estimate` of the IV estimator, with its
    iterations: ``history`` the parameters after each (first: the MAP start), ``changes`` the
    relative change of the simulated torques between iterations, ``stopped`` why the iterations
    ended before converging (empty when they converged or used every iteration): the solver
    failed on an iteration's program, whose iterate is then not taken.

    Attributes
    ----------
    theta, theta_ls, residual_rms, condition_number, rank, samples, solver
        As :class:`~drake_coop.identification.estimate.Estimate`.
    history : list of numpy.ndarray
        The parameters after each iteration (first: the MAP start).
    changes : list of float
        The relative change of the simulated torques between iterations.
    stopped : str
        Why the iterations ended early, or ``''``.
    """

    history: list = field(default_factory=list)
    changes: list = field(default_factory=list)
    stopped: str = ""


def estimate_parameters_iv(regressor: Regressor, data: PreparedData, theta0: np.ndarray,
                           loop: ClosedLoop, iterations: int = 3, tol: float = 1e-3,
                           start: Estimate | None = None) -> IVEstimate:
    """The iterated, physically consistent IV estimate (module docstring).

    Parameters
    ----------
    regressor : Regressor
        The arm's regressor ``Y(q, q̇, q̈)``.
    data : PreparedData
        With ``index`` (the tick of each kept sample).
    theta0 : ndarray
        The prior's centre (the nominal model).
    loop : ClosedLoop
        The experiment's closed loop (reference, feedforward, gains, limits).
    iterations : int
        At most this many instrument simulations (>= 1).
    tol : float
        Stop when the simulated commanded torques change by less than ``tol`` of their RMS.
    start : Estimate, optional
        The MAP estimate to start from (computed when None).

    Returns
    -------
    IVEstimate
        The estimate and its iterations.
    """
    if data.index is None:
        raise ValueError("data: PreparedData with the kept samples' index is required")
    if iterations < 1:
        raise ValueError(f"iterations: an integer >= 1 is required (got {iterations})")
    s = regressor.structure
    Y = regressor.matrix(data.q, data.v, data.a)
    y = data.tau.reshape(-1)
    start = start or estimate_parameters(regressor, data, theta0)
    theta = start.theta
    history, changes, stopped = [theta], [], ""
    tau_prev = None
    solver = start.solver
    theta_iv = start.theta_ls
    for _ in range(iterations):
        try:
            Z, tau_sim = instruments(regressor, theta, loop, data.index)
        except ClosedLoopDiverged as exc:       # keep the last estimate whose loop ran
            stopped = str(exc)
            break
        theta_iv = iv_solution(Y, Z, y)
        rank = condition_number(Y)[1]
        sigma2 = max(float(np.sum((y - Y @ theta_iv) ** 2)) / max(1, Y.shape[0] - rank), 1e-12)
        A, b = projected_equations(Y, Z, y)
        try:
            theta, solver = physically_consistent_map(s, A, b, sigma2, theta0)
        except RuntimeError as exc:
            stopped = str(exc)
            break
        history.append(theta)
        if tau_prev is not None:
            change = float(np.sqrt(np.mean((tau_sim - tau_prev) ** 2))
                           / max(np.sqrt(np.mean(tau_sim ** 2)), 1e-12))
            changes.append(change)
            if change < tol:
                break
        tau_prev = tau_sim
    res = (y - Y @ theta).reshape(-1, s.n)
    return IVEstimate(theta=theta, theta_ls=theta_iv,
                      residual_rms=np.sqrt(np.mean(res ** 2, axis=0)),
                      condition_number=start.condition_number, rank=start.rank,
                      samples=start.samples, solver=solver, history=history,
                      changes=changes, stopped=stopped)


def estimate_parameters_didim(regressor: Regressor, tau: np.ndarray, theta0: np.ndarray,
                              loop: ClosedLoop, iterations: int = 8, tol: float = 1e-3,
                              start: Estimate | None = None) -> IVEstimate:
    r"""The direct-and-inverse-dynamics estimate (DIDIM), physically consistent.

    DIDIM (Gautier, Janot, Vandanjon, "A new closed-loop output error method for parameter
    identification of robot dynamics", IEEE T-CST 2013; BIRDy's ``DIDIM``) fits the *commanded
    torque of a simulated closed loop* to the measured one: the regressor is built from the
    states of the closed loop simulated with the current estimate ``θ_i``
    (:func:`simulate_tracking`: the same reference, feedforward, gains and torque limits), its
    exact positions, velocities and accelerations ``q̈(t_k⁺)`` at the ticks, and

    .. math::
        \theta_{i+1} = \arg\min_\theta \frac{\|Y(q_s, \dot q_s, \ddot q_s)\,\theta
            - \tau_a\|^2}{\sigma^2} + \text{prior} \quad \text{s.t. the constraints of the
            MAP estimate},

    ``τ_a(k)`` the measured commanded torque clipped at the limits (the applied one; ticks at
    a limit dropped). No measured position is differentiated: the estimate has neither the
    differentiating filter's distortion nor the encoder noise in its regressor (the noise
    stays in ``τ``, uncorrelated with the simulated states). Iterated from the MAP estimate
    until the simulated torques change by less than ``tol`` of their RMS.

    Parameters
    ----------
    regressor : Regressor
        The arm's regressor ``Y(q, q̇, q̈)``.
    tau : ndarray, shape (N, n)
        The recorded commanded torques at the loop's N ticks.
    theta0 : ndarray
        The prior's centre (the nominal model).
    loop : ClosedLoop
        The experiment's closed loop (reference, feedforward, gains, limits).
    iterations : int
        At most this many simulations (>= 1).
    tol : float
        Stop when the simulated torques change by less than this fraction of their RMS.
    start : Estimate
        The estimate to start from (the MAP estimate).

    Returns
    -------
    IVEstimate
        The estimate and its iterations.
    """
    if iterations < 1:
        raise ValueError(f"iterations: an integer >= 1 is required (got {iterations})")
    tau = np.asarray(tau, float)
    if tau.shape != loop.q_d.shape:
        raise ValueError(f"tau: shape {loop.q_d.shape} (the loop's ticks) is required "
                         f"(got {tau.shape})")
    s = regressor.structure
    lim = (np.full(s.n, np.inf) if loop.torque_limits is None
           else np.asarray(loop.torque_limits, float))
    keep = ~np.any(np.abs(tau) >= 0.999 * lim, axis=1)
    keep[0] = False                      # the first tick: the loop's initial latch
    y = tau[keep].reshape(-1)
    theta = start.theta
    history, changes, tau_prev, stopped = [theta], [], None, ""
    solver, theta_ls = start.solver, start.theta_ls
    Y = None
    for _ in range(iterations):
        try:
            sim = simulate_tracking(ModelDynamics(s, theta, regressor.coulomb_velocity),
                                    loop.q_d, loop.v_d, loop.feedforward, loop.kp, loop.kv,
                                    loop.h, loop.substeps, loop.torque_limits,
                                    loop.encoder_delay)
        except ClosedLoopDiverged as exc:       # keep the last estimate whose loop ran
            stopped = str(exc)
            break
        if tau_prev is not None:
            change = float(np.sqrt(np.mean((sim.tau - tau_prev) ** 2))
                           / max(np.sqrt(np.mean(sim.tau ** 2)), 1e-12))
            changes.append(change)
            if change < tol:
                break
        tau_prev = sim.tau
        Y = regressor.matrix(sim.q[keep], sim.v[keep], sim.a[keep])
        scale = column_scale(Y)
        theta_ls = np.linalg.lstsq(Y / scale, y, rcond=1e-8)[0] / scale
        rank = condition_number(Y)[1]
        sigma2 = max(float(np.sum((y - Y @ theta_ls) ** 2)) / max(1, Y.shape[0] - rank), 1e-12)
        try:
            theta_next, solver = physically_consistent_map(s, Y, y, sigma2, theta0)
        except RuntimeError as exc:
            stopped = str(exc)
            break
        theta = theta_next
        history.append(theta)
    if Y is None:                 # the start's loop diverged: the start, as it is
        return IVEstimate(theta=theta, theta_ls=theta_ls, residual_rms=start.residual_rms,
                          condition_number=start.condition_number, rank=start.rank,
                          samples=int(keep.sum()), solver=solver, history=history,
                          changes=changes, stopped=stopped)
    res = (y - Y @ theta).reshape(-1, s.n)
    return IVEstimate(theta=theta, theta_ls=theta_ls,
                      residual_rms=np.sqrt(np.mean(res ** 2, axis=0)),
                      condition_number=start.condition_number, rank=start.rank,
                      samples=int(keep.sum()), solver=solver, history=history,
                      changes=changes, stopped=stopped)
