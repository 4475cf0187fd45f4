"""The control law of one robot ("finger") at one sample: (4), (8), (11), (13), (21), (22).

:class:`FingerLaw` evaluates the paper's equations from one sample of the signals; the Drake
systems of :mod:`drake_coop.control.observers` and :mod:`drake_coop.control.controller` are thin wrappers
around it, so that the three systems of a robot share one implementation of each equation.

Symbols (per robot, ``n = 3``, ``m = 1``):

``q``        measured joint positions (the only measurement);
``q_hat``    observer estimate ``q̂`` of (15); ``z = q − q̂`` the observation error;
``qdot_hat`` ``d/dt q̂``, the right-hand side of (15);
``qdot_o``   ``q̇_o = d/dt q̂ − Λ z`` of (8) (not the observer state ``q̇̂_o``);
``q_d, qdot_d, qddot_d``  joint references; ``lambda_d`` the desired force (29);
``Delta_F_tilde``  ``ΔF̃ = ∫ (λ̂ − λ_d)`` of (6); ``lambda_hat`` the estimate ``λ̂`` of (22);
``J_phi, J_pinv, Q``  constraint Jacobian, ``J⁺`` and the projector of Property 1;
``held``     whether the object is held: otherwise the free-motion form (``Q = I``, ``J⁺ = 0``,
             ``J_φ = 0``, ``λ̂ = 0``) of Section IV.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_coop.control import orthogonal
from drake_coop.control.arm_model import ArmModel
from drake_coop.scenario.schema import Gains

#: Rows of the reference vector fed to each robot's controller and observers (built by
#: :mod:`drake_coop.experiment.references`, read by :meth:`Reference.unpack`).
REFERENCE_ROWS = ("q_d", "qdot_d", "qddot_d", "lambda_d", "held")
REFERENCE_SIZE = 3 + 3 + 3 + 1 + 1


@dataclass
class Reference:
    """One sample of a robot's reference vector (see :mod:`drake_coop.experiment.references`)."""

    q_d: np.ndarray
    qdot_d: np.ndarray
    qddot_d: np.ndarray
    lambda_d: float
    held: bool

    @staticmethod
    def unpack(r: np.ndarray) -> "Reference":
        """From the 11-vector ``[q_d, q̇_d, q̈_d, λ_d, held]``."""
        return Reference(r[0:3], r[3:6], r[6:9], float(r[9]), bool(r[10] > 0.5))


@dataclass
class Constraint:
    """``J_φ``, ``J⁺``, ``Q`` and ``Δp = φ(q)`` at one posture (zeros/identity when free)."""

    J_phi: np.ndarray
    J_pinv: np.ndarray
    Q: np.ndarray
    Delta_p: float


class FingerLaw:
    """The paper's per-robot equations, evaluated on the controller's own arm model.

    Parameters
    ----------
    model : ArmModel
        The controller's model of the arm (H, C, D, g, φ, J_φ).
    gains : Gains
        ``Λ = k I``, ``K_R``, ``k_d``, ``k_F``, ``ξ``, ``ζ``, ``β``.
    """

    def __init__(self, model: ArmModel, gains: Gains):
        self.model = model
        self.n = model.n
        self.Lambda = float(gains.Lambda)
        self.K_R = np.diag(np.asarray(gains.K_R, dtype=float))
        self.k_d = float(gains.k_d)
        self.k_F = float(gains.k_F)
        self.xi = float(gains.xi)
        self.zeta = float(gains.zeta)
        self.beta = float(gains.beta)

    # ------------------------------------------------------------------ observer (15), (8)
    def observer_derivative(self, q: np.ndarray, q_hat: np.ndarray, qdot_hat_o: np.ndarray
                            ) -> tuple[np.ndarray, np.ndarray]:
        """``d/dt q̂`` of (15) and ``q̇_o`` of (8).

        ``d/dt q̂ = q̇̂_o + Λ z + k_d z`` and ``q̇_o = d/dt q̂ − Λ z = q̇̂_o + k_d z``.
        """
        z = q - q_hat
        qdot_hat = qdot_hat_o + (self.Lambda + self.k_d) * z
        qdot_o = qdot_hat_o + self.k_d * z
        return qdot_hat, qdot_o

    def observer_acceleration(self, q: np.ndarray, q_hat: np.ndarray,
                              qddot_r_hat: np.ndarray) -> np.ndarray:
        """``d/dt q̇̂_o = q̈̂_r + k_d Λ z`` of (16)."""
        return qddot_r_hat + self.k_d * self.Lambda * (q - q_hat)

    # ------------------------------------------------------------------ constraint
    def constraint(self, q: np.ndarray, held: bool, J_phi: np.ndarray | None = None
                   ) -> Constraint:
        """Projections of Property 1 at ``q`` (free-motion form when not held).

        ``J_phi`` may be passed when already computed at ``q``.
        """
        if not held:
            J_pinv, Q = orthogonal.free_motion_projections(self.n)
            return Constraint(np.zeros((1, self.n)), J_pinv, Q, 0.0)
        if J_phi is None:
            J_phi = self.model.J_phi(q)
        J_pinv, Q = orthogonal.projections(J_phi)
        return Constraint(J_phi, J_pinv, Q, self.model.phi(q))

    def reference_velocity(self, c: Constraint, q_hat: np.ndarray, ref: Reference,
                           Delta_F_tilde: float) -> np.ndarray:
        """``q̇_r`` of (4)."""
        return orthogonal.reference_velocity(
            c.Q, c.J_pinv, q_hat=q_hat, q_d=ref.q_d, qdot_d=ref.qdot_d, Lambda=self.Lambda,
            Delta_p=c.Delta_p, beta=self.beta, xi=self.xi, Delta_F_tilde=Delta_F_tilde)

    # ------------------------------------------------------------------ force observer (22)
    def force_estimate(self, q: np.ndarray, q_hat: np.ndarray, qdot_o: np.ndarray,
                       ref: Reference, Delta_F_tilde: float) -> float:
        """``λ̂`` of (22): ``[J⁺ᵀ K_R (q̇_o − q̇_r) − k_F ΔF̃]/(1 + ζ) + λ_d``; 0 when free."""
        if not ref.held:
            return 0.0
        c = self.constraint(q, True)
        qdot_r = self.reference_velocity(c, q_hat, ref, Delta_F_tilde)
        s = (c.J_pinv.T @ self.K_R @ (qdot_o - qdot_r))[0]
        return float((s - self.k_F * Delta_F_tilde) / (1.0 + self.zeta) + ref.lambda_d)

    def force_estimate_21(self, q: np.ndarray, qdot_r: np.ndarray, qddot_r_hat: np.ndarray,
                          tau: np.ndarray, held: bool) -> float:
        """``λ̂`` of (21): ``J⁺ᵀ {H q̈̂_r + C(q, q̇_r) q̇_r + D q̇_r + g − τ}`` (for checks)."""
        if not held:
            return 0.0
        c = self.constraint(q, True)
        rhs = self.model.inverse_dynamics_terms(q, qdot_r, qddot_r_hat) - tau
        return float((c.J_pinv.T @ rhs)[0])

    # ------------------------------------------------------------------ controller (13)
    def control(self, q: np.ndarray, q_hat: np.ndarray, qdot_hat: np.ndarray,
                qdot_o: np.ndarray, lambda_hat: float, Delta_F_tilde: float, ref: Reference
                ) -> dict[str, np.ndarray]:
        """Torque (13) and the intermediate signals of one sample.

        .. math::
            \\tau = H\\ddot{\\hat q}_r + C(q,\\dot q_r)\\dot q_r + D\\dot q_r + g
                    - K_R(\\dot q_o - \\dot q_r)
                    - J_\\varphi^T(\\lambda_d - k_F\\Delta\\tilde F - \\zeta\\Delta\\tilde\\lambda)

        Returns
        -------
        dict
            ``tau``, ``qdot_r`` (4), ``qddot_r_hat`` (11), ``Delta_lambda_tilde``.
        """
        if ref.held:
            J_phi, J_phi_dot = self.model.J_phi_and_derivative(q, qdot_o)
            J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, J_phi_dot)
            c = self.constraint(q, True, J_phi)
        else:
            J_pinv_dot, Q_dot = np.zeros((self.n, 1)), np.zeros((self.n, self.n))
            c = self.constraint(q, False)
        qdot_r = self.reference_velocity(c, q_hat, ref, Delta_F_tilde)
        Delta_lambda_tilde = (lambda_hat - ref.lambda_d) if ref.held else 0.0
        qddot_r_hat = orthogonal.reference_acceleration(
            c.Q, c.J_pinv, Q_dot, J_pinv_dot, q_hat=q_hat, qdot_hat=qdot_hat, q_d=ref.q_d,
            qdot_d=ref.qdot_d, qddot_d=ref.qddot_d, Lambda=self.Lambda, Delta_p=c.Delta_p,
            beta=self.beta, xi=self.xi, Delta_F_tilde=Delta_F_tilde,
            Delta_lambda_tilde=Delta_lambda_tilde)
        force = ref.lambda_d - self.k_F * Delta_F_tilde - self.zeta * Delta_lambda_tilde
        tau = (self.model.inverse_dynamics_terms(q, qdot_r, qddot_r_hat)
               - self.K_R @ (qdot_o - qdot_r)
               - c.J_phi.T[:, 0] * (force if ref.held else 0.0))
        return {"tau": tau, "qdot_r": qdot_r, "qddot_r_hat": qddot_r_hat,
                "Delta_lambda_tilde": np.array([Delta_lambda_tilde])}
