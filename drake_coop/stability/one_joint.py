r"""The one-period map of one joint under the paper's law, in closed form: why the loop's
sampling limit is where it is.

One joint of inertia ``J`` and viscous friction ``D`` (no gravity, exact model), regulated to
``q_d = 0`` by the free-motion law (13) (``Q = I``), sampled every ``h``, on a plant stepping
every ``Δt`` (``h = N Δt``) as Drake's discrete plant does with its implicit joint damping:

.. math::
    (J + \Delta t D)\, v^+ = J v + \Delta t\, \tau, \qquad q^+ = q + \Delta t\, v^+ .

With the observer (15)–(16) (forward Euler, state ``q̂, q̇̂_o``), ``z = q − q̂``:

.. math::
    \dot{\hat q} = \dot{\hat q}_o + (\Lambda + k_d) z, \quad
    \dot q_o = \dot{\hat q}_o + k_d z, \quad
    \dot q_r = -\Lambda \hat q, \quad \ddot{\hat q}_r = -\Lambda \dot{\hat q},

.. math::
    \tau = J \ddot{\hat q}_r + D \dot q_r - K_R(\dot q_o - \dot q_r), \qquad
    \hat q^+ = \hat q + h \dot{\hat q}, \quad
    \dot{\hat q}_o^+ = \dot{\hat q}_o + h(\ddot{\hat q}_r + k_d \Lambda z).

With measured velocities (``q̂ = q``, ``q̇̂ = q̇_o = v``) the state is ``[q, v]`` and
``τ = −JΛv − DΛq − K_R(v + Λq)``. Either way ``τ(k) = c·x(k)`` is linear and held, so

.. math::
    \Phi = \begin{bmatrix} A^N + B_N c \\ \text{observer rows} \end{bmatrix}, \qquad
    B_N = \sum_{i<N} A^i B .
"""

from __future__ import annotations

import numpy as np

__all__ = ["crossing_period", "observer_period_limit", "one_joint_phi", "one_joint_predicted_phi",
           "one_joint_predicted_rho", "one_joint_rho"]


def one_joint_phi(J: float, D: float, Lambda: float, k_d: float, K_R: float, h: float,
                  dt: float, velocity: str = "observer", delay_steps: int = 0) -> np.ndarray:
    """Φ of ``x = [q, v, q̂, q̇̂_o]`` (``observer``) or ``[q, v]`` (``measured``).

    ``delay_steps = s > 0`` applies ``τ(k)`` from the ``s``-th plant step of the period on
    (a computation delay, :mod:`drake_coop.sensing.latency`): the first ``s`` steps still get
    ``τ(k−1)``, which joins the state as its last entry.

    Parameters
    ----------
    J : float
        The joint's inertia, kg·m².
    D : float
        Its viscous friction, N·m·s/rad.
    Lambda : float
        ``Λ``, 1/s.
    k_d : float
        ``k_d``, 1/s.
    K_R : float
        ``K_R``, N·m·s/rad.
    h : float
        The control period, s.
    dt : float
        The plant's step, s.
    velocity : str
        ``observer`` or ``measured``.
    delay_steps : int
        ``s``, the plant steps of computation delay.
    """
    N = int(round(h / dt))
    s = int(delay_steps)
    a = J / (J + dt * D)
    b = dt / (J + dt * D)
    A = np.array([[1.0, dt * a], [0.0, a]])
    B = np.array([dt * b, b])

    def steps(m: int) -> tuple[np.ndarray, np.ndarray]:
        return (np.linalg.matrix_power(A, m),
                sum((np.linalg.matrix_power(A, i) @ B for i in range(m)), np.zeros(2)))

    if velocity == "measured":
        c = np.array([-D * Lambda - K_R * Lambda, -J * Lambda - K_R])
        rows = np.zeros((0, 2))
    else:
        z = np.array([1.0, 0.0, -1.0, 0.0])
        o = np.array([0.0, 0.0, 0.0, 1.0])
        qdot_hat = o + (Lambda + k_d) * z
        qdot_o = o + k_d * z
        qdot_r = np.array([0.0, 0.0, -Lambda, 0.0])
        c = J * (-Lambda * qdot_hat) + D * qdot_r - K_R * (qdot_o - qdot_r)
        rows = np.vstack([np.array([0.0, 0.0, 1.0, 0.0]) + h * qdot_hat,
                          o + h * (-Lambda * qdot_hat + k_d * Lambda * z)])
    n = len(c)
    A_late, B_late = steps(N - s)          # the steps with τ(k)
    A_early, B_early = steps(s)            # the steps with τ(k−1)
    size = n + (1 if s else 0)
    Phi = np.zeros((size, size))
    Phi[0:2, 0:2] = A_late @ A_early
    Phi[0:2, 0:n] += np.outer(B_late, c)
    Phi[2:n, 0:n] = rows
    if s:
        Phi[0:2, n] = A_late @ B_early
        Phi[n, 0:n] = c
    return Phi


def one_joint_rho(*args, **kwargs) -> float:
    """``ρ(Φ)`` of :func:`one_joint_phi` (same arguments).

    Parameters
    ----------
    *args, **kwargs
        Those of :func:`one_joint_phi`.
    """
    return float(np.max(np.abs(np.linalg.eigvals(one_joint_phi(*args, **kwargs)))))


def crossing_period(J: float, D: float, Lambda: float, k_d: float, K_R: float, dt: float,
                    velocity: str = "observer", max_steps: int = 200) -> float | None:
    """The smallest ``h = N Δt`` at which ``ρ ≥ 1`` (None up to ``max_steps`` steps).

    Parameters
    ----------
    J : float
        The joint's inertia, kg·m².
    D : float
        Its viscous friction, N·m·s/rad.
    Lambda : float
        ``Λ``, 1/s.
    k_d : float
        ``k_d``, 1/s.
    K_R : float
        ``K_R``, N·m·s/rad.
    dt : float
        The plant's step, s.
    velocity : str
        ``observer`` or ``measured``.
    max_steps : int
        The largest ``N`` tried.

    Returns
    -------
    float or None
        ``h``, s, or None.
    """
    for N in range(1, max_steps + 1):
        if one_joint_rho(J, D, Lambda, k_d, K_R, N * dt, dt, velocity) >= 1.0:
            return N * dt
    return None


def observer_period_limit(Lambda: float, k_d: float) -> float:
    """``2 / p_f``: the largest ``h`` at which the forward-Euler observer loop is stable while
    the arm does not move within a sample (``J → ∞``).

    With ``q`` frozen, (15)–(16) with ``q̈̂_r = −Λ q̇̂`` (free motion, ``q_d`` constant) are
    linear in ``(q̂, q̇̂_o)`` with the characteristic polynomial
    ``s² + (2Λ + k_d) s + Λ k_d``; forward Euler maps a real pole ``−p`` to ``1 − h p``, stable
    iff ``h < 2/p``, and the fast pole
    ``p_f = ((2Λ + k_d) + √((2Λ + k_d)² − 4Λk_d)) / 2`` binds first.

    Parameters
    ----------
    Lambda : float
        ``Λ``, 1/s.
    k_d : float
        ``k_d``, 1/s.
    """
    b = 2.0 * Lambda + k_d
    p_fast = 0.5 * (b + np.sqrt(b * b - 4.0 * Lambda * k_d))
    return float(2.0 / p_fast)


def _plant_steps(J: float, D: float, duration: float, dt: float | None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` with ``[q, v](t + duration) = A [q, v](t) + B τ`` for a constant ``τ``: the
    discrete plant's steps of ``dt`` (``duration`` a whole number of them), or the exact
    solution of ``J q̈ + D q̇ = τ`` when ``dt`` is None (the continuous arm)."""
    if duration <= 0.0:
        return np.eye(2), np.zeros(2)
    if dt is None:
        # Exact: the matrix exponential of the augmented system [q, v, τ].
        M = np.array([[0.0, 1.0, 0.0], [0.0, -D / J, 1.0 / J], [0.0, 0.0, 0.0]]) * duration
        E = _expm(M)
        return E[0:2, 0:2], E[0:2, 2]
    m = int(round(duration / dt))
    a = J / (J + dt * D)
    b = dt / (J + dt * D)
    A = np.array([[1.0, dt * a], [0.0, a]])
    B = np.array([dt * b, b])
    return (np.linalg.matrix_power(A, m),
            sum((np.linalg.matrix_power(A, i) @ B for i in range(m)), np.zeros(2)))


def _expm(M: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring of a Taylor series (small matrices)."""
    norm = np.max(np.sum(np.abs(M), axis=1))
    s = max(0, int(np.ceil(np.log2(norm))) + 1) if norm > 0 else 0
    A = M / 2.0 ** s
    E = np.eye(len(M))
    term = np.eye(len(M))
    for i in range(1, 20):
        term = term @ A / i
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


def one_joint_predicted_phi(J: float, D: float, Lambda: float, k_d: float, K_R: float,
                            h: float, delay: float, horizon: float | None,
                            dt: float | None = None, model_scale: float = 1.0,
                            feed: str = "horizon") -> np.ndarray:
    """Φ of one joint under the observer-based law with a computation delay and, optionally,
    the delay compensation of :class:`~drake_coop.control.delay.DelayPredictor`.

    State ``x = [q, v, q̂, q̇̂_o, τ_prev]``, ``τ_prev`` the torque on the arm when the tick
    starts. The torque ``τ(k)`` switches on at ``t_k + delay``; the plant is the discrete one
    of :func:`one_joint_phi` (``dt``; the delay rounded up to whole steps as
    :mod:`drake_coop.sensing.latency` does) or, with ``dt = None``, the continuous arm
    integrated exactly across the switch. The controller's model is ``model_scale·(J, D)``.
    The predictor (``horizon = p``, None: off) computes ``a = (τ_prev − D̂ q̇̂)/Ĵ`` and feeds
    the law ``q_p = q + p q̇̂ + p² a/2`` (likewise ``q̂``), ``q̇̂ + p a``, ``q̇_o + p a``; the
    observer (16) is fed ``w a + (1 − w) q̈̂_r`` with ``w = p/h`` (``feed = "horizon"``, the
    block's), ``w = delay/h`` (``feed = "delay"``) or ``w = 0`` (``feed = "none"``: the
    prediction without the observer's feed, to measure what the feed buys).

    Parameters
    ----------
    J : float
        The joint's inertia, kg·m².
    D : float
        Its viscous friction, N·m·s/rad.
    Lambda : float
        ``Λ``, 1/s.
    k_d : float
        ``k_d``, 1/s.
    K_R : float
        ``K_R``, N·m·s/rad.
    h : float
        The control period, s.
    delay : float
        The computation delay, s.
    horizon : float or None
        The predictor's horizon ``p``, s; None: no predictor.
    dt : float or None
        The plant's step, s; None for the continuous arm.
    model_scale : float
        The controller model's scale of ``J`` and ``D``.
    feed : str
        ``horizon``, ``delay`` or ``none``: the observer's weight ``w``.

    Raises
    ------
    ValueError
        ``feed`` is none of the three.
    """
    if feed not in ("horizon", "delay", "none"):
        raise ValueError(f"feed: one of horizon, delay, none, got {feed!r}")
    Jm, Dm = model_scale * J, model_scale * D
    e = np.eye(5)
    q, v, qh, qo, tp = e
    z = q - qh
    qdot_hat = qo + (Lambda + k_d) * z
    qdot_o = qo + k_d * z
    if horizon is None:
        a = np.zeros(5)
        p = 0.0
        w = 0.0
    else:
        p = float(horizon)
        a = (tp - Dm * qdot_hat) / Jm
        w = {"horizon": p, "delay": delay, "none": 0.0}[feed] / h
    shift = p * qdot_hat + 0.5 * p * p * a
    qh_p = qh + shift
    qdot_hat_p = qdot_hat + p * a
    qdot_o_p = qdot_o + p * a
    qdot_r = -Lambda * qh_p
    qddot_r = -Lambda * qdot_hat_p
    tau = Jm * qddot_r + Dm * qdot_r - K_R * (qdot_o_p - qdot_r)
    fed = w * a + (1.0 - w) * qddot_r
    if dt is None:
        d_early = float(delay)
    else:
        d_early = int(min(round(h / dt), max(0, np.ceil(delay / dt - 1e-9)))) * dt
    A_e, B_e = _plant_steps(J, D, d_early, dt)
    A_l, B_l = _plant_steps(J, D, h - d_early, dt)
    X = np.vstack([q, v])
    X_next = A_l @ (A_e @ X + np.outer(B_e, tp)) + np.outer(B_l, tau)
    Phi = np.vstack([X_next,
                     qh + h * qdot_hat,
                     qo + h * (fed + k_d * Lambda * z),
                     tau])
    return Phi


def one_joint_predicted_rho(*args, **kwargs) -> float:
    """``ρ(Φ)`` of :func:`one_joint_predicted_phi` (same arguments).

    Parameters
    ----------
    *args, **kwargs
        Those of :func:`one_joint_predicted_phi`.
    """
    return float(np.max(np.abs(np.linalg.eigvals(one_joint_predicted_phi(*args, **kwargs)))))
