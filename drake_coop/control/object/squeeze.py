"""The squeeze that holds the object: the least one that keeps every contact in its friction
cone (:func:`squeeze_for_grasp`), and the largest the torque limits allow (:func:`max_squeeze`)."""

from __future__ import annotations

import numpy as np


def squeeze_for_grasp(loads, normals, mu: float, margin: float = 1.5,
                      lambda_max: float | None = None, lambda_min: float = 0.0
                      ) -> tuple[float, bool]:
    r"""The least squeeze that holds every contact in its friction cone, times a margin.

    Contact ``i`` carries its load ``f_i`` (the force the arm applies to the object for the
    object's motion, :func:`load_distribution`) plus the squeeze ``λ`` along its inward
    normal ``n_i``. Its normal force is ``λ + n_i·f_i`` and its tangential force
    ``t_i = |f_i − (n_i·f_i) n_i|``; Coulomb's cone asks ``t_i ≤ μ (λ + n_i·f_i)``, so

    .. math::
        \lambda = \max\Big(\lambda_\min,\ \mathrm{margin}\cdot
                   \max_i\big(t_i/\mu - n_i\cdot f_i\big)\Big)

    (``margin >= 1`` scales the least squeeze: ``t_i ≤ μ (λ + n_i·f_i)/margin`` when
    ``n_i·f_i = 0``). With ``lambda_max`` (the torque limits', :func:`max_squeeze`) the result
    is clipped to it and ``feasible`` is False when it had to be.

    Parameters
    ----------
    loads : array_like, shape (k, 3)
        Each contact's load ``f_i`` (N) (:func:`load_distribution`).
    normals : array_like, shape (k, 3)
        Each contact's inward normal ``n_i`` (normalized here).
    mu : float
        The friction coefficient ``μ``, > 0.
    margin : float
        The factor on the least squeeze, >= 1.
    lambda_max : float, optional
        The largest squeeze allowed (N) (:func:`max_squeeze`); default none.
    lambda_min : float
        The least squeeze returned (N), >= 0.

    Returns
    -------
    lam : float
        The squeeze (N).
    feasible : bool
        Whether ``lam`` holds the margin within ``lambda_max``.

    Raises
    ------
    ValueError
        ``mu`` <= 0, ``margin`` < 1, a negative ``lambda_min``, shapes.
    """
    if not (np.isfinite(mu) and mu > 0):
        raise ValueError(f"mu: a friction coefficient > 0 is required, got {mu!r}")
    if not (np.isfinite(margin) and margin >= 1.0):
        raise ValueError(f"margin: a number >= 1 is required, got {margin!r}")
    if not (np.isfinite(lambda_min) and lambda_min >= 0):
        raise ValueError(f"lambda_min: a number >= 0 is required, got {lambda_min!r}")
    f = np.atleast_2d(np.asarray(loads, dtype=float))
    n = np.atleast_2d(np.asarray(normals, dtype=float))
    if f.shape != n.shape or f.shape[1] != 3:
        raise ValueError(f"loads, normals: k x 3 each are required, got {f.shape}, {n.shape}")
    n = n / np.linalg.norm(n, axis=1)[:, None]
    fn = np.sum(f * n, axis=1)
    ft = np.linalg.norm(f - fn[:, None] * n, axis=1)
    lam = max(lambda_min, margin * float(np.max(ft / mu - fn)))
    if lambda_max is not None and lam > lambda_max:
        return float(lambda_max), False
    return float(lam), True


def max_squeeze(J_phi, tau_limits, tau_other) -> float:
    """The largest squeeze ``λ`` whose torque ``−J_φᵀ λ`` (13) stays, with the other torques
    ``tau_other`` (gravity, load), within ``|τ_j| ≤ tau_limits_j`` at one posture
    (one constraint): ``min_j`` over the joints of the room left in the pushing direction.

    Parameters
    ----------
    J_phi : array_like, shape (n,)
        The constraint's Jacobian row ``J_φ``.
    tau_limits : array_like, shape (n,)
        ``τ_max`` per joint (N·m).
    tau_other : array_like, shape (n,)
        The other torques at the posture (gravity, load) (N·m).

    Returns
    -------
    float
        The largest squeeze, N (``inf`` when no joint limits it).
    """
    j = np.asarray(J_phi, dtype=float).reshape(-1)
    lim = np.asarray(tau_limits, dtype=float).reshape(-1)
    other = np.asarray(tau_other, dtype=float).reshape(-1)
    if not (j.shape == lim.shape == other.shape):
        raise ValueError("J_phi, tau_limits, tau_other: one entry per joint each is required")
    best = np.inf
    for jj, L, o in zip(j, lim, other):
        if abs(jj) < 1e-12:
            continue
        # τ_j = o − jj λ within [−L, L], λ >= 0.
        bound = (o + L) / jj if jj > 0 else (o - L) / jj
        best = min(best, bound)
    return float(max(best, 0.0))
