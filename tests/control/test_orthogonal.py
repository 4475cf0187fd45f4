"""Property 1, the directional derivatives (7) and the reference acceleration (11).

Every check compares the implementation with an independent computation: the defining
identities of Property 1, central finite differences of Q and J⁺, and the numerical time
derivative of the reference velocity (4).
"""

import numpy as np
import pytest

from drake_coop.control import orthogonal
from drake_coop.plant.arms import arm_model
from drake_coop.plant.arms import Arm
from drake_coop.scenario import paper_robots

ROBOTS = paper_robots()


@pytest.fixture(scope="module", params=[0, 1], ids=["robot1", "robot2"])
def model(request):
    return arm_model(Arm(ROBOTS[request.param]))


def random_postures(model, count=20, seed=0):
    """Random postures around the grasp posture (well inside the workspace)."""
    rng = np.random.default_rng(seed)
    arm = model.kinematics
    q_grasp = arm.ik([model.c[0], 0.0, 0.535])
    return q_grasp + rng.uniform(-0.4, 0.4, size=(count, 3))


def test_property1_identities_hold_at_random_postures(model):
    for q in random_postures(model):
        J_phi = model.J_phi(q)
        J_pinv, Q = orthogonal.projections(J_phi)
        np.testing.assert_allclose(Q @ J_pinv, 0.0, atol=1e-14)
        np.testing.assert_allclose(Q @ J_phi.T, 0.0, atol=1e-14)
        np.testing.assert_allclose(J_phi @ J_pinv, np.eye(1), atol=1e-14)
        assert np.linalg.matrix_rank(Q, tol=1e-10) == 3 - 1
        np.testing.assert_allclose(Q @ Q, Q, atol=1e-14)   # a projector
        np.testing.assert_allclose(Q, Q.T, atol=1e-14)      # orthogonal projector


def test_free_motion_projections_are_identity_and_zero():
    J_pinv, Q = orthogonal.free_motion_projections(3)
    np.testing.assert_array_equal(Q, np.eye(3))
    np.testing.assert_array_equal(J_pinv, np.zeros((3, 1)))


def _central_difference(f, q, v, eps=1e-6):
    return (f(q + eps * v) - f(q - eps * v)) / (2 * eps)


def test_directional_derivatives_match_central_differences(model):
    rng = np.random.default_rng(1)
    for q in random_postures(model, count=10, seed=2):
        v = rng.normal(size=3)
        J_phi, J_phi_dot = model.J_phi_and_derivative(q, v)
        J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, J_phi_dot)
        fd_J_pinv = _central_difference(lambda x: orthogonal.projections(model.J_phi(x))[0], q, v)
        fd_Q = _central_difference(lambda x: orthogonal.projections(model.J_phi(x))[1], q, v)
        assert np.linalg.norm(J_pinv_dot - fd_J_pinv) <= 1e-6 * np.linalg.norm(fd_J_pinv)
        assert np.linalg.norm(Q_dot - fd_Q) <= 1e-6 * np.linalg.norm(fd_Q)
        # J̇_φ itself against the difference of J_φ.
        fd_J = _central_difference(model.J_phi, q, v)
        assert np.linalg.norm(J_phi_dot - fd_J) <= 1e-6 * np.linalg.norm(fd_J)


def test_reference_acceleration_is_time_derivative_of_reference_velocity(model):
    """With q̇_o = q̇ (r = 0 in (12)), (11) equals d/dt of (4) along a smooth trajectory."""
    arm = model.kinematics
    Lambda, beta, xi = 26.0, 10.0, 1e-3

    # A smooth motion on the plane (so ṗ = 0 as (11) assumes), an observer estimate that
    # differs from it, a desired trajectory and a force integral, with closed-form derivatives.
    q_c = arm.ik([model.c[0], 0.0, 0.55])
    a = np.array([1e-3, -2e-3, 1.5e-3])

    def motion(t):
        x = np.array([model.c[0], 0.03 * np.sin(1.3 * t), 0.55 + 0.04 * np.cos(0.7 * t)])
        xdot = np.array([0.0, 0.039 * np.cos(1.3 * t), -0.028 * np.sin(0.7 * t)])
        q = arm.ik(x)
        return q, np.linalg.solve(arm.jacobian(q), xdot)

    def signals(t):
        q, qdot = motion(t)
        q_hat = q + 1e-3 * np.array([np.sin(2 * t), np.cos(3 * t), np.sin(t)])
        qdot_hat = qdot + 1e-3 * np.array([2 * np.cos(2 * t), -3 * np.sin(3 * t), np.cos(t)])
        q_d = q_c + a * np.sin(0.8 * t)
        qdot_d = 0.8 * a * np.cos(0.8 * t)
        qddot_d = -0.64 * a * np.sin(0.8 * t)
        DF = 0.5 * np.sin(0.9 * t) + 0.2 * t
        dlam = 0.45 * np.cos(0.9 * t) + 0.2                 # Δλ̃ = d/dt ΔF̃
        return q, qdot, q_hat, qdot_hat, q_d, qdot_d, qddot_d, DF, dlam

    def qdot_r(t):
        q, _, q_hat, _, q_d, qdot_d, _, DF, _ = signals(t)
        J_pinv, Q = orthogonal.projections(model.J_phi(q))
        return orthogonal.reference_velocity(
            Q, J_pinv, q_hat=q_hat, q_d=q_d, qdot_d=qdot_d, Lambda=Lambda,
            Delta_p=model.phi(q), beta=beta, xi=xi, Delta_F_tilde=DF)

    for t in (0.3, 1.1, 2.7):
        q, qdot, q_hat, qdot_hat, q_d, qdot_d, qddot_d, DF, dlam = signals(t)
        J_phi, J_phi_dot = model.J_phi_and_derivative(q, qdot)   # q̇_o = q̇
        J_pinv, Q = orthogonal.projections(J_phi)
        J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J_phi, J_phi_dot)
        assert abs(model.phi(q)) < 1e-12 and abs((J_phi @ qdot)[0]) < 1e-12   # on the plane
        qddot_r_hat = orthogonal.reference_acceleration(
            Q, J_pinv, Q_dot, J_pinv_dot, q_hat=q_hat, qdot_hat=qdot_hat, q_d=q_d,
            qdot_d=qdot_d, qddot_d=qddot_d, Lambda=Lambda, Delta_p=model.phi(q), beta=beta,
            xi=xi, Delta_F_tilde=DF, Delta_lambda_tilde=dlam)
        eps = 1e-5
        numeric = (qdot_r(t + eps) - qdot_r(t - eps)) / (2 * eps)
        assert np.linalg.norm(qddot_r_hat - numeric) <= 1e-6 * np.linalg.norm(numeric), (
            qddot_r_hat, numeric)


def test_one_constraint_shortcuts_are_lapacks_solve_and_inverse(model):
    """For m = 1, ``J⁺`` and ``A⁻¹`` skip NumPy's LAPACK wrappers: the results are the
    doubles ``np.linalg.solve`` and ``np.linalg.inv`` give, to 4 ulp. Error bound: the
    shortcut's ``b · (1/a)`` is within 1.5 ulp of ``b/a`` and LAPACK's quotient within
    1.5 ulp (a division, or OpenBLAS's reciprocal of the pivot and a product: then the same
    bits; which one depends on the BLAS build and CPU kernel, so bits are not asserted)."""
    ulp4 = 4 * np.finfo(float).eps
    rng = np.random.default_rng(3)
    for q in random_postures(model, count=200, seed=4):
        J_phi = model.J_phi(q) * rng.uniform(0.2, 5.0)
        A = J_phi @ J_phi.T
        J_pinv, _ = orthogonal.projections(J_phi)
        np.testing.assert_allclose(J_pinv, np.linalg.solve(A, J_phi).T, rtol=ulp4, atol=0)
        np.testing.assert_allclose(orthogonal._inverse(A), np.linalg.inv(A), rtol=ulp4, atol=0)
    # More than one constraint goes through LAPACK itself.
    J2 = rng.normal(size=(2, 3))
    np.testing.assert_allclose(orthogonal.projections(J2)[0], np.linalg.pinv(J2),
                               rtol=1e-12, atol=1e-12)
