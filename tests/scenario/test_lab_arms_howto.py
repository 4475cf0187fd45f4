"""The lab-arms guide's how-to ("An arm the project does not ship"): the scenarios written from it
(``docs/guide/lab_arms_howto/*.yaml``: two xArm7s and two Unitree Z1s carrying boxes the
project does not ship, without gains) load as ``drake-coop gains`` loads them, build the run's
Diagram, and put each pad where the how-to says (checked with Drake's forward kinematics in the
built plant, independently of the reference's own kinematics); ``drake-coop arms`` gives each
arm's tool axis (checked by turning the flange's last joint: the pad stays on its axis line);
the gains' stability map is computed without the object model (whose estimated mass is a
marginal mode of the map whatever the gains). Skipped without example-robot-data."""

from pathlib import Path

import numpy as np
import pytest

from drake_coop.control.arm_plant import description_packages
from drake_coop.scenario.lab_arms import LAB_ARMS, SENSOR_RPY_FOR_AXIS, arm_facts, lab_arm_robot
from drake_coop.scenario.loading import load_scenario
from drake_coop.scenario.resources import find_scenario
from drake_coop.scenario.schema import Tool
from drake_coop.stability import gains as rules

HOWTO = Path(__file__).resolve().parents[2] / "docs" / "guide" / "lab_arms_howto"
FILES = sorted(HOWTO.glob("*.yaml"))
robots_extra = pytest.mark.skipif(
    "example-robot-data" not in description_packages(),
    reason='example-robot-data is not installed (pip install -e ".[robots]")')


def test_the_howto_ships_its_scenarios_and_the_guide_names_them():
    assert [f.name for f in FILES] == ["two_xarm7_box.yaml", "two_z1_box.yaml"]
    guide = (HOWTO.parent / "lab_arms.md").read_text()
    for f in FILES:
        assert f"lab_arms_howto/{f.name}" in guide


@robots_extra
@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_the_howto_scenario_builds_and_places_each_pad_where_the_guide_says(path):
    from pydrake.math import RigidTransform

    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.stability.gains_cli import load_for_gains

    s = load_for_gains(str(path))            # what `drake-coop gains` reads: no gains given
    assert s.plant.object_mode == "contact" and s.object_model.mode == "estimated"
    plan = plan_run(s, t_end=s.task.t_grasp + 0.1)
    exp = build_experiment(plan)
    plant = exp.coop.plant
    context = plant.CreateDefaultContext()
    box = plant.GetBodyByName("box")
    assert box.default_mass() == pytest.approx(s.plant.object_mass, rel=1e-12)
    names = {ss.get_name() for ss in exp.diagram.GetSystems()}
    for r in s.robots:
        assert f"{r.name}_mass_estimator" in names
    # At the grasp each pad's centre is on its contact point (its surface on the box's face)
    # and its approach axis (the pad's z) points into the box, along -normal.
    for i, r in enumerate(s.robots):
        t, ref = plan.robots[i].samples
        k = int(np.argmin(np.abs(t - s.task.t_grasp)))
        instance = exp.coop.arms[i].instance
        plant.SetPositions(context, instance, plan.robots[i].layout.column(ref, "q_d")[k])
        X = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("pad", instance))
        assert isinstance(X, RigidTransform)
        expected = [*r.contact_xy, plan.z_grasp]
        assert np.allclose(X.translation(), expected, atol=1e-4), (r.name, X.translation())
        normal = np.asarray(r.normals[0], dtype=float)
        assert np.allclose(X.rotation().matrix()[:, 2], -normal, atol=1e-6), r.name


@robots_extra
@pytest.mark.parametrize("name", sorted(LAB_ARMS))
def test_the_tool_axis_of_arms_is_the_flange_axis_its_last_joint_turns_about(name):
    """The pad mounted as ``drake-coop arms --yaml`` says (the sensor turned onto the tool
    axis, the pad 45 mm out along the sensor's z) lies on the last joint's axis line — turning
    that joint does not move it — 45 mm beyond the flange, away from the joint's parent body."""
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from drake_coop.scenario.resources import model_urdf_path

    facts = arm_facts(name)
    if len(facts.joints) < 6:
        pytest.skip("a 5-joint arm holds a position task: its pad's orientation is free (the "
                    "SO-ARM101's gripper frame is off its wrist-roll axis)")
    robot = lab_arm_robot(name)
    robot.tool = Tool(flange=robot.tool.flange,
                      sensor_rpy_deg=SENSOR_RPY_FOR_AXIS[facts.tool_axis])
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(model_urdf_path(robot)))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(robot.base_frame))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    q = 0.5 * (np.asarray(facts.lower) + np.asarray(facts.upper))
    pad, flange = plant.GetBodyByName("pad"), plant.GetBodyByName(robot.tool.flange)
    body = flange                                   # the last moving joint before the flange
    while True:
        joint = next(plant.get_joint(j) for j in plant.GetJointIndices()
                     if plant.get_joint(j).child_body().index() == body.index())
        if joint.num_velocities() == 1:
            break
        body = joint.parent_body()
    last = joint
    plant.SetPositions(context, q)
    p0 = plant.EvalBodyPoseInWorld(context, pad).translation()
    f0 = plant.EvalBodyPoseInWorld(context, flange).translation()
    parent = plant.EvalBodyPoseInWorld(context, last.parent_body()).translation()
    q1 = q.copy()
    q1[last.position_start()] += 0.7
    plant.SetPositions(context, q1)
    p1 = plant.EvalBodyPoseInWorld(context, pad).translation()
    assert np.linalg.norm(p1 - p0) < 1e-9, (name, facts.tool_axis, p1 - p0)
    assert np.linalg.norm(p0 - f0) == pytest.approx(0.045, abs=1e-9)
    assert (p0 - f0) @ (f0 - parent) > 0.0, name


def test_the_gains_map_is_computed_without_the_object_model():
    s = load_scenario(find_scenario("contact"))
    s.object_model.mode = "estimated"
    s.object_model.squeeze = "friction"          # refused without an object model: reset too
    checked, mode = rules.map_copy(s)
    assert mode == "planes" and checked.object_model.mode == "none"
    assert checked.object_model.squeeze == "profile"
    assert s.object_model.mode == "estimated"        # the input is left as it is
    from drake_coop.scenario import validate
    validate(checked)                                # the copy is a valid scenario


def test_an_estimated_mass_is_a_marginal_mode_of_the_map_whatever_the_gains():
    """Why the map is computed without the object model: at the free point the mass
    estimator does not update, so its estimate is an eigenvalue 1 of the map (ρ = 1 for the
    paper's own gains), which the paper's loop without it does not have (ρ < 1)."""
    import copy

    from drake_coop.stability.operating import operating_point
    from drake_coop.stability.period_map import analyse

    s = load_scenario(find_scenario("contact"))
    s.object_model.mode = "estimated"
    with_model = copy.deepcopy(s)
    with_model.plant.object_mode = "planes"       # what the map copy was before
    report = analyse(operating_point(with_model, "free").map, epsilon=1e-5)
    assert report.rho == pytest.approx(1.0, abs=1e-9)
    assert any("mass_estimator" in d for d in report.slowest.dominant)
    checked, _ = rules.map_copy(s)
    assert analyse(operating_point(checked, "free").map, epsilon=1e-5).rho < 0.99


@robots_extra
def test_drake_warns_once_per_message_about_a_prepared_arm(caplog):
    """The xArm7's URDF has joint friction and gear reductions Drake ignores, with a warning
    at every load: a run loads the prepared file many times; each warning reaches the log
    once (the file loaded here twice: the second load adds no record)."""
    import logging

    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from drake_coop.scenario.resources import model_urdf_path

    robot = lab_arm_robot("xarm7")
    robot.tool = Tool(flange=robot.tool.flange, pad_radius=0.0151)   # a file of this test's own
    path = model_urdf_path(robot)

    def load() -> list[str]:
        caplog.clear()
        plant = MultibodyPlant(0.0)
        with caplog.at_level(logging.WARNING, logger="drake"):
            Parser(plant).AddModels(str(path))
        return [r.getMessage() for r in caplog.records if str(path) in r.getMessage()]

    first, second = load(), load()
    assert any("mechanicalReduction" in m for m in first)
    assert len(first) == len(set(first))
    assert second == []


@robots_extra
@pytest.mark.parametrize("name", ["xarm7", "z1"])
def test_the_printed_entry_is_a_robot_with_its_tool_on_the_tool_axis(name):
    """``drake-coop arms --yaml NAME`` prints a robot entry the schema reads, its sensor turned
    onto the arm's tool axis (the Z1's +x, the xArm7's +z: none) and its pad approaching along
    +x (the pad's z, world frame, from Drake's roll-pitch-yaw)."""
    import yaml
    from pydrake.common.yaml import yaml_load_typed
    from pydrake.math import RollPitchYaw

    from drake_coop.scenario.arms_cli import _yaml
    from drake_coop.scenario.schema import Robot

    entry = yaml.safe_load(_yaml(name))[0]
    robot = yaml_load_typed(schema=Robot, data=yaml.safe_dump(entry))
    assert robot.tool.sensor_rpy_deg == SENSOR_RPY_FOR_AXIS[arm_facts(name).tool_axis]
    assert robot.tool.sensor_rpy_deg == ([0.0, 90.0, 0.0] if name == "z1" else [0.0, 0.0, 0.0])
    R = RollPitchYaw(np.radians(robot.ee_rpy_deg)).ToRotationMatrix().matrix()
    assert np.allclose(R[:, 2], [1.0, 0.0, 0.0], atol=1e-12)
    assert robot.normals == [[-1.0, 0.0, 0.0]]
