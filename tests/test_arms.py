"""Kinematics and dynamics of the two arms: published lengths, closed forms against the plant,
inverse kinematics, H(q) and reachability of the paper's path."""

import math

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable

from drake_coop.arm_model import ArmModel
from drake_coop.arms import GEOMETRY, Arm
from drake_coop.references import cartesian_reference
from drake_coop.scenario import default_scenario, paper_robots

ROBOTS = paper_robots()
PUBLISHED = {  # base plate to shoulder, upper arm, forearm, wrist to flange (m)
    "crs_a465": (0.3302, 0.3048, 0.3302, 0.0762),
    "crs_a255": (0.254, 0.254, 0.254, 0.051),
}


@pytest.fixture(scope="module", params=[0, 1], ids=["robot1", "robot2"])
def arm_and_model(request):
    arm = Arm(ROBOTS[request.param])
    return arm, ArmModel(arm)


def _postures(arm, count=30, seed=0):
    g = arm.geometry
    rng = np.random.default_rng(seed)
    lo, hi = np.array(g.q_min) * 0.9, np.array(g.q_max) * 0.9
    return rng.uniform(lo, hi, size=(count, 3))


def test_forward_kinematics_matches_the_published_lengths(arm_and_model):
    arm, model = arm_and_model
    h1, L2, L_fore, L_flange = PUBLISHED[arm.robot.model]
    g = arm.geometry
    L3 = L_fore + L_flange + g.L_sensor + g.r_pad
    assert (g.h1, g.L2, g.L_forearm, g.L_flange) == (h1, L2, L_fore, L_flange)
    cases = {
        (0.0, 0.0, 0.0): [0.0, 0.0, h1 + L2 + L3],                 # straight up
        (0.0, math.pi / 2, 0.0): [L2 + L3, 0.0, h1],               # horizontal, forward
        (0.0, math.pi / 2, -math.pi / 2): [L2, 0.0, h1 + L3],      # forearm back up
        (math.pi / 2, math.pi / 2, 0.0): [0.0, L2 + L3, h1],       # waist turned 90°
    }
    for q, local in cases.items():
        expected = arm.p_base + arm.R_base @ np.array(local)
        np.testing.assert_allclose(arm.fk(np.array(q)), expected, atol=1e-12)
        np.testing.assert_allclose(model.ee_position(np.array(q)), expected, atol=1e-12)


def test_closed_form_kinematics_equal_the_plant(arm_and_model):
    arm, model = arm_and_model
    plant, ctx = model.plant, model.context
    for q in _postures(arm):
        np.testing.assert_allclose(arm.fk(q), model.ee_position(q), atol=1e-12)
        plant.SetPositions(ctx, q)
        J = plant.CalcJacobianTranslationalVelocity(
            ctx, JacobianWrtVariable.kV, model.ee_frame, np.zeros(3), plant.world_frame(),
            plant.world_frame())
        np.testing.assert_allclose(arm.jacobian(q), J, atol=1e-12)


def test_jacobian_and_its_derivative_match_finite_differences(arm_and_model):
    arm, _ = arm_and_model
    rng = np.random.default_rng(1)
    eps = 1e-6
    for q in _postures(arm, 10):
        fd = np.column_stack([(arm.fk(q + eps * e) - arm.fk(q - eps * e)) / (2 * eps)
                              for e in np.eye(3)])
        np.testing.assert_allclose(arm.jacobian(q), fd, atol=1e-8)
        v = rng.normal(size=3)
        fd_dot = (arm.jacobian(q + eps * v) - arm.jacobian(q - eps * v)) / (2 * eps)
        np.testing.assert_allclose(arm.jacobian_dot(q, v), fd_dot, atol=1e-8)


def test_inverse_kinematics_round_trip_on_the_elbow_up_branch(arm_and_model):
    arm, _ = arm_and_model
    rng = np.random.default_rng(2)
    g = arm.geometry
    q = np.column_stack([rng.uniform(-2.5, 2.5, 800), rng.uniform(-1.2, 1.4, 800),
                         rng.uniform(0.15, 1.9, 800)])
    # The branch of the paper's postures: the arm faces the point (r > 0) with the elbow up.
    r = g.L2 * np.sin(q[:, 1]) + g.L3 * np.sin(q[:, 1] + q[:, 2])
    q = q[r > 0.05]
    assert len(q) > 300
    p = arm.fk(q)
    back = arm.ik(p)
    assert np.abs(arm.fk(back) - p).max() < 1e-9
    assert np.all(back[:, 2] > 0)                                  # elbow up
    np.testing.assert_allclose(back, q, atol=1e-7)
    with pytest.raises(ValueError, match="out of reach"):
        arm.ik(arm.p_base + np.array([0.0, 0.0, g.h1 + g.L2 + g.L3 + 0.01]))


def test_inertia_matrix_is_symmetric_positive_definite(arm_and_model):
    arm, model = arm_and_model
    eig_min = np.inf
    for q in _postures(arm, 200, seed=3):
        H = model.H(q)
        np.testing.assert_allclose(H, H.T, atol=1e-14)
        eig_min = min(eig_min, np.linalg.eigvalsh(H)[0])
    # Heavy enough for the paper's gains at h = 9 ms: h K_R / λ_min(H) < 2.
    K_R = arm.robot.gains.K_R[0]
    assert eig_min > 0.009 * K_R / 2, eig_min


def test_coriolis_and_gravity_are_consistent_with_energy(arm_and_model):
    arm, model = arm_and_model
    plant, ctx = model.plant, model.context
    rng = np.random.default_rng(4)
    eps = 1e-6
    for q in _postures(arm, 8, seed=5):
        v = rng.normal(size=3)
        Cv = model.Cv(q, v)
        np.testing.assert_allclose(model.Cv(q, 2 * v), 4 * Cv, rtol=1e-10, atol=1e-12)
        # Skew symmetry of Ḣ − 2C along v: vᵀ(Ḣ v − 2 C(q,v) v) = 0.
        H_dot = (model.H(q + eps * v) - model.H(q - eps * v)) / (2 * eps)
        assert abs(v @ (H_dot @ v - 2 * Cv)) < 1e-6 * (1 + abs(v @ H_dot @ v))
        # g(q) is the gradient of the potential energy.
        def potential(x):
            plant.SetPositions(ctx, x)
            return plant.CalcPotentialEnergy(ctx)
        grad = np.array([(potential(q + eps * e) - potential(q - eps * e)) / (2 * eps)
                         for e in np.eye(3)])
        np.testing.assert_allclose(model.g(q), grad, atol=1e-6)


def test_every_target_of_the_paper_is_reachable_away_from_singularities():
    s = default_scenario()
    t = np.arange(0.0, s.task.t_end + 1e-9, 0.05)
    for robot in s.robots:
        arm = Arm(robot)
        x, _, _ = cartesian_reference(s.task, robot, t)
        q = arm.ik(x)
        np.testing.assert_allclose(arm.fk(q), x, atol=1e-9)
        g = GEOMETRY[robot.model]
        assert np.all(q >= np.array(g.q_min)) and np.all(q <= np.array(g.q_max))
        sigma = np.linalg.svd(arm.jacobian(q), compute_uv=False)[:, -1]
        print(f"{robot.name}: smallest singular value of the position Jacobian on the path "
              f"{sigma.min():.3f} m")
        assert sigma.min() > 0.05
        # The whole circle (28), densely.
        theta = np.linspace(0, 2 * np.pi, 721)
        circle = np.column_stack([np.full_like(theta, robot.plane_b), 0.05 * np.sin(theta),
                                  0.635 - 0.05 + 0.05 * np.cos(theta)])
        assert np.all(arm.reach_ratio(circle) < 0.9)
        np.testing.assert_allclose(arm.fk(arm.ik(circle)), circle, atol=1e-9)
