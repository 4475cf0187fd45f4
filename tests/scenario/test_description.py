"""Arms from a description package (drake_coop.scenario.description): the package map entry,
the prepared URDF (locked joints, the tool, the base weld) against the package's own file,
and bad robot fields named in one line (exit 2 from the command line).

The tests that read example-robot-data skip when it is not installed (the ``robots`` extra);
the one about the missing extra runs everywhere.
"""

import dataclasses

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from drake_coop.control.arm_plant import description_packages
from drake_coop.scenario import ScenarioError, load_scenario
from drake_coop.scenario.resources import model_urdf_path, scenarios_dir
from drake_coop.scenario.schema import Robot, Tool

PANDA = "package://example-robot-data/robots/panda_description/urdf/panda.urdf"
HAVE_ROBOTS = "example-robot-data" in description_packages()
needs_robots = pytest.mark.skipif(
    not HAVE_ROBOTS, reason='example-robot-data is not installed (pip install -e ".[robots]")')


def panda_robot(**changes) -> Robot:
    robot = Robot(model=PANDA, base_frame="panda_link0",
                  locked_joints={"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.01},
                  tool=Tool(flange="panda_hand", sensor_xyz=[0.0, 0.0, 0.01],
                            pad_xyz=[0.0, 0.0, 0.0934]))
    return dataclasses.replace(robot, **changes)


def _plant(add) -> MultibodyPlant:
    plant = MultibodyPlant(0.0)
    add(Parser(plant))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("panda_link0"))
    plant.Finalize()
    return plant


@pytest.fixture(scope="module")
def panda_pair():
    """The package's own Panda (fingers free) and the prepared one, both welded at the base."""
    original = _plant(lambda p: (p.package_map().Add("example-robot-data",
                                                     str(description_packages()["example-robot-data"])),
                                 p.AddModelsFromUrl(PANDA)))
    prepared = _plant(lambda p: p.AddModels(str(model_urdf_path(panda_robot()))))
    return original, prepared


@needs_robots
def test_the_prepared_panda_has_seven_joints_and_its_fingers_where_they_were_locked(panda_pair):
    original, prepared = panda_pair
    assert original.num_positions() == 9 and prepared.num_positions() == 7
    assert prepared.num_actuators() == 7                  # a transmission for every joint
    rng = np.random.default_rng(3)
    arm = rng.uniform(-1.0, 1.0, 7)
    c0, c1 = original.CreateDefaultContext(), prepared.CreateDefaultContext()
    original.SetPositions(c0, np.concatenate([arm, [0.03, 0.01]]))
    prepared.SetPositions(c1, arm)
    for body in ("panda_hand", "panda_leftfinger", "panda_rightfinger"):
        X0 = original.GetBodyByName(body).EvalPoseInWorld(c0)
        X1 = prepared.GetBodyByName(body).EvalPoseInWorld(c1)
        assert X0.IsNearlyEqualTo(X1, 1e-12), body


@needs_robots
def test_the_pad_is_at_the_stated_offset_from_the_flange(panda_pair):
    """sensor 0.01 m + pad 0.0934 m along the hand's z: the package's own TCP frame (0.1034 m)."""
    original, prepared = panda_pair
    q = np.array([0.3, -0.5, 0.2, -2.0, 0.1, 2.5, 0.7])
    c0, c1 = original.CreateDefaultContext(), prepared.CreateDefaultContext()
    original.SetPositions(c0, np.concatenate([q, [0.0, 0.0]]))
    prepared.SetPositions(c1, q)
    tcp = original.GetFrameByName("panda_hand_tcp").CalcPoseInWorld(c0)
    pad = prepared.GetFrameByName("pad").CalcPoseInWorld(c1)
    assert tcp.IsNearlyEqualTo(pad, 1e-12)
    sensor = prepared.GetBodyByName("force_sensor")
    assert prepared.GetJointByName("flange_sensor_weld").child_body().index() == sensor.index()


@needs_robots
def test_the_base_is_welded_where_the_scenario_says():
    from drake_coop.plant.arms import Arm, arm_model

    robot = panda_robot(base_xyz=[1.3, 0.2, -0.15], base_yaw_deg=180.0)
    model = arm_model(Arm(robot))
    X = model.plant.GetFrameByName("panda_link0").CalcPoseInWorld(model.context)
    expected = RigidTransform(np.asarray(robot.base_xyz))
    assert np.allclose(X.translation(), expected.translation(), atol=1e-12)
    assert np.allclose(X.rotation().matrix()[:2, 0], [-1.0, 0.0], atol=1e-12)   # yaw 180°


def _scenario_text(**robot0) -> str:
    """two_pandas.yaml with fields of robot 1 replaced (YAML flow values)."""
    text = (scenarios_dir() / "two_pandas.yaml").read_text()
    lines = text.splitlines()
    start = lines.index("- name: robot1")
    for key, value in robot0.items():
        for i in range(start, len(lines)):
            if lines[i].startswith(f"  {key}:"):
                lines[i] = f"  {key}: {value}"
                break
        else:
            lines.insert(start + 1, f"  {key}: {value}")
    return "\n".join(lines) + "\n"


BAD_FIELDS = [
    ({"model": "package://no-such-robots/arm.urdf"}, "robots[0].model", "unknown package"),
    ({"base_frame": "panda_link_base"}, "robots[0].base_frame", "no link named"),
    ({"locked_joints": "{panda_finger_joint3: 0.0}"}, "robots[0].locked_joints",
     "no moving joint named 'panda_finger_joint3'"),
    ({"locked_joints": "{panda_finger_joint1: 0.5}"}, "robots[0].locked_joints",
     "within the joint's limits"),
    ({"tool": "{flange: panda_wrist}"}, "robots[0].tool.flange", "no link named"),
]


@needs_robots
@pytest.mark.parametrize("fields, name, problem", BAD_FIELDS)
def test_bad_robot_fields_are_named_in_one_line(fields, name, problem):
    with pytest.raises(ScenarioError) as info:
        load_scenario(data=_scenario_text(**fields))
    message = str(info.value)
    assert name in message and problem in message and "\n" not in message


@needs_robots
def test_a_bad_robot_field_exits_2_from_the_command_line(tmp_path, capsys):
    from drake_coop.cli import main

    path = tmp_path / "bad.yaml"
    path.write_text(_scenario_text(locked_joints="{panda_finger_joint3: 0.0}"))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "robots[0].locked_joints" in err[0]
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_missing_robots_extra_is_named(monkeypatch, tmp_path, capsys):
    """Without example-robot-data (here: looked for where it is not), one line names the extra
    and the command exits 2."""
    from drake_coop.cli import main
    from drake_coop.control import arm_plant

    monkeypatch.setattr(arm_plant, "DESCRIPTION_PACKAGES",
                        {"example-robot-data": "no/such/folder/example-robot-data"})
    with pytest.raises(ScenarioError, match=r'robots\[0\].model: .* install the robots extra: '
                                            r'pip install -e "\.\[robots\]"'):
        load_scenario(data=_scenario_text())
    path = tmp_path / "pandas.yaml"
    path.write_text(_scenario_text())
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'pip install -e ".[robots]"' in err[0]


def test_a_locked_revolute_joint_of_a_local_urdf_holds_the_links_where_they_were():
    """Locking is not only for packages: coop6's wrist joint 6 locked at 0.3 rad gives a
    5-joint arm whose pad is where the 6-joint arm's is with q6 = 0.3 (independent: the
    original file at that posture)."""
    from drake_coop.scenario.resources import urdf_dir

    robot = Robot(model="coop6", locked_joints={"joint6": 0.3})
    original, prepared = MultibodyPlant(0.0), MultibodyPlant(0.0)
    Parser(original).AddModels(str(urdf_dir() / "coop6_6dof.urdf"))
    Parser(prepared).AddModels(str(model_urdf_path(robot)))
    for plant in (original, prepared):
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
        plant.Finalize()
    assert prepared.num_positions() == 5 and prepared.num_actuators() == 5
    q = np.array([0.2, 0.4, 0.9, -0.3, 0.5])
    c0, c1 = original.CreateDefaultContext(), prepared.CreateDefaultContext()
    original.SetPositions(c0, np.append(q, 0.3))
    prepared.SetPositions(c1, q)
    X0 = original.GetFrameByName("pad").CalcPoseInWorld(c0)
    X1 = prepared.GetFrameByName("pad").CalcPoseInWorld(c1)
    assert X0.IsNearlyEqualTo(X1, 1e-12)


@needs_robots
def test_the_controller_plant_reads_the_package_url_and_the_prepared_file():
    """make_arm_controller_plant (the ArmModel of AddCooperativeController) knows the package
    by the URDFs' name: the package's own file parses (9 positions: the fingers are free), and
    the prepared file is the 7-joint arm whose model the controller uses."""
    from drake_coop.control.arm_model import ArmModel
    from drake_coop.control.arm_plant import make_arm_controller_plant

    raw = make_arm_controller_plant(PANDA, "panda_link0")
    assert raw.num_positions() == 9
    plant = make_arm_controller_plant(model_urdf_path(panda_robot()), "panda_link0")
    model = ArmModel(plant, "pad", [[1.0, 0.0, 0.0]], [0.5, 0.0, 0.5])
    assert model.n == 7 and model.H(np.zeros(7)).shape == (7, 7)


def test_an_identified_urdf_of_a_prepared_arm_is_not_prepared_twice(tmp_path):
    """``drake-coop identify`` writes its URDF from the prepared arm (locked joints fixed, the
    tool on): as the robot's ``controller_model`` it is used with neither applied again — the
    same 5-joint kinematics as the prepared model — where an unmarked copy of it is refused
    (the locked joint is no longer a moving joint)."""
    from drake_coop.scenario.description import IDENTIFIED_MARK, prepared_urdf
    from drake_coop.scenario.resources import urdf_dir

    robot = Robot(model="coop6", locked_joints={"joint6": 0.3})
    prepared = model_urdf_path(robot)
    text = prepared.read_text()
    root = text.index("<robot")
    head = text.index(">", root) + 1
    marked = tmp_path / "coop6_identified.urdf"
    marked.write_text(text[:head] + f"<!-- {IDENTIFIED_MARK} 5 s -->" + text[head:])
    again = prepared_urdf(robot, marked, "robots[0].controller_model")
    plants = []
    for path in (prepared, again):
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(path))
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
        plant.Finalize()
        plants.append(plant)
    assert [p.num_positions() for p in plants] == [5, 5]
    q = np.array([0.2, 0.4, 0.9, -0.3, 0.5])
    poses = []
    for plant in plants:
        context = plant.CreateDefaultContext()
        plant.SetPositions(context, q)
        poses.append(plant.GetFrameByName("pad").CalcPoseInWorld(context))
    assert poses[0].IsNearlyEqualTo(poses[1], 1e-12)
    unmarked = tmp_path / "coop6_copy.urdf"
    unmarked.write_text(text)
    with pytest.raises(ScenarioError, match="joint6"):
        prepared_urdf(robot, unmarked, "robots[0].controller_model")
    assert (urdf_dir() / "coop6_6dof.urdf").is_file()

