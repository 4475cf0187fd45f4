"""Numeric kinematics of one arm from its URDF: Drake's forward kinematics, Jacobians and IK.

The closed forms of :class:`drake_coop.kinematics.crs.CrsKinematics` exist for the paper's two 3-joint arms
only. :class:`DrakeArmKinematics` gives the same quantities for any serial arm, numerically,
from a single-arm :class:`~pydrake.multibody.plant.MultibodyPlant` (the URDF parsed, its
``base_frame`` welded to the world at ``X_WB``).

The task of the end effector E (origin of ``ee_frame``) is its position ``x(q)`` in the world
(``task_dim = 3``), or its position and orientation held at ``R_d`` (``task_dim = 6``). The
task Jacobian stacks E's translational velocity and, for ``task_dim = 6``, the angular velocity
of ``ee_frame``, both in the world frame::

    [ẋ; ω] = J(q) q̇,    [ẍ; ω̇] = J(q) q̈ + J̇(q, q̇) q̇.

A reference posture path ``q(t)`` for a Cartesian path ``x(t)`` with ``R(q(t)) = R_d`` solves
the task equations by Newton's method on the task error

    e(q) = [x − x(q);  vee(R_d R(q)ᵀ)],     q ← q + J(q)⁻¹ e(q),

with ``vee(R_d Rᵀ) = ½ [M₃₂ − M₂₃, M₁₃ − M₃₁, M₂₁ − M₁₂]`` of ``M = R_d Rᵀ`` (``= sin θ · axis``
of the rotation taking ``R`` to ``R_d``, zero exactly when ``R = R_d`` for ``θ < π``); then

    q̇ = J⁻¹ [ẋ; 0],     q̈ = J⁻¹ ([ẍ; 0] − J̇ q̇)                                       (∗)

with ``J̇ q̇`` Drake's bias acceleration of E. Assumption 1 of the paper (a non-redundant,
non-singular arm) is what makes (∗) well posed: ``n == task_dim`` and ``J`` invertible.

A **redundant** arm (``n > task_dim``, a Panda's 7 joints for a 6-D task) has no unique
posture per point: its reference (:meth:`DrakeArmKinematics.redundant_reference`) is a
differential inverse kinematics with a null-space posture objective, integrated in time
((R1) of :mod:`drake_coop.kinematics.redundant`, whose :class:`~drake_coop.kinematics.redundant.RedundantReference`
this class takes its redundant-arm methods from).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.solvers import Solve

from drake_coop.kinematics.redundant import (
    NEWTON_TOL,
    SINGULAR_RATIO,
    TASK_FEEDBACK,
    RedundantReference,
    _vee_of_skew_part,
)

__all__ = ["NEWTON_TOL", "SINGULAR_RATIO", "TASK_FEEDBACK", "DrakeArmKinematics"]

#: Restarts of Drake's IK from fixed pseudo-random postures before a point is unreachable.
_IK_RESTARTS = 8
#: Orientation tolerance of Drake's IK (rad); Newton then brings the error below NEWTON_TOL.
_IK_THETA_BOUND = 1e-6
_NEWTON_MAX_ITER = 20
#: Pseudo-random postures over which :meth:`DrakeArmKinematics.generic_rank` takes its maximum.
_RANK_POSTURES = 16


class DrakeArmKinematics(RedundantReference):
    """Forward and inverse kinematics of one arm, computed by Drake from its URDF.

    Parameters
    ----------
    urdf : Path
        The arm's model file.
    X_WB : RigidTransform
        Pose of ``base_frame`` in the world.
    base_frame : str
        Frame welded to the world.
    ee_frame : str
        Frame whose origin is the end-effector point E.
    R_d : RotationMatrix, optional
        Orientation of ``ee_frame`` held along paths; ``None`` for a position-only task.
    q_seed : ndarray, optional
        Initial guess of the first IK of :meth:`joint_reference` (default zeros).
    name : str
        The robot's name, first word of every error message.

    Raises
    ------
    ValueError
        ``base_frame`` or ``ee_frame`` not in the model, or a joint with ``q̇ ≠ v``.
    """

    def __init__(self, urdf: Path, X_WB: RigidTransform, base_frame: str = "base_link",
                 ee_frame: str = "pad", R_d: RotationMatrix | None = None,
                 q_seed: np.ndarray | None = None, name: str = "robot"):
        self.name = name
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(urdf))
        for frame in (base_frame, ee_frame):
            if not plant.HasFrameNamed(frame):
                raise ValueError(f"{name}: {urdf} has no frame {frame!r}")
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base_frame), X_WB)
        plant.Finalize()
        self.plant = plant
        self.context = plant.CreateDefaultContext()
        self.ee_frame = plant.GetFrameByName(ee_frame)
        self._world = plant.world_frame()
        #: Number of joints n (generalized positions).
        self.n = plant.num_positions()
        if plant.num_velocities() != self.n:
            raise ValueError(f"{name}: {urdf} has joints whose positions are not their velocities")
        self.q_min = np.asarray(plant.GetPositionLowerLimits(), dtype=float)
        self.q_max = np.asarray(plant.GetPositionUpperLimits(), dtype=float)
        self.joint_names = [""] * self.n
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            for k in range(joint.num_positions()):
                self.joint_names[joint.position_start() + k] = joint.name()
        self.R_d = R_d
        self._R_d = None if R_d is None else np.asarray(R_d.matrix())
        #: 3 (position of E) or 6 (position of E and orientation of ``ee_frame``).
        self.task_dim = 3 if R_d is None else 6
        self.q_seed = np.zeros(self.n) if q_seed is None else np.asarray(q_seed, dtype=float)
        self._generic_rank: int | None = None

    # ------------------------------------------------------------------ forward kinematics
    def _pose(self, q: np.ndarray) -> RigidTransform:
        self.plant.SetPositions(self.context, q)
        return self.ee_frame.CalcPoseInWorld(self.context)

    def _map(self, q: np.ndarray, f: Callable[[np.ndarray], np.ndarray],
             shape: tuple[int, ...]) -> np.ndarray:
        """``f`` of one posture (n,) or of each row of (K, n)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return f(q)
        out = np.empty((q.shape[0],) + shape)
        for k, qk in enumerate(q):
            out[k] = f(qk)
        return out

    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector point ``x(q)`` in the world: (3,) for q (n,), (K, 3) for q (K, n).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,) or (K, n), rad (m for a prismatic joint).

        Returns
        -------
        numpy.ndarray
            E in the world frame, m.
        """
        return self._map(q, lambda qk: self._pose(qk).translation(), (3,))

    def rotation(self, q: np.ndarray) -> np.ndarray:
        """The orientation ``R(q)`` of ``ee_frame`` in the world: (3, 3) or (K, 3, 3).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,) or (K, n).
        """
        return self._map(q, lambda qk: self._pose(qk).rotation().matrix(), (3, 3))

    def _jacobian_here(self) -> np.ndarray:
        """Task Jacobian at the context's posture: rows ``[v_E; ω]`` (Drake's are ``[ω; v]``)."""
        J = self.plant.CalcJacobianSpatialVelocity(
            self.context, JacobianWrtVariable.kV, self.ee_frame, np.zeros(3), self._world,
            self._world)
        return J[3:] if self.task_dim == 3 else np.vstack([J[3:], J[:3]])

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Task Jacobian ``J(q)`` (task_dim × n), or (K, task_dim, n) for q of shape (K, n).

        Rows 0–2: ``∂x/∂q`` (E's translational velocity per unit q̇); rows 3–5 when
        ``task_dim == 6``: the angular velocity of ``ee_frame`` per unit q̇; world frame.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,) or (K, n).

        Returns
        -------
        numpy.ndarray
            The Jacobian: m per unit q in rows 0–2, rad per unit q in rows 3–5.
        """
        def one(qk):
            self.plant.SetPositions(self.context, qk)
            return self._jacobian_here()
        return self._map(q, one, (self.task_dim, self.n))

    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``J̇(q, v) v`` (task_dim,): the task acceleration at ``q̈ = 0`` (Drake's bias
        acceleration of E, ``[translational; rotational]``, world frame).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,).
        v : numpy.ndarray
            Joint velocities (n,).

        Returns
        -------
        numpy.ndarray
            ``J̇ v``: m/s² (rows 0–2), rad/s² (rows 3–5).
        """
        self.plant.SetPositions(self.context, np.asarray(q, dtype=float))
        self.plant.SetVelocities(self.context, np.asarray(v, dtype=float))
        return self._bias_here()

    def _bias_here(self) -> np.ndarray:
        A = self.plant.CalcBiasSpatialAcceleration(
            self.context, JacobianWrtVariable.kV, self.ee_frame, np.zeros(3), self._world,
            self._world)
        if self.task_dim == 3:
            return np.asarray(A.translational())
        return np.concatenate([A.translational(), A.rotational()])

    def task_error(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """``e(q) = [p − x(q); vee(R_d R(q)ᵀ)]`` (task_dim,), the Newton residual.

        Parameters
        ----------
        p : numpy.ndarray
            The target point of E (3,), m, world frame.
        q : numpy.ndarray
            Joint positions (n,).

        Returns
        -------
        numpy.ndarray
            The residual: m (rows 0–2), rad (rows 3–5).
        """
        X = self._pose(np.asarray(q, dtype=float))
        e = np.asarray(p, dtype=float) - X.translation()
        if self.task_dim == 3:
            return e
        return np.concatenate([e, _vee_of_skew_part(self._R_d @ X.rotation().matrix().T)])

    # ------------------------------------------------------------------ inverse kinematics
    def _ik_program(self, p: np.ndarray, q_guess: np.ndarray, orientation: bool):
        """Drake's IK program: E at p, ``R_d`` (if ``orientation``), limits, ``|q − q_guess|²``."""
        ik = InverseKinematics(self.plant, with_joint_limits=True)
        ik.AddPositionConstraint(self.ee_frame, np.zeros(3), self._world, p, p)
        if orientation:
            ik.AddOrientationConstraint(self._world, self.R_d, self.ee_frame, RotationMatrix(),
                                        _IK_THETA_BOUND)
        prog = ik.get_mutable_prog()
        prog.AddQuadraticErrorCost(np.eye(self.n), q_guess, ik.q())
        prog.SetInitialGuess(ik.q(), q_guess)
        result = Solve(prog)
        return result, result.GetSolution(ik.q())

    def solve_ik(self, p: np.ndarray, q_guess: np.ndarray) -> np.ndarray:
        """A posture with E at ``p`` (and ``ee_frame`` at ``R_d``), within the joint limits.

        Drake's :class:`InverseKinematics` (E at ``p``; orientation ``R_d`` within
        ``_IK_THETA_BOUND`` rad when given; joint limits; cost ``|q − q_guess|²`` to stay on
        ``q_guess``'s branch), solved by :func:`pydrake.solvers.Solve` from ``q_guess``. A
        singular ``q_guess`` (such as ``q = 0``, straight up) can stall the solver: then the
        program is solved again from the position-only solution and from
        ``_IK_RESTARTS`` fixed pseudo-random postures within 80 % of the limits. The result
        is polished by :meth:`newton` to :data:`NEWTON_TOL` when that stays within the limits.

        Parameters
        ----------
        p : numpy.ndarray
            The target point of E (3,), m, world frame.
        q_guess : numpy.ndarray
            The start posture (n,), clipped to the limits; the solution stays on its branch.

        Raises
        ------
        ValueError
            ``"<name>: point [...] out of reach ..."`` when no start gives a solution.
        """
        p = np.asarray(p, dtype=float)
        q_guess = np.clip(np.asarray(q_guess, dtype=float), self.q_min, self.q_max)
        orientation = self.R_d is not None
        result, q = self._ik_program(p, q_guess, orientation)
        starts = []
        if not result.is_success() and orientation:
            position_only, q_position = self._ik_program(p, q_guess, False)
            if position_only.is_success():
                starts.append(q_position)
        if not result.is_success():
            rng = np.random.default_rng(0)
            starts += list(rng.uniform(0.8 * self.q_min, 0.8 * self.q_max,
                                       size=(_IK_RESTARTS, self.n)))
        for start in starts:
            if result.is_success():
                break
            result, q = self._ik_program(p, start, orientation)
        if not result.is_success():
            raise ValueError(f"{self.name}: point {np.round(p, 4).tolist()} out of reach "
                             f"(inverse kinematics within the joint limits: "
                             f"{result.get_solution_result().name})")
        try:
            polished = self.newton(p, q)
        except ValueError:
            return q
        inside = np.all((polished >= self.q_min) & (polished <= self.q_max))
        return polished if inside else q

    def newton(self, p: np.ndarray, q_guess: np.ndarray) -> np.ndarray:
        """Newton's method ``q ← q + J(q)⁺ e(q)`` from ``q_guess`` until ``|e| < NEWTON_TOL``.

        ``J⁺ e`` is the least-squares step (``J⁻¹ e`` for a square J). Joint limits are not
        enforced (see :meth:`check_path`).

        Parameters
        ----------
        p : numpy.ndarray
            The target point of E (3,), m, world frame.
        q_guess : numpy.ndarray
            The start posture (n,).

        Returns
        -------
        numpy.ndarray
            The posture (n,).

        Raises
        ------
        ValueError
            When the error is not below the tolerance after 20 iterations.
        """
        q = np.array(q_guess, dtype=float)
        for _ in range(_NEWTON_MAX_ITER):
            e = self.task_error(p, q)        # leaves the context at q
            if np.linalg.norm(e) < NEWTON_TOL:
                return q
            J = self._jacobian_here()
            if J.shape[0] == J.shape[1]:
                step = np.linalg.solve(J, e)
            else:
                step = np.linalg.lstsq(J, e, rcond=None)[0]
            q += step
        raise ValueError(f"{self.name}: Newton's method did not reach point "
                         f"{np.round(p, 4).tolist()}")

    # ------------------------------------------------------------------ reference postures
    def generic_rank(self) -> int:
        """The rank of the task Jacobian at a generic posture.

        The largest rank of ``J(q)`` over :data:`_RANK_POSTURES` fixed pseudo-random postures
        within the joint limits (relative tolerance :data:`SINGULAR_RATIO`). An arm whose
        joints move E in fewer than ``task_dim`` directions everywhere — a planar arm, say —
        has ``generic_rank() < task_dim`` even with ``n == task_dim``: no posture reaches a
        point off its plane, and its Jacobian is singular everywhere.

        Returns
        -------
        int
            The generic rank, at most ``task_dim``.
        """
        if self._generic_rank is None:
            rng = np.random.default_rng(1)
            low = np.where(np.isfinite(self.q_min), self.q_min, -np.pi)
            high = np.where(np.isfinite(self.q_max), self.q_max, np.pi)
            q = rng.uniform(0.8 * low + 0.2 * high, 0.2 * low + 0.8 * high,
                            size=(_RANK_POSTURES, self.n))
            sigma = np.linalg.svd(self.jacobian(q), compute_uv=False)
            self._generic_rank = int((sigma > SINGULAR_RATIO * sigma[:, :1]).sum(axis=1).max())
        return self._generic_rank

    def _require_square(self) -> None:
        if self.n != self.task_dim:
            kind = "redundant" if self.n > self.task_dim else "deficient"
            raise ValueError(
                f"{self.name}: {self.n} joints for a {self.task_dim}-dimensional task: the arm is "
                f"{kind} (Assumption 1 needs as many joints as task coordinates)")
        rank = self.generic_rank()
        if rank < self.task_dim:
            what = "position" if self.task_dim == 3 else "position and orientation"
            raise ValueError(
                f"{self.name}: its {self.n} joints move the end effector in only {rank} of the "
                f"{self.task_dim} directions of its {what} task at every posture (a planar arm, "
                f"or joints with parallel axes): Assumption 1 needs a task Jacobian of full "
                f"rank, so no reference can be followed off that subspace")

    def joint_positions(self, x: np.ndarray) -> np.ndarray:
        """Postures along a Cartesian path x (K, 3): IK at ``x[0]`` from ``q_seed``, then Newton
        from the linear extrapolation of the two previous postures (IK as a fallback).

        Parameters
        ----------
        x : numpy.ndarray
            The path of E (K, 3), m, world frame.

        Returns
        -------
        numpy.ndarray
            The postures (K, n).

        Raises
        ------
        ValueError
            ``"<name>: point ... out of reach ..."`` with the sample's index.
        """
        x = np.atleast_2d(np.asarray(x, dtype=float))
        q = np.empty((x.shape[0], self.n))
        for k, xk in enumerate(x):
            guess = (self.q_seed if k == 0 else q[k - 1] if k == 1
                     else 2.0 * q[k - 1] - q[k - 2])
            try:
                q[k] = self.solve_ik(xk, guess) if k == 0 else self.newton(xk, guess)
            except ValueError as error:
                if k == 0:
                    raise ValueError(f"{error} at sample 0") from None
                try:
                    q[k] = self.solve_ik(xk, q[k - 1])
                except ValueError as error:
                    raise ValueError(f"{error} at sample {k}") from None
        return q

    def joint_reference(self, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint positions, velocities and accelerations along a Cartesian path.

        Parameters
        ----------
        x, xd, xdd : ndarray, shape (K, 3)
            Position, velocity and acceleration of E at increasing times; the orientation is
            held at ``R_d`` (zero angular velocity and acceleration) when ``task_dim == 6``.

        Returns
        -------
        q, qd, qdd : ndarray, shape (K, n)
            ``q`` from :meth:`joint_positions` (``x(q) = x`` and ``R(q) = R_d`` to 1e-12),
            ``qd = J⁻¹ [ẋ; 0]``, ``qdd = J⁻¹ ([ẍ; 0] − J̇ q̇)``.

        Raises
        ------
        ValueError
            A redundant or deficient arm (``n != task_dim``), or a point out of reach.
        """
        self._require_square()
        xd = np.atleast_2d(np.asarray(xd, dtype=float))
        xdd = np.atleast_2d(np.asarray(xdd, dtype=float))
        q = self.joint_positions(x)
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        pad = np.zeros(self.task_dim - 3)
        for k in range(q.shape[0]):
            self.plant.SetPositions(self.context, q[k])
            J = self._jacobian_here()
            qd[k] = np.linalg.solve(J, np.concatenate([xd[k], pad]))
            self.plant.SetVelocities(self.context, qd[k])
            qdd[k] = np.linalg.solve(J, np.concatenate([xdd[k], pad]) - self._bias_here())
        return q, qd, qdd

    # ------------------------------------------------------------------ validation
    def check_path(self, x: np.ndarray, t: np.ndarray | None = None) -> str:
        """``''`` if the arm can follow the Cartesian path x (K, 3), else one line saying why.

        In this order: a redundant or deficient arm (Assumption 1: ``n == task_dim``); a point
        out of reach (IK fails); a joint outside its limits (the first one: joint name, value,
        limits, sample index); a singular posture (``σ_min(J)/σ_max(J) <`` :data:`SINGULAR_RATIO`,
        the first sample). With the samples' times ``t``, the message gives the time instead of
        the index.

        Parameters
        ----------
        x : numpy.ndarray
            The path of E (K, 3), m, world frame.
        t : numpy.ndarray or None
            The samples' times (K,), s, for the message; None names the sample index.

        Returns
        -------
        str
            ``''`` or the reason.
        """
        if t is not None:
            message = self.check_path(x)
            return re.sub(r"at sample (\d+)", lambda m: f"at t = {t[int(m.group(1))]:.2f} s",
                          message)
        try:
            self._require_square()
            q = self.joint_positions(x)
        except ValueError as error:
            return str(error)
        outside = (q < self.q_min) | (q > self.q_max)
        if outside.any():
            k, j = np.argwhere(outside)[0]
            return (f"{self.name}: joint {self.joint_names[j]} at {q[k, j]:.4f} rad outside its "
                    f"limits [{self.q_min[j]:.4f}, {self.q_max[j]:.4f}] at sample {k}")
        sigma = np.linalg.svd(self.jacobian(q), compute_uv=False)
        ratio = sigma[:, -1] / sigma[:, 0]
        if (ratio < SINGULAR_RATIO).any():
            k = int(np.argmax(ratio < SINGULAR_RATIO))
            return (f"{self.name}: singular posture at sample {k} (smallest/largest singular "
                    f"value of the task Jacobian {ratio[k]:.2e} < {SINGULAR_RATIO:g})")
        return ""
