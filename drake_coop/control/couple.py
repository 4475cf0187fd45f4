r"""The squeeze's couple in the load split of two opposing pads.

Two pads squeeze an object along the unit normal ``n`` (inward at pad 1, ``−n`` at pad 2).
A spherical pad's normal force passes through its centre ``E_i`` (the pressure is normal to
the face the sphere touches, its centre the point of the face nearest ``E_i``), so the
squeeze pair ``λ n`` at ``E_1``, ``−λ n`` at ``E_2`` acts along two parallel lines. When the
centres are offset across the normal, ``d = T (E_1 − E_2)`` (``T = I − n nᵀ``; e.g. the pads
at different heights ``Δz``), the pair has the moment

.. math:: M = (E_1 - E_2) \times \lambda n = \lambda\, d \times n

(the part of ``E_1 − E_2`` along ``n`` gives none), which no motion of the object asks for:
the pads' tangential (friction) forces must cancel it. They act on the faces, at
``p_i = E_i + (ρ_i − δ_i) n_i`` (``ρ_i`` the pad's radius, ``δ_i`` its compression,
``n_i`` its inward normal), a lever ``w = n·(p_2 − p_1)`` apart along the normal (the
object's width between the faces). The least such pair (no internal part, equal and
opposite, across the normal) solves ``(p_1 − p_2) × f_1 = −M`` with ``f_2 = −f_1``:

.. math::
    f_{c,1} = -\frac{\lambda}{w}\, T (E_1 - E_2), \qquad f_{c,2} = -f_{c,1}

(check: :math:`(p_1 - p_2) \times f_{c,1} = (-w n) \times (-\lambda d/w) = \lambda\, n \times
d = -M`). Along a vertical offset ``Δz = z_1 − z_2`` this is the moment balance of the object about
its centre of mass under the two pads' forces: each pad's vertical force is its share of the weight
and inertial load ``m_i (g + a_z)`` and ``∓ λ Δz / w``,

.. math:: f_{1,z} - f_{2,z} = -\frac{2 \lambda \Delta z}{w}

(the higher pad carries less). The forces are the ones *the arms apply to the object*, as
:class:`~drake_coop.control.object.LoadFeedforward`'s ``f_i``: add :math:`f_{c,i}` to arm ``i``'s
load (its ``f_couple`` input). A centre-of-mass offset along the grasp line changes the
weight's split (:func:`~drake_coop.control.object.mass_shares`), not the couple's. The pair
``f_c`` has no moment about the grasp line itself; a moment about it (the weight, when the
pads' centres are beside the centre of mass) is held by the contact patches' torsional
friction, not by point forces, and is not part of this.

What each arm needs: both pads' centres along the desired motion — from the two arms'
references, fixed before the run like the path (forward kinematics of ``q_d``) — the desired
squeeze ``λ_d`` and the lever ``w``. Nothing passes between the arms during the run.

This module imports only NumPy.
"""

from __future__ import annotations

import numpy as np


def _unit(normal) -> np.ndarray:
    n = np.asarray(normal, dtype=float)
    if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) < 1e-12:
        raise ValueError(f"normal: a nonzero 3-vector is required, got {np.shape(normal)}")
    return n / np.linalg.norm(n)


def squeeze_couple(centres, normal, lam, lever) -> np.ndarray:
    r"""The two pads' forces on the object that carry the squeeze's couple.

    Parameters
    ----------
    centres : array_like, shape (..., 2, 3)
        ``E_1``, ``E_2``: the pads' centres (m), where their normal forces pass (world frame),
        at one instant or along a path (leading dimensions).
    normal : array_like, shape (3,)
        ``n``: the squeeze's direction at pad 1 (unit after normalization; pad 1 pushes the
        object along ``n``, pad 2 along ``−n``).
    lam : float or array_like, shape (...)
        ``λ`` (N), the squeeze.
    lever : float or array_like, shape (...)
        ``w`` (m), > 0: the distance along ``n`` between the points where the pads' tangential
        forces act (:func:`face_distance`; the centres' distance for pads that are held at
        their centres, e.g. a ball joint).

    Returns
    -------
    ndarray, shape (..., 2, 3)
        :math:`f_{c,1} = -(\lambda/w)\, T (E_1 - E_2)` and :math:`f_{c,2} = -f_{c,1}` (N).

    Raises
    ------
    ValueError
        ``centres`` not (..., 2, 3), a zero ``normal``, a ``lever`` <= 0, non-finite values.
    """
    E = np.asarray(centres, dtype=float)
    if E.ndim < 2 or E.shape[-2:] != (2, 3) or not np.all(np.isfinite(E)):
        raise ValueError(f"centres: finite (..., 2, 3) pad centres are required, got {E.shape}")
    n = _unit(normal)
    lam = np.asarray(lam, dtype=float)
    w = np.asarray(lever, dtype=float)
    if not (np.all(np.isfinite(w)) and np.all(w > 0)):
        raise ValueError("lever: a distance > 0 (m) is required")
    if not np.all(np.isfinite(lam)):
        raise ValueError("lam: finite squeeze values (N) are required")
    T = np.eye(3) - np.outer(n, n)
    d = (E[..., 0, :] - E[..., 1, :]) @ T
    f1 = -(lam / w)[..., None] * d
    return np.stack([f1, -f1], axis=-2)


def face_distance(centres, normal, radii=(0.0, 0.0), compressions=(0.0, 0.0)) -> np.ndarray:
    """The lever ``w = n·(p_2 − p_1)`` of :func:`squeeze_couple`: the distance along ``n``
    between the pads' surfaces where they touch the object, ``p_i = E_i + (ρ_i − δ_i) n_i``
    (``n_1 = n``, ``n_2 = −n``), i.e. ``n·(E_2 − E_1) − (ρ_1 − δ_1) − (ρ_2 − δ_2)``.

    Parameters
    ----------
    centres : array_like, shape (..., 2, 3)
        The pads' centres (m).
    normal : array_like, shape (3,)
        ``n`` (pad 1's inward normal).
    radii : array_like, shape (2,) or (..., 2)
        ``ρ_i`` (m), >= 0 (0 for pads held at their centres).
    compressions : array_like, shape (2,) or (..., 2)
        ``δ_i`` (m), >= 0, each pad's compression.
    """
    E = np.asarray(centres, dtype=float)
    if E.ndim < 2 or E.shape[-2:] != (2, 3):
        raise ValueError(f"centres: (..., 2, 3) pad centres are required, got {E.shape}")
    n = _unit(normal)
    rho = np.asarray(radii, dtype=float)
    delta = np.asarray(compressions, dtype=float)
    if np.any(rho < 0) or np.any(delta < 0):
        raise ValueError("radii, compressions: numbers >= 0 (m) are required")
    gap = (E[..., 1, :] - E[..., 0, :]) @ n
    return gap - (rho[..., 0] - delta[..., 0]) - (rho[..., 1] - delta[..., 1])
