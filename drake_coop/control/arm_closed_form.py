r"""The arm model's kinematics in closed form: exact, cheap, no AutoDiff.

* The one constraint row of a three-joint arm of the paper's kind (the closed form of
  :class:`~drake_coop.kinematics.crs.CrsKinematics`, which the application passes as
  ``ArmModel(closed_form=...)``), on plain floats (a 3-vector per NumPy call costs more than
  the arithmetic): :func:`paper_arm_row` (``φ`` and ``J_φ``), :func:`paper_arm_row_dot`
  (``J̇_φ`` along a direction). With the normal ``n`` rotated into the base frame,
  ``φ = (R_bᵀ n)·x_local(q) + n·(p_b − c)`` and ``J_φ = (R_bᵀ n)ᵀ J_local(q)``.
* ``J̇_x`` of any serial chain from its geometric Jacobian: :func:`jacobian_dot`.

``J̇_φ`` along a direction ``d`` on a serial chain of revolute and prismatic joints is the
closed-form derivative of the geometric Jacobian's columns (no AutoDiff): with ``a_k`` the
angular column of joint ``k`` (its world axis, 0 for a prismatic joint), ``J_k`` its
translational column, :math:`\omega_k = \sum_{j<k} a_j d_j` the angular velocity of the body
that carries joint ``k`` and :math:`s_k = \sum_{j \ge k} J_j d_j` the pad's velocity relative
to that body,

.. math:: \dot J_k = \omega_k \times J_k + a_k \times s_k

(``J_k = a_k × (x − p_k)``: ``ȧ_k = ω_k × a_k``, ``d/dt (x − p_k) = ω_k × (x − p_k) + s_k``,
and the Jacobi identity). Exact, to the roundings of a few cross products; checked against
forward-mode AutoDiff (:meth:`~drake_coop.control.arm_model.ArmModel.J_phi_and_derivative_autodiff`, kept as the reference
and as the fallback for a model that is not such a chain) and finite differences.
Both paths are exact; they differ by roundings.

Both are evaluated by :class:`~drake_coop.control.arm_model.ArmModel`, which keeps their
inputs (the constants of the row, the tick's Jacobian) and caches their results per ``q``.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.multibody.plant import MultibodyPlant


def paper_arm_row_setup(closed_form, normal: np.ndarray, c: np.ndarray, offset: np.ndarray
                        ) -> tuple[tuple, tuple]:
    """The constants of :func:`paper_arm_row` for one arm and one constraint.

    Parameters
    ----------
    closed_form : CrsKinematics
        The arm's closed-form kinematics (``geometry`` with ``h1, L2, L3``, ``R_base``,
        ``p_base``).
    normal : numpy.ndarray
        The constraint's unit normal ``n`` (3,), world frame.
    c : numpy.ndarray
        The contact point (3,), m, world frame.
    offset : numpy.ndarray
        The controlled point's offset ``o`` (3,), m, in the end effector's frame.

    Returns
    -------
    constants : tuple of float
        ``(n_x, n_y, n_z, off)`` of :func:`paper_arm_row`.
    lengths : tuple of float
        ``(h1, L2, L3 + o_z, o_x, o_y)`` of :func:`paper_arm_row`.
    """
    geometry = closed_form.geometry
    # (h1, L2, A = L3 + o_z, o_x, o_y): the centre's formulas with the forearm to P.
    lengths = (geometry.h1, geometry.L2, geometry.L3 + float(offset[2]),
               float(offset[0]), float(offset[1]))
    nl = closed_form.R_base.T @ normal            # the first normal in the base frame
    constants = (float(nl[0]), float(nl[1]), float(nl[2]),
                 float(normal @ (closed_form.p_base - c)))
    return constants, lengths


def paper_arm_row(constants: tuple, lengths: tuple, q: list[float]
                  ) -> tuple[float, list[float], tuple]:
    """``φ(q)`` and the row ``J_φ(q)`` of one constraint of a three-joint arm of the paper's
    kind, on plain floats.

    Parameters
    ----------
    constants : tuple of float
        ``(n_x, n_y, n_z, off)``: the normal in the arm's base frame, ``R_bᵀ n`` (unit), and
        ``n·(p_b − c)`` (m).
    lengths : tuple of float
        ``(h1, L2, L3 + o_z, o_x, o_y)``: the arm's lengths with the controlled point's offset
        ``o`` from the forearm's end (m).
    q : list of float
        Joint positions (3), rad.

    Returns
    -------
    phi : float
        ``φ(q)``, m.
    J_phi : list of float
        ``J_φ(q)`` (3 numbers), m/rad.
    terms : tuple of float
        The intermediate terms :func:`paper_arm_row_dot` reuses at the same ``q``.
    """
    nx, ny, nz, off = constants
    h1, L2, L3, ox, oy = lengths
    q1, q2, q3 = q
    s1, c1 = math.sin(q1), math.cos(q1)
    s2, c2 = math.sin(q2), math.cos(q2)
    s23, c23 = math.sin(q2 + q3), math.cos(q2 + q3)
    if ox or oy:                      # a point off the forearm's axis (point_offset)
        b, e = L3 * c23 - ox * s23, L3 * s23 + ox * c23
        r, a = L2 * s2 + e, L2 * c2 + b
        phi = (nx * (r * c1 - oy * s1) + ny * (r * s1 + oy * c1)
               + nz * (h1 + L2 * c2 + b) + off)
        j = [-nx * (r * s1 + oy * c1) + ny * (r * c1 - oy * s1),
             nx * a * c1 + ny * a * s1 - nz * r, nx * b * c1 + ny * b * s1 - nz * e]
    else:
        b, e = L3 * c23, L3 * s23
        r, a = L2 * s2 + e, L2 * c2 + b
        phi = nx * r * c1 + ny * r * s1 + nz * (h1 + L2 * c2 + b) + off
        j = [-nx * r * s1 + ny * r * c1, nx * a * c1 + ny * a * s1 - nz * r,
             nx * b * c1 + ny * b * s1 - nz * e]
    return phi, j, (s1, c1, s2, r, a, b, e)


def paper_arm_row_dot(constants: tuple, lengths: tuple, terms: tuple, v: list[float]
                      ) -> list[float]:
    """``J̇_φ`` along ``v`` of one constraint of a three-joint arm of the paper's kind, on
    plain floats (the derivative of :func:`paper_arm_row`'s ``J_φ``).

    Parameters
    ----------
    constants : tuple of float
        As :func:`paper_arm_row`'s.
    lengths : tuple of float
        As :func:`paper_arm_row`'s.
    terms : tuple of float
        :func:`paper_arm_row`'s ``terms`` at the same ``q``.
    v : list of float
        The direction (joint velocities) (3), rad/s.

    Returns
    -------
    list of float
        The row ``J̇_φ`` (3 numbers), m/(rad·s).
    """
    s1, c1, s2, r, a, b, e = terms
    nx, ny, nz, _ = constants
    L2 = lengths[1]
    oy = lengths[4]
    v1, v2, v3 = v
    w = v2 + v3
    rd = a * v2 + b * v3
    ad = -L2 * s2 * v2 - e * w
    bd = -e * w
    ed = b * w
    if oy:
        return [nx * (-rd * s1 - r * c1 * v1 + oy * s1 * v1)
                + ny * (rd * c1 - r * s1 * v1 - oy * c1 * v1),
                nx * (ad * c1 - a * s1 * v1) + ny * (ad * s1 + a * c1 * v1) - nz * rd,
                nx * (bd * c1 - b * s1 * v1) + ny * (bd * s1 + b * c1 * v1) - nz * ed]
    return [nx * (-rd * s1 - r * c1 * v1) + ny * (rd * c1 - r * s1 * v1),
            nx * (ad * c1 - a * s1 * v1) + ny * (ad * s1 + a * c1 * v1) - nz * rd,
            nx * (bd * c1 - b * s1 * v1) + ny * (bd * s1 + b * c1 * v1) - nz * ed]


def jacobian_dot(Jw: np.ndarray, Jx: np.ndarray, direction: np.ndarray) -> np.ndarray:
    r"""``J̇_x`` along ``direction`` (3×n) from a serial chain's geometric Jacobian, in closed
    form: :math:`\dot J_k = \omega_k \times J_k + a_k \times s_k` (module docstring).

    Parameters
    ----------
    Jw : numpy.ndarray
        The angular Jacobian ``J_ω`` (3, n): the joints' world axes ``a_k`` (0 for a prismatic
        joint).
    Jx : numpy.ndarray
        The controlled point's translational Jacobian ``J_x`` (3, n), m/rad.
    direction : numpy.ndarray
        The joint velocities along which to differentiate (n,), rad/s.

    Returns
    -------
    numpy.ndarray
        ``J̇_x`` (3, n), m/(rad·s).
    """
    d = np.asarray(direction, dtype=float)
    wd = Jw * d                                     # a_j d_j
    vd = Jx * d                                     # J_j d_j
    w = np.cumsum(wd, axis=1) - wd                  # ω_k = Σ_{j<k} a_j d_j
    sk = np.cumsum(vd[:, ::-1], axis=1)[:, ::-1]    # s_k = Σ_{j≥k} J_j d_j
    return _cross_columns(w, Jx) + _cross_columns(Jw, sk)


def _cross_columns(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Column-wise cross products of two 3×n arrays (``np.cross`` without its overhead)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def is_serial_chain(plant: MultibodyPlant, frame) -> bool:
    """Whether the joints moving ``frame`` form a chain of revolute and prismatic joints of
    one velocity each, numbered from the base outwards (what :func:`jacobian_dot` assumes);
    joints off the chain have zero Jacobian columns and do not matter.

    Parameters
    ----------
    plant : MultibodyPlant
        The arm's finalized plant.
    frame : Frame
        The controlled frame (the end effector's).

    Returns
    -------
    bool
        True on such a chain.
    """
    parent_joint = {}
    for j in plant.GetJointIndices():
        joint = plant.get_joint(j)
        parent_joint[joint.child_body().index()] = joint
    body = frame.body()
    starts = []
    while body.index() in parent_joint:
        joint = parent_joint[body.index()]
        if joint.num_velocities() == 1:
            if joint.type_name() not in ("revolute", "prismatic"):
                return False
            starts.append(joint.velocity_start())
        elif joint.num_velocities() != 0:
            return False
        body = joint.parent_body()
    starts.reverse()
    return all(a < b for a, b in zip(starts, starts[1:]))
