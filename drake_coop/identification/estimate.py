r"""Estimating the parameters: offline smoothing, least squares, physical consistency.

**Velocities and accelerations** come from offline, non-causal filtering of the encoder
readings: a Savitzky–Golay filter (a local least-squares polynomial of degree ``order`` over
``window`` samples, evaluated with its first two derivatives at the window's centre;
zero-phase). The commanded torque is held on :math:`[t_k, t_{k+1})`, so the torque acting around
``t_k`` is ``(τ(k−1) + τ(k)) / 2``; that average goes through the same smoothing filter, so
that torques and motion see the same filter. Samples whose window touches a torque limit (the
applied torque is then not the commanded one) or the ends of the record are dropped.

**Estimate**: the maximum a posteriori estimate under physical consistency, a semidefinite
program solved by a solver the drake wheel ships (Clarabel):

.. math::
    \min_\theta \; \frac{\|Y\theta - \tau\|^2}{\sigma^2}
      + \sum_i \Big(\frac{\theta_i - \theta_{0,i}}{s_i}\Big)^2
    \quad \text{s.t.} \quad J_b(\theta_b) \succeq 0 \;\forall b,
    \quad I_{a,j},\, D_j,\, f_{c,j} \ge 0,

with ``J_b`` the 4×4 pseudo-inertia of each composite body
(:func:`~drake_coop.identification.regressor.pseudo_inertia`; PSD exactly when the parameters
are those of a real mass distribution), ``σ²`` the residual variance of the plain least
squares, ``θ_0`` the nominal model the user starts from and ``s_i`` a broad prior spread
(``PRIOR_SPREAD`` of the nominal value, with a floor per kind of parameter). The data decide
every combination of parameters the torques determine; the prior only picks, among the
parameter sets that explain the data equally well, the one closest to the nominal model (the
combinations no joint torque can reveal, e.g. the waist link's mass, which does not change
the arm's dynamics at all).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram

from drake_coop.identification.regressor import ArmStructure, Regressor, pseudo_inertia

#: Relative spread of the prior around the nominal model (1-sigma).
PRIOR_SPREAD = 0.5
#: ``J_b ⪰ PSD_MARGIN · 1`` (kg·m²): strictly physical, so that Drake accepts the written URDF
#: (its validity check has a tolerance of its own).
PSD_MARGIN = 1e-5
#: Floors of the prior's spread: mass (kg), first moment (kg·m), inertia (kg·m²), and per
#: joint: reflected rotor inertia (kg·m²), viscous (N·m·s/rad), Coulomb (N·m).
PRIOR_FLOORS = {"m": 0.5, "h": 0.1, "I": 0.05, "rotor_inertia": 0.05, "viscous": 0.5,
                "coulomb": 0.5}


def savgol_kernels(window: int, order: int) -> np.ndarray:
    """Savitzky–Golay kernels for value, first and second derivative (per sample, ``h = 1``).

    Parameters
    ----------
    window : int
        The window's samples (odd).
    order : int
        The polynomial's order (< window).

    Returns
    -------
    ndarray, shape (3, window)
        Row ``d``: the weights whose dot product with ``window`` samples centred on ``t_k``
        gives the ``d``-th derivative at ``t_k`` of the fitted polynomial.
    """
    if window % 2 == 0 or window <= order:
        raise ValueError(f"window must be odd and larger than order, got {window}, {order}")
    half = window // 2
    x = np.arange(-half, half + 1, dtype=float)
    V = np.vander(x, order + 1, increasing=True)        # columns 1, x, x², ...
    P = np.linalg.pinv(V)                               # coefficients = P @ samples
    return np.vstack([P[0], P[1], 2.0 * P[2]])


def smooth_and_differentiate(y: np.ndarray, h: float, window: int, order: int
                             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zero-phase Savitzky–Golay value, derivative and second derivative of ``y`` (N, n).

    Returns three arrays of shape (N − window + 1, n): the samples ``window // 2`` to
    ``N − window // 2 − 1``.

    Parameters
    ----------
    y : numpy.ndarray
        The samples (N, n).
    h : float
        The sampling time, s.
    window : int
        The window's samples (odd).
    order : int
        The polynomial's order.

    Returns
    -------
    value, derivative, second_derivative : numpy.ndarray
        Each (N − window + 1, n), per s and s².
    """
    K = savgol_kernels(window, order)
    y = np.asarray(y, float)
    out = []
    for d, kernel in enumerate(K):
        # correlate each column with the kernel ('valid' part)
        cols = [np.convolve(y[:, j], kernel[::-1], mode="valid") for j in range(y.shape[1])]
        out.append(np.column_stack(cols) / h ** d)
    return out[0], out[1], out[2]


@dataclass
class PreparedData:
    """Samples ready for the regressor: ``q, q̇, q̈`` and the torque, with kept-sample times.

    Attributes
    ----------
    t : numpy.ndarray
        The kept samples' times (N,), s.
    q, v, a : numpy.ndarray
        Positions (rad), velocities (rad/s), accelerations (rad/s²), (N, n).
    tau : numpy.ndarray
        The torques (N, n), N·m.
    index : numpy.ndarray or None
        The tick ``k`` of each kept sample.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    index: np.ndarray | None = None     # the tick k of each kept sample


def prepare(t: np.ndarray, q_m: np.ndarray, tau_cmd: np.ndarray, h: float,
            torque_limits: np.ndarray, window: int = 15, order: int = 3) -> PreparedData:
    """Smooth, differentiate and select the samples (module docstring).

    Parameters
    ----------
    t : numpy.ndarray
        The ticks' times (N,), s.
    q_m : numpy.ndarray
        The encoder readings (N, n), rad.
    tau_cmd : numpy.ndarray
        The commanded torques (N, n), N·m.
    h : float
        The sampling time, s.
    torque_limits : numpy.ndarray
        ``|τ_j|`` bounds (n,), N·m; samples near them are dropped.
    window : int
        The Savitzky–Golay window (odd).
    order : int
        Its polynomial's order.

    Returns
    -------
    PreparedData
        The kept samples.
    """
    tau_mid = np.vstack([tau_cmd[:1], 0.5 * (tau_cmd[1:] + tau_cmd[:-1])])
    q, v, a = smooth_and_differentiate(q_m, h, window, order)
    tau, _, _ = smooth_and_differentiate(tau_mid, h, window, order)
    half = window // 2
    saturated = np.any(np.abs(tau_cmd) >= 0.999 * np.asarray(torque_limits), axis=1)
    bad = np.convolve(saturated.astype(float), np.ones(window), mode="valid") > 0
    keep = ~bad
    keep[:1] = False                         # the first sample's torque average is one-sided
    ts = t[half: len(t) - half]
    ticks = np.arange(half, len(t) - half)
    return PreparedData(t=ts[keep], q=q[keep], v=v[keep], a=a[keep], tau=tau[keep],
                        index=ticks[keep])


def prior_spread(structure: ArmStructure, theta0: np.ndarray) -> np.ndarray:
    """The prior's 1-sigma per parameter: ``PRIOR_SPREAD |θ_0|`` with ``PRIOR_FLOORS``.

    Parameters
    ----------
    structure : ArmStructure
        The arm's parameter layout.
    theta0 : numpy.ndarray
        The prior's centre (p,).

    Returns
    -------
    numpy.ndarray
        The 1-sigma per parameter (p,), in each parameter's unit.
    """
    floors = []
    for _ in structure.links:
        floors += [PRIOR_FLOORS["m"]] + [PRIOR_FLOORS["h"]] * 3 + [PRIOR_FLOORS["I"]] * 6
    for kind in ("rotor_inertia", "viscous", "coulomb"):
        floors += [PRIOR_FLOORS[kind]] * structure.n
    return np.maximum(PRIOR_SPREAD * np.abs(theta0), np.asarray(floors))


@dataclass
class Estimate:
    """The identified parameters and how well they explain the data.

    Attributes
    ----------
    theta : ndarray
        The physically consistent estimate.
    theta_ls : ndarray
        The plain (minimum-norm) least-squares solution, for comparison.
    residual_rms : ndarray (n,)
        RMS of ``τ − Y θ`` per joint (N·m) on the data used.
    condition_number : float
        Of the column-scaled regressor on its identifiable subspace.
    rank : int
        Number of identifiable parameter combinations.
    samples : int
        Samples used.
    solver : str
        The SDP solver that found ``theta``.
    """

    theta: np.ndarray
    theta_ls: np.ndarray
    residual_rms: np.ndarray
    condition_number: float
    rank: int
    samples: int
    solver: str


def physically_consistent_map(structure: ArmStructure, A: np.ndarray, b: np.ndarray,
                              sigma2: float, theta0: np.ndarray) -> tuple[np.ndarray, str]:
    """The SDP of the module docstring on a generic data term ``‖Aθ − b‖² / σ²``.

    ``A = Y, b = τ`` is the MAP estimate of :func:`estimate_parameters`; the instrumental
    variable estimate (:mod:`~drake_coop.identification.instrumental`) passes the projected
    equations ``A = U_rᵀ Y, b = U_rᵀ τ`` instead. Same prior, same constraints (each composite
    body's pseudo-inertia ``⪰ PSD_MARGIN · 1``; rotor inertia, viscous and Coulomb friction
    ``≥ 0``).

    Parameters
    ----------
    structure : ArmStructure
        The arm's parameter layout (its composite bodies and joints).
    A : ndarray, shape (M, p)
        The data term's matrix (``Y`` or ``U_rᵀ Y``).
    b : ndarray, shape (M,)
        Its right-hand side (``τ`` or ``U_rᵀ τ``), N·m.
    sigma2 : float
        The data term's variance (> 0).
    theta0 : ndarray, shape (p,)
        The prior's centre.

    Returns
    -------
    (theta, solver_name)
        The estimate (p,) and the solver's name.

    Raises
    ------
    RuntimeError
        When the solver reports no solution.
    """
    s = structure
    spread = prior_spread(s, theta0)
    # Decision variables in units of the prior's spread: x = (θ − θ_0) / s.
    prog = MathematicalProgram()
    x = prog.NewContinuousVariables(s.num_parameters, "x")
    As = A * spread / np.sqrt(sigma2)
    r = (b - A @ theta0) / np.sqrt(sigma2)
    Q = 2.0 * (As.T @ As + np.eye(s.num_parameters))
    prog.AddQuadraticCost(Q, -2.0 * As.T @ r, float(r @ r), x, is_convex=True)
    theta_expr = np.array([float(t0) + float(sp) * xi                 # elementwise: numpy's
                           for t0, sp, xi in zip(theta0, spread, x)])  # ufuncs warn on symbols
    for i, _ in enumerate(s.links):
        J = pseudo_inertia(theta_expr[10 * i: 10 * i + 10])
        for d in range(4):
            J[d, d] = J[d, d] - PSD_MARGIN
        prog.AddPositiveSemidefiniteConstraint(J)
    for kind in ("rotor_inertia", "viscous", "coulomb"):
        sl = s.joint_slice(kind)
        prog.AddBoundingBoxConstraint(-theta0[sl] / spread[sl], np.full(s.n, np.inf), x[sl])
    solver = ClarabelSolver()
    result = solver.Solve(prog)
    if not result.is_success():
        raise RuntimeError(f"the identification program failed: {result.get_solution_result()}")
    return theta0 + spread * result.GetSolution(x), solver.solver_id().name()


def estimate_parameters(regressor: Regressor, data: PreparedData, theta0: np.ndarray
                        ) -> Estimate:
    """The physically consistent MAP estimate (module docstring).

    Parameters
    ----------
    regressor : Regressor
        The arm's regressor ``Y(q, q̇, q̈)``.
    data : PreparedData
        The prepared samples.
    theta0 : ndarray
        The nominal parameters (the prior's centre), e.g. of the controller's model.
    """
    from drake_coop.identification.regressor import column_scale, condition_number

    s = regressor.structure
    Y = regressor.matrix(data.q, data.v, data.a)
    y = data.tau.reshape(-1)
    cond, rank = condition_number(Y)
    scale = column_scale(Y)          # round-off columns: inf, so θ_ls is 0 there
    theta_ls = np.linalg.lstsq(Y / scale, y, rcond=1e-8)[0] / scale
    dof = max(1, Y.shape[0] - rank)
    sigma2 = max(float(np.sum((y - Y @ theta_ls) ** 2)) / dof, 1e-12)
    theta, solver = physically_consistent_map(s, Y, y, sigma2, theta0)
    res = (y - Y @ theta).reshape(-1, s.n)
    return Estimate(theta=theta, theta_ls=theta_ls,
                    residual_rms=np.sqrt(np.mean(res ** 2, axis=0)),
                    condition_number=cond, rank=rank, samples=data.q.shape[0],
                    solver=solver)
