"""The squeeze within the torque limits (drake_coop.control.squeeze_limits and its check before a
contact run, drake_coop.experiment.squeeze_check): the torques against an independent Jᵀf at the
posture (Drake's CalcJacobianTranslationalVelocity of the contact point fixed in the pad, its
mass matrix, bias and gravity terms), the feasible squeezes against |τ| ≤ τ_max evaluated on a
grid, and a grasp no squeeze can hold within weak limits refused with one line naming the arm
and the time."""

from __future__ import annotations

import copy
import re

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable

from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object import load_distribution
from drake_coop.control.squeeze_limits import (
    check_squeeze_path,
    effort_limits,
    squeeze_interval,
    squeeze_torques,
)
from drake_coop.experiment.object_blocks import acceleration_samples
from drake_coop.experiment.plan import grasp_object, plan_run
from drake_coop.experiment.squeeze_check import check_squeeze_limits, torque_limits
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario import ScenarioError, load_scenario
from drake_coop.scenario.resources import find_scenario


@pytest.fixture(scope="module")
def contact():
    return load_scenario(find_scenario("contact"))


def _independent_torque(model, q, v, a, force, point_in_pad):
    """τ = M a + C v + D v − τ_g + J_cᵀ F with J_c of the contact point fixed in the pad body."""
    plant, context = model.plant, model.plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    plant.SetVelocities(context, v)
    frame = plant.GetFrameByName("pad")
    Jc = plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kV, frame,
                                                 point_in_pad, plant.world_frame(),
                                                 plant.world_frame())
    damping = np.zeros(plant.num_velocities())
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        if joint.num_velocities() == 1:
            damping[joint.velocity_start()] = joint.default_damping()
    return (plant.CalcMassMatrix(context) @ a + plant.CalcBiasTerm(context) + damping * v
            - plant.CalcGravityGeneralizedForces(context) + Jc.T @ force)


@pytest.mark.parametrize("index", [0, 1])
def test_torques_and_feasible_squeezes_against_an_independent_jacobian(contact, index):
    arm = Arm(contact.robots[index], contact.task)
    model = arm_model(arm, arm.urdf_path)
    rng = np.random.default_rng(3 + index)
    q = np.array([0.1, 0.6, 1.2]) if index == 0 else np.array([-0.2, 0.5, 1.4])
    v, a = rng.normal(0.0, 0.3, 3), rng.normal(0.0, 0.5, 3)
    nu = -np.asarray(contact.robots[index].normals[0], dtype=float)
    r = plan_run(contact).robots[index].contact_offset
    f = np.array([0.3, -0.2, 2.4])
    tau0, c = squeeze_torques(model, q, v, a, f, nu, r)
    # The contact point in the pad's frame: the pad's centre + r (r given in the world).
    plant, context = model.plant, model.plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    R_WP = plant.GetFrameByName("pad").CalcPoseInWorld(context).rotation().matrix()
    point = R_WP.T @ r
    for lam in (0.0, 7.5, 40.0):
        np.testing.assert_allclose(tau0 + lam * c,
                                   _independent_torque(model, q, v, a, f + lam * nu, point),
                                   rtol=1e-9, atol=1e-9)
    # The feasible squeezes: |τ(λ)| <= τ_max on every joint, checked on a fine grid.
    limits = np.abs(tau0) + np.array([20.0, 3.0, 2.0])
    lo, hi, _, j_hi = squeeze_interval(tau0, c, limits)
    grid = np.linspace(0.0, 200.0, 200_001)
    ok = np.all(np.abs(np.array([_independent_torque(model, q, v, a, f, point)]).T
                       + np.outer(_independent_torque(model, q, 0 * v, 0 * a, nu, point)
                                  - _independent_torque(model, q, 0 * v, 0 * a, 0 * nu, point),
                                  grid)) <= limits[:, None], axis=0)
    assert ok.any() and np.all(np.diff(ok.astype(int)) != 2)
    assert grid[ok][0] == pytest.approx(lo, abs=2e-3)
    assert grid[ok][-1] == pytest.approx(hi, abs=2e-3)
    assert abs(tau0[j_hi] + hi * c[j_hi]) == pytest.approx(limits[j_hi], rel=1e-12)


def test_an_interval_is_empty_when_no_squeeze_helps():
    lo, hi, j, _ = squeeze_interval([5.0, 1.0], [0.0, 1.0], [4.0, 10.0])
    assert lo > hi and j == 0
    lo, hi, _, _ = squeeze_interval([-12.0, 0.0], [-0.06, 0.2], [3.0, 10.0])   # needs λ < 0
    assert lo > hi


def test_effort_limits_are_the_urdfs(contact):
    arm = Arm(contact.robots[0], contact.task)
    text = arm.urdf_path.read_text()
    efforts = [float(x) for x in re.findall(r'effort="([0-9.eE+-]+)"', text)]
    limits = effort_limits(arm_model(arm, arm.urdf_path).plant)
    assert limits.tolist() == efforts[:limits.size] and limits.size == 3
    assert torque_limits(plan_run(contact).robots[0]).tolist() == limits.tolist()


def test_the_shipped_contact_scenario_is_within_its_limits(contact):
    check_squeeze_limits(plan_run(contact))


def _first_violation(scenario, index, limits):
    """The first held tick where the squeeze and the load need more than ``limits`` (computed
    with the independent torque, on the reference samples)."""
    arm = Arm(scenario.robots[index], scenario.task)
    model = arm_model(arm, arm.urdf_path)
    plan = plan_run(scenario)
    t, r = plan.robots[index].samples
    layout = ReferenceLayout(3, 1)
    obj = grasp_object(scenario, float(scenario.plant.object_mass))
    nu = obj.grasp_normals[index]
    off = plan.robots[index].contact_offset
    held = layout.column(r, "held")[:, 0] > 0.5
    xdd = acceleration_samples(plan.robots[index], t)
    for k in np.flatnonzero(held):
        q = layout.column(r[k:k + 1], "q_d")[0]
        v = layout.column(r[k:k + 1], "qdot_d")[0]
        a = layout.column(r[k:k + 1], "qddot_d")[0]
        lam = layout.column(r[k:k + 1], "lambda_d")[0, 0]
        plant, context = model.plant, model.plant.CreateDefaultContext()
        plant.SetPositions(context, q)
        R_WP = plant.GetFrameByName("pad").CalcPoseInWorld(context).rotation().matrix()
        F = load_distribution(obj, xdd[k])[index] + lam * nu
        tau = _independent_torque(model, q, v, a, F, R_WP.T @ off)
        if np.any(np.abs(tau) > limits):
            return t[k]
    return None


@pytest.mark.parametrize("limits, mass, expect", [
    ([2000.0, 20.0, 2000.0], 0.5, "they allow"),       # weak shoulder: less squeeze would do
    ([2000.0, 2000.0, 3.0], 0.5, "no squeeze"),        # weak elbow: no squeeze helps
    ([2000.0, 40.0, 2000.0], 6.0, None),               # a heavy box on a moderate shoulder
])
def test_a_grasp_beyond_the_limits_is_refused_in_one_line(contact, limits, mass, expect):
    s = copy.deepcopy(contact)
    s.robots[0].actuators.torque_limits = limits
    s.plant.object_mass = mass
    with pytest.raises(ScenarioError) as info:
        check_squeeze_limits(plan_run(s))
    message = str(info.value)
    assert "\n" not in message and message.startswith("robots[0] (robot1): at t = ")
    if expect:
        assert expect in message
    t_named = float(re.search(r"at t = ([0-9.]+) s", message).group(1))
    assert t_named == pytest.approx(_first_violation(s, 0, np.array(limits)), abs=1e-3)


def test_the_run_command_refuses_before_building(tmp_path, capsys, contact):
    from drake_coop.cli import main
    from drake_coop.scenario.loading import dump_scenario

    s = copy.deepcopy(contact)
    s.robots[1].actuators.torque_limits = [2000.0, 2000.0, 3.0]
    path = tmp_path / "weak.yaml"
    path.write_text(dump_scenario(s))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert err.startswith("drake-coop: error: robots[1] (robot2): at t = ")
    assert not out.exists()


def test_check_squeeze_path_names_the_joint_and_time():
    t = np.array([0.0, 0.1, 0.2])
    tau0 = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    c = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    check_squeeze_path(t, tau0, c, np.array([1.0, 2.0, 3.0]), np.array([2.0, 3.0]), "arm")
    with pytest.raises(ValueError, match=r"^arm: at t = 0\.200 s .* squeeze 4 N need 4 at wrist,"
                                         r" beyond its torque limit 3; they allow 0 to 3 N"):
        check_squeeze_path(t, tau0, c, np.array([1.0, 2.0, 4.0]), np.array([2.0, 3.0]), "arm",
                           ["shoulder", "wrist"])
