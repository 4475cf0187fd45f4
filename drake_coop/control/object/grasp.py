"""The grasp and the load split: the contact Jacobian, the grasp matrix ``G``, the object's
wrench ``w``, its minimum-norm split ``f_L = G⁺ w`` over the contacts, the internal (squeeze)
part, and each contact's share of the mass."""

from __future__ import annotations

import numpy as np

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.object.model import GRAVITY, ObjectModel, _vector


def _skew(r: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def contact_jacobian(model: ArmModel, q: np.ndarray, contact_offset: np.ndarray | None
                     ) -> np.ndarray:
    """``J_c = J_x − [r]_× J_ω`` (3×n): the translational Jacobian of the point ``E + r`` moving
    with the end effector, ``r`` = ``contact_offset`` (world frame); ``J_x`` when None. A
    force ``F`` applied at ``E + r`` takes the joint torque ``J_cᵀ F`` (its moment ``r × F``
    about ``E`` included): for a spherical pad of radius ``ρ``, ``r = ρ n`` with ``n`` the
    inward normal, the point where the object touches it.

    Parameters
    ----------
    model : ArmModel
        The arm's model (``J_x``, ``J_ω``).
    q : ndarray, shape (n,)
        Joint positions.
    contact_offset : array_like, shape (3,), optional
        ``r`` (m, world frame); None: ``J_x``.

    Returns
    -------
    numpy.ndarray
        ``J_c`` (3, n), m/rad.
    """
    J = model.J_x(q)
    if contact_offset is None:
        return J
    return J - _skew(contact_offset) @ model.J_omega(q)


def grasp_matrix(points: np.ndarray, reference_point=(0.0, 0.0, 0.0)) -> np.ndarray:
    r"""The grasp matrix ``G`` (6 × 3k) of point contacts: ``w = G [f_1; …; f_k]``.

    .. math::
        G = \begin{bmatrix} I & \cdots & I \\ [r_1]_\times & \cdots & [r_k]_\times
            \end{bmatrix}, \qquad r_i = p_i - p_\mathrm{ref}

    maps the contact forces ``f_i`` (applied to the object at ``p_i``) to their resultant
    force and moment about ``reference_point``.

    Parameters
    ----------
    points : array_like, shape (k, 3)
        The contact points ``p_i`` (m).
    reference_point : array_like, shape (3,)
        ``p_ref``, the point the moments are taken about (m; default the
        origin).

    Returns
    -------
    numpy.ndarray
        ``G`` (6, 3k): rows 0–2 dimensionless, rows 3–5 m.
    """
    points = np.asarray(points, dtype=float)
    ref = _vector(reference_point, "reference_point")
    blocks = [np.vstack([np.eye(3), _skew(p - ref)]) for p in points]
    return np.hstack(blocks)


def object_wrench(model: ObjectModel, acceleration, angular_velocity=(0.0, 0.0, 0.0),
                  angular_acceleration=(0.0, 0.0, 0.0), gravity: float = GRAVITY
                  ) -> np.ndarray:
    """The wrench the contacts must apply to the object, about its centre of mass:
    ``w = [m (a − g); I α + ω × I ω]`` with ``g = (0, 0, −gravity)`` (Newton–Euler).

    Parameters
    ----------
    model : ObjectModel
        The held object.
    acceleration : array_like, shape (3,)
        The centre of mass's acceleration ``a`` (m/s², world frame).
    angular_velocity : array_like, shape (3,)
        ``ω`` (rad/s); default zero.
    angular_acceleration : array_like, shape (3,)
        ``α`` (rad/s²); default zero.
    gravity : float
        ``g`` (m/s²).

    Returns
    -------
    numpy.ndarray
        ``w`` (6,): force (N) then moment (N·m), world frame.
    """
    a = _vector(acceleration, "acceleration")
    w = _vector(angular_velocity, "angular_velocity")
    alpha = _vector(angular_acceleration, "angular_acceleration")
    force = model.mass * (a - np.array([0.0, 0.0, -gravity]))
    moment = model.inertia @ alpha + np.cross(w, model.inertia @ w)
    return np.concatenate([force, moment])


def load_distribution(model: ObjectModel, acceleration, angular_velocity=(0.0, 0.0, 0.0),
                      angular_acceleration=(0.0, 0.0, 0.0), gravity: float = GRAVITY
                      ) -> np.ndarray:
    """Each contact's load ``f_L,i`` (k × 3): the minimum-norm contact forces that apply the
    object's wrench (:func:`object_wrench`), ``f_L = G⁺ w`` with ``G`` the grasp matrix about
    the centre of mass.

    ``f_L`` has no internal part (it is orthogonal to the null space of ``G``); any squeeze
    ``f_I`` with ``G f_I = 0`` (for two opposing pads, equal and opposite forces along the
    grasp line) can be added without changing the object's motion (:func:`internal_part`).

    Parameters
    ----------
    model : ObjectModel
        The held object.
    acceleration : array_like, shape (3,)
        The centre of mass's acceleration ``a`` (m/s², world frame).
    angular_velocity : array_like, shape (3,)
        ``ω`` (rad/s); default zero.
    angular_acceleration : array_like, shape (3,)
        ``α`` (rad/s²); default zero.
    gravity : float
        ``g`` (m/s²).

    Returns
    -------
    numpy.ndarray
        ``f_L`` (k, 3), N.
    """
    G = grasp_matrix(model.grasp_points, model.com)
    w = object_wrench(model, acceleration, angular_velocity, angular_acceleration, gravity)
    f = np.linalg.pinv(G) @ w
    return f.reshape(model.contacts, 3)


def internal_part(model: ObjectModel, forces) -> np.ndarray:
    """The internal (squeeze) part of contact forces (k × 3): their projection on the null
    space of ``G``, ``(I − G⁺ G) f`` (what moves no object).

    Parameters
    ----------
    model : ObjectModel
        The held object.
    forces : array_like, shape (k, 3)
        Contact forces ``f`` (N), one row per contact.

    Returns
    -------
    numpy.ndarray
        The internal forces (k, 3), N.
    """
    G = grasp_matrix(model.grasp_points, model.com)
    f = np.asarray(forces, dtype=float).reshape(-1)
    return ((np.eye(f.size) - np.linalg.pinv(G) @ G) @ f).reshape(model.contacts, 3)


def mass_shares(model: ObjectModel) -> np.ndarray:
    """Each contact's share ``m_i`` (kg) of the object's weight in the minimum-norm split
    (:func:`load_distribution` of a static hold): ``m_i = f_L,i,z / g``, ``Σ m_i = m``.

    For two opposing pads with the centre of mass on the grasp line, the lever rule:
    ``m_1 = m · |p_2 − c| / |p_2 − p_1|``. Arm ``i``'s load along the desired motion is then
    ``f_i = m_i (a − g)`` (exact for the components across the grasp line; along it, any two
    splits differ by an internal force, which the squeeze control sets).

    Parameters
    ----------
    model : ObjectModel
        The held object (its mass, centre of mass and grasp points).
    """
    f = load_distribution(model, np.zeros(3))
    return f[:, 2] / GRAVITY
