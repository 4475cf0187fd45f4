"""The reference of a redundant arm: (R1), a differential inverse kinematics with a null-space
posture objective, and the task tolerances the square arm's Newton steps share.

A **redundant** arm (``n > task_dim``, a Panda's 7 joints for a 6-D task) has no unique
posture per point. Its reference
(:meth:`~drake_coop.kinematics.drake_arm.DrakeArmKinematics.redundant_reference`) is a
differential inverse kinematics with a null-space posture objective, integrated in time::

    q̇_d = f(t, q_d) = z + J⁺ (u − J z),     z = K_n (q_nom − q_d),
    u = [ẋ_d; 0] + K_e e(t, q_d),          J⁺ = Jᵀ (J Jᵀ)⁻¹                              (R1)

(``e`` the task error ``[x − x(q); vee(R_d R(q)ᵀ)]`` of :mod:`drake_coop.kinematics.drake_arm`, ``K_e`` = :data:`TASK_FEEDBACK` 1/s removing the integration's
drift, ``K_n`` the posture gain, ``q_nom`` the nominal posture), so that ``J q̇_d = u``: the
task moves exactly as ``x_d`` (``e`` stays at round-off) while the null-space part
``(I − J⁺J) z`` pulls the posture towards ``q_nom``. ``q_d`` is (R1) integrated by the
classical Runge–Kutta method on the sample grid, each step followed by minimum-norm Newton
steps ``q ← q + J⁺ e`` back onto the task (so ``x(q_d) = x_d`` to :data:`NEWTON_TOL`, as for a
square arm; the correction is the size of the step's integration error, ~1e-8 rad at 9 ms),
from ``q_d(t_0)``, the posture of the first
point nearest ``q_nom`` (Drake's IK, then projected Newton steps, so that ``q̇_d(t_0) = 0`` at a
path that starts at rest). ``q̈_d`` is the exact time derivative of (R1) along the solution::

    q̈_d = ż + J̇⁺ (u − J z) + J⁺ (u̇ − J̇ z − J ż),      ż = −K_n q̇_d,
    J̇⁺ = J̇ᵀ A⁻¹ − Jᵀ A⁻¹ (J̇ Jᵀ + J J̇ᵀ) A⁻¹,  A = J Jᵀ,
    u̇ = [ẍ_d; 0] + K_e ė,  ė = [ẋ_d − J_v q̇_d;  −½ vee(M ω̂ + ω̂ Mᵀ)],  M = R_d Rᵀ, ω = J_ω q̇_d

(``J̇`` the derivative of ``J`` along ``q̇_d``, by forward-mode AutoDiff). It is continuous
wherever ``ẍ_d`` is. With ``ẋ_d = 0`` the posture error ``V = ½|q_nom − q_d|²`` never grows
(``V̇ = −K_n (q_nom − q_d)ᵀ (I − J⁺J) (q_nom − q_d) ≤ 0``): the null-space motion is bounded. Joint limits are not
part of (R1): the whole path is checked (:meth:`check_redundant_path`) and refused when it
leaves them (choose ``q_nom`` or ``K_n``).

Drake's ``DifferentialInverseKinematics`` solves a QP per step (velocity and position limits
as constraints): its ``q̇`` switches with the active set and it gives no ``q̈``, so the
reference would not be consistent (``q̈_d`` the derivative of ``q̇_d``); (R1) is its
unconstrained, smooth form.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.multibody.tree import JacobianWrtVariable

__all__ = ["NEWTON_TOL", "SINGULAR_RATIO", "TASK_FEEDBACK", "RedundantReference"]

#: ``K_e`` of the redundant reference (R1), 1/s: the task error's decay rate.
TASK_FEEDBACK = 20.0

#: Smallest-over-largest singular value of J below which a posture is called singular.
SINGULAR_RATIO = 1e-3
#: Newton's iterations stop when the task error's norm is below this (m, rad).
NEWTON_TOL = 1e-12


def _vee_of_skew_part(M: np.ndarray) -> np.ndarray:
    """``½ vee(M − Mᵀ)``: ``sin θ · axis`` for a rotation matrix M of angle θ about axis."""
    return 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])


class RedundantReference:
    """The redundant-arm methods of :class:`~drake_coop.kinematics.drake_arm.DrakeArmKinematics`
    ((R1) of the module's docstring): a base class only, on that class's task Jacobian,
    task error, inverse kinematics and joint limits."""

    @property
    def redundant(self) -> bool:
        """Whether the arm has more joints than task coordinates (``n > task_dim``)."""
        return self.n > self.task_dim

    def nominal_posture(self, q_nominal: np.ndarray | None = None) -> np.ndarray:
        """``q_nom``: the given posture, else the middle of the joint limits (0 where a joint has
        none).

        Parameters
        ----------
        q_nominal : numpy.ndarray or None
            The posture (n,), rad, or None for the middle of the limits.
        """
        if q_nominal is not None:
            return np.asarray(q_nominal, dtype=float)
        mid = 0.5 * (self.q_min + self.q_max)
        return np.where(np.isfinite(mid), mid, 0.0)

    def _jacobian_and_derivative(self, q: np.ndarray, v: np.ndarray
                                 ) -> tuple[np.ndarray, np.ndarray]:
        """``J(q)`` and ``J̇ = Σ_k ∂J/∂q_k v_k`` (forward-mode AutoDiff, one component)."""
        if not hasattr(self, "_plant_ad"):
            self._plant_ad = self.plant.ToAutoDiffXd()
            self._context_ad = self._plant_ad.CreateDefaultContext()
            self._ee_ad = self._plant_ad.GetFrameByName(self.ee_frame.name(),
                                                        self.ee_frame.model_instance())
        q_ad = InitializeAutoDiff(np.asarray(q, float), np.asarray(v, float).reshape(-1, 1))
        self._plant_ad.SetPositions(self._context_ad, q_ad.reshape(-1))
        world = self._plant_ad.world_frame()
        J = self._plant_ad.CalcJacobianSpatialVelocity(
            self._context_ad, JacobianWrtVariable.kV, self._ee_ad, np.zeros(3), world, world)
        value = ExtractValue(J).reshape(6, self.n)
        grad = ExtractGradient(J.reshape(-1, 1))
        grad = grad.reshape(6, self.n) if grad.size == 6 * self.n else np.zeros((6, self.n))
        order = [3, 4, 5] if self.task_dim == 3 else [3, 4, 5, 0, 1, 2]
        return value[order], grad[order]

    def _rates(self, t_x: tuple, q: np.ndarray, q_nom: np.ndarray, K_n: float,
               with_acceleration: bool = False):
        """``q̇_d = f(t, q)`` of (R1), and with ``with_acceleration`` its derivative ``q̈_d``."""
        x, xd, xdd = t_x
        X = self._pose(q)
        J = self._jacobian_here()
        e = np.asarray(x, dtype=float) - X.translation()
        v_d = np.zeros(self.task_dim)
        v_d[:3] = xd
        if self.task_dim == 6:
            M = self._R_d @ X.rotation().matrix().T
            e = np.concatenate([e, _vee_of_skew_part(M)])
        z = K_n * (q_nom - q)
        u = v_d + TASK_FEEDBACK * e
        A_inv = np.linalg.inv(J @ J.T)
        J_pinv = J.T @ A_inv
        w = u - J @ z
        qd = z + J_pinv @ w
        if not with_acceleration:
            return qd
        _, Jdot = self._jacobian_and_derivative(q, qd)
        zd = -K_n * qd
        e_dot = np.empty(self.task_dim)
        e_dot[:3] = xd - J[:3] @ qd
        if self.task_dim == 6:
            om = J[3:] @ qd
            w_hat = np.array([[0.0, -om[2], om[1]], [om[2], 0.0, -om[0]],
                              [-om[1], om[0], 0.0]])
            e_dot[3:] = -_vee_of_skew_part(M @ w_hat + w_hat @ M.T)
        a_d = np.zeros(self.task_dim)
        a_d[:3] = xdd
        u_dot = a_d + TASK_FEEDBACK * e_dot
        J_pinv_dot = Jdot.T @ A_inv - J_pinv @ (Jdot @ J.T + J @ Jdot.T) @ A_inv
        qdd = zd + J_pinv_dot @ w + J_pinv @ (u_dot - Jdot @ z - J @ zd)
        return qd, qdd

    def start_posture(self, x0: np.ndarray, q_nom: np.ndarray) -> np.ndarray:
        """The posture with E at ``x0`` (and ``R_d``) nearest ``q_nom``: Drake's IK (cost
        ``|q − q_nom|²``), then projected Newton steps ``q ← q + J⁺ e + (I − J⁺J)(q_nom − q)``
        until both parts are below 1e-12 (at most 200 steps).

        Parameters
        ----------
        x0 : numpy.ndarray
            The control point's start position (3,), m, palm frame.
        q_nom : numpy.ndarray
            The nominal posture (n,), rad.

        Returns
        -------
        numpy.ndarray
            The start posture (n,), rad.
        """
        q = self.solve_ik(x0, q_nom)
        for _ in range(200):
            e = self.task_error(x0, q)
            J = self._jacobian_here()
            J_pinv = J.T @ np.linalg.inv(J @ J.T)
            task = J_pinv @ e
            null = (q_nom - q) - J_pinv @ (J @ (q_nom - q))
            q = q + task + null
            if np.linalg.norm(task) + np.linalg.norm(null) < 1e-12:
                break
        return q

    def redundant_reference(self, t: np.ndarray, path: Callable, q_nominal=None,
                            nullspace_gain: float = 1.0, q_start=None
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint reference of a redundant arm along a Cartesian path: (R1) of the module's
        docstring, integrated by RK4 on the grid ``t`` (one step per interval).

        Parameters
        ----------
        t : ndarray, shape (K,)
            Increasing sample times.
        path : callable
            ``path(times) -> (x, ẋ, ẍ)``, each (len(times), 3): the Cartesian path of E
            (orientation held at ``R_d`` when ``task_dim == 6``).
        q_nominal : array_like, optional
            ``q_nom`` (default :meth:`nominal_posture`).
        nullspace_gain : float
            ``K_n`` (1/s, >= 0).
        q_start : array_like, optional
            ``q_d(t_0)``, a posture with E at ``x(t_0)`` (put onto the task by Newton steps);
            default :meth:`start_posture` (the one nearest ``q_nom``).

        Returns
        -------
        q, qd, qdd : ndarray, shape (K, n)
            The joint reference: rad, rad/s, rad/s².

        Raises
        ------
        ValueError
            A deficient arm, or the first point out of reach.
        """
        if self.n < self.task_dim:
            self._require_square()
        t = np.asarray(t, dtype=float)
        q_nom = self.nominal_posture(q_nominal)
        K_n = float(nullspace_gain)
        mid = 0.5 * (t[:-1] + t[1:])
        x, xd, xdd = path(np.concatenate([t, mid]))
        K = t.size
        at = lambda i: (x[i], xd[i], xdd[i])      # noqa: E731 (sample i of the grid or mid)
        q = np.empty((K, self.n))
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        q[0] = (self.start_posture(x[0], q_nom) if q_start is None
                else self._onto_task(x[0], np.asarray(q_start, dtype=float)))
        for k in range(K):
            qd[k], qdd[k] = self._rates(at(k), q[k], q_nom, K_n, with_acceleration=True)
            if k + 1 == K:
                break
            dt = t[k + 1] - t[k]
            k1 = qd[k]
            k2 = self._rates(at(K + k), q[k] + 0.5 * dt * k1, q_nom, K_n)
            k3 = self._rates(at(K + k), q[k] + 0.5 * dt * k2, q_nom, K_n)
            k4 = self._rates(at(k + 1), q[k] + dt * k3, q_nom, K_n)
            q[k + 1] = self._onto_task(x[k + 1], q[k] + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4))
        return q, qd, qdd

    def _onto_task(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Minimum-norm Newton steps ``q ← q + J⁺ e(q)`` until ``|e| <`` :data:`NEWTON_TOL` (at
        most 5): the integrated posture put back on the task (a correction of the size of the
        integration step's error)."""
        for _ in range(5):
            e = self.task_error(p, q)
            if np.linalg.norm(e) < NEWTON_TOL:
                break
            J = self._jacobian_here()
            q = q + J.T @ np.linalg.solve(J @ J.T, e)
        return q

    def check_redundant_path(self, t: np.ndarray, path: Callable, q_nominal=None,
                             nullspace_gain: float = 1.0) -> str:
        """``''`` if the redundant reference along ``path`` stays within the joint limits and
        away from singular postures at every time of ``t``, else one line saying why (the
        joint, its value and limits, the time).

        Parameters
        ----------
        t : numpy.ndarray
            The times (K,) to check, s.
        path : Callable
            ``path(t) -> (x, ẋ, ẍ)``, the control point's Cartesian path (m, m/s, m/s²).
        q_nominal : numpy.ndarray or None
            The nominal posture (n,), rad; None for the middle of the joint limits.
        nullspace_gain : float
            The null-space gain pulling the posture towards ``q_nom``, 1/s.

        Returns
        -------
        str
            ``''`` or the reason.
        """
        try:
            q, _, _ = self.redundant_reference(t, path, q_nominal, nullspace_gain)
        except (ValueError, np.linalg.LinAlgError) as error:
            return str(error)
        outside = (q < self.q_min) | (q > self.q_max)
        if outside.any():
            k, j = np.argwhere(outside)[0]
            return (f"{self.name}: joint {self.joint_names[j]} at {q[k, j]:.4f} rad outside its "
                    f"limits [{self.q_min[j]:.4f}, {self.q_max[j]:.4f}] at t = {t[k]:.2f} s "
                    "along the redundant reference (choose q_nominal or nullspace_gain)")
        sigma = np.linalg.svd(self.jacobian(q), compute_uv=False)
        ratio = sigma[:, -1] / sigma[:, 0]
        if (ratio < SINGULAR_RATIO).any():
            k = int(np.argmax(ratio < SINGULAR_RATIO))
            return (f"{self.name}: singular posture at t = {t[k]:.2f} s (smallest/largest "
                    f"singular value of the task Jacobian {ratio[k]:.2e} < {SINGULAR_RATIO:g})")
        return ""
