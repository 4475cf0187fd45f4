"""What an arm's reference can do with its pad, and the pad's material point on any arm.

A pad held on a box by friction carries the box by its *material* contact point ``P``: the
point fixed in the pad body at its radius ``ρ`` from the centre ``E`` along the inward normal
``n`` at the grasp, ``P = E + R(q) o`` with ``o = ρ R(q_g)ᵀ n`` (``R`` the pad frame's
orientation, ``q_g`` the posture of the grasp). When the pad turns by ``Δα`` it rolls on the
face, and the box, stuck to ``P``, moves ``ρ Δα`` against the centre. Which remedy an arm's
reference can apply depends on what it controls (:func:`pad_control`, the one rule behind
``object_model.control_point: auto``):

``pose``
    A 6-D task (position and orientation ``R_d`` of the pad, ``task_dim == 6``: six or more
    joints, Drake's kinematics, square or redundant): the reference holds ``R(q) = R_d``, so
    ``R(q) o = ρ n`` is constant and ``P`` moves exactly as ``E``; the pad does not roll in
    the reference, and following ``E``'s path is following ``P``'s (across the normal:
    ``T P = T E``, ``T = I − n nᵀ``).
``contact``
    A 3-D task with as many joints (``n == task_dim == 3``: the paper's arms' closed form, or
    any 3-joint arm through Drake's kinematics): the orientation follows from the position and
    the pad rolls; the reference follows ``P`` across the normal instead of ``E``
    (:func:`drake_coop.experiment.references.contact_point_reference`, on
    :func:`point_kinematics`).
``centre``
    A 3-D task on a redundant arm (more than three joints and no orientation given): neither
    the orientation nor a unique posture per point is fixed; the reference follows ``E``.

:class:`DrakePadPoint` is a pad-body point's kinematics through Drake (forward kinematics,
translational Jacobian and its derivative, the pad's angular velocity and orientation), with
the interface of :class:`~drake_coop.kinematics.crs.CrsKinematics` that the contact-point
reference uses; :func:`point_kinematics` gives either.
"""

from __future__ import annotations

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.multibody.tree import JacobianWrtVariable

__all__ = ["PAD_CONTROLS", "DrakePadPoint", "pad_control", "point_kinematics"]

#: What an arm's reference can do with its pad (:func:`pad_control`).
PAD_CONTROLS = ("pose", "contact", "centre")

_NEWTON_TOL = 1e-13
_NEWTON_MAX_ITER = 30


def pad_control(kinematics) -> str:
    """What the arm with these kinematics can hold of its pad: ``pose``, ``contact`` or
    ``centre`` (see the module).

    ``pose`` when its task holds the pad's orientation (``task_dim == 6``, which needs six
    or more joints); ``contact`` when it controls three coordinates with three joints (the
    pad's orientation then follows from its position, and the reference follows the pad's
    material point instead of its centre); ``centre`` otherwise (a redundant arm with a
    position-only task: give it ``ee_rpy_deg`` to hold the orientation).

    Parameters
    ----------
    kinematics : CrsKinematics or DrakeArmKinematics
        The arm's kinematics (its ``n`` and ``task_dim``).

    Returns
    -------
    str
        ``"pose"``, ``"contact"`` or ``"centre"``.
    """
    task_dim = int(getattr(kinematics, "task_dim", 3))
    n = int(kinematics.n)
    if task_dim == 6 and n >= 6:
        return "pose"
    if task_dim == 3 and n == 3:
        return "contact"
    return "centre"


def point_kinematics(kinematics, offset=None):
    """The kinematics of the pad-body point ``offset`` (pad frame, m; None: the centre):
    ``kinematics.with_offset`` for the closed form, :class:`DrakePadPoint` for Drake's.

    Parameters
    ----------
    kinematics : CrsKinematics or DrakeArmKinematics
        The arm's kinematics of its pad centre.
    offset : array_like or None
        The point in the pad body's frame (3,), m; None for the centre.

    Returns
    -------
    CrsKinematics or DrakePadPoint
        The kinematics of that point.
    """
    if hasattr(kinematics, "with_offset"):
        return kinematics if offset is None else kinematics.with_offset(offset)
    return DrakePadPoint(kinematics, offset)


class DrakePadPoint:
    """A point fixed in the pad body, through Drake's kinematics of the arm.

    Parameters
    ----------
    kinematics : DrakeArmKinematics
        The arm (its plant, ``ee_frame`` the pad's frame, ``n`` joints).
    offset : array_like, shape (3,), optional
        The point in ``ee_frame`` (m); default its origin, the pad's centre E.

    Raises
    ------
    ValueError
        ``offset`` not three finite numbers.
    """

    def __init__(self, kinematics, offset=None):
        o = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
        if o.shape != (3,) or not np.all(np.isfinite(o)):
            raise ValueError(f"offset: 3 finite numbers are required (m, pad frame), got "
                             f"{np.shape(offset)}")
        self.kinematics = kinematics
        self.offset = o
        self.n = kinematics.n
        self.name = kinematics.name
        self.q_min, self.q_max = kinematics.q_min, kinematics.q_max
        plant = kinematics.plant
        self._plant, self._context = plant, kinematics.context
        self._frame = kinematics.ee_frame
        self._plant_ad = plant.ToAutoDiffXd()
        self._context_ad = self._plant_ad.CreateDefaultContext()
        self._frame_ad = self._plant_ad.GetFrameByName(self._frame.name(),
                                                       self._frame.model_instance())

    def with_offset(self, offset) -> "DrakePadPoint":
        """The same arm's pad-body point ``offset``.

        Parameters
        ----------
        offset : array_like
            The point in the pad body's frame (3,), m.

        Returns
        -------
        DrakePadPoint
            The kinematics of that point.
        """
        return DrakePadPoint(self.kinematics, offset)

    def _each(self, q, f, shape, *more):
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return f(q, *[np.asarray(m, dtype=float) for m in more])
        out = np.empty(q.shape[:-1] + shape)
        flat = q.reshape(-1, self.n)
        rest = [np.asarray(m, dtype=float).reshape(-1, self.n) for m in more]
        view = out.reshape((-1,) + shape)
        for k in range(flat.shape[0]):
            view[k] = f(flat[k], *[r[k] for r in rest])
        return out

    def _pose(self, q):
        self._plant.SetPositions(self._context, q)
        return self._frame.CalcPoseInWorld(self._context)

    def fk(self, q: np.ndarray) -> np.ndarray:
        """The point in the world, ``E(q) + R(q) o``: (3,) or (..., 3).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,) or (..., n).

        Returns
        -------
        numpy.ndarray
            The point in the world, m.
        """
        return self._each(q, lambda qk: self._pose(qk) @ self.offset, (3,))

    def pad_rotation(self, q: np.ndarray) -> np.ndarray:
        """The pad frame's orientation ``R(q)`` (one posture, 3×3).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,).
        """
        return self._pose(np.asarray(q, dtype=float)).rotation().matrix()

    def _jacobian_ad(self, q, v):
        q_ad = InitializeAutoDiff(q, v.reshape(-1, 1))
        self._plant_ad.SetPositions(self._context_ad, q_ad.reshape(-1))
        world = self._plant_ad.world_frame()
        J = self._plant_ad.CalcJacobianSpatialVelocity(
            self._context_ad, JacobianWrtVariable.kV, self._frame_ad, self.offset, world, world)
        value = ExtractValue(J).reshape(6, self.n)
        grad = ExtractGradient(J.reshape(-1, 1))
        grad = grad.reshape(6, self.n) if grad.size == 6 * self.n else np.zeros((6, self.n))
        return value, grad

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """``∂P/∂q`` (3 × n, or (..., 3, n)): the point's translational velocity per unit q̇.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,) or (..., n).

        Returns
        -------
        numpy.ndarray
            ``∂P/∂q``, m per unit q.
        """
        def one(qk):
            self._plant.SetPositions(self._context, qk)
            J = self._plant.CalcJacobianTranslationalVelocity(
                self._context, JacobianWrtVariable.kV, self._frame, self.offset,
                self._plant.world_frame(), self._plant.world_frame())
            return np.asarray(J)
        return self._each(q, one, (3, self.n))

    def jacobian_dot(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``J̇ = Σ_k ∂J/∂q_k v_k`` of :meth:`jacobian` (forward-mode AutoDiff).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,) or (..., n).
        v : numpy.ndarray
            Joint velocities, same shape, per s.

        Returns
        -------
        numpy.ndarray
            J̇, m per unit q per s.
        """
        return self._each(q, lambda qk, vk: self._jacobian_ad(qk, vk)[1][3:], (3, self.n), v)

    def angular_velocity(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The pad's angular velocity in the world, ``J_ω(q) v``: (3,) or (..., 3).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,) or (..., n).
        v : numpy.ndarray
            Joint velocities, same shape.

        Returns
        -------
        numpy.ndarray
            The angular velocity, rad/s, world frame.
        """
        def one(qk, vk):
            self._plant.SetPositions(self._context, qk)
            J = self._plant.CalcJacobianSpatialVelocity(
                self._context, JacobianWrtVariable.kV, self._frame, np.zeros(3),
                self._plant.world_frame(), self._plant.world_frame())
            return np.asarray(J)[:3] @ vk
        return self._each(q, one, (3,), v)

    def ik(self, p: np.ndarray) -> np.ndarray:
        """Postures putting the point at ``p`` ((3,) or (K, 3)): the arm's own inverse
        kinematics of its centre at ``p`` (a start on the arm's branch), then Newton's
        method on ``P(q) − p`` (square arms, ``n == 3``).

        Parameters
        ----------
        p : numpy.ndarray
            The target points (3,) or (K, 3), m, world frame.

        Returns
        -------
        numpy.ndarray
            The postures, (n,) or (K, n), rad.

        Raises
        ------
        ValueError
            Newton's method does not reach 1e-13 m, or the arm has ``n != 3``.
        """
        if self.n != 3:
            raise ValueError(f"{self.name}: the material point's inverse kinematics needs "
                             f"three joints, the arm has {self.n}")
        p = np.asarray(p, dtype=float)
        points = np.atleast_2d(p)
        q = np.array(self.kinematics.joint_positions(points))
        for k, pk in enumerate(points):
            for _ in range(_NEWTON_MAX_ITER):
                residual = self.fk(q[k]) - pk
                if np.abs(residual).max() < _NEWTON_TOL:
                    break
                q[k] -= np.linalg.solve(self.jacobian(q[k]), residual)
            else:
                raise ValueError(f"{self.name}: the pad point's inverse kinematics did not "
                                 f"converge at {np.round(pk, 4).tolist()}")
        return q if p.ndim > 1 else q[0]
