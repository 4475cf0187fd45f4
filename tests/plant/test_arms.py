"""Kinematics and dynamics of the two arms.

Closed forms of :class:`drake_coop.plant.arms.Arm` against the published lengths, finite differences
and the MultibodyPlant built from the URDF (:class:`drake_coop.control.arm_model.ArmModel`); inverse
kinematics; the properties of H, C, g and J_φ used by the controller; reachability of the paper's
whole reference path; the URDF files against ``urdf/generate.py``.
"""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable

from drake_coop.plant.arms import arm_model
from drake_coop.scenario.task_path import cartesian_reference
from drake_coop.plant.arms import Arm, urdf_dir
from drake_coop.kinematics.crs import GEOMETRY, urdf_joint_limits
from drake_coop.scenario import default_scenario, paper_robots

ROBOTS = paper_robots()
#: Base plate to shoulder, upper arm, forearm, wrist to flange (m): CRS A465 / A255 manuals.
PUBLISHED = {
    "crs_a465": (0.3302, 0.3048, 0.3302, 0.0762),
    "crs_a255": (0.254, 0.254, 0.254, 0.051),
}
EPS = 1e-6            # step of the central finite differences


@pytest.fixture(scope="module", params=[0, 1], ids=["robot1", "robot2"])
def arm_and_model(request):
    arm = Arm(ROBOTS[request.param])
    # Drake's kinematics (AutoDiff J̇_φ): checked here against the closed form, independently.
    return arm, arm_model(arm, closed_form=False)


def _postures(arm, count=30, seed=0, fraction=0.9):
    """Random joint positions within ``fraction`` of the joint limits."""
    rng = np.random.default_rng(seed)
    return rng.uniform(arm.q_min * fraction, arm.q_max * fraction, size=(count, 3))


def _load_generate():
    spec = importlib.util.spec_from_file_location(
        "urdf_generate", Path(__file__).resolve().parents[2] / "urdf" / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# ------------------------------------------------------------------ lengths and the URDF files
def test_geometry_uses_the_published_lengths(arm_and_model):
    arm, _ = arm_and_model
    g = arm.geometry
    assert (g.h1, g.L2, g.L_forearm, g.L_flange) == PUBLISHED[arm.robot.model]
    assert g.L3 == pytest.approx(g.L_forearm + g.L_flange + g.L_sensor + g.r_pad, abs=1e-15)


def test_urdf_files_are_the_output_of_generate_py_with_the_same_lengths():
    gen = _load_generate()
    for model, p in gen.ARMS.items():
        text = (urdf_dir() / f"{model}_3dof.urdf").read_text()
        assert text == gen.arm_urdf(model, p), f"{model}: run python urdf/generate.py"
        g = GEOMETRY[model]
        assert (p["h1"], p["L2"], p["L_forearm"], p["L_flange"]) == PUBLISHED[model]
        assert (g.L_sensor, g.r_pad) == (gen.SENSOR["length"], gen.PAD["radius"])
        limits = urdf_joint_limits(urdf_dir() / f"{model}_3dof.urdf")   # what the arms use
        np.testing.assert_allclose(np.radians(p["limits_deg"]), np.column_stack(limits),
                                   atol=1e-15)


@pytest.mark.parametrize("q, local", [
    ((0.0, 0.0, 0.0), lambda h1, L2, L3: [0.0, 0.0, h1 + L2 + L3]),             # straight up
    ((0.0, math.pi / 2, 0.0), lambda h1, L2, L3: [L2 + L3, 0.0, h1]),           # horizontal
    ((0.0, math.pi / 2, -math.pi / 2), lambda h1, L2, L3: [L2, 0.0, h1 + L3]),  # forearm up
    ((0.0, math.pi / 2, math.pi / 2), lambda h1, L2, L3: [L2, 0.0, h1 - L3]),   # forearm down
    ((math.pi / 2, math.pi / 2, 0.0), lambda h1, L2, L3: [0.0, L2 + L3, h1]),   # waist 90°
    ((0.0, -math.pi / 4, 0.0), lambda h1, L2, L3: [-(L2 + L3) / math.sqrt(2), 0.0,
                                                   h1 + (L2 + L3) / math.sqrt(2)]),
], ids=["up", "horizontal", "forearm-up", "forearm-down", "waist-90", "lean-back"])
def test_forward_kinematics_of_closed_form_and_plant_equal_the_lengths(arm_and_model, q, local):
    arm, model = arm_and_model
    g = arm.geometry
    expected = arm.p_base + arm.R_base @ np.array(local(g.h1, g.L2, g.L3))
    np.testing.assert_allclose(arm.fk(np.array(q)), expected, atol=1e-12)
    np.testing.assert_allclose(model.ee_position(np.array(q)), expected, atol=1e-12)


def test_closed_form_forward_kinematics_equals_the_plant(arm_and_model):
    arm, model = arm_and_model
    for q in _postures(arm):
        np.testing.assert_allclose(arm.fk(q), model.ee_position(q), atol=1e-12)


# ------------------------------------------------------------------------------- Jacobians
def test_closed_form_jacobian_equals_the_plant(arm_and_model):
    arm, model = arm_and_model
    plant, ctx = model.plant, model.context
    for q in _postures(arm):
        plant.SetPositions(ctx, q)
        J = plant.CalcJacobianTranslationalVelocity(
            ctx, JacobianWrtVariable.kV, model.ee_frame, np.zeros(3), plant.world_frame(),
            plant.world_frame())
        np.testing.assert_allclose(arm.jacobian(q), J, atol=1e-12)


def test_closed_form_jacobian_equals_finite_differences_of_fk(arm_and_model):
    arm, _ = arm_and_model
    for q in _postures(arm, 10, seed=1):
        fd = np.column_stack([(arm.fk(q + EPS * e) - arm.fk(q - EPS * e)) / (2 * EPS)
                              for e in np.eye(3)])
        np.testing.assert_allclose(arm.jacobian(q), fd, atol=1e-8)


def test_jacobian_dot_equals_finite_difference_of_the_jacobian_along_v(arm_and_model):
    arm, _ = arm_and_model
    rng = np.random.default_rng(2)
    for q in _postures(arm, 10, seed=3):
        v = rng.normal(size=3)
        fd = (arm.jacobian(q + EPS * v) - arm.jacobian(q - EPS * v)) / (2 * EPS)
        np.testing.assert_allclose(arm.jacobian_dot(q, v), fd, atol=1e-8)


# ---------------------------------------------------------------------- inverse kinematics
def test_inverse_kinematics_round_trip_over_random_workspace_points(arm_and_model):
    arm, _ = arm_and_model
    g = arm.geometry
    rng = np.random.default_rng(4)
    # Points in the shell between 0.3 and 0.98 of the full reach around the shoulder.
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    radius = (g.L2 + g.L3) * rng.uniform(0.3, 0.98, size=(3000, 1))
    local = d * radius + np.array([0.0, 0.0, g.h1])
    local = local[np.hypot(local[:, 0], local[:, 1]) > 0.01]      # off the waist axis
    p = local @ arm.R_base.T + arm.p_base
    q = arm.ik(p)
    assert np.abs(arm.fk(q) - p).max() < 1e-9
    assert np.all(q[:, 2] > 0)                                      # elbow up


def test_inverse_kinematics_recovers_elbow_up_postures(arm_and_model):
    arm, _ = arm_and_model
    g = arm.geometry
    rng = np.random.default_rng(5)
    q = np.column_stack([rng.uniform(-2.5, 2.5, 800), rng.uniform(-1.2, 1.4, 800),
                         rng.uniform(0.15, 1.9, 800)])
    # The branch of the paper's postures: the arm faces the point (r > 0), elbow up.
    r = g.L2 * np.sin(q[:, 1]) + g.L3 * np.sin(q[:, 1] + q[:, 2])
    q = q[r > 0.05]
    assert len(q) > 300
    np.testing.assert_allclose(arm.ik(arm.fk(q)), q, atol=1e-7)


def test_inverse_kinematics_rejects_a_point_out_of_reach(arm_and_model):
    arm, _ = arm_and_model
    g = arm.geometry
    with pytest.raises(ValueError, match="out of reach"):
        arm.ik(arm.p_base + np.array([0.0, 0.0, g.h1 + g.L2 + g.L3 + 0.01]))


# ------------------------------------------------------------------------------- dynamics
def test_inertia_matrix_is_symmetric_positive_definite_and_heavy_enough(arm_and_model):
    arm, model = arm_and_model
    # Full joint range, plus q = 0 (arm straight up), where λ_min(H) is smallest: the waist
    # inertia N² J_m + Σ I_zz.
    postures = np.vstack([np.zeros(3), _postures(arm, 300, seed=6, fraction=1.0)])
    eig_min = np.inf
    for q in postures:
        H = model.H(q)
        np.testing.assert_allclose(H, H.T, atol=1e-14)
        eig_min = min(eig_min, np.linalg.eigvalsh(H)[0])
    # The paper's K_R at h = 9 ms needs h K_R / λ_min(H) < 2 (see urdf/README.md).
    K_R = arm.robot.gains.K_R[0]
    assert eig_min > 0.4, f"λ_min(H) = {eig_min:.4f} kg·m²"
    assert eig_min > 0.009 * K_R / 2, f"λ_min(H) = {eig_min:.4f} kg·m²"


def test_coriolis_term_is_quadratic_in_velocity(arm_and_model):
    arm, model = arm_and_model
    rng = np.random.default_rng(7)
    for q in _postures(arm, 8, seed=8):
        v = rng.normal(size=3)
        Cv = model.Cv(q, v)
        assert np.abs(Cv).max() > 1e-3                              # not trivially zero
        np.testing.assert_allclose(model.Cv(q, 2 * v), 4 * Cv, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(model.Cv(q, -v), Cv, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(model.Cv(q, np.zeros(3)), 0.0, atol=1e-14)


def test_inertia_rate_minus_twice_coriolis_is_skew_symmetric_along_v(arm_and_model):
    arm, model = arm_and_model
    rng = np.random.default_rng(9)
    for q in _postures(arm, 8, seed=10):
        v = rng.normal(size=3)
        H_dot = (model.H(q + EPS * v) - model.H(q - EPS * v)) / (2 * EPS)
        # vᵀ(Ḣ − 2C)v = 0 with C(q,v)v the plant's bias term.
        residual = v @ (H_dot @ v - 2 * model.Cv(q, v))
        assert abs(residual) < 1e-6 * (1 + abs(v @ H_dot @ v)), residual


def test_gravity_vector_is_the_gradient_of_the_potential_energy(arm_and_model):
    arm, model = arm_and_model
    plant, ctx = model.plant, model.context

    def potential(x):
        plant.SetPositions(ctx, x)
        return plant.CalcPotentialEnergy(ctx)

    for q in _postures(arm, 8, seed=11):
        grad = np.array([(potential(q + EPS * e) - potential(q - EPS * e)) / (2 * EPS)
                         for e in np.eye(3)])
        np.testing.assert_allclose(model.g(q), grad, atol=1e-6)


# ---------------------------------------------------------------------------- constraint
def test_constraint_jacobian_is_the_signed_x_row_of_the_jacobian(arm_and_model):
    arm, model = arm_and_model
    for q in _postures(arm, 10, seed=12):
        expected = arm.s * arm.jacobian(q)[0:1, :]
        np.testing.assert_allclose(model.J_phi(q), expected, atol=1e-12)
        np.testing.assert_allclose(arm.J_phi(q), expected, atol=1e-15)
        assert model.phi(q) == pytest.approx(arm.s * (arm.fk(q)[0] - arm.b), abs=1e-12)


def test_constraint_jacobian_derivative_equals_finite_difference(arm_and_model):
    arm, model = arm_and_model
    rng = np.random.default_rng(13)
    for q in _postures(arm, 10, seed=14):
        d = rng.normal(size=3)
        J, dJ = model.J_phi_and_derivative(q, d)
        np.testing.assert_allclose(J, model.J_phi(q), atol=1e-12)
        np.testing.assert_allclose(dJ, arm.s * arm.jacobian_dot(q, d)[0:1, :], atol=1e-12)
        fd = (model.J_phi(q + EPS * d) - model.J_phi(q - EPS * d)) / (2 * EPS)
        assert np.linalg.norm(dJ - fd) < 1e-6 * np.linalg.norm(fd), (dJ, fd)


@pytest.mark.parametrize("index", [0, 1], ids=["robot1", "robot2"])
def test_paper_arms_model_uses_the_closed_form_equal_to_drakes_kinematics(index):
    arm = Arm(ROBOTS[index])
    fast, drake = arm_model(arm), arm_model(arm, closed_form=False)
    assert fast.closed_form and not drake.closed_form
    rng = np.random.default_rng(20 + index)
    for q in _postures(arm, 10, seed=21):
        d = rng.normal(size=3)
        for a, b in zip(fast.J_phi_and_derivative(q, d), drake.J_phi_and_derivative(q, d)):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)
        np.testing.assert_allclose(fast.phi(q), drake.phi(q), rtol=0, atol=1e-13)


def test_inverse_dynamics_call_equals_H_a_plus_C_v_plus_D_v_plus_g(arm_and_model):
    """One ``CalcInverseDynamics`` with the force elements (gravity, joint damping) against the
    separate terms of (1) from Drake's mass matrix, bias term and gravity."""
    arm, model = arm_and_model
    plant, context = model.plant, model.plant.CreateDefaultContext()
    rng = np.random.default_rng(22)
    assert np.all(np.diag(model.D) > 0)     # the damping term is exercised
    for q in _postures(arm, 5, seed=23):
        v, a = rng.normal(size=(2, 3))
        plant.SetPositions(context, q)
        plant.SetVelocities(context, v)
        expected = (plant.CalcMassMatrix(context) @ a + plant.CalcBiasTerm(context)
                    + model.D @ v - plant.CalcGravityGeneralizedForces(context))
        np.testing.assert_allclose(model.inverse_dynamics_terms(q, v, a), expected,
                                   rtol=0, atol=1e-13 * np.abs(expected).max())


# --------------------------------------------------------------------------- paper's path
@pytest.mark.parametrize("index", [0, 1], ids=["robot1", "robot2"])
def test_whole_circle_is_reachable_within_the_joint_limits(index):
    robot = ROBOTS[index]
    arm = Arm(robot)
    theta = np.linspace(0, 2 * np.pi, 721)
    circle = np.column_stack([np.full_like(theta, robot.contact_xy[0]), 0.05 * np.sin(theta),
                              0.635 - 0.05 + 0.05 * np.cos(theta)])     # (28)
    q = arm.ik(circle)
    np.testing.assert_allclose(arm.fk(q), circle, atol=1e-9)
    assert np.all(q >= arm.q_min) and np.all(q <= arm.q_max)
    assert np.all(arm.reach_ratio(circle) < 0.9)


@pytest.mark.parametrize("index", [0, 1], ids=["robot1", "robot2"])
def test_whole_reference_path_is_reachable_away_from_singularities(index):
    s = default_scenario()
    robot = s.robots[index]
    arm = Arm(robot)
    t = np.arange(0.0, s.task.t_end + 1e-9, 0.05)
    x, _, _ = cartesian_reference(s.task, robot, t)
    q = arm.ik(x)
    np.testing.assert_allclose(arm.fk(q), x, atol=1e-9)
    assert np.all(q >= arm.q_min) and np.all(q <= arm.q_max)
    sigma = np.linalg.svd(arm.jacobian(q), compute_uv=False)[:, -1]
    print(f"{robot.name}: smallest singular value of the position Jacobian on the path "
          f"{sigma.min():.3f} m")
    assert sigma.min() > 0.05


def test_one_sample_on_plain_floats_equals_the_batched_closed_form():
    """``fk``, ``jacobian`` and ``jacobian_dot`` take a plain-float path for one sample (the
    controller's); it gives the batched NumPy evaluation's values to rounding."""
    for robot in paper_robots():
        arm = Arm(robot)
        rng = np.random.default_rng(3)
        Q, V = rng.uniform(-1.2, 1.2, (8, 3)), rng.normal(size=(8, 3))
        fk, J, Jd = arm.fk(Q), arm.jacobian(Q), arm.jacobian_dot(Q, V)
        for k in range(len(Q)):
            np.testing.assert_allclose(arm.fk(Q[k]), fk[k], rtol=0, atol=1e-15)
            np.testing.assert_allclose(arm.jacobian(Q[k]), J[k], rtol=0, atol=1e-15)
            np.testing.assert_allclose(arm.jacobian_dot(Q[k], V[k]), Jd[k], rtol=0, atol=1e-14)


def test_shipped_arm_models_are_the_models_the_scenario_files_name_each_once():
    """Every ``model:`` of the shipped scenario files (read as plain YAML; a file without
    ``robots`` has the paper's, ``paper.yaml``'s), first met in name order, the lab arms'
    only with the robots extra; each URDF has the base link and the sensor joint it is
    given with."""
    import xml.etree.ElementTree as ET

    import yaml

    from drake_coop.control.arm_plant import description_packages
    from drake_coop.plant.arms import shipped_arm_models

    root = Path(__file__).resolve().parents[2]
    have_robots = "example-robot-data" in description_packages()
    paper = yaml.safe_load((root / "scenarios" / "paper.yaml").read_text())["robots"]
    expected: list[str] = []
    for path in sorted((root / "scenarios").glob("*.yaml")):
        for robot in yaml.safe_load(path.read_text()).get("robots", paper):
            model = robot.get("model", "crs_a465")        # a robot's default model
            if model not in expected and (have_robots or "://" not in model):
                expected.append(model)
    models = shipped_arm_models()
    assert list(models) == expected
    assert {"crs_a465", "crs_a255", "coop6"} <= set(models)
    for model, (urdf, base, sensor) in models.items():
        tree = ET.parse(urdf).getroot()
        assert base in {link.get("name") for link in tree.iter("link")}, model
        assert sensor in {joint.get("name") for joint in tree.iter("joint")}, model
