"""Property 1, (7), (11) and the matrix gain ξ for m = 1, 2, 3 constraints on 3- and 6-joint arms.

The paper's Section II is written for ``m_i`` constraints per finger (``λ_i ∈ R^{m_i}``,
``ξ_i ∈ R^{m_i×m_i}``); the experiment has ``m = 1``. Here :mod:`drake_coop.control.orthogonal`
is checked for every ``m ≤ min(n, 3)`` on ``n = 3`` and ``n = 6`` joints, and for ``m = n``,
against computations that do not use it:

* the constraint is the test's own ``φ(q) = N (x(q) − c)``: ``x`` is the CRS A465's closed-form
  forward kinematics (n = 3, checked equal to the package's ``Arm.fk``) or ``A tanh(B q + b)``
  (n = 6), ``N`` holds ``m`` random, linearly independent unit normals;
* ``J_φ`` is written in closed form and checked against the complex-step derivative of ``φ``;
  ``J̇_φ`` along ``v`` is the complex-step derivative of ``J_φ`` (exact to rounding);
* Property 1 by its defining identities and by NumPy's SVD pseudo-inverse;
* (7) against central differences of ``Q`` and ``J⁺`` and against the complex-step derivative of
  ``Jᵀ (J Jᵀ)⁻¹`` written here;
* (11) against the numerical time derivative of (4) along smooth motions, on the constraint
  manifold (``ṗ = 0``, solved by Newton) and off it (explicit ``ṗ``, ``ṗ_d``, ``p̈_d``).

Tolerances (relative unless stated): 1e-12 where the reference is exact to rounding (complex
step, SVD, the split of (4)); for the identities of Property 1, 100 · eps · cond(J_φ) times the
scale of each product (a backward-stable solve errs by ≈ eps · cond); 1e-8 where the reference
is a fourth-order central difference with step 3e-4 (truncation ≈ h⁴ ≈ 1e-14 times the fifth
derivative, rounding ≈ 1e-16 / h ≈ 3e-13 times the amplification; measured errors ≤ 2e-10, so
the margin is ≥ 50×). Postures and normals are drawn with ``cond(J_φ) < 1e3`` (measured ≤ 25).
"""

from __future__ import annotations

import numpy as np
import pytest

from drake_coop.control import orthogonal
from drake_coop.plant.arms import Arm
from drake_coop.scenario import paper_robots

#: (n joints, m constraints): every m ≤ min(n, 3).
CASES = [(3, 1), (3, 2), (3, 3), (6, 1), (6, 2), (6, 3)]
CASE_IDS = [f"n{n}-m{m}" for n, m in CASES]

#: Complex-step size: the derivative is Im f(q + i h v) / h, with no subtractive cancellation.
H_COMPLEX = 1e-30


# ---------------------------------------------------------------------------- the test's φ(q)

class CrsMap:
    """x(q) of the CRS A465 (waist yaw, shoulder and elbow pitch), written here in closed form."""

    n = 3
    d = 3

    def __init__(self):
        arm = Arm(paper_robots()[0])
        g = arm.geometry
        self.arm = arm
        self.h1, self.L2, self.L3 = g.h1, g.L2, g.L3
        self.R, self.p = arm.R_base, arm.p_base
        self.q_center = np.array([0.4, 0.6, 0.9])     # elbow bent, away from r = 0 and q3 = 0

    def x(self, q):
        q1, q2, q3 = q
        r = self.L2 * np.sin(q2) + self.L3 * np.sin(q2 + q3)
        z = self.h1 + self.L2 * np.cos(q2) + self.L3 * np.cos(q2 + q3)
        return self.R @ np.array([r * np.cos(q1), r * np.sin(q1), z]) + self.p

    def J(self, q):
        q1, q2, q3 = q
        s1, c1 = np.sin(q1), np.cos(q1)
        r = self.L2 * np.sin(q2) + self.L3 * np.sin(q2 + q3)
        a = self.L2 * np.cos(q2) + self.L3 * np.cos(q2 + q3)       # ∂r/∂q2; ∂z/∂q2 = −r
        b = self.L3 * np.cos(q2 + q3)                              # ∂r/∂q3
        e = self.L3 * np.sin(q2 + q3)                              # −∂z/∂q3
        local = np.array([[-r * s1, a * c1, b * c1],
                          [r * c1, a * s1, b * s1],
                          [0.0 * r, -r, -e]])
        return self.R @ local


class TanhMap:
    """A smooth map x(q) = A tanh(B q + b): R^n -> R^d with random A, B, b (seeded)."""

    def __init__(self, n: int, d: int, seed: int):
        rng = np.random.default_rng(seed)
        self.n, self.d = n, d
        self.A = rng.normal(size=(d, n))
        self.B = rng.normal(size=(n, n)) / np.sqrt(n)
        self.b = rng.normal(size=n) * 0.3
        self.q_center = rng.normal(size=n) * 0.3

    def x(self, q):
        return self.A @ np.tanh(self.B @ q + self.b)

    def J(self, q):
        sech2 = 1.0 - np.tanh(self.B @ q + self.b) ** 2
        return self.A @ (sech2[:, None] * self.B)


class Constraint:
    """φ(q) = N (x(q) − c) with m unit normals N (m×d), c = x(q_center) (so φ(q_center) = 0).

    Every method accepts complex q (for the complex step): only ``np.sin``/``np.tanh``/``@``.
    """

    def __init__(self, xmap, m: int, seed: int):
        rng = np.random.default_rng(seed)
        while True:
            N = rng.normal(size=(m, xmap.d))
            N /= np.linalg.norm(N, axis=1, keepdims=True)
            if np.linalg.svd(N, compute_uv=False)[-1] > 0.3:    # well independent
                break
        self.xmap, self.N, self.n, self.m = xmap, N, xmap.n, m
        self.q_center = xmap.q_center
        self.c = xmap.x(self.q_center)

    def phi(self, q):
        return self.N @ (self.xmap.x(q) - self.c)

    def J_phi(self, q):
        return self.N @ self.xmap.J(q)

    def J_phi_dot(self, q, v):
        """d/ds J_φ(q + s v) at s = 0 by the complex step (exact to rounding)."""
        return np.imag(self.J_phi(q + 1j * H_COMPLEX * np.asarray(v))) / H_COMPLEX

    def postures(self, count: int, seed: int, spread: float = 0.3):
        rng = np.random.default_rng(seed)
        qs = self.q_center + rng.uniform(-spread, spread, size=(count, self.n))
        for q in qs:
            assert np.linalg.cond(self.J_phi(q)) < 1e3    # tolerances below assume this
        return qs


def make_constraint(n: int, m: int, d: int | None = None) -> Constraint:
    xmap = CrsMap() if n == 3 else TanhMap(n, d or 3, seed=100 + n)
    return Constraint(xmap, m, seed=10 * n + m)


@pytest.fixture(scope="module", params=CASES, ids=CASE_IDS)
def con(request) -> Constraint:
    return make_constraint(*request.param)


def central4(f, h: float = 3e-4):
    """Fourth-order central difference of f(s) at s = 0 (error O(h⁴))."""
    return (f(-2 * h) - 8 * f(-h) + 8 * f(h) - f(2 * h)) / (12 * h)


def rel_err(a, b) -> float:
    return np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b)


def spd_xi(m: int, seed: int) -> np.ndarray:
    """A symmetric positive definite, non-diagonal m×m ξ (for m = 1: a 1×1 matrix)."""
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(m, m))
    xi = 0.5 * (M @ M.T) + 0.5 * np.eye(m)
    if m > 1:
        assert np.min(np.abs(xi[~np.eye(m, dtype=bool)])) > 1e-3          # not diagonal
    assert np.all(np.linalg.eigvalsh(xi) > 0) and np.array_equal(xi, xi.T)
    return xi


# ------------------------------------------------------------- the test's own derivatives

def test_the_tests_constraint_jacobians_are_derivatives_of_phi(con):
    """The helper itself: closed-form J_φ = complex-step ∂φ/∂q, J̇_φ = central difference of J_φ;
    for n = 3 the map is the package's arm (Arm.fk)."""
    rng = np.random.default_rng(5)
    for q in con.postures(5, seed=6):
        J_cs = np.column_stack([np.imag(con.phi(q + 1j * H_COMPLEX * e)) / H_COMPLEX
                                for e in np.eye(con.n)])
        assert rel_err(con.J_phi(q), J_cs) < 1e-12
        v = rng.normal(size=con.n)
        assert rel_err(con.J_phi_dot(q, v), central4(lambda s: con.J_phi(q + s * v))) < 1e-8
        if isinstance(con.xmap, CrsMap):
            np.testing.assert_allclose(con.xmap.x(q), con.xmap.arm.fk(q), rtol=0, atol=1e-15)


# ------------------------------------------------------------------------------ Property 1

def test_property1_for_m_constraints(con):
    n, m = con.n, con.m
    for q in con.postures(20, seed=1):
        J_phi = con.J_phi(q)
        J_pinv, Q = orthogonal.projections(J_phi)
        assert J_pinv.shape == (n, m) and Q.shape == (n, n)
        # A backward-stable solve errs by ≈ eps · cond(J_φ) relative; 100 × that, times the
        # scale of each product.
        tol = 100 * np.finfo(float).eps * np.linalg.cond(J_phi)
        np.testing.assert_allclose(Q @ J_pinv, 0.0, atol=tol * np.linalg.norm(J_pinv))
        np.testing.assert_allclose(Q @ J_phi.T, 0.0, atol=tol * np.linalg.norm(J_phi))
        np.testing.assert_allclose(J_phi @ J_pinv, np.eye(m), atol=tol)
        assert np.linalg.matrix_rank(Q, tol=1e-10) == n - m
        np.testing.assert_allclose(Q @ Q, Q, atol=tol)
        np.testing.assert_allclose(Q, Q.T, atol=tol)
        # An orthogonal projector of rank n − m: eigenvalues m zeros and n − m ones.
        np.testing.assert_allclose(np.linalg.eigvalsh(0.5 * (Q + Q.T)),
                                   [0.0] * m + [1.0] * (n - m), atol=tol)
        # J⁺ is the Moore–Penrose inverse of a full-row-rank J_φ (NumPy's SVD, independent).
        assert rel_err(J_pinv, np.linalg.pinv(J_phi)) < 1e-12


@pytest.mark.parametrize("n, d", [(3, 3), (6, 6)], ids=["n3-m3", "n6-m6"])
def test_m_equal_n_holds_the_point_in_place(n, d):
    """m = n: no tangent space, Q = 0, J⁺ = J_φ⁻¹; (7) then reduces to Q̇ = 0 and
    J̇⁺ = −J_φ⁻¹ J̇_φ J_φ⁻¹ (the derivative of the inverse)."""
    con = make_constraint(n, n, d=d)
    rng = np.random.default_rng(7)
    for q in con.postures(10, seed=8):
        J_phi = con.J_phi(q)
        J_inv = np.linalg.inv(J_phi)
        J_pinv, Q = orthogonal.projections(J_phi)
        np.testing.assert_allclose(Q, 0.0, atol=1e-12)
        assert rel_err(J_pinv, J_inv) < 1e-12
        v = rng.normal(size=n)
        J_phi_dot = con.J_phi_dot(q, v)
        J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, J_phi_dot)
        np.testing.assert_allclose(Q_dot, 0.0, atol=1e-11 * np.linalg.norm(J_phi_dot))
        assert rel_err(J_pinv_dot, -J_inv @ J_phi_dot @ J_inv) < 1e-12


# ------------------------------------------------------------------------------------ (7)

def _pinv_by_definition(J):
    """J⁺ = Jᵀ (J Jᵀ)⁻¹ written here (plain transposes: valid for the complex step)."""
    return J.T @ np.linalg.inv(J @ J.T)


def test_projection_derivatives_match_differences_of_projections(con):
    rng = np.random.default_rng(2)
    for q in con.postures(10, seed=3):
        v = rng.normal(size=con.n)
        J_phi = con.J_phi(q)
        J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, con.J_phi_dot(q, v))

        def proj(s, k):
            return orthogonal.projections(con.J_phi(q + s * v))[k]

        assert rel_err(J_pinv_dot, central4(lambda s: proj(s, 0))) < 1e-8
        if con.m < con.n:                        # Q ≡ 0 for m = n: checked by absolute value
            assert rel_err(Q_dot, central4(lambda s: proj(s, 1))) < 1e-8
        # The complex step of the definitions: exact to rounding, so a tight bound.
        J_c = con.J_phi(q + 1j * H_COMPLEX * v)
        pinv_c = _pinv_by_definition(J_c)
        Q_c = np.eye(con.n) - pinv_c @ J_c
        assert rel_err(J_pinv_dot, np.imag(pinv_c) / H_COMPLEX) < 1e-12
        if con.m < con.n:
            assert rel_err(Q_dot, np.imag(Q_c) / H_COMPLEX) < 1e-12
        else:
            np.testing.assert_allclose(Q_dot, 0.0, atol=1e-11 * np.linalg.norm(J_pinv_dot))


# ----------------------------------------------------------------------------- ξ and (4)

@pytest.mark.parametrize("m", [1, 2, 3])
def test_scalar_xi_gives_the_same_doubles_as_xi_times_identity(m):
    rng = np.random.default_rng(20 + m)
    xi = 0.731
    x = rng.normal(size=m)
    assert np.array_equal(orthogonal.xi_times(xi, x), orthogonal.xi_times(xi * np.eye(m), x))
    assert np.array_equal(orthogonal.xi_times(xi, x), xi * x)


@pytest.mark.parametrize("m", [2, 3])
def test_matrix_xi_acts_as_a_matrix(m):
    """A general (non-symmetric) ξ multiplies as ξ x, row by column — not ξᵀ x, not ξ ⊙ x."""
    rng = np.random.default_rng(30 + m)
    xi = rng.normal(size=(m, m))
    x = rng.normal(size=m)
    expected = np.array([sum(xi[i, j] * x[j] for j in range(m)) for i in range(m)])
    assert not np.allclose(xi.T @ x, expected)          # the data tells the two apart
    np.testing.assert_allclose(orthogonal.xi_times(xi, x), expected, rtol=1e-14, atol=1e-15)


def _reference_inputs(con, seed):
    """Random inputs of (4) at a random posture of ``con``."""
    rng = np.random.default_rng(seed)
    n, m = con.n, con.m
    q = con.postures(1, seed=seed)[0]
    return q, dict(q_hat=q + 0.01 * rng.normal(size=n), q_d=q + 0.05 * rng.normal(size=n),
                   qdot_d=rng.normal(size=n), Lambda=26.0, Delta_p=0.01 * rng.normal(size=m),
                   beta=10.0, Delta_F_tilde=rng.normal(size=m), pdot_d=rng.normal(size=m))


def test_reference_velocity_splits_into_tangent_and_normal_parts(con):
    """(4) by Property 1: J_φ q̇_r = ṗ_d − βΔp + ξΔF̃ and Q q̇_r = Q(q̇_d − Λ(q̂ − q_d)),
    with a general (non-symmetric) matrix ξ."""
    q, kw = _reference_inputs(con, seed=40)
    xi = np.random.default_rng(41).normal(size=(con.m, con.m))
    J_phi = con.J_phi(q)
    J_pinv, Q = orthogonal.projections(J_phi)
    qdot_r = orthogonal.reference_velocity(Q, J_pinv, xi=xi, **kw)
    normal = kw["pdot_d"] - kw["beta"] * kw["Delta_p"] + xi @ kw["Delta_F_tilde"]
    tangent = Q @ (kw["qdot_d"] - kw["Lambda"] * (kw["q_hat"] - kw["q_d"]))
    assert rel_err(J_phi @ qdot_r, normal) < 1e-12
    if con.m < con.n:
        assert rel_err(Q @ qdot_r, tangent) < 1e-12


def test_scalar_xi_in_4_and_11_is_the_matrix_xi_identity_bit_for_bit(con):
    """A scalar ξ in (4) and (11) gives the very doubles of the matrix ξ I (the paper's m = 1
    runs keep their bits when ξ becomes a matrix)."""
    q, kw = _reference_inputs(con, seed=50)
    rng = np.random.default_rng(51)
    xi, m = 0.37, con.m
    J_phi = con.J_phi(q)
    J_pinv, Q = orthogonal.projections(J_phi)
    J_phi_dot = con.J_phi_dot(q, rng.normal(size=con.n))
    J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, J_phi_dot)
    v_s = orthogonal.reference_velocity(Q, J_pinv, xi=xi, **kw)
    v_m = orthogonal.reference_velocity(Q, J_pinv, xi=xi * np.eye(m), **kw)
    assert np.array_equal(v_s, v_m)
    extra = dict(qdot_hat=rng.normal(size=con.n), qddot_d=rng.normal(size=con.n),
                 Delta_lambda_tilde=rng.normal(size=m), pdot=rng.normal(size=m),
                 pddot_d=rng.normal(size=m))
    a_s = orthogonal.reference_acceleration(Q, J_pinv, Q_dot, J_pinv_dot, xi=xi, **kw, **extra)
    a_m = orthogonal.reference_acceleration(Q, J_pinv, Q_dot, J_pinv_dot, xi=xi * np.eye(m),
                                            **kw, **extra)
    assert np.array_equal(a_s, a_m)


# ----------------------------------------------------------------------------------- (11)

class ManifoldMotion:
    """A smooth motion q(t) with φ(q(t)) = 0: free coordinates z(t) ∈ R^{n−m} along the null
    space S of J_φ(q_center), the remaining y(t) ∈ R^m along K = J_φ(q_center)ᵀ solved by Newton;
    q̇ = S ż + K ẏ with J_φ q̇ = 0 (implicit function theorem)."""

    def __init__(self, con: Constraint, seed: int):
        rng = np.random.default_rng(seed)
        self.con = con
        J0 = con.J_phi(con.q_center)
        self.S = np.linalg.svd(J0)[2][con.m:].T            # n×(n−m), orthonormal null space
        self.K = J0.T
        k = con.n - con.m
        self.a = rng.uniform(0.05, 0.15, size=k)
        self.w = rng.uniform(0.5, 2.0, size=k)
        self.ph = rng.uniform(0, 2 * np.pi, size=k)

    def __call__(self, t: float):
        con = self.con
        z = self.S @ (self.a * np.sin(self.w * t + self.ph))
        zdot = self.S @ (self.a * self.w * np.cos(self.w * t + self.ph))
        y = np.zeros(con.m)
        for _ in range(50):
            q = con.q_center + z + self.K @ y
            step = np.linalg.solve(con.J_phi(q) @ self.K, con.phi(q))
            y -= step
            if np.linalg.norm(step) < 1e-15:
                break
        else:
            raise AssertionError("Newton did not converge")
        q = con.q_center + z + self.K @ y
        J = con.J_phi(q)
        qdot = zdot - self.K @ np.linalg.solve(J @ self.K, J @ zdot)
        return q, qdot


class FreeMotion:
    """A smooth motion q(t) off the manifold (ṗ = J_φ q̇ ≠ 0) with a moving p_d(t)."""

    def __init__(self, con: Constraint, seed: int):
        rng = np.random.default_rng(seed)
        self.con = con
        self.a = rng.uniform(0.05, 0.15, size=con.n)
        self.w = rng.uniform(0.5, 2.0, size=con.n)
        self.ph = rng.uniform(0, 2 * np.pi, size=con.n)

    def __call__(self, t: float):
        arg = self.w * t + self.ph
        return self.con.q_center + self.a * np.sin(arg), self.a * self.w * np.cos(arg)


def _check_11_against_derivative_of_4(con, motion, xi, *, on_manifold: bool):
    """(11) with q̇_o = q̇ equals d/dt (4) (fourth-order central difference in t)."""
    n, m = con.n, con.m
    rng = np.random.default_rng(60)
    Lambda, beta = 26.0, 10.0
    e_a, e_w = rng.uniform(0.005, 0.01, size=n), rng.uniform(1.0, 3.0, size=n)
    d_a, d_w = rng.uniform(0.05, 0.1, size=n), rng.uniform(0.5, 1.0, size=n)
    f_a, f_w = rng.uniform(0.5, 1.0, size=m), rng.uniform(0.5, 1.5, size=m)
    p_a, p_w = rng.uniform(0.005, 0.01, size=m), rng.uniform(0.5, 1.5, size=m)

    def signals(t):
        q, qdot = motion(t)
        s = dict(q=q, qdot=qdot,
                 q_hat=q + e_a * np.sin(e_w * t), qdot_hat=qdot + e_a * e_w * np.cos(e_w * t),
                 q_d=con.q_center + d_a * np.sin(d_w * t), qdot_d=d_a * d_w * np.cos(d_w * t),
                 qddot_d=-d_a * d_w**2 * np.sin(d_w * t),
                 DF=f_a * np.sin(f_w * t) + 0.2 * t, dlam=f_a * f_w * np.cos(f_w * t) + 0.2)
        if on_manifold:                   # the paper's case: p_d = 0, ṗ = ṗ_d = p̈_d = 0
            s.update(p_d=np.zeros(m), pdot_d=0.0, pddot_d=0.0)
        else:
            s.update(p_d=p_a * np.sin(p_w * t), pdot_d=p_a * p_w * np.cos(p_w * t),
                     pddot_d=-p_a * p_w**2 * np.sin(p_w * t))
        return s

    def qdot_r(t):
        s = signals(t)
        J_pinv, Q = orthogonal.projections(con.J_phi(s["q"]))
        return orthogonal.reference_velocity(
            Q, J_pinv, q_hat=s["q_hat"], q_d=s["q_d"], qdot_d=s["qdot_d"], Lambda=Lambda,
            Delta_p=con.phi(s["q"]) - s["p_d"], beta=beta, xi=xi, Delta_F_tilde=s["DF"],
            pdot_d=s["pdot_d"])

    for t in (0.3, 1.1, 2.7):
        s = signals(t)
        q, qdot = s["q"], s["qdot"]
        J_phi = con.J_phi(q)
        J_pinv, Q = orthogonal.projections(J_phi)
        J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, con.J_phi_dot(q, qdot))
        pdot = J_phi @ qdot
        extra = {}
        if on_manifold:
            assert np.linalg.norm(con.phi(q)) < 1e-13 and np.linalg.norm(pdot) < 1e-13
        else:
            assert np.linalg.norm(pdot) > 1e-3                     # really off the manifold
            extra = dict(pdot=pdot, pdot_d=s["pdot_d"], pddot_d=s["pddot_d"])
        qddot_r_hat = orthogonal.reference_acceleration(
            Q, J_pinv, Q_dot, J_pinv_dot, q_hat=s["q_hat"], qdot_hat=s["qdot_hat"],
            q_d=s["q_d"], qdot_d=s["qdot_d"], qddot_d=s["qddot_d"], Lambda=Lambda,
            Delta_p=con.phi(q) - s["p_d"], beta=beta, xi=xi, Delta_F_tilde=s["DF"],
            Delta_lambda_tilde=s["dlam"], **extra)
        numeric = central4(lambda h: qdot_r(t + h))
        assert rel_err(qddot_r_hat, numeric) < 1e-8, (qddot_r_hat, numeric)


XI_KINDS = ["matrix", "scalar"]


def _xi(kind, m):
    return spd_xi(m, seed=70 + m) if kind == "matrix" else 0.8


@pytest.mark.parametrize("xi_kind", XI_KINDS)
def test_11_is_the_time_derivative_of_4_on_the_constraint_manifold(con, xi_kind):
    _check_11_against_derivative_of_4(con, ManifoldMotion(con, seed=80), _xi(xi_kind, con.m),
                                      on_manifold=True)


@pytest.mark.parametrize("xi_kind", XI_KINDS)
def test_11_is_the_time_derivative_of_4_off_the_manifold_with_moving_p_d(con, xi_kind):
    _check_11_against_derivative_of_4(con, FreeMotion(con, seed=90), _xi(xi_kind, con.m),
                                      on_manifold=False)
