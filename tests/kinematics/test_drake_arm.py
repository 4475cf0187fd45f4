"""Numeric kinematics from a URDF (:class:`drake_coop.kinematics.drake_arm.DrakeArmKinematics`).

Each quantity against an independent computation: the Jacobian and its bias term against
central differences of the forward kinematics; the joint reference against the Cartesian path
it was asked for and against differences of itself in time; on the paper's 3-joint arms, every
result against the closed forms of :class:`drake_coop.plant.arms.Arm`; ``check_path`` on paths
built so that the expected problem and its sample are known; the shipped 6-joint URDF against
the numbers of ``urdf/generate.py``.
"""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.tree import RevoluteJoint

from drake_coop.plant.arms import Arm
from drake_coop.kinematics.drake_arm import DrakeArmKinematics
from drake_coop.kinematics.redundant import SINGULAR_RATIO
from drake_coop.scenario import paper_robots

URDF = Path(__file__).resolve().parents[2] / "urdf"
CRS_MODELS = ("crs_a465", "crs_a255")    # paper_robots()[0], [1]
PLANES_B = (0.6, 0.8192)                  # their constraint planes x = b_i (Section IV)
EPS = 1e-6                                # step of the central differences in q

#: The 6-joint arm's base: away from the origin and turned, so that X_WB is exercised.
X_WB6 = RigidTransform(RotationMatrix.MakeZRotation(0.4), [0.2, -0.1, 0.05])
#: Tool pointing down (ee z axis along −z of the world).
R_D6 = X_WB6.rotation() @ RotationMatrix.MakeYRotation(math.pi)
Q_SEED6 = np.array([0.0, 0.8, 1.6, 0.0, 0.7, 0.0])


def _load_generate():
    spec = importlib.util.spec_from_file_location("urdf_generate", URDF / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def arm6():
    return DrakeArmKinematics(URDF / "coop6_6dof.urdf", X_WB6, R_d=R_D6, q_seed=Q_SEED6,
                              name="arm6")


def _crs_kinematics(i, arm, q_seed=None):
    """Numeric kinematics of paper robot i's URDF at its closed form's base pose."""
    X_WB = RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base)
    return DrakeArmKinematics(URDF / f"{CRS_MODELS[i]}_3dof.urdf", X_WB, q_seed=q_seed,
                              name=f"robot{i + 1}")


@pytest.fixture(scope="module", params=[0, 1], ids=["robot1", "robot2"])
def crs(request):
    """(closed-form Arm, numeric kinematics of the same URDF at the same base pose,
    a builder of the latter with a given ``q_seed``)."""
    i = request.param
    arm = Arm(paper_robots()[i])
    return arm, _crs_kinematics(i, arm), lambda q_seed: _crs_kinematics(i, arm, q_seed)


def _postures(kin, count, seed, fraction=0.8):
    rng = np.random.default_rng(seed)
    return rng.uniform(fraction * kin.q_min, fraction * kin.q_max, size=(count, kin.n))


def _vee(S):
    """Vector of a skew-symmetric matrix S = [w]×."""
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


def _path6(t):
    """A smooth Lissajous path of the 6-joint arm's E in its base frame, then in the world:
    position, velocity and acceleration (closed-form derivatives), each (K, 3)."""
    c = np.array([0.45, 0.0, 0.3])
    s1, c1, s2, c2 = np.sin(t), np.cos(t), np.sin(2 * t), np.cos(2 * t)
    zero = np.zeros_like(t)
    local = (c + np.column_stack([0.05 * s2, 0.1 * s1, 0.08 * c1]),
             np.column_stack([0.1 * c2, 0.1 * c1, -0.08 * s1]),
             np.column_stack([-0.2 * s2, -0.1 * s1, -0.08 * c1 + zero]))
    R = X_WB6.rotation().matrix()
    return (local[0] @ R.T + X_WB6.translation(), local[1] @ R.T, local[2] @ R.T)


# ------------------------------------------------------------------------- Jacobian and bias
def test_jacobian_equals_central_differences_of_position_and_rotation(arm6):
    for q in _postures(arm6, 8, seed=0):
        J = arm6.jacobian(q)
        assert J.shape == (6, 6)
        R = arm6.rotation(q)
        for j, e in enumerate(np.eye(6)):
            dx = (arm6.fk(q + EPS * e) - arm6.fk(q - EPS * e)) / (2 * EPS)
            dR = (arm6.rotation(q + EPS * e) - arm6.rotation(q - EPS * e)) / (2 * EPS)
            np.testing.assert_allclose(J[:3, j], dx, atol=1e-8)
            np.testing.assert_allclose(J[3:, j], _vee(dR @ R.T), atol=1e-8)


def test_position_only_jacobian_is_the_translational_rows(arm6):
    position_only = DrakeArmKinematics(URDF / "coop6_6dof.urdf", X_WB6)
    assert position_only.task_dim == 3
    for q in _postures(arm6, 3, seed=1):
        np.testing.assert_allclose(position_only.jacobian(q), arm6.jacobian(q)[:3], atol=0)


def test_bias_equals_the_jacobian_differentiated_along_v(arm6):
    rng = np.random.default_rng(2)
    for q in _postures(arm6, 6, seed=3):
        v = rng.normal(size=6)
        Jdot_v = (arm6.jacobian(q + EPS * v) - arm6.jacobian(q - EPS * v)) / (2 * EPS) @ v
        np.testing.assert_allclose(arm6.bias(q, v), Jdot_v, atol=1e-7)


def test_batched_calls_equal_single_ones(arm6):
    Q = _postures(arm6, 4, seed=4)
    np.testing.assert_array_equal(arm6.fk(Q), [arm6.fk(q) for q in Q])
    np.testing.assert_array_equal(arm6.rotation(Q), [arm6.rotation(q) for q in Q])
    np.testing.assert_array_equal(arm6.jacobian(Q), [arm6.jacobian(q) for q in Q])


# ------------------------------------------------------------------------- joint reference
@pytest.fixture(scope="module")
def reference6(arm6):
    dt = 2e-3
    t = np.arange(0.0, 2.0 + dt / 2, dt)
    x, xd, xdd = _path6(t)
    return dt, x, xd, xdd, arm6.joint_reference(x, xd, xdd)


def test_joint_reference_puts_E_on_the_path_with_the_held_orientation(arm6, reference6):
    _, x, _, _, (q, _, _) = reference6
    np.testing.assert_allclose(arm6.fk(q), x, atol=1e-10)
    np.testing.assert_allclose(arm6.rotation(q), np.broadcast_to(R_D6.matrix(), (len(q), 3, 3)),
                               atol=1e-10)
    assert np.all((q >= arm6.q_min) & (q <= arm6.q_max))


def test_joint_reference_velocity_and_acceleration_are_the_time_derivatives_of_q(reference6):
    dt, _, _, _, (q, qd, qdd) = reference6
    fd_qd = (q[2:] - q[:-2]) / (2 * dt)
    fd_qdd = (q[2:] - 2 * q[1:-1] + q[:-2]) / dt ** 2
    # central differences are exact to O(dt²) = 4e-6 times the third/fourth derivatives
    np.testing.assert_allclose(qd[1:-1], fd_qd, atol=2e-5)
    np.testing.assert_allclose(qdd[1:-1], fd_qdd, atol=2e-4)


def test_joint_reference_moves_E_with_the_path_velocity_and_acceleration(arm6, reference6):
    """Along ``q(t+s) ≈ q + s q̇ + ½ s² q̈`` the forward kinematics alone (no Jacobian) moves
    E with velocity ẋ and acceleration ẍ, and keeps the orientation still."""
    _, _, xd, xdd, (q, qd, qdd) = reference6
    s = 1e-3
    for k in range(0, len(q), 100):
        plus, minus = (arm6.fk(q[k] + h * qd[k] + 0.5 * h * h * qdd[k]) for h in (s, -s))
        np.testing.assert_allclose((plus - minus) / (2 * s), xd[k], atol=1e-6)
        np.testing.assert_allclose((plus - 2 * arm6.fk(q[k]) + minus) / s ** 2, xdd[k],
                                   atol=1e-5)
        dR = (arm6.rotation(q[k] + s * qd[k]) - arm6.rotation(q[k] - s * qd[k])) / (2 * s)
        np.testing.assert_allclose(_vee(dR @ R_D6.matrix().T), 0.0, atol=1e-6)


# ------------------------------------------------------------- the paper's arms, closed form
def test_forward_kinematics_and_jacobian_equal_the_closed_form(crs):
    arm, kin, _ = crs
    assert (kin.n, kin.task_dim) == (3, 3)
    Q = _postures(kin, 20, seed=5)
    np.testing.assert_allclose(kin.fk(Q), arm.fk(Q), atol=1e-9)
    np.testing.assert_allclose(kin.jacobian(Q), arm.jacobian(Q), atol=1e-9)


def test_inverse_kinematics_finds_the_closed_form_branch(crs):
    arm, kin, _ = crs
    rng = np.random.default_rng(6)
    for q in _postures(kin, 6, seed=7, fraction=0.5):
        q[2] = abs(q[2]) + 0.2                          # the closed form's branch: elbow up
        p = arm.fk(q)
        guess = arm.ik(p) + rng.uniform(-0.1, 0.1, size=3)
        np.testing.assert_allclose(kin.solve_ik(p, guess), arm.ik(p), atol=1e-9)


def test_joint_reference_equals_the_closed_form_on_the_paper_circle(crs):
    arm, kin, with_seed = crs
    w, r, dt = 2 * math.pi / 40.0, 0.05, 0.05                      # circle (28), 40 s period
    t = np.arange(0.0, 40.0, dt)
    b = PLANES_B[int(kin.name[-1]) - 1]
    x = np.column_stack([np.full_like(t, b), r * np.sin(w * t), 0.585 + r * np.cos(w * t)])
    xd = np.column_stack([0 * t, r * w * np.cos(w * t), -r * w * np.sin(w * t)])
    xdd = np.column_stack([0 * t, -r * w * w * np.sin(w * t), -r * w * w * np.cos(w * t)])
    kin = with_seed(arm.ik(x[0]) + 0.05)
    q, qd, qdd = kin.joint_reference(x, xd, xdd)
    np.testing.assert_allclose(q, arm.ik(x), atol=1e-9)
    J = arm.jacobian(q)
    np.testing.assert_allclose(qd, np.linalg.solve(J, xd[..., None])[..., 0], atol=1e-9)
    h = 1e-5                                # J̇ q̇ of the closed form by differences along q̇
    Jdot_qd = np.einsum("kij,kj->ki", (arm.jacobian(q + h * qd) - arm.jacobian(q - h * qd))
                        / (2 * h), qd)
    np.testing.assert_allclose(qdd, np.linalg.solve(J, (xdd - Jdot_qd)[..., None])[..., 0],
                               atol=1e-8)


# ------------------------------------------------------------------------------ check_path
def test_check_path_accepts_a_reachable_regular_path(arm6):
    x, _, _ = _path6(np.linspace(0.0, 2.0, 21))
    assert arm6.check_path(x) == ""


def test_check_path_names_a_point_out_of_reach(crs):
    arm, _, with_seed = crs
    kin = with_seed(np.array([0.0, 0.3, 1.2]))
    x = arm.fk(np.array([[0.0, 0.3, 1.2], [0.0, 0.3, 1.1]]))
    far = arm.p_base + np.array([0.0, 0.0, 3.0])              # 3 m above the base
    message = kin.check_path(np.vstack([x, far]))
    assert message.startswith(f"{kin.name}: point ") and "out of reach" in message
    assert message.endswith("at sample 2") and "\n" not in message


def test_check_path_names_the_joint_leaving_its_limits(crs):
    arm, _, with_seed = crs
    q_path = np.column_stack([np.full(41, 0.1), np.full(41, -0.2), np.linspace(1.7, 2.1, 41)])
    first = int(np.argmax(q_path[:, 2] > math.radians(110)))   # the published limit of J3
    kin = with_seed(q_path[0])
    message = kin.check_path(arm.fk(q_path))
    assert message == (f"{kin.name}: joint joint3 at {q_path[first, 2]:.4f} rad outside its "
                       f"limits [{-math.radians(110):.4f}, {math.radians(110):.4f}] "
                       f"at sample {first}")


def test_check_path_names_the_first_singular_posture(crs):
    arm, _, with_seed = crs
    q_path = np.column_stack([np.zeros(50), np.full(50, 0.4), np.geomspace(0.3, 1e-4, 50)])
    sigma = np.linalg.svd(arm.jacobian(q_path), compute_uv=False)   # closed form
    first = int(np.argmax(sigma[:, -1] / sigma[:, 0] < SINGULAR_RATIO))
    assert 0 < first < 49
    kin = with_seed(q_path[0])
    message = kin.check_path(arm.fk(q_path))
    assert message.startswith(f"{kin.name}: singular posture at sample {first} ")


@pytest.mark.parametrize("urdf, R_d, kind", [
    ("coop6_6dof.urdf", None, "6 joints for a 3-dimensional task: the arm is redundant"),
    ("crs_a465_3dof.urdf", RotationMatrix(),
     "3 joints for a 6-dimensional task: the arm is deficient"),
])
def test_check_path_and_joint_reference_refuse_a_non_square_task(urdf, R_d, kind):
    kin = DrakeArmKinematics(URDF / urdf, RigidTransform(), R_d=R_d, name="r")
    x = np.array([[0.4, 0.0, 0.5]])
    assert kin.check_path(x).startswith(f"r: {kind} (Assumption 1")
    with pytest.raises(ValueError, match=kind):
        kin.joint_reference(x, 0 * x, 0 * x)


def _planar_3r_urdf(folder: Path) -> Path:
    """Three revolute joints about parallel y axes: E moves in the x-z plane only."""
    links = "".join(
        f'<link name="l{k}"><inertial><mass value="1"/><origin xyz="0 0 0.15"/>'
        f'<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        for k in range(1, 4))
    joints = "".join(
        f'<joint name="j{k}" type="revolute"><parent link="{"base_link" if k == 1 else f"l{k-1}"}"/>'
        f'<child link="l{k}"/><origin xyz="0 0 {0 if k == 1 else 0.3}"/><axis xyz="0 1 0"/>'
        f'<limit lower="-2.5" upper="2.5" effort="50" velocity="3"/></joint>'
        for k in range(1, 4))
    path = folder / "planar3r.urdf"
    path.write_text(f'<robot name="planar"><link name="base_link"/>{links}{joints}'
                    f'<link name="pad"/><joint name="pad_fixed" type="fixed"><parent link="l3"/>'
                    f'<child link="pad"/><origin xyz="0 0 0.3"/></joint></robot>')
    return path


def test_a_planar_arm_is_refused_for_a_3d_task_not_called_out_of_reach(tmp_path):
    kin = DrakeArmKinematics(_planar_3r_urdf(tmp_path), RigidTransform(), name="r")
    assert kin.n == kin.task_dim == 3 and kin.generic_rank() == 2
    x = np.array([[0.3, 0.2, 0.5]])
    message = kin.check_path(x)
    assert message.startswith("r: its 3 joints move the end effector in only 2 of the 3 "
                              "directions"), message
    assert "out of reach" not in message
    with pytest.raises(ValueError, match="only 2 of the 3 directions"):
        kin.joint_reference(x, 0 * x, 0 * x)


def test_a_spatial_arm_has_full_generic_rank(arm6):
    assert arm6.generic_rank() == 6
    assert DrakeArmKinematics(URDF / "crs_a465_3dof.urdf", RigidTransform()).generic_rank() == 3


@pytest.mark.parametrize("frames", [{"base_frame": "plate"}, {"ee_frame": "tool0"}],
                         ids=["base", "ee"])
def test_an_unknown_frame_is_named(frames):
    name = next(iter(frames.values()))
    with pytest.raises(ValueError, match=f"^r: .*coop6_6dof.urdf has no frame '{name}'$"):
        DrakeArmKinematics(URDF / "coop6_6dof.urdf", RigidTransform(), name="r", **frames)


def test_solve_ik_raises_out_of_reach_with_the_name(arm6):
    with pytest.raises(ValueError, match=r"^arm6: point \[2\.0, 0\.0, 0\.0\] out of reach"):
        arm6.solve_ik(np.array([2.0, 0.0, 0.0]), Q_SEED6)


# --------------------------------------------------------------------- the 6-joint URDF
def test_six_joint_urdf_is_the_output_of_generate_py():
    gen = _load_generate()
    for model, p in gen.ARMS6.items():
        assert (URDF / f"{model}_6dof.urdf").read_text() == gen.arm6_urdf(model, p), \
            f"{model}: run python urdf/generate.py"


def test_six_joint_arm_has_the_numbers_of_generate_py():
    p = _load_generate().ARMS6["coop6"]
    kin = DrakeArmKinematics(URDF / "coop6_6dof.urdf", RigidTransform())
    plant = kin.plant
    assert kin.n == 6 and kin.joint_names == [f"joint{k}" for k in range(1, 7)]
    np.testing.assert_allclose(np.column_stack([kin.q_min, kin.q_max]),
                               np.radians(p["limits_deg"]), atol=1e-9)
    for k in range(6):
        joint = plant.GetJointByName(f"joint{k + 1}")
        assert isinstance(joint, RevoluteJoint)
        assert joint.default_damping() == p["damping"][k]
        actuator = plant.get_joint_actuator(plant.GetJointActuatorIndices()[k])
        assert actuator.joint().name() == f"joint{k + 1}"
        assert actuator.default_gear_ratio() == p["gear_ratio"][k]
        assert actuator.default_rotor_inertia() == p["rotor_inertia"][k]
        assert plant.GetBodyByName(f"link{k + 1}").default_mass() == p["links"][k][0]
    # straight up at q = 0: plate-to-shoulder + upper arm + forearm + wrist-to-flange + sensor
    # + pad radius
    gen = _load_generate()
    height = (p["h1"] + p["L2"] + p["L_forearm"] + p["L_flange"] + gen.SENSOR["length"]
              + gen.PAD["radius"])
    np.testing.assert_allclose(kin.fk(np.zeros(6)), [0.0, 0.0, height], atol=1e-12)
    for frame in ("force_sensor", "pad"):
        plant.GetBodyByName(frame)
    assert plant.GetJointByName("flange_sensor_weld").parent_body().name() == "link6"
    assert plant.GetJointByName("sensor_pad_weld").child_body().name() == "pad"


def test_six_joint_arm_has_a_spherical_wrist():
    """Axes of joints 4, 5, 6 pass through one point, L_forearm beyond the elbow."""
    p = _load_generate().ARMS6["coop6"]
    kin = DrakeArmKinematics(URDF / "coop6_6dof.urdf", X_WB6)
    plant, context = kin.plant, kin.context
    for q in _postures(kin, 10, seed=8):
        plant.SetPositions(context, q)
        axes = []
        for k in (3, 4, 5, 6):
            joint = plant.GetJointByName(f"joint{k}")
            X = joint.frame_on_child().CalcPoseInWorld(context)
            axes.append((X.translation(), X.rotation() @ joint.revolute_axis()))
        elbow, centre = axes[0][0], axes[2][0]      # origins of joints 3 and 5
        assert np.linalg.norm(centre - elbow) == pytest.approx(p["L_forearm"], abs=1e-12)
        for point, direction in axes[1:]:
            offset = centre - point
            assert np.linalg.norm(offset - (offset @ direction) * direction) < 1e-12


def test_six_joint_arm_inertia_stays_above_the_reflected_rotor_inertia_of_the_wrist():
    """λ_min(H) ≥ N² J_m of the wrist joints (0.45 kg·m²) over random postures: H is the links'
    inertia (positive semidefinite) plus the diagonal N² J_m (urdf/README.md)."""
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    p = _load_generate().ARMS6["coop6"]
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(URDF / "coop6_6dof.urdf"))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    reflected = min(N * N * J for N, J in zip(p["gear_ratio"], p["rotor_inertia"]))
    for q in _postures(DrakeArmKinematics(URDF / "coop6_6dof.urdf", RigidTransform()), 50, 9, 1.0):
        plant.SetPositions(context, q)
        assert np.linalg.eigvalsh(plant.CalcMassMatrix(context))[0] >= reflected
