"""The control law of one robot ("finger") at one sample: (4), (8), (11), (13), (21), (22).

:class:`FingerLaw` evaluates the paper's equations from one sample of the signals; the Drake
systems of :mod:`drake_coop.control.observers` and :mod:`drake_coop.control.controller` are thin wrappers
around it, so that the three systems of a robot share one implementation of each equation.

Symbols (per robot, ``n`` joints, ``m`` constraints; the paper's experiment ``n = 3``,
``m = 1``):

* ``q``: measured joint positions (the only measurement);
* ``q_hat``: observer estimate ``q̂`` of (15); ``z = q − q̂`` the observation error;
* ``qdot_hat``: ``d/dt q̂``, the right-hand side of (15);
* ``qdot_o``: ``q̇_o = d/dt q̂ − Λ z`` of (8) (not the observer state ``q̇̂_o``);
* ``q_d, qdot_d, qddot_d``: joint references; ``lambda_d`` the desired force (29) (m-vector);
* ``Delta_F_tilde``: ``ΔF̃ = ∫ (λ̂ − λ_d)`` of (6); ``lambda_hat`` the estimate ``λ̂`` of (22);
* ``J_phi, J_pinv, Q``: constraint Jacobian (m×n), ``J⁺`` (n×m) and the projector of
  Property 1;
* ``held``: whether the object is held: otherwise the free-motion form (``Q = I``, ``J⁺ = 0``,
  ``J_φ = 0``, ``λ̂ = 0``) of Section IV.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_coop.control import orthogonal
from drake_coop.control.arm_model import ArmModel
from drake_coop.control.params import Gains, check_gains
from drake_coop.control.deprecation import moved
from drake_coop.control.reference_layout import Reference, ReferenceLayout

#: Names this module no longer holds (found here until the removal date of
#: :mod:`drake_coop.control.deprecation`).
_MOVED = {"REFERENCE_ROWS": "drake_coop.control.reference_layout"}


def observer_qdot_hat(q: np.ndarray, q_hat: np.ndarray, qdot_hat_o: np.ndarray,
                      Lambda_plus_k_d: float) -> np.ndarray:
    """``d/dt q̂ = q̇̂_o + (Λ + k_d) z`` of (15), ``z = q − q̂`` (the velocity estimate).

    Parameters
    ----------
    q, q_hat : ndarray, shape (n,)
        The measured positions and the observer's ``q̂`` (``z = q − q̂``).
    qdot_hat_o : ndarray, shape (n,)
        The observer's ``q̇̂_o``.
    Lambda_plus_k_d : float
        ``Λ + k_d`` (1/s).

    Returns
    -------
    numpy.ndarray
        ``d/dt q̂`` (n,), rad/s.
    """
    return qdot_hat_o + Lambda_plus_k_d * (q - q_hat)


def observer_qdot_o(q: np.ndarray, q_hat: np.ndarray, qdot_hat_o: np.ndarray, k_d: float
                    ) -> np.ndarray:
    """``q̇_o = d/dt q̂ − Λ z = q̇̂_o + k_d z`` of (8).

    Parameters
    ----------
    q, q_hat : ndarray, shape (n,)
        The measured positions and the observer's ``q̂`` (``z = q − q̂``).
    qdot_hat_o : ndarray, shape (n,)
        The observer's ``q̇̂_o``.
    k_d : float
        ``k_d`` (1/s).
    """
    return qdot_hat_o + k_d * (q - q_hat)


def observer_acceleration(q: np.ndarray, q_hat: np.ndarray, qddot_r_hat: np.ndarray,
                          k_d_Lambda: float) -> np.ndarray:
    """``d/dt q̇̂_o = q̈̂_r + k_d Λ z`` of (16).

    Parameters
    ----------
    q, q_hat : ndarray, shape (n,)
        The measured positions and the observer's ``q̂`` (``z = q − q̂``).
    qddot_r_hat : ndarray, shape (n,)
        ``q̈̂_r`` (11).
    k_d_Lambda : float
        ``k_d Λ`` (1/s²).

    Returns
    -------
    numpy.ndarray
        ``d/dt q̇̂_o`` (n,), rad/s².
    """
    return qddot_r_hat + k_d_Lambda * (q - q_hat)


@dataclass
class Constraint:
    """``J_φ``, ``J⁺``, ``Q`` and ``Δp = φ(q)`` at one posture (zeros/identity when free).

    Attributes
    ----------
    J_phi : ndarray, shape (m, n)
        ``J_φ``.
    J_pinv : ndarray, shape (n, m)
        ``J⁺``.
    Q : ndarray, shape (n, n)
        ``Q``.
    Delta_p : ndarray, shape (m,)
        ``Δp = φ(q)``.
    """

    J_phi: np.ndarray
    J_pinv: np.ndarray
    Q: np.ndarray
    Delta_p: np.ndarray


class FingerLaw:
    """The paper's per-robot equations, evaluated on the controller's own arm model.

    Parameters
    ----------
    model : ArmModel
        The controller's model of the arm (H, C, D, g, φ, J_φ).
    gains : Gains
        ``Λ = k I``, ``K_R``, ``k_d``, ``k_F``, ``ξ`` (m×m, or ``ξ I``), ``ζ``, ``β``,
        checked by :func:`check_gains` against the model's ``n`` and ``m``.
    pinv_damping : float, optional
        ``μ`` of the damped pseudo-inverse ``J⁺ = J_φᵀ (J_φ J_φᵀ + μ² I)⁻¹`` used in (4),
        (11), (22) and its derivative (7) (:func:`~drake_coop.control.orthogonal.projections`):
        0 (the paper's exact ``J⁺``, the default) or > 0 for arms that pass near a singular
        posture of ``J_φ`` (opt-in; ``J⁺`` stays below ``1/(2μ)``, at the price of exact
        orthogonality).
    contact_stiffness : ContactStiffness, optional
        A compliant contact's stiffness model (:class:`~drake_coop.control.object.ContactStiffness`):
        the constrained position's reference becomes ``p_d = −δ(λ_d)``, the compression the
        contact takes at the desired squeeze, so (4) reads ``Δp = φ(q) + δ(λ_d)`` (``ṗ_d`` is
        not fed forward: ``λ_d`` is slow); and the force integral ``ξ ΔF̃`` of (4) gets the
        gain ``ξ_c = β c(λ_d)/T_i`` on top of ``ξ`` (``c = dδ/dλ`` the model's compliance at
        ``max(λ_d, 1 N)``, ``T_i`` its ``integral_time``), which integrates the stiffness
        model's own error out in about ``T_i``. Default None: ``p_d = 0``, the paper's law,
        the same doubles.

    Raises
    ------
    ValueError
        A gain of the wrong shape or sign, naming it (``K_R``, ``xi_matrix``, ...), or a
        negative or non-finite ``pinv_damping``.
    """

    def __init__(self, model: ArmModel, gains: Gains, contact_stiffness=None,
                 pinv_damping: float = 0.0):
        check_gains(gains, model.n, model.m)
        if contact_stiffness is not None and not callable(
                getattr(contact_stiffness, "compression", None)):
            raise TypeError("contact_stiffness: a ContactStiffness (with compression(λ)) or "
                            f"None is required, got {type(contact_stiffness).__name__}")
        #: The compliant contact's model (None: rigid, ``p_d = 0``).
        self.contact_stiffness = contact_stiffness
        if (isinstance(pinv_damping, bool) or not isinstance(pinv_damping, (int, float))
                or not np.isfinite(pinv_damping) or pinv_damping < 0.0):
            raise ValueError(f"pinv_damping: a finite number >= 0 is required (got "
                             f"{pinv_damping!r})")
        #: ``μ`` of the damped pseudo-inverse (0: the paper's ``J⁺``).
        self.pinv_damping = float(pinv_damping)
        self._mu2 = self.pinv_damping ** 2
        self.model = model
        self.n = model.n
        self.m = model.m
        self.layout = ReferenceLayout(self.n, self.m)
        self.Lambda = float(gains.Lambda)
        self.K_R = np.diag(np.asarray(gains.K_R, dtype=float))
        self.k_d = float(gains.k_d)
        self._Lambda_plus_k_d = self.Lambda + self.k_d
        self.k_F = float(gains.k_F)
        # ξ of (4): the m×m matrix when given, else the scalar of ξ I (the same doubles).
        self.xi = (float(gains.xi) if gains.xi_matrix is None
                   else np.asarray(gains.xi_matrix, dtype=float))
        self.zeta = float(gains.zeta)
        self.beta = float(gains.beta)
        #: ``K_O`` of the momentum observer (``force_source = "momentum"``), 1/s.
        self.momentum_gain = float(gains.momentum_gain)
        self._zero_m = np.zeros(self.m)
        self._constraint_key = b""
        self._constraint: Constraint | None = None
        #: One constraint and a scalar ξ, on plain floats (see :meth:`_held_m1`): the paper's
        #: case (closed-form kinematics) and any arm with Drake's (its row ``J_φ`` and
        #: ``J̇_φ q̇_o`` from the tick's one kinematics evaluation). Anything else takes the
        #: general path (any n, m, ξ matrix).
        self.fast = (self.m == 1 and np.ndim(self.xi) == 0
                     and hasattr(model, "constraint_row"))
        self._K_R_diag = np.diag(self.K_R).tolist()
        # K_R is diagonal: K_R x as an elementwise product (the same doubles as K_R @ x).
        self._K_R_vector = np.diag(self.K_R).copy()

    # ------------------------------------------------------------------ observer (15), (8)
    def observer_derivative(self, q: np.ndarray, q_hat: np.ndarray, qdot_hat_o: np.ndarray
                            ) -> tuple[np.ndarray, np.ndarray]:
        """``d/dt q̂`` of (15) and ``q̇_o`` of (8) with this law's ``Λ``, ``k_d``.

        Parameters
        ----------
        q : numpy.ndarray
            Measured joint positions (n,), rad.
        q_hat : numpy.ndarray
            The observer's ``q̂`` (n,), rad.
        qdot_hat_o : numpy.ndarray
            The observer's ``q̇̂_o`` (n,), rad/s.

        Returns
        -------
        qdot_hat : numpy.ndarray
            ``d/dt q̂`` (n,), rad/s.
        qdot_o : numpy.ndarray
            ``q̇_o`` (n,), rad/s.
        """
        return (observer_qdot_hat(q, q_hat, qdot_hat_o, self._Lambda_plus_k_d),
                observer_qdot_o(q, q_hat, qdot_hat_o, self.k_d))

    def observer_acceleration(self, q: np.ndarray, q_hat: np.ndarray,
                              qddot_r_hat: np.ndarray) -> np.ndarray:
        """``d/dt q̇̂_o`` of (16) with this law's ``Λ``, ``k_d``.

        Parameters
        ----------
        q : numpy.ndarray
            Measured joint positions (n,), rad.
        q_hat : numpy.ndarray
            The observer's ``q̂`` (n,), rad.
        qddot_r_hat : numpy.ndarray
            ``q̈̂_r`` of (11) (n,), rad/s².

        Returns
        -------
        numpy.ndarray
            ``d/dt q̇̂_o`` (n,), rad/s².
        """
        return observer_acceleration(q, q_hat, qddot_r_hat, self.k_d * self.Lambda)

    # ------------------------------------------------------------------ constraint
    def constraint(self, q: np.ndarray, held: bool, J_phi: np.ndarray | None = None
                   ) -> Constraint:
        """Projections of Property 1 at ``q`` (free-motion form when not held).

        ``J_phi`` may be passed when already computed at ``q``. Held, the result is kept for
        the last ``q``: the force observer and the controller of a tick share it (the caller
        must not modify its arrays).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        held : bool
            Whether the object is held (else the free-motion form).
        J_phi : numpy.ndarray or None
            ``J_φ(q)`` (m, n) if already computed.

        Returns
        -------
        Constraint
            ``J_φ``, ``J⁺``, ``Q`` and ``Δp = φ(q)`` (m).
        """
        if not held:
            J_pinv, Q = orthogonal.free_motion_projections(self.n, self.m)
            return Constraint(np.zeros((self.m, self.n)), J_pinv, Q, self._zero_m)
        key = np.asarray(q, dtype=float).tobytes()
        if key == self._constraint_key:      # the force observer's, at the same sample
            return self._constraint
        if J_phi is None:
            J_phi = self.model.J_phi(q)
        J_pinv, Q = orthogonal.projections(J_phi, self.pinv_damping)
        c = Constraint(J_phi, J_pinv, Q, self.model.phi(q))
        self._constraint_key, self._constraint = key, c
        return c

    def _offset(self, c: Constraint, ref: Reference) -> Constraint:
        """``Δp = φ(q) − p_d`` with ``p_d = −δ(λ_d)`` on a compliant contact (else ``c``)."""
        if self.contact_stiffness is None:
            return c
        return Constraint(c.J_phi, c.J_pinv, c.Q,
                          c.Delta_p + self.contact_stiffness.compression(ref.lambda_d))

    def xi_at(self, ref: Reference):
        """``ξ`` of (4) at a sample: the gains' ``ξ``, plus ``ξ_c = β c(λ_d)/T_i`` on a
        compliant contact (see ``contact_stiffness``).

        Parameters
        ----------
        ref : Reference
            The reference sample (its ``λ_d``, N).

        Returns
        -------
        float or numpy.ndarray
            ``ξ``: a scalar for ``ξ I`` or (m, m).
        """
        if self.contact_stiffness is None:
            return self.xi
        xi_c = self.beta * self.contact_stiffness.integral_gain(float(np.max(ref.lambda_d)))
        return self.xi + (xi_c if np.ndim(self.xi) == 0 else xi_c * np.eye(self.m))

    def reference_velocity(self, c: Constraint, q_hat: np.ndarray, ref: Reference,
                           Delta_F_tilde: np.ndarray) -> np.ndarray:
        """``q̇_r`` of (4).

        Parameters
        ----------
        c : Constraint
            The projections at ``q`` (:meth:`constraint`).
        q_hat : numpy.ndarray
            ``q̂`` (n,), rad.
        ref : Reference
            The reference sample.
        Delta_F_tilde : numpy.ndarray
            ``ΔF̃`` of (6) (m,), N·s.
        """
        return orthogonal.reference_velocity(
            c.Q, c.J_pinv, q_hat=q_hat, q_d=ref.q_d, qdot_d=ref.qdot_d, Lambda=self.Lambda,
            Delta_p=c.Delta_p, beta=self.beta, xi=self.xi_at(ref), Delta_F_tilde=Delta_F_tilde)

    # ------------------------------------------------------------------ m = 1 on plain floats
    def _held_m1(self, q: np.ndarray, q_hat: np.ndarray, ref: Reference, DF: float
                 ) -> tuple[list[float], float, float, list[float], list[float]]:
        """The held form of (4) for one constraint, on plain floats.

        With the row ``j = J_φ`` (1×n) and ``ν = j jᵀ`` (``+ μ²`` when damped):
        ``J⁺ = jᵀ/ν``, ``Q x = x − J⁺ (j x)``,
        ``q̇_r = Q (q̇_d − Λ(q̂ − q_d)) + J⁺ (−β φ + ξ ΔF̃)``. Returns ``j``, ``ν``, the force
        part ``−β φ + ξ ΔF̃``, the motion part ``q̇_d − Λ(q̂ − q_d)`` and ``q̇_r``.
        """
        phi, j = self.model.constraint_row(q)
        xi = self.xi
        if self.contact_stiffness is not None:
            phi = phi + float(self.contact_stiffness.compression(ref.lambda_d)[0])
            xi = self.xi_at(ref)
        nu = j[0] * j[0] + j[1] * j[1] + j[2] * j[2] if len(j) == 3 else sum(x * x for x in j)
        if self._mu2:                    # the damped J⁺ = jᵀ/(ν + μ²); its ν̇ is unchanged
            nu = nu + self._mu2
        f = -self.beta * phi + xi * DF
        L = self.Lambda
        motion = [vd - L * (qh - qd) for vd, qh, qd in
                  zip(ref.qdot_d.tolist(), q_hat.tolist(), ref.q_d.tolist())]
        jm = sum(a * b for a, b in zip(j, motion))
        qdot_r = [x - (jk / nu) * jm + (jk / nu) * f for x, jk in zip(motion, j)]
        return j, nu, f, motion, qdot_r

    def _force_estimate_m1(self, q, q_hat, qdot_o, ref, Delta_F_tilde) -> np.ndarray:
        """(22) for one constraint on plain floats (see :meth:`force_estimate`)."""
        DF = float(Delta_F_tilde[0])
        j, nu, _, _, qdot_r = self._held_m1(q, q_hat, ref, DF)
        s = sum((jk / nu) * kr * (vo - vr) for jk, kr, vo, vr in
                zip(j, self._K_R_diag, qdot_o.tolist(), qdot_r))
        return np.array([(s - self.k_F * DF) / (1.0 + self.zeta) + float(ref.lambda_d[0])])

    def _control_m1(self, q, q_hat, qdot_hat, qdot_o, lambda_hat, Delta_F_tilde, ref):
        """(4), (11), (13) for one constraint on plain floats (see :meth:`control`).

        ``J̇⁺ = J̇_φᵀ/ν − 2 jᵀ (J̇_φ jᵀ)/ν²`` and ``Q̇ x = −(J̇⁺ (j x) + J⁺ (J̇_φ x))``.
        """
        DF = float(Delta_F_tilde[0])
        j, nu, f, motion, qdot_r = self._held_m1(q, q_hat, ref, DF)
        jd = self.model.constraint_row_dot(q, qdot_o)
        lam_d = float(ref.lambda_d[0])
        dlt = float(lambda_hat[0]) - lam_d
        L = self.Lambda
        motion_dot = [ad - L * (vh - vd) for ad, vh, vd in
                      zip(ref.qddot_d.tolist(), qdot_hat.tolist(), ref.qdot_d.tolist())]
        jdj = sum(a * b for a, b in zip(jd, j))
        jmd = sum(a * b for a, b in zip(j, motion_dot))
        jm = sum(a * b for a, b in zip(j, motion))
        jdm = sum(a * b for a, b in zip(jd, motion))
        xi_dl = (self.xi if self.contact_stiffness is None else self.xi_at(ref)) * dlt
        qddot_r = []
        for jk, jdk, md in zip(j, jd, motion_dot):
            jp, jpd = jk / nu, jdk / nu - jk * 2.0 * jdj / (nu * nu)
            qddot_r.append(md - jp * jmd + jp * xi_dl - (jpd * jm + jp * jdm) + jpd * f)
        qdot_r_a, qddot_r_a = np.array(qdot_r), np.array(qddot_r)
        force = lam_d - self.k_F * DF - self.zeta * dlt
        tau = (self.model.inverse_dynamics_terms(q, qdot_r_a, qddot_r_a)
               - self._K_R_vector * (qdot_o - qdot_r_a) - np.array(j) * force)
        return {"tau": tau, "qdot_r": qdot_r_a, "qddot_r_hat": qddot_r_a,
                "Delta_lambda_tilde": np.array([dlt])}

    def _control_free(self, q, q_hat, qdot_hat, qdot_o, ref: Reference) -> dict[str, np.ndarray]:
        """(4), (11), (13) in free motion (before the grasp, after the release).

        With ``Q = I``, ``J⁺ = 0``, ``Q̇ = 0``, ``J̇⁺ = 0`` and no force term:
        ``q̇_r = q̇_d − Λ(q̂ − q_d)``, ``q̈̂_r = q̈_d − Λ(d/dt q̂ − q̇_d)`` and
        ``τ = H q̈̂_r + C(q, q̇_r) q̇_r + D q̇_r + g − K_R(q̇_o − q̇_r)``.
        """
        L = self.Lambda
        qdot_r = ref.qdot_d - L * (q_hat - ref.q_d)
        qddot_r_hat = ref.qddot_d - L * (qdot_hat - ref.qdot_d)
        tau = (self.model.inverse_dynamics_terms(q, qdot_r, qddot_r_hat)
               - self._K_R_vector * (qdot_o - qdot_r))
        return {"tau": tau, "qdot_r": qdot_r, "qddot_r_hat": qddot_r_hat,
                "Delta_lambda_tilde": np.zeros(self.m)}

    # ------------------------------------------------------------------ force observer (22)
    def force_estimate(self, q: np.ndarray, q_hat: np.ndarray, qdot_o: np.ndarray,
                       ref: Reference, Delta_F_tilde: np.ndarray) -> np.ndarray:
        """``λ̂`` of (22): ``[J⁺ᵀ K_R (q̇_o − q̇_r) − k_F ΔF̃]/(1 + ζ) + λ_d``; 0 when free.

        Parameters
        ----------
        q : numpy.ndarray
            Measured joint positions (n,), rad.
        q_hat : numpy.ndarray
            ``q̂`` (n,), rad.
        qdot_o : numpy.ndarray
            ``q̇_o`` of (8) (n,), rad/s.
        ref : Reference
            The reference sample.
        Delta_F_tilde : numpy.ndarray
            ``ΔF̃`` of (6) (m,), N·s.
        """
        if not ref.held:
            return self._zero_m
        if self.fast:
            return self._force_estimate_m1(q, q_hat, qdot_o, ref, Delta_F_tilde)
        c = self._offset(self.constraint(q, True), ref)
        qdot_r = self.reference_velocity(c, q_hat, ref, Delta_F_tilde)
        s = c.J_pinv.T @ self.K_R @ (qdot_o - qdot_r)
        return (s - self.k_F * Delta_F_tilde) / (1.0 + self.zeta) + ref.lambda_d

    def force_estimate_21(self, q: np.ndarray, qdot_r: np.ndarray, qddot_r_hat: np.ndarray,
                          tau: np.ndarray, held: bool) -> np.ndarray:
        """``λ̂`` of (21): ``J⁺ᵀ {H q̈̂_r + C(q, q̇_r) q̇_r + D q̇_r + g − τ}`` (for checks).

        Parameters
        ----------
        q : numpy.ndarray
            Measured joint positions (n,), rad.
        qdot_r : numpy.ndarray
            ``q̇_r`` of (4) (n,), rad/s.
        qddot_r_hat : numpy.ndarray
            ``q̈̂_r`` of (11) (n,), rad/s².
        tau : numpy.ndarray
            The torque (n,), N·m.
        held : bool
            Whether the object is held (else 0).
        """
        if not held:
            return self._zero_m
        c = self.constraint(q, True)
        rhs = self.model.inverse_dynamics_terms(q, qdot_r, qddot_r_hat) - tau
        return c.J_pinv.T @ rhs

    # ------------------------------------------------------------------ controller (13)
    def control(self, q: np.ndarray, q_hat: np.ndarray, qdot_hat: np.ndarray,
                qdot_o: np.ndarray, lambda_hat: np.ndarray, Delta_F_tilde: np.ndarray,
                ref: Reference) -> dict[str, np.ndarray]:
        r"""Torque (13) and the intermediate signals of one sample.

        .. math::
            \tau = H\ddot{\hat q}_r + C(q,\dot q_r)\dot q_r + D\dot q_r + g
                    - K_R(\dot q_o - \dot q_r)
                    - J_\varphi^T(\lambda_d - k_F\Delta\tilde F - \zeta\Delta\tilde\lambda)

        Parameters
        ----------
        q : numpy.ndarray
            Measured joint positions (n,), rad.
        q_hat : numpy.ndarray
            ``q̂`` (n,), rad.
        qdot_hat : numpy.ndarray
            ``d/dt q̂`` of (15) (n,), rad/s.
        qdot_o : numpy.ndarray
            ``q̇_o`` of (8) (n,), rad/s.
        lambda_hat : numpy.ndarray
            ``λ̂`` (m,), N.
        Delta_F_tilde : numpy.ndarray
            ``ΔF̃`` of (6) (m,), N·s.
        ref : Reference
            The reference sample.

        Returns
        -------
        dict
            ``tau`` (N·m), ``qdot_r`` (4) (rad/s), ``qddot_r_hat`` (11) (rad/s²),
            ``Delta_lambda_tilde`` (m,) (N).

        Notes
        -----
        One constraint and a scalar ξ (:attr:`fast`: the paper's case, and any arm at
        ``m = 1``) runs on plain floats (:meth:`_control_m1`); the same equations, other roundings.
        Free motion, for any arm, takes :meth:`_control_free` (the same equations with
        ``Q = I``, ``J⁺ = 0``, ``J_φ = 0``, without forming those matrices).
        """
        if not ref.held:
            return self._control_free(q, q_hat, qdot_hat, qdot_o, ref)
        if self.fast:
            return self._control_m1(q, q_hat, qdot_hat, qdot_o, lambda_hat, Delta_F_tilde, ref)
        J_phi, J_phi_dot = self.model.J_phi_and_derivative(q, qdot_o)
        J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, J_phi_dot,
                                                              self.pinv_damping)
        c = self._offset(self.constraint(q, True, J_phi), ref)
        Delta_lambda_tilde = lambda_hat - ref.lambda_d
        qdot_r = self.reference_velocity(c, q_hat, ref, Delta_F_tilde)
        qddot_r_hat = orthogonal.reference_acceleration(
            c.Q, c.J_pinv, Q_dot, J_pinv_dot, q_hat=q_hat, qdot_hat=qdot_hat, q_d=ref.q_d,
            qdot_d=ref.qdot_d, qddot_d=ref.qddot_d, Lambda=self.Lambda, Delta_p=c.Delta_p,
            beta=self.beta, xi=self.xi_at(ref), Delta_F_tilde=Delta_F_tilde,
            Delta_lambda_tilde=Delta_lambda_tilde)
        force = ref.lambda_d - self.k_F * Delta_F_tilde - self.zeta * Delta_lambda_tilde
        tau = (self.model.inverse_dynamics_terms(q, qdot_r, qddot_r_hat)
               - self.K_R @ (qdot_o - qdot_r) - c.J_phi.T @ force)
        return {"tau": tau, "qdot_r": qdot_r, "qddot_r_hat": qddot_r_hat,
                "Delta_lambda_tilde": np.array(Delta_lambda_tilde, dtype=float)}


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
