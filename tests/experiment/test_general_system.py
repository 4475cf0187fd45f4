"""The paper's general system: l robots, n_i joints, m_i constraints.

Independent checks: the constraint Jacobian of the controller's model against the closed-form
kinematics, a NumPy replay of (4), (8), (11), (13), (15)-(16), (22) with NumPy's SVD
pseudo-inverse for m = 2 and 3, the rotational symmetry of three arms around one object, the
6-joint arm's orientation reference, and the bad inputs found in review (exit 2, one line).
"""

import subprocess
import sys

import numpy as np
import pytest

from drake_coop.plant.arms import arm_model
from drake_coop.experiment.plan import plan_run
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.experiment.simulate import simulate
from drake_coop.plant.arms import Arm
from drake_coop.scenario import ScenarioError, Task, load_scenario

from tests.conftest import short_scenario

#: Normals of the m = 2 and m = 3 cases: a vertical line, and a point held in place.
NORMALS = {1: [[-1.0, 0.0, 0.0]], 2: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
           3: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]}


def multi_constraint_scenario():
    """The paper's short scenario with robot 1 on m = 2 planes (ξ a full 2×2 matrix) and robot
    2 on m = 3 (its contact point held in place): no lift and no circle, the squeeze (29) on
    the first row."""
    s = short_scenario(lift_height=0.0, circle_radius=0.0)
    r1, r2 = s.robots
    r1.normals = NORMALS[2]
    r1.force_weights = [1.0, 0.25]
    r1.gains.xi_matrix = [[2e-5, 5e-6], [5e-6, 1e-5]]
    r2.normals = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    r2.force_weights = [1.0, 0.0, 0.0]
    return s


# ----------------------------------------------------------------------- the model's J_φ
@pytest.mark.parametrize("m", [1, 2, 3])
def test_constraint_jacobian_is_N_times_the_closed_form_jacobian(m):
    robot = load_scenario().robots[0]
    robot.normals = NORMALS[m]
    arm = Arm(robot)
    model = arm_model(arm, closed_form=False)     # Drake's kinematics against the closed form
    rng = np.random.default_rng(m)
    for q in arm.ik([0.6, 0.0, 0.535]) + rng.uniform(-0.3, 0.3, size=(5, 3)):
        N = np.asarray(NORMALS[m])
        np.testing.assert_allclose(model.J_phi(q), N @ arm.jacobian(q), rtol=0, atol=1e-13)
        np.testing.assert_allclose(model.phi(q), N @ (arm.fk(q) - arm.c), rtol=0, atol=1e-13)
        v = rng.normal(size=3)
        J, J_dot = model.J_phi_and_derivative(q, v)
        np.testing.assert_allclose(J_dot, N @ arm.jacobian_dot(q, v), rtol=0, atol=1e-12)


def test_reference_layout_owns_the_rows():
    layout = ReferenceLayout(6, 2)
    assert layout.size == 6 * 3 + 2 + 1
    K = 4
    parts = [np.full((K, 6), 1.0), np.full((K, 6), 2.0), np.full((K, 6), 3.0),
             np.full((K, 2), 4.0), np.array([0, 1, 1, 0])]
    r = layout.pack(*parts)
    ref = layout.unpack(r[1])
    assert ref.q_d.tolist() == [1.0] * 6 and ref.qddot_d.tolist() == [3.0] * 6
    assert ref.lambda_d.tolist() == [4.0, 4.0] and ref.held
    assert not layout.unpack(r[0]).held
    np.testing.assert_array_equal(layout.column(r, "qdot_d"), parts[1])


# ----------------------------------------------------------------------- replay, m = 2, 3
def _replay(scenario, index, q_log):
    """(4), (8), (11), (13), (15)-(16), (22) as a plain loop for any m, with J⁺ from NumPy's
    SVD pseudo-inverse and J̇_φ from the closed-form kinematics (not the package's code)."""
    from pydrake.math import RigidTransform, RotationMatrix
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    robot = scenario.robots[index]
    arm = Arm(robot, scenario.task)
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(arm.urdf_path))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"),
                     RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base))
    plant.Finalize()
    pc = plant.CreateDefaultContext()
    D = np.diag([plant.get_joint(j).default_damping() for j in plant.GetJointIndices()
                 if plant.get_joint(j).num_velocities() == 1])
    g, h = robot.gains, scenario.control_period
    N = np.asarray(robot.normals, float)
    N = N / np.linalg.norm(N, axis=1, keepdims=True)
    m = N.shape[0]
    xi = np.eye(m) * g.xi if g.xi_matrix is None else np.asarray(g.xi_matrix)
    Lam, KR, kd, kF, zeta, beta = g.Lambda, np.diag(g.K_R), g.k_d, g.k_F, g.zeta, g.beta
    _, ref = plan_run(scenario).robots[index].samples
    q_hat, qdot_hat_o, DF = q_log[0].copy(), np.zeros(3), np.zeros(m)
    out = {"tau": [], "q_hat": [], "lambda_hat": []}
    for k, q in enumerate(q_log):
        q_d, qdot_d, qddot_d = ref[k, 0:3], ref[k, 3:6], ref[k, 6:9]
        lam_d, held = ref[k, 9:9 + m], ref[k, 9 + m] > 0.5
        z = q - q_hat
        qdot_hat = qdot_hat_o + Lam * z + kd * z                   # (15)
        qdot_o = qdot_hat - Lam * z                                # (8)
        if held:
            J = N @ arm.jacobian(q)
            Jp = np.linalg.pinv(J)
            Q = np.eye(3) - Jp @ J
            phi = N @ (arm.fk(q) - arm.c)
            qdot_r = Q @ (qdot_d - Lam * (q_hat - q_d)) + Jp @ (-beta * phi + xi @ DF)    # (4)
            lam_hat = (Jp.T @ KR @ (qdot_o - qdot_r) - kF * DF) / (1 + zeta) + lam_d     # (22)
            dlt = lam_hat - lam_d
            Jd = N @ arm.jacobian_dot(q, qdot_o)
            A_inv = np.linalg.inv(J @ J.T)
            Jpd = Jd.T @ A_inv - J.T @ A_inv @ (Jd @ J.T + J @ Jd.T) @ A_inv
            Qd = -(Jpd @ J + Jp @ Jd)
            qddot_r = (Q @ (qddot_d - Lam * (qdot_hat - qdot_d)) + Jp @ (xi @ dlt)
                       + Qd @ (qdot_d - Lam * (q_hat - q_d)) + Jpd @ (-beta * phi + xi @ DF))
            force_term = J.T @ (lam_d - kF * DF - zeta * dlt)
        else:
            qdot_r = qdot_d - Lam * (q_hat - q_d)
            qddot_r = qddot_d - Lam * (qdot_hat - qdot_d)
            lam_hat, force_term = np.zeros(m), np.zeros(3)
        plant.SetPositions(pc, q)
        plant.SetVelocities(pc, qdot_r)
        tau = (plant.CalcMassMatrix(pc) @ qddot_r + plant.CalcBiasTerm(pc) + D @ qdot_r
               - plant.CalcGravityGeneralizedForces(pc) - KR @ (qdot_o - qdot_r) - force_term)
        out["tau"].append(tau)
        out["q_hat"].append(q_hat.copy())
        out["lambda_hat"].append(lam_hat)
        q_hat = q_hat + h * qdot_hat
        qdot_hat_o = qdot_hat_o + h * (qddot_r + kd * Lam * z)
        DF = DF + h * (lam_hat - lam_d) if held else np.zeros(m)
    return {k: np.array(v) for k, v in out.items()}


@pytest.fixture(scope="module")
def multi_run():
    s = multi_constraint_scenario()
    return s, simulate(s)


@pytest.mark.slow
@pytest.mark.parametrize("index, m", [(0, 2), (1, 3)], ids=["m2", "m3"])
def test_numpy_replay_reproduces_the_run_for_m_constraints(multi_run, index, m):
    scenario, result = multi_run
    assert result.ok, result.meta["message"]
    log = result.logs[scenario.robots[index].name]
    assert log["lambda_hat"].shape == (log["t"].size, m)
    replay = _replay(scenario, index, log["q"])
    held = plan_run(scenario).robots[index].samples[1][: log["t"].size, 9 + m] > 0.5
    assert held.sum() > 100 and (~held).sum() > 100
    # 1e-11 of each signal's largest magnitude (the same equations in other operation
    # orders: SVD vs the package's normal equations, closed-form vs Drake kinematics).
    for key in ("q_hat", "lambda_hat", "tau"):
        scale = np.abs(log[key]).max()
        np.testing.assert_allclose(replay[key], log[key], rtol=0, atol=1e-11 * scale,
                                   err_msg=key)


@pytest.mark.slow
@pytest.mark.parametrize("index", [0, 1], ids=["m2", "m3"])
def test_every_constraint_row_tracks_its_desired_force(multi_run, index):
    """Theorem 1 per row: on the held phase λ follows λ_d = w f(t) on every row, and the
    contact point stays on its planes. (The compressed task's λ_d jumps at t_circle_end, where
    (29)'s sine is not back to zero: 0.2 s after each switch are left out.)"""
    scenario, result = multi_run
    log = result.logs[scenario.robots[index].name]
    t, task = log["t"], scenario.task
    hold = (((t > task.t_grasp + 0.5) & (t < task.t_circle_end))
            | ((t > task.t_circle_end + 0.2) & (t < task.t_release)))
    err = log["lambda_meas"][hold] - log["lambda_d"][hold]
    assert np.abs(err).max() < 0.5, np.abs(err).max(axis=0)
    arm = Arm(scenario.robots[index], scenario.task)
    assert np.abs((log["x"][hold] - arm.c) @ arm.N.T).max() < 1e-3


# ----------------------------------------------------------------------- demonstrations
def _compressed(name):
    s = load_scenario(name)
    s.task = Task(**{**s.task.__dict__, **dict(
        t_pregrasp=0.6, t_grasp=1.0, t_circle_start=2.0, t_circle_end=6.0, t_release=7.0,
        t_end=8.0)})
    return s


@pytest.mark.slow
def test_three_arms_squeeze_and_carry_the_object_symmetrically():
    """Three identical arms 120° apart: each one's run is the others' rotated, and each
    follows the vertical dip while squeezing with (29)."""
    s = _compressed("scenarios/three_arms.yaml")
    result = simulate(s)
    assert result.ok, result.meta["message"]
    logs = [result.logs[r.name] for r in s.robots]
    for log in logs[1:]:
        np.testing.assert_allclose(log["lambda_meas"], logs[0]["lambda_meas"], atol=1e-6)
        np.testing.assert_allclose(log["q"], logs[0]["q"], atol=1e-8)
    t = logs[0]["t"]
    circle = (t >= s.task.t_circle_start) & (t < s.task.t_circle_end)
    z = logs[0]["x"][circle, 2]
    assert z.max() - z.min() == pytest.approx(2 * s.task.circle_radius, abs=2e-3)
    err = logs[0]["lambda_meas"][circle] - logs[0]["lambda_d"][circle]
    assert np.abs(err).max() < 0.5


@pytest.mark.slow
def test_six_joint_arm_holds_its_orientation_and_squeezes():
    from drake_coop.kinematics.drake_arm import DrakeArmKinematics  # noqa: F401  (the arm's kind)

    s = _compressed("scenarios/six_joint.yaml")
    result = simulate(s)
    assert result.ok, result.meta["message"]
    log = result.logs["robot1"]
    assert log["q"].shape[1] == 6
    arm = Arm(s.robots[0], s.task)
    R = arm.kinematics.rotation(log["q"])
    R_d = arm.kinematics.R_d.matrix()
    angle = np.arccos(np.clip((np.trace(R_d.T @ R, axis1=1, axis2=2) - 1) / 2, -1, 1))
    assert angle.max() < 0.01, angle.max()           # rad, the whole run
    t = log["t"]
    circle = (t >= s.task.t_circle_start) & (t < s.task.t_circle_end)
    assert np.abs(log["lambda_meas"][circle] - log["lambda_d"][circle]).max() < 1.0
    assert np.abs(log["x"][circle] - log["x_d"][circle]).max() < 2e-3


# ----------------------------------------------------------------------- bad input
def _refused(mutate) -> str:
    s = load_scenario()
    mutate(s)
    from drake_coop.scenario.validation import validate

    with pytest.raises(ScenarioError) as info:
        validate(s)
    message = str(info.value)
    assert "\n" not in message and len(message) <= 300
    return message


@pytest.mark.parametrize("mutate, expected", [
    (lambda s: setattr(s.robots[0], "normals", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]]),
     "robots[0].normals has 4 rows; allowed 1 to 3"),
    (lambda s: setattr(s.robots[0], "normals", [[1, 0, 0], [-1, 0, 0]]),
     "robots[0].normals must be linearly independent"),
    (lambda s: setattr(s.robots[1], "normals", [[0, 0, 1]]),
     "robots[1].normals[0] must be orthogonal to the lift (z)"),
    (lambda s: setattr(s.robots[0], "ee_frame", "tool0"),
     "has no link named 'tool0' (robots[0].ee_frame)"),
    (lambda s: setattr(s.robots[1], "sensor_joint", "wrist"),
     "has no fixed joint named 'wrist'"),
    (lambda s: setattr(s.robots[0], "force_weights", [1.0, 0.5]),
     "robots[0].force_weights must have 1 entries"),
    (lambda s: setattr(s.robots[0].gains, "xi_matrix", [[1e-5, 0.0], [0.0, 1e-5]]),
     "robots[0].gains.xi_matrix must be 1x1"),
    (lambda s: (setattr(s.robots[0], "normals", NORMALS[2]),
                setattr(s.robots[0], "force_weights", [1.0, 0.0]),
                setattr(s.robots[1], "normals", [[1, 0, 0], [0, 1, 0]]),
                setattr(s.robots[1], "force_weights", [1.0, 0.0]),
                setattr(s.task, "circle_radius", 0.0),
                setattr(s.robots[0].gains, "xi_matrix", [[1e-5, 2e-5], [2e-5, 1e-5]])),
     "robots[0].gains.xi_matrix must be symmetric positive definite"),
    (lambda s: (setattr(s.robots[0], "model", "coop6"),
                setattr(s.robots[0].gains, "K_R", [100.0] * 6)),
     "robots[0].ee_rpy_deg must be given for a 6-joint arm"),
    (lambda s: setattr(s.robots[0], "ee_rpy_deg", [0.0, 90.0, 0.0]),
     "robots[0].ee_rpy_deg must be null for a 3-joint arm"),
    (lambda s: setattr(s, "robots", s.robots[:1]), "robots must list 2 to 8 robots"),
    (lambda s: setattr(s.robots[1], "home", [1.2, 0.0, 0.05]), "out of reach"),
    (lambda s: setattr(s.robots[0], "model", "arm.stl"),
     "robots[0].model must be one of crs_a465, crs_a255, coop6 or the path of a .urdf file"),
])
def test_bad_general_inputs_are_named_in_one_line(mutate, expected):
    assert expected in _refused(mutate)


def test_six_joint_arm_with_three_gains_is_named():
    def mutate(s):
        s.robots[0] = load_scenario("scenarios/six_joint.yaml").robots[0]
        s.robots[0].gains.K_R = [100.0] * 3
    assert "robots[0].gains.K_R must have 6 entries" in _refused(mutate)


def test_singular_six_joint_reference_is_refused():
    """Assumption 1: a path through a wrist singularity (pad axis along the forearm) exits 2."""
    def mutate(s):
        s.robots[0] = load_scenario("scenarios/six_joint.yaml").robots[0]
        s.robots[0].ee_rpy_deg = [0.0, 0.0, 0.0]      # pad pointing up: the wrist stretched
        s.robots[0].q_seed = [0.0] * 6
    message = _refused(mutate)
    assert message.startswith("robots[0] (robot1): ") and (
        "singular" in message or "out of reach" in message), message


def test_command_line_exits_2_naming_the_field(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("robots:\n- {normals: [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1]]}\n"
                    "- {name: b, model: crs_a255, base_xyz: [1.16, 0, 0], base_yaw_deg: 180, "
                    "contact_xy: [0.8192, 0], normals: [[1, 0, 0]], home: [0.9, 0, 0.6]}\n")
    proc = subprocess.run([sys.executable, "-m", "drake_coop", "run", str(path), "--out",
                           str(tmp_path / "out")], capture_output=True, text=True)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "robots[0].normals has 4 rows" in lines[0], proc.stderr


# ----------------------------------------------------------------------- systems, m = 2, 3
H = 0.009


def _law_for(m):
    from drake_coop.control.finger import FingerLaw

    robot = load_scenario().robots[0]
    robot.normals = NORMALS[m]
    robot.force_weights = [1.0] + [0.5] * (m - 1)
    A = np.random.default_rng(m).normal(size=(m, m))
    robot.gains.xi_matrix = (1e-5 * (A @ A.T + m * np.eye(m))).tolist()   # SPD, not diagonal
    arm = Arm(robot)
    return robot, arm, FingerLaw(arm_model(arm), robot.gains)


@pytest.mark.parametrize("m", [2, 3])
def test_force_observer_is_22_and_integrates_6_for_m_constraints(m):
    from drake_coop.control.observers import ForceObserver

    robot, arm, law = _law_for(m)
    g = robot.gains
    fo = ForceObserver(law, H)
    ctx = fo.CreateDefaultContext()
    DF = np.linspace(0.3, 0.9, m)
    ctx.SetDiscreteState(0, DF)
    q = arm.ik([0.6, 0.01, 0.56])
    q_hat, qdot_o = q - np.array([1e-4, 2e-4, -1e-4]), np.array([0.01, 0.02, -0.03])
    q_d, qdot_d = q + 1e-3, np.array([0.01, -0.02, 0.03])
    lam_d = np.array([12.0, 3.0, -2.0][:m])
    ref = law.layout.pack(q_d[None], qdot_d[None], np.zeros((1, 3)), lam_d[None], [1.0])[0]
    for name, value in (("q", q), ("q_hat", q_hat), ("qdot_o", qdot_o), ("reference", ref)):
        fo.GetInputPort(name).FixValue(ctx, value)
    N, xi = np.asarray(NORMALS[m]), np.asarray(g.xi_matrix)
    J = N @ arm.jacobian(q)
    Jp = np.linalg.pinv(J)
    qdot_r = ((np.eye(3) - Jp @ J) @ (qdot_d - g.Lambda * (q_hat - q_d))
              + Jp @ (-g.beta * N @ (arm.fk(q) - arm.c) + xi @ DF))
    expected = (Jp.T @ np.diag(g.K_R) @ (qdot_o - qdot_r) - g.k_F * DF) / (1 + g.zeta) + lam_d
    np.testing.assert_allclose(fo.GetOutputPort("lambda_hat").Eval(ctx), expected, atol=1e-9)
    update = fo.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector(0).CopyToVector()
    np.testing.assert_allclose(update, DF + H * (expected - lam_d), atol=1e-12)


@pytest.mark.parametrize("m", [2, 3])
def test_controller_at_rest_on_the_constraint_is_gravity_minus_JT_lambda_d(m):
    from drake_coop.control.controller import Controller

    robot, arm, law = _law_for(m)
    q = arm.ik(arm.c)                      # on every plane: φ(q) = 0
    lam_d = np.array([12.0, 3.0, -2.0][:m])
    ctrl = Controller(law, H)
    ctx = ctrl.CreateDefaultContext()
    ctx.SetTime(5 * H)
    ref = law.layout.pack(q[None], np.zeros((1, 3)), np.zeros((1, 3)), lam_d[None], [1.0])[0]
    for name, value in (("q", q), ("q_hat", q), ("qdot_hat", np.zeros(3)),
                        ("qdot_o", np.zeros(3)), ("lambda_hat", lam_d),
                        ("Delta_F_tilde", np.zeros(m)), ("reference", ref)):
        ctrl.GetInputPort(name).FixValue(ctx, value)
    J = np.asarray(NORMALS[m]) @ arm.jacobian(q)
    # The law at the tick's inputs, which the tick's update latches (the tau port is state and
    # holds the previous torque until then).
    np.testing.assert_allclose(ctrl.next_tau(ctx),
                               law.model.g(q) - J.T @ lam_d, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_force_observer_22_equals_21_for_m_constraints_in_the_loop():
    """(22) is (21) with the controller's own torque substituted, for every row (m = 2, 3)."""

    from tests.conftest import advance_to_tick

    scenario = multi_constraint_scenario()
    k = plan_run(scenario).k_grasp + 60
    exp, sim, ctx = advance_to_tick(scenario, k)
    for i, rs in enumerate(exp.robots):
        cc = rs.control.GetMyContextFromRoot(ctx)
        lam_22 = rs.control.GetOutputPort("lambda_hat").Eval(cc)
        terms = rs.controller.terms(rs.controller.GetMyContextFromRoot(ctx))
        q = exp.coop.arm_positions(exp.coop.plant.GetMyContextFromRoot(ctx), i)
        lam_21 = rs.law.force_estimate_21(q, terms["qdot_r"], terms["qddot_r_hat"],
                                          terms["tau"], True)
        assert lam_22.shape == (rs.law.m,) and rs.law.m in (2, 3)
        np.testing.assert_allclose(lam_21, lam_22, rtol=0, atol=1e-9)
        assert lam_22[0] > 0.1


@pytest.mark.parametrize("l", [2, 3, 5, 8])
def test_ring_of_l_arms_is_valid_and_its_squeezes_balance(l):
    """The benchmark's l arms around one object: a valid scenario, each base facing the
    centre, and the l equal squeezes along the normals summing to zero."""
    from drake_coop.scenario.ring import BASE_RADIUS, ring_scenario

    s = ring_scenario(l)
    assert [r.name for r in s.robots] == [f"robot{i + 1}" for i in range(l)]
    normals = np.array([r.normals[0] for r in s.robots])
    np.testing.assert_allclose(normals.sum(axis=0), 0.0, atol=1e-12)
    for r, n in zip(s.robots, normals):
        base = np.asarray(r.base_xyz)
        np.testing.assert_allclose(base, BASE_RADIUS * n, atol=1e-12)
        yaw = np.radians(r.base_yaw_deg)      # the base's x axis points at the centre
        np.testing.assert_allclose([np.cos(yaw), np.sin(yaw), 0.0], -n, atol=1e-12)
