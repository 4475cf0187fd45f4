"""Joint-space orthogonalization: the pure math of the paper's Section III (NumPy only).

Notation (per robot, ``n`` joints, ``m`` constraints):

* ``J_phi`` (m×n): the constraint Jacobian ``∂φ/∂q`` of (2).
* ``J_pinv`` (n×m): ``J⁺ = J_φᵀ (J_φ J_φᵀ)⁻¹``, the right pseudo-inverse (Property 1).
* ``Q`` (n×n): ``Q = I − J⁺ J_φ``, the projector onto the tangent space of the constraint
  (Property 1: ``Q J⁺ = 0``, ``Q J_φᵀ = 0``, ``rank Q = n − m``).
* ``Q_dot``, ``J_pinv_dot``: the directional derivatives ``Q̂̇(q, q̇_o)`` and ``Ĵ⁺̇(q, q̇_o)`` of
  (7) — the time derivatives of ``Q`` and ``J⁺`` with the observer velocity ``q̇_o`` in place of
  the unmeasured ``q̇``. They are exact: given ``J̇_φ`` (the derivative of ``J_φ`` along the
  same direction) they follow from differentiating the definitions above.
* ``qdot_r``: the reference velocity (4); ``qddot_r_hat``: its estimated derivative (11).

With ``J_phi = 0`` (free motion, Section IV "force part set to zero") use
:func:`free_motion_projections`: ``Q = I``, ``J⁺ = 0``.
"""

from __future__ import annotations

import functools

import numpy as np


@functools.lru_cache(maxsize=None)
def _identity(n: int) -> np.ndarray:
    """A shared read-only ``n×n`` identity (allocating one per tick costs more than the math)."""
    eye = np.eye(n)
    eye.flags.writeable = False
    return eye


def _solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A⁻¹ B`` for a small SPD ``A``; one constraint (m = 1): ``B · (1/a)``.

    For m = 1 this is what LAPACK's ``gesv`` computes (the reciprocal of the pivot, then a
    product), without NumPy's per-call overhead; the test suite checks it against
    ``np.linalg.solve`` on random Jacobians to 4 ulp (OpenBLAS picks its kernel by CPU, so
    no bit-for-bit claim holds on every machine).
    """
    if A.shape == (1, 1):
        return B * (1.0 / A[0, 0])
    return np.linalg.solve(A, B)


def _inverse(A: np.ndarray) -> np.ndarray:
    """``A⁻¹`` for a small SPD ``A``; one constraint (m = 1): ``1/a`` (as ``getri``, to 4 ulp)."""
    if A.shape == (1, 1):
        return 1.0 / A
    return np.linalg.inv(A)


def projections(J_phi: np.ndarray, damping: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    r"""``J⁺`` and ``Q`` of Property 1.

    .. math:: J^+ = J_\varphi^T (J_\varphi J_\varphi^T + \mu^2 I)^{-1}, \qquad Q = I - J^+ J_\varphi

    ``μ = 0`` (the paper's, the default) is the exact right pseudo-inverse. ``μ > 0`` is the
    damped least-squares inverse (opt-in, for postures near a singularity of ``J_φ``): with
    ``J_φ = U Σ Vᵀ`` it is ``V Σ (Σ² + μ²)⁻¹ Uᵀ``, bounded by ``1/(2μ)`` however small the
    singular values; far from the singularity (``σ ≫ μ``) it differs from ``J⁺`` by a factor
    ``σ²/(σ² + μ²)`` per direction, and ``Q`` is then no exact projector (``Q J⁺ ≠ 0``): the
    force and motion parts of the law are no longer exactly orthogonal.

    Parameters
    ----------
    J_phi : ndarray, shape (m, n)
        Constraint Jacobian (full rank when ``damping`` is 0).
    damping : float
        ``μ`` (same unit as ``J_φ``'s entries, m/rad for a position constraint), ``≥ 0``.

    Returns
    -------
    J_pinv : ndarray, shape (n, m)
        ``J⁺ = J_φᵀ (J_φ J_φᵀ)⁻¹``, rad/m.
    Q : ndarray, shape (n, n)
        ``Q = I − J⁺ J_φ``.
    """
    J_phi = np.atleast_2d(J_phi)
    A = J_phi @ J_phi.T
    if damping:
        A = A + damping * damping * _identity(A.shape[0])
    J_pinv = _solve(A, J_phi).T
    Q = _identity(J_phi.shape[1]) - J_pinv @ J_phi
    return J_pinv, Q


def free_motion_projections(n: int, m: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``J⁺ = 0`` (n×m) and ``Q = I`` (n×n): the controller with its force part set to zero.

    Parameters
    ----------
    n : int
        Joints.
    m : int
        Constraints.

    Returns
    -------
    J_pinv : numpy.ndarray
        ``J⁺ = 0`` (n, m).
    Q : numpy.ndarray
        ``Q = I`` (n, n).
    """
    return np.zeros((n, m)), _identity(n)


def projection_derivatives(
    J_phi: np.ndarray, J_phi_dot: np.ndarray, damping: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    r"""Directional derivatives ``Ĵ⁺̇`` and ``Q̂̇`` of (7) from ``J_φ`` and its derivative.

    With ``A = J_φ J_φᵀ + μ² I`` (``μ`` the constant ``damping`` of :func:`projections`, 0 by
    default) and ``Ȧ = J̇_φ J_φᵀ + J_φ J̇_φᵀ``:

    .. math::
        \dot J^+ = \dot J_\varphi^T A^{-1} - J_\varphi^T A^{-1} \dot A A^{-1},
        \qquad \dot Q = -(\dot J^+ J_\varphi + J^+ \dot J_\varphi)

    Parameters
    ----------
    J_phi : ndarray, shape (m, n)
        The constraint Jacobian ``J_φ``.
    J_phi_dot : ndarray, shape (m, n)
        Derivative of ``J_φ(q)`` along the direction of interest (``q̇_o`` in (7)).
    damping : float
        ``μ`` of :func:`projections`, ``≥ 0``.

    Returns
    -------
    J_pinv_dot : ndarray, shape (n, m)
        The directional derivative of ``J⁺``, rad/(m·s).
    Q_dot : ndarray, shape (n, n)
        The directional derivative of ``Q``, 1/s.
    """
    J_phi = np.atleast_2d(J_phi)
    J_phi_dot = np.atleast_2d(J_phi_dot)
    A = J_phi @ J_phi.T
    if damping:
        A = A + damping * damping * _identity(A.shape[0])
    A_inv = _inverse(A)
    A_dot = J_phi_dot @ J_phi.T + J_phi @ J_phi_dot.T
    J_pinv = J_phi.T @ A_inv
    J_pinv_dot = J_phi_dot.T @ A_inv - J_phi.T @ A_inv @ A_dot @ A_inv
    Q_dot = -(J_pinv_dot @ J_phi + J_pinv @ J_phi_dot)
    return J_pinv_dot, Q_dot


def xi_times(xi: float | np.ndarray, x: np.ndarray | float) -> np.ndarray:
    """``ξ x`` for the gain ``ξ`` of (4): an m×m matrix, or a scalar meaning ``ξ I``.

    A scalar multiplies element-wise (the same doubles as the paper's scalar ``ξ``); a matrix
    multiplies as a matrix.

    Parameters
    ----------
    xi : float or ndarray, shape (m, m)
        ``ξ``.
    x : ndarray, shape (m,), or float
        The vector it multiplies.
    """
    if np.ndim(xi) == 0:
        return xi * np.asarray(x)
    if np.ndim(xi) != 2:
        raise ValueError(f"xi must be a scalar or an m×m matrix, got shape {np.shape(xi)}")
    return np.asarray(xi) @ np.atleast_1d(x)


def reference_velocity(
    Q: np.ndarray,
    J_pinv: np.ndarray,
    *,
    q_hat: np.ndarray,
    q_d: np.ndarray,
    qdot_d: np.ndarray,
    Lambda: float,
    Delta_p: np.ndarray,
    beta: float,
    xi: float | np.ndarray,
    Delta_F_tilde: np.ndarray,
    pdot_d: np.ndarray | float = 0.0,
) -> np.ndarray:
    r"""The reference velocity ``q̇_r`` of (4).

    .. math::
        \dot q_r = Q\big(\dot q_d - \Lambda(\hat q - q_d)\big)
                  + J^+\big(\dot p_d - \beta\,\Delta p + \xi\,\Delta\tilde F\big)

    ``Delta_p = φ(q) − p_d`` with ``p_d = 0``; ``Delta_F_tilde`` is the integral (6) of
    ``Δλ̃ = λ̂ − λ_d``. ``Lambda`` is the scalar of ``Λ = k I``; ``xi`` is ``ξ`` (m×m) or a
    scalar standing for ``ξ I`` (see :func:`xi_times`).

    Parameters
    ----------
    Q, J_pinv : ndarray
        ``Q`` (n×n) and ``J⁺`` (n×m) of Property 1 (:func:`projections`).
    q_hat, q_d, qdot_d : ndarray, shape (n,)
        ``q̂``, ``q_d`` and ``q̇_d``.
    Lambda : float
        ``k`` of ``Λ = k I`` (1/s).
    Delta_p : ndarray, shape (m,)
        ``Δp = φ(q) − p_d``.
    beta : float
        ``β`` (1/s).
    xi : float or ndarray, shape (m, m)
        ``ξ`` (:func:`xi_times`).
    Delta_F_tilde : ndarray, shape (m,)
        ``ΔF̃``, the integral (6).
    pdot_d : ndarray, shape (m,), or float
        ``ṗ_d`` (0 in the paper).
    """
    motion = np.asarray(qdot_d) - Lambda * (np.asarray(q_hat) - np.asarray(q_d))
    force = pdot_d - beta * np.asarray(Delta_p) + xi_times(xi, Delta_F_tilde)
    return Q @ motion + J_pinv @ np.atleast_1d(force)


def reference_acceleration(
    Q: np.ndarray,
    J_pinv: np.ndarray,
    Q_dot: np.ndarray,
    J_pinv_dot: np.ndarray,
    *,
    q_hat: np.ndarray,
    qdot_hat: np.ndarray,
    q_d: np.ndarray,
    qdot_d: np.ndarray,
    qddot_d: np.ndarray,
    Lambda: float,
    Delta_p: np.ndarray,
    beta: float,
    xi: float | np.ndarray,
    Delta_F_tilde: np.ndarray,
    Delta_lambda_tilde: np.ndarray,
    pdot: np.ndarray | float = 0.0,
    pdot_d: np.ndarray | float = 0.0,
    pddot_d: np.ndarray | float = 0.0,
) -> np.ndarray:
    r"""The estimated reference acceleration ``q̈̂_r`` of (11).

    .. math::
        \ddot{\hat q}_r = Q\big(\ddot q_d - \Lambda(\dot{\hat q} - \dot q_d)\big)
          + J^+\big(\ddot p_d - \beta(\dot p - \dot p_d) + \xi\Delta\tilde\lambda\big)
          + \dot{\hat Q}\big(\dot q_d - \Lambda(\hat q - q_d)\big)
          + \dot{\hat J}^+\big(\dot p_d - \beta\Delta p + \xi\Delta\tilde F\big)

    The paper sets ``ṗ = ṗ_d = p̈_d = 0`` (``ṗ`` is not measured); they are arguments so that a
    test can check (11) against the exact derivative of (4). ``qdot_hat`` is the observer's
    derivative estimate ``d/dt q̂`` of (15).

    Parameters
    ----------
    Q, J_pinv : ndarray
        ``Q`` (n×n) and ``J⁺`` (n×m) of Property 1 (:func:`projections`).
    Q_dot, J_pinv_dot : ndarray
        Their derivatives (:func:`projection_derivatives`).
    q_hat, qdot_hat : ndarray, shape (n,)
        ``q̂`` and ``d/dt q̂`` (15).
    q_d, qdot_d, qddot_d : ndarray, shape (n,)
        The joint reference and its derivatives.
    Lambda : float
        ``k`` of ``Λ = k I`` (1/s).
    Delta_p : ndarray, shape (m,)
        ``Δp = φ(q) − p_d``.
    beta : float
        ``β`` (1/s).
    xi : float or ndarray, shape (m, m)
        ``ξ`` (:func:`xi_times`).
    Delta_F_tilde, Delta_lambda_tilde : ndarray, shape (m,)
        ``ΔF̃`` (6) and ``Δλ̃ = λ̂ − λ_d``.
    pdot, pdot_d, pddot_d : ndarray, shape (m,), or float
        ``ṗ``, ``ṗ_d`` and ``p̈_d`` (0 in the paper).
    """
    motion = np.asarray(qdot_d) - Lambda * (np.asarray(q_hat) - np.asarray(q_d))
    motion_dot = np.asarray(qddot_d) - Lambda * (np.asarray(qdot_hat) - np.asarray(qdot_d))
    force = pdot_d - beta * np.asarray(Delta_p) + xi_times(xi, Delta_F_tilde)
    force_dot = pddot_d - beta * (np.asarray(pdot) - pdot_d) + xi_times(xi, Delta_lambda_tilde)
    return (Q @ motion_dot + J_pinv @ np.atleast_1d(force_dot)
            + Q_dot @ motion + J_pinv_dot @ np.atleast_1d(force))
